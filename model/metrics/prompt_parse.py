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
                         "cabinets", "dressers", "kitchen cabinet", "bedside table",
                         "bedside cabinet", "night stand", "tallboy", "chest-of-drawers",
                         "file cabinet", "drawer unit", "drawer cabinet"),
    "Safe": ("safety box", "cash box", "deposit box", "safe deposit box", "gun safe", "wall safe"),
    "Oven": ("toaster oven", "microwave oven", "baking oven", "electric oven", "gas oven"),
    "WashingMachine": ("washer-dryer", "laundry washer", "washing-machine", "washers"),
    "Bottle": ("thermos", "vial", "water flask", "jug", "canteen", "bottles", "flasks"),
    "USB": ("usb key", "usb memory stick", "memory key", "usb-stick", "usb stick drive",
            "flashdrive", "usb flash stick"),
}
EXTRA_PART = {
    "handle": ("handlebar", "bar handle", "bar pull", "door handle", "drawer pull", "pull bar"),
    "knob": ("control knob", "temperature knob", "burner knob"),
    "button": ("switch", "start button", "power button"),
    "dial": ("program dial", "timer dial", "program selector", "selector"),
    "door": ("oven door", "glass door", "porthole door", "front door", "hatch"),
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
                  "pushed in", "can be pressed", "can be pushed", "pressable", "pop off"),
    "revolute": ("hinge", "hinges", "hinged", "swing", "swings", "swinging", "swing open",
                 "swings open", "swings out", "pivot", "pivots", "pivoting", "flips open",
                 "flips up", "flip open", "flip-up", "folds down", "drops down", "swivel",
                 "swivels", "swiveling", "swivelling", "opens on hinges", "drop-down", "drops open",
                 "hinged at"),
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
DISTRIBUTIVE = ("each", "every", "per", "each of the", "every one of the")
EXACT_NUMBER_PHRASES = {"a pair of": 2, "pair of": 2, "a couple of": 2, "couple of": 2,
                        "a single": 1, "one single": 1, "just one": 1, "only one": 1,
                        "single": 1, "double": 2, "twin": 2, "triple": 3, "a trio of": 3,
                        "a dozen": 12, "dozen": 12, "a": 1, "an": 1, "another": 1,
                        "one more": 1, "an extra": 1, "one": 1}


@dataclass
class ExpectedStructure:
    """What a prompt asks for. Labels not mentioned are unconstrained."""
    category: str | None = None
    counts: dict[str, int] = field(default_factory=dict)       # exact counts
    min_counts: dict[str, int] = field(default_factory=dict)   # lower bounds (no exact count)
    joint_types: dict[str, list[str]] = field(default_factory=dict)  # acceptable types

    def to_json(self) -> dict:
        return {"category": self.category, "counts": dict(self.counts),
                "min_counts": dict(self.min_counts),
                "joint_types": {k: list(v) for k, v in self.joint_types.items()}}

    @property
    def is_empty(self) -> bool:
        return not (self.category or self.counts or self.min_counts or self.joint_types)


@dataclass
class _Tok:
    kind: str          # CAT PART MOTION NUM ZERO LOWER DET DIST MULT WORD PUNCT
    text: str
    value: object = None
    plural: bool = False


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
        if s in table:
            kind, value, plural = table[s]
            toks.append(_Tok(kind, s, value, plural))
        elif s.isdigit():
            toks.append(_Tok("NUM", s, int(s)))
        elif s in ",:;()":
            toks.append(_Tok("PUNCT", s))
        else:
            toks.append(_Tok("WORD", s))
    return toks


def _sentences(text: str) -> list[str]:
    text = text.lower().replace("—", ", ").replace("–", ", ").replace("&", " and ")
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
            m.dist_head = t.kind == "DIST"
            return
        else:   # PUNCT, PART, CAT end the noun phrase
            break
        j -= 1
    m.lower = 2 if m.plural else 1


def _distributive_target(toks: list[_Tok], k: int) -> str | None:
    """Label whose count multiplies the part at k, if a distributive word governs it."""
    # after: "<Y> on each <X>", "<Y> per <X>" (within 3 tokens)
    for j in range(k + 1, min(len(toks), k + 4)):
        if toks[j].kind == "DIST":
            for i in range(j + 1, min(len(toks), j + 5)):
                if toks[i].kind == "PART":
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
            for i in range(j - 1, max(-1, j - 6), -1):
                if toks[i].kind == "PART":
                    return toks[i].value
            return None
        if t.kind in ("PUNCT",) and t.text in ";:":
            break
    return None


def parse_prompt(text: str) -> ExpectedStructure:
    """The structure a prompt asks for (see the module docstring)."""
    out = ExpectedStructure()
    mentions: list[_Mention] = []
    motion_links: list[tuple[frozenset, str, bool]] = []
    last_part: str | None = None
    for si, sentence in enumerate(_sentences(text)):
        toks = _tokenize(sentence)
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
    return out
