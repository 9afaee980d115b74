"""The words the prompt parser (model.metrics.prompt_parse) knows and the tokenizer that finds
them: the vocabulary of ``model.data.vocab`` (categories, part synonyms and plurals, motion
phrases) plus the extra wordings a person may use below, compiled into one longest-match
regex (``_lexicon``) whose tokens carry a kind (CAT PART MOTION NUM ZERO LOWER DET DIST
MULT WORD PUNCT) and a value.

    _tokenize("two sliding drawers")   # [NUM "two" = 2, PART "sliding drawers" = drawer (plural)]
"""
from __future__ import annotations

import functools
import re
from dataclasses import dataclass

from model.data import vocab

# Extra wordings a person may use that the description templates do not (owned here).
EXTRA_CATEGORY = {
    "StorageFurniture": ("closet", "armoire", "bureau", "locker", "credenza", "cupboards",
                         "tv stand", "media console", "pedestal", "base unit", "shoe cabinet",
                         "bathroom cabinet", "display cabinet", "pantry cupboard",
                         "cabinets", "dressers", "kitchen cabinet", "bedside table",
                         "bedside cabinet", "night stand", "tallboy", "chest-of-drawers",
                         "file cabinet", "drawer unit", "drawer cabinet", "tv console",
                         "console table", "vanity", "bathroom vanity", "hutch", "china hutch",
                         "buffet cabinet", "media cabinet", "card catalog", "card catalogue",
                         "cubby unit", "apothecary cabinet", "spice cabinet", "tool chest",
                         "medicine cabinet", "flat file cabinet", "plan chest", "shoe rack",
                         "jewelry box", "jewellery box", "jewelry chest", "side table",
                         "end table", "toolbox", "tool box", "printer stand", "kitchen island",
                         "pantry", "pantry cabinet", "bookcase", "bookshelf", "china cabinet",
                         "curio cabinet", "desk pedestal", "wall cabinet", "base cabinet",
                         "toy box", "toy trunk", "blanket box", "trunk", "storage trunk",
                         "storage box", "storage bench", "storage ottoman", "ottoman",
                         "refrigerator", "fridge", "freezer", "mini fridge", "chest freezer",
                         "deep freezer", "tool cabinet", "roller cabinet",
                         "entertainment center", "entertainment centre", "entertainment unit",
                         "cooler", "cool box", "coolbox", "crate", "storage crate"),
    "Safe": ("safety box", "cash box", "lock box", "deposit box", "safe deposit box", "gun safe",
             "wall safe"),
    "Oven": ("toaster oven", "microwave oven", "baking oven", "electric oven", "gas oven",
             "microwave", "microwaves", "dishwasher", "dish washer", "dishwashers"),
    "WashingMachine": ("washer-dryer", "laundry washer", "washing-machine", "washers",
                       "front loader", "top loading washer", "dryer", "dryers", "tumble dryer",
                       "clothes dryer", "laundry dryer", "tumble drier"),
    "Bottle": ("thermos", "vial", "water flask", "jug", "canteen", "bottles", "flasks"),
    "USB": ("usb key", "usb memory stick", "memory key", "usb-stick", "usb stick drive",
            "flashdrive", "usb flash stick", "pendrive", "pen-drive"),
}
EXTRA_PART = {
    "handle": ("handlebar", "bar handle", "bar pull", "door handle", "drawer pull", "pull bar",
               # a handle of a style: one part ("four drawers with knob handles" had been
               # read as one knob besides the handles, and made one handle)
               "knob handle", "knob pull", "cup pull", "cup handle", "ring pull",
               "square handle", "edge pull", "edge handle", "finger pull", "t-bar handle"),
    "knob": ("control knob", "temperature knob", "burner knob"),
    "button": ("switch", "start button", "power button"),
    "dial": ("program dial", "timer dial", "program selector", "selector"),
    "door": ("oven door", "glass door", "porthole door", "front door", "hatch", "porthole",
             "flap", "front flap", "flap door"),
    "lid": ("top lid", "cover", "flip cap", "flip-top cap", "flip top cap", "flip top"),
    "cap": ("screw cap", "bottle cap", "usb cap", "stopper"),
    "tray": ("baking tray", "baking sheet"),
    "drawer": ("drawer front",),
}
REVOLUTE_OR_CONTINUOUS = ("revolute", "continuous")
EXTRA_MOTION = {
    "prismatic": ("slide", "slides", "slid", "sliding", "slide out", "slide-out", "slides off",
                  "pull out", "pulls out", "pulled out", "pull-out", "pullout", "on runners",
                  "on rails", "telescopic", "glides out", "glide out", "draws out",
                  "slides in and out", "retractable", "pops out", "extends out", "pushes in",
                  "can be pushed in", "can be pulled out", "translates", "translating",
                  "pulls off", "pull off", "pulled off", "slide off", "comes off", "come off",
                  "lifts off", "lift off", "press in", "presses in", "pressed in", "push in",
                  "pushed in", "can be pressed", "can be pushed", "pressable", "pop off",
                  "pull straight off", "pulled straight off", "pull it off"),
    "revolute": ("hinge", "hinges", "hinged", "swing", "swings", "swinging", "swing open",
                 "swings open", "swings out", "pivot", "pivots", "pivoting", "flips open",
                 "flips up", "flip open", "flip-up", "folds down", "drops down", "swivel",
                 "swivels", "swiveling", "swivelling", "opens on hinges", "drop-down", "drops open",
                 "hinged at", "pull-down", "fold-down", "flip-up", "lift-up", "to a stop",
                 "tilting", "tilts"),
    "continuous": ("spin", "spins", "spinning", "spins freely", "turns freely",
                   "rotates freely", "endlessly", "all the way around", "360 degrees",
                   "rotates continuously", "without a stop", "without stops"),
    "screw": ("screw", "screws", "screw-on", "screw-top", "screw on", "screws on", "unscrew",
              "unscrews", "threaded", "twist-off", "twists off", "twist off", "twist-on"),
    "fixed": ("fixed", "rigid", "static", "stationary", "does not move", "doesn't move",
              "do not move", "don't move", "rigidly attached", "immovable"),
}
# Generic rotation words: a knob that "turns" may have limits (revolute) or not (continuous).
GENERIC_ROTATION = ("rotate", "rotates", "rotating", "rotated", "turn", "turns", "turning",
                    "twist", "twists", "twisting", "rotatable", "rotary motion")

SIDE_ADJECTIVES = {"left", "right", "top", "bottom", "upper", "lower", "middle", "center",
                   "centre", "front", "back", "rear", "left-hand", "right-hand", "lefthand",
                   "righthand", "first", "second", "third", "inner", "outer"}
STOP_WORDS = {"with", "and", "or", "on", "in", "at", "of", "to", "has", "have", "having",
              "features", "featuring", "plus", "that", "which", "where", "while", "is", "are",
              "from", "for", "by", "its", "it", "whose", "there", "below", "above", "under",
              "over", "beside", "behind", "inside", "into", "as", "but", "then", "also",
              "include", "includes", "including", "comes", "contains"}
DEFINITE = {"the", "this", "these", "those", "that", "its", "their", "his", "her", "all",
            "each", "every", "any", "which", "whose"}
LOWER_BOUND_WORDS = {"both": 2, "several": 2, "multiple": 2, "many": 2, "some": 1,
                     "various": 2, "numerous": 2, "a few": 2, "a number of": 2, "lots of": 2}
# words before a number that make it a lower bound ("at least four buttons")
LOWER_BOUND_PHRASES = (("at", "least"), ("no", "fewer", "than"), ("no", "less", "than"),
                       ("not", "less", "than"), ("not", "fewer", "than"), ("minimum", "of"))
ZERO_WORDS = ("no", "without", "zero", "lacks", "lacking", "none of")
DISTRIBUTIVE = ("each", "every", "per", "each of the", "every one of the", "both with")
EXACT_NUMBER_PHRASES = {"a pair of": 2, "pair of": 2, "a couple of": 2, "couple of": 2,
                        "a single": 1, "one single": 1, "just one": 1, "only one": 1,
                        "single": 1, "double": 2, "twin": 2, "triple": 3, "a trio of": 3,
                        "a dozen": 12, "dozen": 12, "a": 1, "an": 1, "another": 1,
                        "one more": 1, "an extra": 1, "one": 1}


@dataclass
class _Tok:
    kind: str          # CAT PART MOTION NUM ZERO LOWER DET DIST MULT WORD PUNCT
    text: str
    value: object = None
    plural: bool = False
    start: int = 0     # character span in the sentence
    end: int = 0


# --------------------------------------------------------------------------------------------
# lexicon
# --------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=1)
def _lexicon():
    """(compiled master regex, phrase -> (kind, value, plural))."""
    table: dict[str, tuple[str, object, bool]] = {}

    def add(phrase: str, kind: str, value, plural=False):
        table.setdefault(phrase.lower(), (kind, value, plural))

    for w, n in EXACT_NUMBER_PHRASES.items():
        add(w, "NUM", n)
    for i, w in enumerate(vocab.NUMBER_WORDS):
        add(w, "NUM", i)
    for w, n in LOWER_BOUND_WORDS.items():
        add(w, "LOWER", n)
    for w in ZERO_WORDS:
        add(w, "ZERO", 0)
    for w in DISTRIBUTIVE:
        add(w, "DIST", None)
    add("pairs of", "MULT", 2)
    add("sets of", "MULT", 1)
    for w in DEFINITE - {"each", "every"}:
        add(w, "DET", None)
    motions: dict[str, set] = {}
    for jt, words in list(vocab.MOTION_SYNONYMS.items()) + list(vocab.MOTION_ADJECTIVES.items()) \
            + list(EXTRA_MOTION.items()):
        for w in words:
            motions.setdefault(w.lower(), set()).add(jt)
    for table_name in ("LABEL_MOTION_SYNONYMS", "LABEL_MOTION_ADJECTIVES"):
        for (_, jt), words in getattr(vocab, table_name, {}).items():
            for w in words:
                motions.setdefault(w.lower(), set()).add(jt)
    for w in GENERIC_ROTATION:
        motions.setdefault(w, set()).update(REVOLUTE_OR_CONTINUOUS)
    # The templates' "rotating"/"turning" adjectives also mean a generic rotation to a person.
    for w in ("rotating", "turning"):
        motions[w] = set(REVOLUTE_OR_CONTINUOUS)
    for w, types in list(motions.items()):   # "the knobs turn without limit" (plural verb)
        for v in _verb_variants(w):
            motions.setdefault(v, set(types))
    for w, types in motions.items():
        add(w, "MOTION", frozenset(types))
    parts: dict[str, tuple[str, bool]] = {}
    for label, words in vocab.PART_SYNONYMS.items():
        for w in words:
            parts.setdefault(w, (label, False))
    for label, words in vocab.PART_PLURALS.items():
        for w in words:
            parts.setdefault(w, (label, True))
    for (_, label), words in vocab.ROLE_NAMES.items():
        for w in words:
            parts.setdefault(w, (label, False))
            parts.setdefault(vocab.plural(w), (label, True))
    for label, words in EXTRA_PART.items():
        for w in words:
            parts.setdefault(w, (label, False))
            parts.setdefault(vocab.plural(w), (label, True))
    cats: dict[str, str] = dict(vocab.PHRASE_TO_CATEGORY)
    for cat, words in EXTRA_CATEGORY.items():
        for w in words:
            cats.setdefault(w, cat)
    # Categories and parts win over motions and numbers for the same text ("chest of drawers"
    # is a category, "pull-out drawer" a part), so they are entered with priority.
    for w, cat in cats.items():
        table[w.lower()] = ("CAT", cat, False)
    for w, (label, pl) in parts.items():
        if w.lower() not in table or table[w.lower()][0] != "CAT":
            table[w.lower()] = ("PART", label, pl)
    phrases = sorted(table, key=len, reverse=True)   # longest alternative first
    alt = "|".join(re.escape(p) for p in phrases)
    regex = re.compile(rf"(?<![\w-])(?:{alt})(?![\w])|\d+|[a-z][a-z'\-]*|[,:;()]")
    return regex, table


def _verb_variants(phrase: str) -> list[str]:
    """Plural-subject forms of a 3rd-person motion phrase ("swings open" → "swing open")."""
    words = phrase.split()
    if not words:
        return []
    head, rest = words[0], words[1:]
    out = []
    if head == "is":
        out.append(" ".join(["are"] + rest))
    elif head == "does":
        out.append(" ".join(["do"] + rest))
    elif re.search(r"(sh|ch|x|ss)es$", head):
        out.append(" ".join([head[:-2]] + rest))
    elif head.endswith("s") and not head.endswith("ss") and len(head) > 3:
        out.append(" ".join([head[:-1]] + rest))
    return out


def _tokenize(sentence: str) -> list[_Tok]:
    regex, table = _lexicon()
    toks = []
    for m in regex.finditer(sentence):
        s = m.group(0)
        a, b = m.span()
        if s in table:
            kind, value, plural = table[s]
            toks.append(_Tok(kind, s, value, plural, a, b))
        elif s.isdigit():
            toks.append(_Tok("NUM", s, int(s), False, a, b))
        elif s in ",:;()":
            toks.append(_Tok("PUNCT", s, None, False, a, b))
        else:
            toks.append(_Tok("WORD", s, None, False, a, b))
    return toks


def _sentences(text: str) -> list[str]:
    text = text.lower().replace("—", ", ").replace("–", ", ").replace("&", " and ")
    # "next to each other" is not a distribution, "one another" not a count
    text = re.sub(r"\beach other\b", "eachother", text)
    text = re.sub(r"\b([a-z]+)-like\b", " ", text)          # "a knob-like dial" is a dial
    text = re.sub(r"\bone another\b", "oneanother", text)
    # a telephone's keypad: three keys wide, four rows
    text = re.sub(r"\b(?:tele)?phone[- ]style (?:number ?pad|numpad|keypad)s?\b", "4 x 3 keypad",
                  text)
    text = re.sub(r"\(?\b[a-z]+[- ]style\b\)?", " ", text)   # "(knob style)" is a look, not a part
    text = re.sub(r"\s+", " ", text)
    # "a 10-key keypad" (or "a 12 key keypad", "a keypad of 10 keys") counts its buttons
    text = _KEYS.sub(lambda m: f"{m.group(1) or m.group(2)} keypad buttons", text)
    text = _NUMBER_COMPOUND.sub(_compound, text)
    return [s.strip() for s in re.split(r"[.!?\n]+", text) if s.strip()]


_NUMBER = r"(\d+|" + "|".join(sorted(vocab.NUMBER_WORDS[1:13], key=len, reverse=True)) + r")"
_NUMBER_COMPOUND = re.compile(rf"\b{_NUMBER}-([a-z]+)\b")


_KEYS = re.compile(
    rf"\b{_NUMBER}[- ]keys? (?:key ?pad|number ?pad|numpad)\b"
    rf"|\b(?:key ?pad|number ?pad|numpad) (?:of|with) {_NUMBER} keys\b")


def _compound(m) -> str:
    """"a three-drawer dresser" counts drawers; "a three-spoke handle", "a 4-burner range",
    "a 4-digit dial" count no part: that number is part of an adjective, kept as one word
    (digits as their word: the tokenizer reads any digits as a count)."""
    _, table = _lexicon()
    kind = table.get(m.group(2), ("WORD",))[0]
    if kind == "PART":
        return m.group(0)
    n = m.group(1)
    if n.isdigit():
        n = vocab.NUMBER_WORDS[int(n)] if int(n) < len(vocab.NUMBER_WORDS) else "many"
    return f"{n}{m.group(2)}"


def _motion_in_phrase(phrase: str) -> frozenset | None:
    """Motion implied by a part synonym itself ("sliding drawer", "hinged lid")."""
    _, table = _lexicon()
    types: set = set()
    words = phrase.split()
    for w in words:
        e = table.get(w)
        if w in vocab.PHRASE_TO_JOINT or (e and e[0] == "MOTION"):
            types |= set(e[1]) if e and e[0] == "MOTION" else {vocab.PHRASE_TO_JOINT[w]}
    return frozenset(types) if types else None
