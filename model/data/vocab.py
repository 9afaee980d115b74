"""Fixed vocabulary of the dataset: part labels, categories, and the synonym tables the
description generator uses (and a free-form prompt parser can import).

Everything here is plain data (tuples / dicts of strings) plus a few pure lookup helpers; it
is part of the data contract, so entries are only ever added, never renamed.

* ``LABELS``: the part-label vocabulary, in a fixed order (index = class id).
* ``CATEGORIES``: the six object categories of the paper (PartNet-Mobility names).
* ``CATEGORY_SYNONYMS`` / ``PART_SYNONYMS`` / ``PART_PLURALS`` / ``MOTION_SYNONYMS``: the
  wordings used in descriptions. The first entry of each list is the canonical wording.
* ``SIDE_DIRECTIONS`` / ``side_of``: the one definition of "left" / "right" (the viewer's,
  facing the object's front: left = -y) and of top / bottom / front / back.
* ``OPENING_PHRASES``, ``ROW_PHRASES``, ``COLUMN_PHRASES``, ``ROLE_NAMES``: wordings
  of the spatial facts and part roles of the descriptions (everyday object names are in
  ``CATEGORY_SYNONYMS``; ``model.data.describe.everyday_names`` says when each fits).
* ``PARTNET_LABEL_MAP``: real PartNet-Mobility semantic names → our labels.
* ``semantic_text(category, label)`` → "storage furniture, drawer" (the part's semantic
  condition text, DESIGN §4.2).
"""
from __future__ import annotations

import re

# --- part labels ----------------------------------------------------------------------------
LABELS: tuple[str, ...] = (
    "body",     # the root carcass / housing / bottle body
    "drawer",   # open box that slides out (prismatic)
    "door",     # hinged (revolute) panel closing an opening; round doors of washers too
    "handle",   # pull / bar / knob-like grip, a fixed child of a drawer, door or lid
    "knob",     # control knob turning about its own axis (continuous or revolute)
    "button",   # push button (prismatic, a few millimetres)
    "dial",     # larger rotary selector (continuous or revolute)
    "lid",      # hinged top cover (flip lid, washer top lid)
    "cap",      # bottle screw cap (screw) or USB cap (revolute swivel / prismatic slide-off)
    "tray",     # oven rack / tray sliding out (prismatic)
    "other",    # anything of the real data that maps to none of the above
)
LABEL_INDEX = {name: i for i, name in enumerate(LABELS)}

# Labels that are parts a user counts ("two drawers"); body/other are not counted in prompts.
COUNTABLE_LABELS: tuple[str, ...] = ("drawer", "door", "handle", "knob", "button", "dial",
                                     "lid", "cap", "tray")

# --- categories -----------------------------------------------------------------------------
CATEGORIES: tuple[str, ...] = ("StorageFurniture", "Safe", "Oven", "WashingMachine", "Bottle", "USB")
CATEGORY_INDEX = {name: i for i, name in enumerate(CATEGORIES)}

CATEGORY_TEXT: dict[str, str] = {
    "StorageFurniture": "storage furniture",
    "Safe": "safe",
    "Oven": "oven",
    "WashingMachine": "washing machine",
    "Bottle": "bottle",
    "USB": "usb",
}

CATEGORY_SYNONYMS: dict[str, tuple[str, ...]] = {
    "StorageFurniture": ("cabinet", "storage cabinet", "cupboard", "dresser", "chest of drawers",
                         "sideboard", "storage unit", "nightstand", "filing cabinet", "wardrobe",
                         "storage furniture", "chest", "locker", "bedside table", "credenza",
                         "armoire", "file cabinet", "bedside cabinet"),
    "Safe": ("safe", "strongbox", "lockbox", "security safe", "safe box", "vault box",
             "microwave-sized safe", "small safe", "compact safe"),
    "Oven": ("oven", "stove", "cooker", "range", "kitchen oven", "wall oven", "kitchen range"),
    "WashingMachine": ("washing machine", "washer", "laundry machine", "clothes washer",
                       "front-loader", "top-loader", "front-loading washer", "top-loading washer",
                       "top loader", "front-loading washing machine"),
    "Bottle": ("bottle", "flask", "water bottle", "jar", "container", "drink bottle",
               "flip-top bottle", "sports bottle", "screw-top bottle"),
    "USB": ("usb stick", "usb drive", "flash drive", "thumb drive", "memory stick", "pen drive",
            "usb flash drive", "usb", "swivel usb stick", "swivel flash drive"),
}

# --- parts ----------------------------------------------------------------------------------
PART_SYNONYMS: dict[str, tuple[str, ...]] = {
    "body": ("body", "frame", "carcass", "housing", "shell", "main body"),
    "drawer": ("drawer", "pull-out drawer", "sliding drawer", "storage drawer"),
    "door": ("door", "hinged door", "panel door", "swing door"),
    "handle": ("handle", "pull", "grip", "pull handle"),
    "knob": ("knob", "control knob", "rotary knob", "turn knob"),
    "button": ("button", "push button", "push-button", "press button"),
    "dial": ("dial", "rotary dial", "selector dial", "control dial"),
    "lid": ("lid", "flip lid", "hinged lid", "flip-top", "top cover"),
    "cap": ("cap", "cover cap", "protective cap", "closure"),
    "tray": ("tray", "rack", "sliding tray", "oven rack", "shelf tray"),
    "other": ("part", "component", "piece"),
}

_IRREGULAR_PLURALS = {"chest of drawers": "chests of drawers", "shelf": "shelves",
                      "shelf tray": "shelf trays", "flip-top": "flip-tops", "usb": "usbs"}


def plural(word: str) -> str:
    """English plural of a (possibly multi-word) noun phrase."""
    if word in _IRREGULAR_PLURALS:
        return _IRREGULAR_PLURALS[word]
    if re.search(r"(s|x|ch|sh)$", word):
        return word + "es"
    if re.search(r"[^aeiou]y$", word):
        return word[:-1] + "ies"
    return word + "s"


PART_PLURALS: dict[str, tuple[str, ...]] = {k: tuple(plural(w) for w in v)
                                            for k, v in PART_SYNONYMS.items()}

# --- motion ---------------------------------------------------------------------------------
# Keys are model.core.JointType names in lower case. Phrases complete "the <part> ...".
MOTION_SYNONYMS: dict[str, tuple[str, ...]] = {
    "revolute": ("is hinged", "swings open", "rotates on a hinge", "pivots open", "opens on a hinge"),
    "prismatic": ("slides out", "pulls out", "slides open", "moves in and out on runners",
                  "translates outward"),
    "continuous": ("spins freely", "turns without limit", "rotates continuously",
                   "can be turned all the way round"),
    "screw": ("screws on and off", "twists off", "unscrews", "turns and lifts off on a thread"),
    "fixed": ("is fixed", "is rigidly attached", "does not move", "is fixed in place"),
}
# Adjectives for the same facts ("a hinged door", "a sliding drawer").
MOTION_ADJECTIVES: dict[str, tuple[str, ...]] = {
    "revolute": ("hinged", "swinging", "pivoting"),
    "prismatic": ("sliding", "pull-out", "slide-out"),
    "continuous": ("freely spinning", "rotating", "turning"),
    "screw": ("screw-on", "threaded", "twist-off"),
    "fixed": ("fixed", "static", "rigid"),
}
# Label-specific wording that reads better than the generic one (same joint facts).
LABEL_MOTION_SYNONYMS: dict[tuple[str, str], tuple[str, ...]] = {
    ("button", "prismatic"): ("can be pressed in", "pushes in", "presses in", "can be pushed"),
    ("knob", "revolute"): ("turns", "rotates within a limited range", "twists to a stop"),
    ("dial", "revolute"): ("turns", "rotates within a limited range", "twists to a stop"),
    ("cap", "revolute"): ("swivels", "swings around", "pivots open", "rotates on a pivot"),
    ("cap", "prismatic"): ("slides off", "pulls off", "slides forward off the plug"),
}
LABEL_MOTION_ADJECTIVES: dict[tuple[str, str], tuple[str, ...]] = {
    ("button", "prismatic"): ("push", "pressable"),
    ("cap", "revolute"): ("swivel", "swivelling"),
    ("cap", "prismatic"): ("slide-off", "removable"),
}
# --- sides: the ONE definition of "left" and "right" -------------------------------------------
# Object frame (DESIGN §2, REP-103): x forward out of the object's front, y to the object's own
# left, z up. "Left" and "right" in every text of this project (the generator's hinge sides, the
# descriptions, the prompt parser, the alignment check) are the VIEWER's: a person standing in
# front of the object and facing it looks towards -x, so the viewer's left is -y and the
# viewer's right is +y. "Back" is -x (away from the viewer), "front" +x.
SIDE_DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "left": (0.0, -1.0, 0.0),     # the viewer's left, facing the object's front
    "right": (0.0, 1.0, 0.0),
    "top": (0.0, 0.0, 1.0),
    "bottom": (0.0, 0.0, -1.0),
    "front": (1.0, 0.0, 0.0),
    "back": (-1.0, 0.0, 0.0),
}


def side_of(vector) -> str:
    """The side word (:data:`SIDE_DIRECTIONS`) a direction in the object frame points to."""
    v = [float(x) for x in vector]
    return max(SIDE_DIRECTIONS, key=lambda k: sum(a * b for a, b in zip(SIDE_DIRECTIONS[k], v)))


# Hinge / mounting sides used by the generator (metadata "side").
SIDE_WORDS: dict[str, tuple[str, ...]] = {
    "left": ("left", "left-hand"),
    "right": ("right", "right-hand"),
    "top": ("top", "upper"),
    "bottom": ("bottom", "lower"),
    "front": ("front",),
    "back": ("back", "rear"),
}

# --- spatial facts (model.data.describe.spatial_summary) --------------------------------------
# Direction a door or lid opens (where its free edge goes): "down" (a drop-down oven door),
# "up" (a lid, a top-hinged flap), "sideways" (a side-hinged door).
# Each phrase completes "the <part> ..." (said of a part that turns on a hinge).
OPENING_PHRASES: dict[str, tuple[str, ...]] = {
    "down": ("swings down", "drops down", "folds down", "swings open downward", "opens downward"),
    "up": ("swings up", "flips up", "swings open upward", "lifts up on its hinge", "opens upward"),
    "sideways": ("swings open sideways", "swings to the side", "swings sideways", "opens sideways"),
}
# Arrangement of a group of like parts ("layout" of the summary): a single row, a single column
# (one above the other) or a grid of rows x columns.
ROW_PHRASES: tuple[str, ...] = ("side by side", "in a row", "next to each other", "in a single row")
COLUMN_PHRASES: tuple[str, ...] = ("stacked", "stacked one above the other", "one above the other",
                                   "in a single column", "stacked vertically")
# Names of a part by its role, used only where the role is certain: (category, label) -> words.
ROLE_NAMES: dict[tuple[str, str], tuple[str, ...]] = {
    ("WashingMachine", "dial"): ("program dial", "program selector"),
    ("WashingMachine", "drawer"): ("detergent drawer", "soap drawer"),
    ("Safe", "dial"): ("combination dial",),
    ("Oven", "knob"): ("control knob", "burner knob"),
}

NUMBER_WORDS: tuple[str, ...] = ("zero", "one", "two", "three", "four", "five", "six", "seven",
                                 "eight", "nine", "ten", "eleven", "twelve", "thirteen",
                                 "fourteen", "fifteen", "sixteen", "seventeen", "eighteen",
                                 "nineteen", "twenty")
NUMBER_VALUES: dict[str, int] = {w: i for i, w in enumerate(NUMBER_WORDS)}
NUMBER_VALUES.update({"a": 1, "an": 1, "single": 1, "a single": 1, "one single": 1, "a pair of": 2,
                      "pair of": 2, "double": 2, "twin": 2, "both": 2, "several": 3, "multiple": 3})


def number_word(n: int) -> str:
    return NUMBER_WORDS[n] if 0 <= n < len(NUMBER_WORDS) else str(n)


# --- real PartNet-Mobility semantics -> our labels ------------------------------------------
PARTNET_LABEL_MAP: dict[str, str] = {
    # bodies
    "furniture_body": "body", "body": "body", "bottle_body": "body", "usb_body": "body",
    "base_body": "body", "oven_body": "body", "washing_machine_body": "body", "safe_body": "body",
    "frame": "body", "base": "body", "shell": "body", "case": "body",
    # moving parts
    "drawer": "drawer", "door": "door", "rotation_door": "door", "translation_door": "door",
    "slider_door": "door", "door_frame": "door", "handle": "handle", "knob": "knob",
    "button": "button", "switch": "button", "toggle_button": "button", "press_button": "button",
    "dial": "dial", "rotation_knob": "knob", "lid": "lid", "rotation_lid": "lid",
    "translation_lid": "lid", "cap": "cap", "usb_rotation": "cap", "usb_cap": "cap",
    "tray": "tray", "shelf": "tray", "board": "tray", "rack": "tray",
}


def map_partnet_label(name: str) -> str:
    """Map a PartNet-Mobility semantic name (or any free label) to a vocabulary label."""
    key = name.strip().lower().replace(" ", "_").replace("-", "_")
    if key in LABEL_INDEX:
        return key
    if key in PARTNET_LABEL_MAP:
        return PARTNET_LABEL_MAP[key]
    for token, label in (("drawer", "drawer"), ("door", "door"), ("handle", "handle"),
                         ("knob", "knob"), ("button", "button"), ("dial", "dial"), ("lid", "lid"),
                         ("cap", "cap"), ("tray", "tray"), ("body", "body")):
        if token in key:
            return label
    return "other"


def semantic_text(category: str, label: str) -> str:
    """The part's semantic-condition text, e.g. ``"storage furniture, drawer"``."""
    return f"{CATEGORY_TEXT.get(category, category.lower())}, {label}"


# --- reverse lookups (for prompt parsing) ---------------------------------------------------
def _reverse(table: dict[str, tuple[str, ...]], extra: dict[str, tuple[str, ...]] | None = None
             ) -> dict[str, str]:
    out: dict[str, str] = {}
    for key, words in table.items():
        for w in words:
            out.setdefault(w, key)
    for key, words in (extra or {}).items():
        for w in words:
            out.setdefault(w, key)
    return out


PHRASE_TO_LABEL: dict[str, str] = _reverse(PART_SYNONYMS, PART_PLURALS)
PHRASE_TO_CATEGORY: dict[str, str] = _reverse(
    CATEGORY_SYNONYMS, {k: tuple(plural(w) for w in v) for k, v in CATEGORY_SYNONYMS.items()})
PHRASE_TO_JOINT: dict[str, str] = _reverse(MOTION_SYNONYMS, MOTION_ADJECTIVES)
for (_label, _jt), _words in list(LABEL_MOTION_SYNONYMS.items()) + list(LABEL_MOTION_ADJECTIVES.items()):
    for _w in _words:
        PHRASE_TO_JOINT.setdefault(_w, _jt)


def lookup_label(phrase: str) -> str | None:
    """Part label of a singular or plural synonym (``"pull-out drawers"`` → ``"drawer"``)."""
    return PHRASE_TO_LABEL.get(phrase.strip().lower())


def lookup_category(phrase: str) -> str | None:
    return PHRASE_TO_CATEGORY.get(phrase.strip().lower())
