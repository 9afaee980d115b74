"""Text prompt → the structure it asks for (category, part counts, joint types).

Used by the alignment metric (DESIGN §7) on the dataset's template descriptions *and* on
free-form prompts no template wrote. Rule-based on the vocabulary of ``model.data.vocab``
(categories, part synonyms and plurals, motion phrases) plus the extra wordings below.

What it understands
-------------------
* quantities: digits, number words ("three", "a", "a single"), "a pair of", "double"/"twin",
  "two pairs of", compounds ("a three-drawer dresser"), "no"/"without" (count 0);
  "both", "several", bare plurals and definite mentions give lower bounds only.
* distribution: "each drawer has a handle", "two doors, each with a knob",
  "a handle on every drawer", "one knob per burner" → counts multiplied.
* lists with sides: "a left door and a right door" → 2 doors; an appositive after a counted
  plural ("two doors, a left door and a right door") is not counted twice.
* motion: adjectives ("sliding drawers", "hinged lid") and clauses ("the drawers slide out",
  "a door hinged on the left", "the cap screws off") attach to the nearest part mention;
  generic rotation words ("rotates", "turns", "rotating") accept revolute or continuous.

Example::

    >>> parse_prompt("A dresser with three sliding drawers, each with a handle").to_json()
    {'category': 'StorageFurniture', 'counts': {'drawer': 3, 'handle': 3},
     'min_counts': {}, 'joint_types': {'drawer': ['prismatic']}}
"""
from __future__ import annotations

import functools
import re
from dataclasses import dataclass, field

from model.data import vocab

# Extra wordings a person may use that the description templates do not (owned here).
EXTRA_CATEGORY = {
    "StorageFurniture": ("closet", "armoire", "bureau", "locker", "credenza", "cupboards",
                         "tv stand", "media console", "pedestal", "base unit", "shoe cabinet",
                         "bathroom cabinet", "display cabinet", "pantry cupboard",
                         "cabinets", "dressers", "kitchen cabinet", "bedside table",
                         "bedside cabinet", "night stand", "tallboy", "chest-of-drawers",
                         "file cabinet", "drawer unit", "drawer cabinet"),
    "Safe": ("safety box", "cash box", "deposit box", "safe deposit box", "gun safe", "wall safe"),
    "Oven": ("toaster oven", "microwave oven", "baking oven", "electric oven", "gas oven"),
    "WashingMachine": ("washer-dryer", "laundry washer", "washing-machine", "washers",
                       "front loader", "top loading washer"),
    "Bottle": ("thermos", "vial", "water flask", "jug", "canteen", "bottles", "flasks"),
    "USB": ("usb key", "usb memory stick", "memory key", "usb-stick", "usb stick drive",
            "flashdrive", "usb flash stick"),
}
EXTRA_PART = {
    "handle": ("handlebar", "bar handle", "bar pull", "door handle", "drawer pull", "pull bar"),
    "knob": ("control knob", "temperature knob", "burner knob"),
    "button": ("switch", "start button", "power button"),
    "dial": ("program dial", "timer dial", "program selector", "selector"),
    "door": ("oven door", "glass door", "porthole door", "front door", "hatch", "porthole",
             "flap", "front flap", "flap door"),
    "lid": ("top lid", "cover"),
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
ZERO_WORDS = ("no", "without", "zero", "lacks", "lacking", "none of")
DISTRIBUTIVE = ("each", "every", "per", "each of the", "every one of the", "both with")
EXACT_NUMBER_PHRASES = {"a pair of": 2, "pair of": 2, "a couple of": 2, "couple of": 2,
                        "a single": 1, "one single": 1, "just one": 1, "only one": 1,
                        "single": 1, "double": 2, "twin": 2, "triple": 3, "a trio of": 3,
                        "a dozen": 12, "dozen": 12, "a": 1, "an": 1, "another": 1,
                        "one more": 1, "an extra": 1, "one": 1}


# Spatial facts a prompt can state, and their values (model.data.describe.spatial_summary).
SIDES = ("left", "right", "top", "bottom", "back", "front", "side")   # "side": left or right
SPATIAL_KEYS: dict[str, tuple[str, ...]] = {
    "hinge": SIDES,
    "opens": ("down", "up", "sideways"),
    "layout": ("row", "column", "grid"),
    "rows": ("int",),
    "columns": ("int",),
    "hpos": ("left", "middle", "right"),
    "vpos": ("top", "middle", "bottom"),
    "above": (),    # values: part labels
    "below": (),
}
SPATIAL_KINDS = {"hinge": "hinge", "opens": "opening", "layout": "arrangement",
                 "rows": "arrangement", "columns": "arrangement", "hpos": "position",
                 "vpos": "position", "above": "position", "below": "position"}


@dataclass
class ExpectedStructure:
    """What a prompt asks for. Labels not mentioned are unconstrained."""
    category: str | None = None
    counts: dict[str, int] = field(default_factory=dict)       # exact counts
    min_counts: dict[str, int] = field(default_factory=dict)   # lower bounds (no exact count)
    joint_types: dict[str, list[str]] = field(default_factory=dict)  # acceptable types
    # spatial facts per label (see SPATIAL_KEYS): {"door": {"hinge": ["left"]}, ...}
    spatial: dict[str, dict] = field(default_factory=dict)

    def to_json(self) -> dict:
        out = {"category": self.category, "counts": dict(self.counts),
               "min_counts": dict(self.min_counts),
               "joint_types": {k: list(v) for k, v in self.joint_types.items()}}
        if self.spatial:
            out["spatial"] = {k: dict(v) for k, v in self.spatial.items()}
        return out

    @property
    def is_empty(self) -> bool:
        return not (self.category or self.counts or self.min_counts or self.joint_types
                    or self.spatial)

    @property
    def num_parts(self) -> int:
        """Countable parts the prompt asks for (exact counts, else lower bounds)."""
        return sum(self.counts.values()) + sum(v for k, v in self.min_counts.items()
                                               if k not in self.counts)

    # -- the free-form file's annotation line ---------------------------------------------------
    def to_line(self) -> str:
        """``CATEGORY drawer=3 knob>=2 door:revolute door.hinge=left drawer.layout=column``."""
        items = [self.category or "-"]
        items += [f"{k}={v}" for k, v in self.counts.items()]
        items += [f"{k}>={v}" for k, v in self.min_counts.items()]
        items += [f"{k}:{'/'.join(v)}" for k, v in self.joint_types.items()]
        for lab, facts in self.spatial.items():
            for key, v in facts.items():
                val = "/".join(str(x) for x in v) if isinstance(v, (list, tuple)) else str(v)
                items.append(f"{lab}.{key}={val}")
        return " ".join(items)

    @classmethod
    def from_line(cls, line: str) -> "ExpectedStructure":
        """Inverse of :meth:`to_line`; a clear ValueError on anything it does not know."""
        items = line.split()
        if not items:
            raise ValueError("empty structure line")
        cat = None if items[0] == "-" else items[0]
        if cat is not None and cat not in vocab.CATEGORIES:
            raise ValueError(f"unknown category {cat!r} (one of {list(vocab.CATEGORIES)} or -)")
        out = cls(category=cat)
        labels = set(vocab.COUNTABLE_LABELS)
        for it in items[1:]:
            m = re.fullmatch(r"([a-z]+)\.([a-z]+)=([a-z0-9/]+)", it)
            if m:
                lab, key, val = m.groups()
                if lab not in labels or key not in SPATIAL_KEYS:
                    raise ValueError(f"{it!r}: label must be one of {sorted(labels)}, fact one "
                                     f"of {list(SPATIAL_KEYS)}")
                vals = val.split("/")
                bad = [v for v in vals if v not in SPATIAL_KEYS[key] and not
                       (SPATIAL_KEYS[key] == ("int",) and v.isdigit())
                       and not (key in ("above", "below") and v in labels)]
                if bad:
                    raise ValueError(f"{it!r}: {bad} not among {SPATIAL_KEYS[key]}")
                fact = int(vals[0]) if SPATIAL_KEYS[key] == ("int",) else \
                    (vals[0] if key == "layout" else sorted(vals))
                out.spatial.setdefault(lab, {})[key] = fact
                continue
            m = re.fullmatch(r"([a-z]+)(=|>=|:)([a-z0-9/]+)", it)
            if not m or m.group(1) not in labels:
                raise ValueError(f"cannot read {it!r} (label=N, label>=N, label:type/type or "
                                 f"label.fact=value; labels {sorted(labels)})")
            lab, op, val = m.groups()
            if op == ":":
                types = val.split("/")
                bad = [t for t in types if t not in vocab.MOTION_SYNONYMS]
                if bad:
                    raise ValueError(f"{it!r}: unknown joint types {bad}")
                out.joint_types[lab] = sorted(types)
            elif not val.isdigit():
                raise ValueError(f"{it!r}: a count must be a whole number")
            elif op == "=":
                out.counts[lab] = int(val)
            else:
                out.min_counts[lab] = int(val)
        return out


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
    text = re.sub(r"\(?\b[a-z]+[- ]style\b\)?", " ", text)   # "(knob style)" is a look, not a part
    text = re.sub(r"\s+", " ", text)
    return [s.strip() for s in re.split(r"[.!?\n]+", text) if s.strip()]


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


# --------------------------------------------------------------------------------------------
# parsing
# --------------------------------------------------------------------------------------------
@dataclass
class _Mention:
    label: str
    sent: int
    pos: int
    plural: bool
    exact: int | None = None       # exact count contributed
    lower: int | None = None       # lower bound contributed
    zero: bool = False
    side: bool = False             # a side adjective before the noun ("a left door")
    dist_of: str | None = None     # distributive: multiply by the count of this label
    dist_head: bool = False        # the part a distributive word quantifies ("each drawer")
    single: bool = False           # "the door", "its lid", "porthole door," (one, if nothing
                                   # else counts this part kind)


def _scan_quantifier(toks: list[_Tok], k: int, m: _Mention, motions: list) -> None:
    """Walk back from the part noun at k over adjectives to its quantifier."""
    j, adjectives = k - 1, 0
    mult = 1
    while j >= 0 and adjectives <= 4:
        t = toks[j]
        if t.kind == "WORD":
            if t.text in STOP_WORDS:
                break
            if t.text in SIDE_ADJECTIVES:
                m.side = True
            adjectives += 1
        elif t.kind == "MOTION":
            motions.append((t.value, k))
            adjectives += 1
        elif t.kind == "MULT":
            mult *= int(t.value)
            if j == 0 or toks[j - 1].kind != "NUM":   # "pairs of doors": at least two pairs
                m.lower = 2 * mult
                return
        elif t.kind == "NUM":
            m.exact = int(t.value) * mult
            return
        elif t.kind == "ZERO":
            m.zero = True
            return
        elif t.kind == "LOWER":
            m.lower = int(t.value)
            return
        elif t.kind in ("DET", "DIST"):
            m.lower = 1
            m.dist_head = t.kind == "DIST" and t.text != "both with"
            m.single = t.kind == "DET" and not m.plural and t.text not in ("all", "any")
            return
        else:   # PUNCT, PART, CAT end the noun phrase
            break
        j -= 1
    m.lower = 2 if m.plural else 1
    m.single = not m.plural


def _distributive_target(toks: list[_Tok], k: int) -> str | None:
    """Label whose count multiplies the part at k, if a distributive word governs it."""
    # after: "<Y> on each <X>", "<Y> per <X>" (within 3 tokens)
    for j in range(k + 1, min(len(toks), k + 4)):
        if toks[j].kind == "DIST":
            for i in range(j + 1, min(len(toks), j + 5)):
                if toks[i].kind == "PART":
                    return toks[i].value
                if toks[i].kind == "PUNCT":
                    break
            for i in range(k - 1, max(-1, k - 8), -1):   # "four drawers with knobs on each"
                if toks[i].kind == "PART" and toks[i].value != toks[k].value:
                    return toks[i].value
            return None
        if not (toks[j].kind == "WORD" and toks[j].text in ("on", "for", "in", "at", "to", "of")):
            break
    # before: "each <X> has a <Y>" or "<X>, each with a <Y>"
    for j in range(k - 1, max(-1, k - 8), -1):
        t = toks[j]
        if t.kind == "DIST":
            for i in range(j + 1, k):
                if toks[i].kind == "PART":
                    return toks[i].value
            for i in range(j - 1, max(-1, j - 9), -1):
                if toks[i].kind == "PART":
                    return toks[i].value
            return None
        if t.kind in ("PUNCT",) and t.text in ";:":
            break
    return None


# --------------------------------------------------------------------------------------------
# spatial facts ("hinged on the left", "opens downward", "in two columns", "on the right",
# "above the door"). Left / right are the viewer's (model.data.vocab.SIDE_DIRECTIONS).
# --------------------------------------------------------------------------------------------
_N = r"(\d+|" + "|".join(sorted(vocab.NUMBER_WORDS[1:13], key=len, reverse=True)) + r"|a single|single)"
_SIDE = r"(left|right|top|bottom|back|rear|upper|lower|side)"
_SIDE_NAME = {"rear": "back", "upper": "top", "lower": "bottom"}
HINGED = ("door", "lid", "cap")   # a bottle's hinged "cap" is read as its lid (_tidy)
ARRANGED = ("drawer", "door", "lid", "tray", "knob", "dial", "button")


def _num(word: str) -> int:
    word = word.strip()
    if word.isdigit():
        return int(word)
    if word in ("a single", "single"):
        return 1
    return vocab.NUMBER_VALUES[word]


@dataclass
class _Fact:
    key: str
    values: list
    start: int
    end: int
    mode: str            # "post": the part named before; "pre": the part named next
    relation_to: str | None = None


def _rewrite_counts(sentence: str) -> tuple[str, list[_Fact]]:
    """Rewrite grid wordings that carry a count ("two rows of three drawers" -> "6 drawers",
    "a 3 x 3 keypad" -> "9 keypad buttons") and return the arrangement facts they state."""
    facts: list[_Fact] = []

    def grid(m, rows: int, cols: int, tail: str) -> str:
        return f"{rows * cols} {tail}".rstrip() + " "

    out, pos = [], 0
    pat = re.compile(
        rf"\b(?:in |into |as )?(?:a |an )?{_N}\s?(?:x|×|by)\s?{_N}\s(grid|array|keypad|matrix|layout)(\s+of\b)?"
        rf"|\b{_N} (rows|columns) of {_N}\b(\s+(?=\w))?"
        rf"|\b(?:a |an |the |its |their |two |both )?keypads?(?!\s+(?:buttons?|keys))( of\b)?")
    for m in pat.finditer(sentence):
        out.append(sentence[pos:m.start()])
        here = sum(len(x) for x in out)
        g = m.groups()
        if g[0] is not None:                 # R x C grid / keypad
            R, C = _num(g[0]), _num(g[1])
            arr = {"layout": "grid" if R > 1 and C > 1 else ("row" if R == 1 else "column"),
                   "rows": R, "columns": C}
            if g[2] == "keypad" and not g[3]:
                text = f"{R * C} keypad buttons"
                mode = "pre"
            elif g[3]:
                text = f"{R * C}"
                mode = "pre"
            else:
                text = "in a grid"
                mode = "post"
            for k, v in arr.items():
                facts.append(_Fact(k, [v], here, here if mode == "pre" else here + len(text), mode))
            out.append(text + (" " if mode == "pre" and not text.endswith("buttons") else ""))
        elif g[4] is not None:               # N rows of M (drawers)
            a, b = _num(g[4]), _num(g[6])
            R, C = (a, b) if g[5] == "rows" else (b, a)
            followed = g[7] is not None and _part_follows(sentence[m.end():])
            if followed:
                text = f"{R * C} "
                mode = "pre"
            else:
                text = "in a grid"
                mode = "post"
            lay = "grid" if R > 1 and C > 1 else ("row" if R == 1 else "column")
            for k, v in (("layout", lay), ("rows", R), ("columns", C)):
                facts.append(_Fact(k, [v], here, here if mode == "pre" else here + len(text), mode))
            out.append(text)
        else:                                 # "a keypad" (of ...)
            out.append("" if g[8] else "several keypad buttons")
        pos = m.end()
    out.append(sentence[pos:])
    return re.sub(r"[ ]{2,}", " ", "".join(out)) if not facts else "".join(out), facts


def _part_follows(text: str) -> bool:
    """The next few words name a part ("three drawers", "small doors")."""
    for k, t in enumerate(_tokenize(text)[:4]):
        if t.kind == "PART":
            return True
        if t.kind == "PUNCT" or (t.kind == "WORD" and t.text in STOP_WORDS):
            return False
    return False


_SPATIAL_PATTERNS: list[tuple[str, str, str]] = [
    # (key, regex, mode); values come from group 1 (and 2) or the fixed value after '='
    ("hinge", rf"\bhinged (?:on|at|along|to) (?:the |its |their )?{_SIDE}(?:[- ]hand)?(?: sides?| edges?| ends?)?"
              rf"(?:,? (?:and|or) (?:on |at )?(?:the |its )?{_SIDE}(?:[- ]hand)?(?: sides?| edges?)?)?", "post"),
    ("hinge", rf"\b{_SIDE}[- ]hinged\b", "pre"),
    ("hinge", rf"\bwith (?:a|its|the|their) {_SIDE}(?:[- ]hand)? hinges?\b", "post"),
    ("hinge", rf"\bhinges? (?:is |are |sits? |sit |runs? )?(?:on|at|along) (?:the |its )?{_SIDE}(?: side| edge)?\b", "post"),
    ("hinge", rf"\b(?:at|on|by) (?:the|its) {_SIDE} hinges?\b", "post"),
    ("hinge+sideways", r"\b(?:swings?|opens?|swinging|opening) (?:open |out )?(?:to|towards) the (left|right)\b", "post"),
    ("opens=down", r"\b(?:opens?|swings?|folds?|drops?|pulls?|flips?|tips?|falls?|tilts?)(?: open| out)?,? ?down(?:ward|wards)?\b", "post"),
    ("opens=down", r"\b(?:drop|fold|pull|flip)[- ]down\b", "pre"),
    ("opens=down", r"\bdrops open\b", "post"),
    ("opens=up", r"\b(?:opens?|swings?|flips?|lifts?|folds?|tilts?|lifting|flipping)(?: open| out)?,? ?up(?:ward|wards)?\b", "post"),
    ("opens=up", r"\b(?:flip|lift|swing)[- ]up\b", "pre"),
    ("opens=sideways", r"\b(?:opens?|swings?|swinging|opening)(?: open| out)? (?:sideways|to the side|to one side)\b", "post"),
    ("opens=sideways+hinge=side", r"\bside[- ](?:opening|hinged)\b", "pre"),
    ("layout=column", r"\b(?:stacked(?: vertically| up)?(?: one (?:above|on top of|over) (?:the other|another))?"
                      r"|one (?:above|on top of|over|below|under) (?:the other|another)"
                      r"|on top of (?:eachother|oneanother)|in a (?:single |vertical )?(?:column|stack)"
                      r"|vertically stacked|in a vertical line)\b", "post"),
    ("layout=column", r"\ba (?:vertical )?stack of\b", "pre"),
    ("layout=row", r"\b(?:side[- ]by[- ]side|in (?:a|one) (?:single |horizontal |neat |straight )?(?:row|line)"
                   r"|next to (?:eachother|oneanother)|beside (?:eachother|oneanother)"
                   r"|in a horizontal line)\b", "post"),
    ("layout=row", r"\ba (?:horizontal )?row of\b", "pre"),
    ("layout=grid", r"\bin a grid\b", "post"),
    ("across", rf"\b{_N} across(?:,? (?:and |by |in )?{_N} (?:down|high|deep|tall))?", "post"),
    ("over", rf"\b{_N} over {_N}\b", "post"),
    ("relit", r"\b(above|below|under|underneath|beneath|on top of) (?:it|them)\b", "post"),
    ("vpos+hpos", r"\b(?:on|at|in) the (top|bottom)[- ](left|right)\b", "post"),
    ("vpos", r"\bacross the (top|bottom)\b", "post"),
    ("rows", rf"\bin {_N} (?:horizontal )?rows\b", "post"),
    ("columns", rf"\bin {_N} (?:vertical )?columns\b", "post"),
    ("relation", r"\b(above|on top of|below|under|underneath|beneath)\b(?: (?:the|a|an|its|their|both))?", "post"),
    ("hpos", r"\b(?:on|at|to) the (left|right)(?:[- ]hand)?(?: side| end| half)?\b", "post"),
    ("vpos", r"\b(?:on|at) the (top|bottom)\b(?! of)|\bon (top)\b(?! of)|\bat the (base)\b", "post"),
]
_COMPILED = [(k, re.compile(r), m) for k, r, m in _SPATIAL_PATTERNS]
_ABOVE = {"above", "over", "on top of"}
_PRE_SIDE = {"left": ("hpos", "left"), "right": ("hpos", "right"), "left-hand": ("hpos", "left"),
             "right-hand": ("hpos", "right"), "top": ("vpos", "top"), "bottom": ("vpos", "bottom"),
             "upper": ("vpos", "top"), "lower": ("vpos", "bottom")}


def _spatial_facts(sentence: str, toks: list[_Tok]) -> list[_Fact]:
    """Every spatial phrase of a sentence (spans of earlier patterns are not re-read)."""
    work = sentence
    facts: list[_Fact] = []
    for key, rx, mode in _COMPILED:
        for m in rx.finditer(work):
            a, b = m.span()
            vals = [v for v in m.groups() if v]
            if key == "relation":
                part = None
                for t in [t for t in toks if t.start >= b][:5]:   # "above a row of three buttons"
                    if t.kind == "PART":
                        part = t
                        break
                    if t.kind not in ("WORD", "NUM", "DET", "MULT") or \
                            (t.text in STOP_WORDS and t.text != "of"):
                        break
                if part is not None:
                    rel = "above" if vals[0] in _ABOVE else "below"
                    facts.append(_Fact(rel, [part.value], a, part.end, "post", part.value))
                    b = part.end
                else:   # "a door underneath": below the part named before it, if any
                    facts.append(_Fact("relprev", ["above" if vals[0] in _ABOVE else "below"],
                                       a, b, "post"))
            elif key == "across":
                facts.append(_Fact("columns", [_num(vals[0])], a, b, mode))
                if len(vals) > 1:
                    facts.append(_Fact("rows", [_num(vals[1])], a, b, mode))
            elif key == "over":
                if _num(vals[0]) == _num(vals[1]):
                    for k2, v2 in (("layout", "grid" if _num(vals[0]) > 1 else "column"),
                                   ("rows", 2), ("columns", _num(vals[0]))):
                        facts.append(_Fact(k2, [v2], a, b, mode))
            elif key == "relit":
                # "three drawers side by side above them": about the part named just before;
                # "and, below them, two doors": about the part named next
                before = [t for t in toks if t.end <= a and t.kind in ("PART", "PUNCT")]
                mode2 = "post" if before and before[-1].kind == "PART" else "next"
                facts.append(_Fact("relit", ["above" if vals[0] in _ABOVE else "below"], a, b, mode2))
            elif key == "vpos+hpos":
                facts.append(_Fact("vpos", [vals[0]], a, b, mode))
                facts.append(_Fact("hpos", [vals[1]], a, b, mode))
            elif key == "hinge+sideways":
                facts.append(_Fact("hinge", vals, a, b, mode))
                facts.append(_Fact("opens", ["sideways"], a, b, mode))
            elif "=" in key:
                for kv in key.split("+"):
                    k, v = kv.split("=")
                    facts.append(_Fact(k, [v], a, b, mode))
            elif key in ("rows", "columns"):
                facts.append(_Fact(key, [_num(vals[0])], a, b, mode))
            elif key == "vpos":
                facts.append(_Fact("vpos", ["bottom" if vals[0] == "base" else vals[0]], a, b, mode))
            else:
                facts.append(_Fact(key, [_SIDE_NAME.get(v, v) for v in vals], a, b, mode))
            work = work[:a] + " " * (b - a) + work[b:]
    # side adjectives right before a part: "a left door", "the upper drawer"
    for k, t in enumerate(toks):
        if t.kind == "WORD" and t.text in _PRE_SIDE and work[t.start:t.end] == t.text:
            nxt = toks[k + 1:k + 3]
            if nxt and (nxt[0].kind == "PART" or (len(nxt) > 1 and nxt[0].kind in ("WORD", "MOTION")
                                                   and nxt[1].kind == "PART")):
                key, val = _PRE_SIDE[t.text]
                facts.append(_Fact(key, [val], t.start, t.end, "pre"))
    return facts


def _attach(facts: list[_Fact], toks: list[_Tok], earlier: list[str],
            spatial: dict[str, dict]) -> list[str]:
    """Attach each fact to the part it describes and merge it into ``spatial``; returns the
    labels a hinge or opening fact was said of (they turn on a hinge: revolute)."""
    hinged: list[str] = []
    parts = [t for t in toks if t.kind == "PART"]
    for f in facts:
        allowed = HINGED if f.key in ("hinge", "opens") else \
            ARRANGED if f.key in ("layout", "rows", "columns") else vocab.COUNTABLE_LABELS
        if f.key == "relit":
            # "below it, a small door" / "three doors below them": one part kind relative to
            # the one named before
            before = [t.value for t in parts if t.end <= f.start]
            after = [t.value for t in parts if t.start >= f.end]
            if f.mode == "post" and before:
                subj = before[-1]
                objs = [v for v in before[:-1] if v != subj] or [v for v in earlier if v != subj]
            else:
                subj = after[0] if after else None
                objs = [v for v in before if v != subj] or [v for v in earlier if v != subj]
            if subj is not None and objs:
                d = spatial.setdefault(subj, {})
                d[f.values[0]] = sorted(set(d.get(f.values[0], [])) | {objs[-1]})
            continue
        target = None
        # a phrase right before a part noun (adjectives between) is about that part:
        # "stacked hinged doors", "a drop-down door"
        nxt = [t for t in toks if t.start >= f.end][:3]
        for t in nxt:
            if t.kind == "PART":
                target = t.value if t.value in allowed else None
                break
            if t.kind not in ("WORD", "MOTION") or t.text in STOP_WORDS:
                break
            if f.mode != "pre" and t.kind == "WORD" and t.text not in SIDE_ADJECTIVES:
                break   # "... side by side that ..." is not a pre-modifier
        if f.mode == "pre" and target is None:
            target = next((t.value for t in nxt if t.kind == "PART" and t.value in allowed), None)
        if target is None:
            before = [t.value for t in parts if t.end <= f.start and t.value in allowed]
            target = before[-1] if before else None
        if target is None:
            prev = [lab for lab in earlier if lab in allowed]
            target = prev[-1] if prev else None
        if target is None:
            after = [t.value for t in parts if t.start >= f.end and t.value in allowed]
            target = after[0] if after else None
        if target is None or target == f.relation_to:
            continue
        if f.key == "relprev":
            subject = [t for t in parts if t.end <= f.start and t.value == target]
            other = [t.value for t in parts if subject and t.end <= subject[-1].start
                     and t.value != target]
            if other:
                f = _Fact(f.values[0], [other[-1]], f.start, f.end, f.mode)
            else:
                f = _Fact("vpos", ["top" if f.values[0] == "above" else "bottom"], f.start,
                          f.end, f.mode)
        facts_of = spatial.setdefault(target, {})
        if f.key in ("hinge", "opens"):
            hinged.append(target)
        if f.key in ("layout", "rows", "columns"):
            facts_of[f.key] = f.values[0]
        else:
            facts_of[f.key] = sorted(set(facts_of.get(f.key, [])) | set(f.values))
    return hinged


def parse_prompt(text: str) -> ExpectedStructure:
    """The structure a prompt asks for (see the module docstring)."""
    out = ExpectedStructure()
    mentions: list[_Mention] = []
    motion_links: list[tuple[frozenset, str, bool]] = []
    last_part: str | None = None
    earlier_parts: list[str] = []
    for si, sentence in enumerate(_sentences(text)):
        sentence, grid_facts = _rewrite_counts(sentence)
        toks = _tokenize(sentence)
        for lab in _attach(grid_facts + _spatial_facts(sentence, toks), toks, earlier_parts,
                           out.spatial):
            motion_links.append((frozenset({"revolute"}), lab, False))
        earlier_parts += [t.value for t in toks if t.kind == "PART"]
        prefix_motion_at: set[int] = set()
        for k, t in enumerate(toks):
            if t.kind == "CAT" and out.category is None:
                out.category = t.value
            if t.kind != "PART":
                continue
            m = _Mention(t.value, si, k, t.plural)
            pre: list = []
            _scan_quantifier(toks, k, m, pre)
            for types, _ in pre:
                motion_links.append((types, t.value, False))
            for j in range(max(0, k - 5), k):
                if toks[j].kind == "MOTION" and any(toks[j].value == p[0] for p in pre):
                    prefix_motion_at.add(j)
            own = _motion_in_phrase(t.text)
            if own:
                motion_links.append((own, t.value, False))
            dist = _distributive_target(toks, k)
            if dist and dist != t.value and not m.zero and not m.dist_head:
                m.dist_of = dist
            mentions.append(m)
        # motion clauses: attach to the nearest part before (or the last one of the text)
        for k, t in enumerate(toks):
            if t.kind != "MOTION" or k in prefix_motion_at:
                continue
            target = None
            for j in range(k - 1, -1, -1):
                if toks[j].kind == "PART":
                    target = toks[j].value
                    break
            if target is None:
                target = last_part
            if target is None:
                for j in range(k + 1, len(toks)):
                    if toks[j].kind == "PART":
                        target = toks[j].value
                        break
            if target is not None:
                # "can turn without limit or rotate on a hinge": either is acceptable
                j = k - 1
                is_or = False
                while j >= 0 and toks[j].kind != "PART":
                    is_or |= toks[j].kind == "WORD" and toks[j].text == "or"
                    j -= 1
                motion_links.append((t.value, target, is_or))
        parts_here = [t.value for t in toks if t.kind == "PART"]
        if parts_here:
            last_part = parts_here[-1]

    # counts, pass 1 (without distribution)
    countable = set(vocab.COUNTABLE_LABELS)

    def combine(ms: list[_Mention], base: dict[str, int]) -> tuple[dict, dict]:
        exact: dict[str, int] = {}
        lower: dict[str, int] = {}
        zero: set[str] = set()
        plural_seen: dict[tuple[int, str], int] = {}
        for m in ms:
            if m.label not in countable:
                continue
            if m.zero:
                zero.add(m.label)
                continue
            if m.exact is not None:
                key = (m.sent, m.label)
                # appositive: "two doors, a left door and a right door"
                if m.exact == 1 and m.side and plural_seen.get(key, 0) >= 1:
                    plural_seen[key] -= 1
                    continue
                n = m.exact
                if m.dist_of is not None:
                    if m.dist_of in base:
                        n = n * base[m.dist_of]
                    else:
                        lower[m.label] = max(lower.get(m.label, 0), n)
                        continue
                exact[m.label] = exact.get(m.label, 0) + n
                if m.exact >= 2:
                    plural_seen[key] = plural_seen.get(key, 0) + m.exact
            elif m.lower is not None:
                n = m.lower
                # "handles on every door", "each with its own handle": one per governing part
                if m.dist_of is not None and m.dist_of in base:
                    exact[m.label] = exact.get(m.label, 0) + base[m.dist_of]
                    continue
                lower[m.label] = max(lower.get(m.label, 0), n)
        for lab in zero:
            exact.setdefault(lab, 0)
        lower = {k: v for k, v in lower.items() if k not in exact}
        return exact, lower

    exact1, _ = combine(mentions, {})
    exact, lower = combine(mentions, exact1)
    # "the door is hinged on the left", "porthole door, soap drawer": one of each, when no
    # other mention counts or bounds that part kind
    for lab in list(lower):
        ms = [m for m in mentions if m.label == lab]
        if ms and all(m.single and m.dist_of is None for m in ms):
            exact[lab] = 1
            del lower[lab]
    out.counts, out.min_counts = exact, lower

    joint: dict[str, set] = {}
    for types, label, is_or in motion_links:
        if label not in countable:
            continue
        if label in joint and is_or:
            joint[label] = joint[label] | set(types)
        elif label in joint:
            both = joint[label] & set(types)
            joint[label] = both if both else joint[label] | set(types)
        else:
            joint[label] = set(types)
    out.joint_types = {k: sorted(v) for k, v in joint.items()
                       if out.counts.get(k, 1) != 0}
    _tidy(out, text)
    return out


# Everyday names that say which part an object has ("a swivel flash drive" has a swivel cap).
IMPLIED_PARTS = {
    "swivel usb stick": ("cap", "revolute"), "swivel flash drive": ("cap", "revolute"),
    "screw-top bottle": ("cap", "screw"), "flip-top bottle": ("lid", "revolute"),
}


def _tidy(out: ExpectedStructure, text: str) -> None:
    """Category-specific readings and tidy spatial facts."""
    low = text.lower()
    for name, (lab, jt) in IMPLIED_PARTS.items():
        if name in low and lab not in out.counts and lab not in out.min_counts:
            out.counts[lab] = 1
            out.joint_types.setdefault(lab, [jt])
    if out.category == "USB" and "lid" in (set(out.counts) | set(out.min_counts)) \
            and "cap" not in out.counts:          # a USB stick's cover is its cap
        _relabel(out, "lid", "cap")
    if out.category == "Bottle" and out.joint_types.get("cap") == ["revolute"] \
            and "lid" not in out.counts:          # a bottle's hinged "cap" is a flip lid
        _relabel(out, "cap", "lid")
    for facts in out.spatial.values():
        h = facts.get("hinge")
        if h and "side" in h and len(h) > 1:
            facts["hinge"] = [x for x in h if x != "side"]
        if "rows" in facts and "columns" in facts and "layout" not in facts:
            R, C = facts["rows"], facts["columns"]
            facts["layout"] = "grid" if R > 1 and C > 1 else ("row" if R == 1 else "column")


def _relabel(out: ExpectedStructure, a: str, b: str) -> None:
    for table in (out.counts, out.min_counts, out.joint_types, out.spatial):
        if a in table:
            table[b] = table.pop(a)


# --------------------------------------------------------------------------------------------
# the annotated free-form prompt file
# --------------------------------------------------------------------------------------------
def read_annotated_prompts(path=None) -> list[tuple[str, ExpectedStructure]]:
    """(prompt, expected structure) of every prompt of a free-form file: each prompt line is
    followed by its ``#> ...`` structure line (``ExpectedStructure.from_line``). Default: the
    shipped ``prompts_freeform.txt``. A prompt without a structure line, or a structure line
    without a prompt, is a ValueError naming the line."""
    from pathlib import Path
    path = Path(path) if path else Path(__file__).with_name("prompts_freeform.txt")
    out: list[tuple[str, ExpectedStructure]] = []
    pending: tuple[int, str] | None = None
    for no, raw in enumerate(path.read_text().splitlines(), 1):
        line = raw.strip()
        if line.startswith("#>"):
            if pending is None:
                raise ValueError(f"{path}:{no}: structure line without a prompt above it")
            try:
                out.append((pending[1], ExpectedStructure.from_line(line[2:].strip())))
            except ValueError as e:
                raise ValueError(f"{path}:{no}: {e}") from None
            pending = None
        elif not line or line.startswith("#"):
            continue
        else:
            if pending is not None:
                raise ValueError(f"{path}:{pending[0]}: prompt without a '#> ...' structure line")
            pending = (no, line)
    if pending is not None:
        raise ValueError(f"{path}:{pending[0]}: prompt without a '#> ...' structure line")
    return out
