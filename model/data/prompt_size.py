"""The size a prompt states: "60 cm wide", "1.2 m tall", "a depth of 40 cm", "24 inches high".

``read_size(text)`` -> {"width": m, "height": m, "depth": m} with the dimensions the
text states, in metres, of the object's body (width across the front, the viewer's left to
right; height bottom to top; depth front to back). "long" / "length" is the body's longest
side. A value outside 1 cm - 5 m is not a size a generated object can take and is ignored.

``with_usual_size`` adds the usual size of everyday objects the data lacks at their size for
the dimensions the text leaves open (``NAMED_SIZES``: a microwave is read as an oven, whose
data is 45-95 cm tall, so without it "a microwave" came out oven-sized), and keeps the
data's everyday names within the body sizes the data gives them (``NAMED_RANGES``: a locker
is over 1.2 m tall), and names the data never uses within their usual sizes
(``EVERYDAY_RANGES``: a TV stand is 35-70 cm tall); ``with_usual_layout``
their usual arrangement (``NAMED_LAYOUTS``: a microwave's controls beside its door);
``with_usual_keypad`` a keypad the text does not count its usual keys.
"""
from __future__ import annotations

import re

import numpy as np

from model.core.structure import SIZE_LIMITS as LIMITS
from model.data.expected_structure import ARRANGEMENT_KEYS

AXIS = {"depth": 0, "width": 1, "height": 2}   # the object frame: x front-back, y left-right

_UNITS = {"mm": 0.001, "millimeter": 0.001, "millimetre": 0.001,
          "cm": 0.01, "centimeter": 0.01, "centimetre": 0.01,
          "m": 1.0, "meter": 1.0, "metre": 1.0,
          "in": 0.0254, "inch": 0.0254, "inches": 0.0254, '"': 0.0254,
          "ft": 0.3048, "foot": 0.3048, "feet": 0.3048}
_WORDS = {"wide": "width", "width": "width", "across": "width",
          "tall": "height", "high": "height", "height": "height", "in height": "height",
          "deep": "depth", "depth": "depth", "in depth": "depth", "in width": "width",
          "long": "length", "length": "length", "in length": "length"}
_NUM = r"(\d+(?:[.,]\d+)?)"
_UNIT = (r"(mm|millimet(?:er|re)s?|cm|centimet(?:er|re)s?|meters?|metres?|m|inch(?:es)?|in|\"|"
         r"ft|foot|feet)")
_AFTER = re.compile(rf"\b{_NUM}\s*-?\s*{_UNIT}(?![a-z])\s*-?\s*"
                    r"(wide|tall|high|deep|long|across|in (?:width|height|depth|length))\b")
_BEFORE = re.compile(r"\b(width|height|depth|length)\s*(?:of|is|:|=|about|around|approx\.?)?\s*"
                     rf"(?:about |around |roughly )?{_NUM}\s*{_UNIT}(?![a-z])")

# usual sizes (m) of everyday names whose category's data is another size
NAMED_SIZES: dict[str, list[tuple[tuple[str, ...], dict[str, float]]]] = {
    "Oven": [(("microwave",), {"width": 0.50, "height": 0.30, "depth": 0.38}),
             (("toaster oven", "countertop oven"), {"width": 0.45, "height": 0.27, "depth": 0.36})],
}


# body ranges (m) of the everyday names the data's descriptions give only to bodies within
# them (model/data/describe.py), and the data's median of each name (synth-v6 val + test):
# name -> {dim: (lowest, highest, median)}. The network reads these rare names loosely ("a
# locker" decoded 0.76-1.08 m tall in 7 of 8 seeds, "a filing cabinet" 0.9 m wide); an open
# dimension outside its range takes the median, one inside keeps its decoded value.
NAMED_RANGES: dict[str, list[tuple[tuple[str, ...], dict[str, tuple[float, float, float]]]]] = {
    "StorageFurniture": [
        (("filing cabinet", "file cabinet"), {"width": (0.0, 0.6, 0.49),
                                              "height": (0.6, 9.9, 1.24)}),
        (("locker",), {"width": (0.0, 0.65, 0.53), "height": (1.2, 9.9, 1.39)}),
        (("wardrobe", "armoire"), {"height": (1.5, 9.9, 1.68)}),
        (("nightstand", "bedside table", "bedside cabinet"), {"width": (0.0, 0.65, 0.47),
                                                               "height": (0.0, 0.75, 0.59)}),
        (("sideboard", "credenza"), {"width": (1.0, 9.9, 1.34), "height": (0.0, 1.1, 0.71)}),
    ],
    "Safe": [(("microwave-sized safe", "small safe", "compact safe"),
              {"width": (0.0, 0.6, 0.47), "height": (0.0, 0.45, 0.36)})],
}

# a dishwasher's usual body (m), for either category the network reads it as
_DISHWASHER = {"width": (0.45, 0.61, 0.6), "height": (0.8, 0.9, 0.85),
               "depth": (0.55, 0.65, 0.6)}

# chests that open at the top (a lid: model.refine.orient) and their usual body, for a chest
# with a lid that no other name sizes ("a chest with a lid hinged at the back")
LIDDED_NAMES = ("toy chest", "toy box", "toy trunk", "blanket chest", "blanket box",
                "hope chest", "storage chest", "storage trunk", "trunk", "storage box",
                "storage bench", "storage ottoman", "ottoman", "storage crate", "crate")
LIDDED_RANGES = {"width": (0.5, 1.3, 0.85), "height": (0.35, 0.7, 0.5),
                 "depth": (0.3, 0.65, 0.45)}

# body ranges (m) of everyday names the data's descriptions never use, from the usual sizes
# of such furniture and appliances, in the form and use of NAMED_RANGES (lowest, highest,
# usual). The network reads a name it never saw as no name at all: "a TV stand" decoded
# 1.46 and 1.64 m tall in 2 of 4 seeds, "a jewelry box" 0.92 m wide and 0.96 m tall, "a
# side table" 1.1-1.2 m wide in 4 of 4, "a gun safe" 0.33 m tall.
EVERYDAY_RANGES: dict[str, list[tuple[tuple[str, ...], dict[str, tuple]]]] = {
    "StorageFurniture": [
        (("jewelry box", "jewellery box", "jewelry chest", "jewellery chest", "trinket box"),
         {"width": (0.15, 0.5, 0.3), "height": (0.08, 0.45, 0.2), "depth": (0.1, 0.35, 0.2)}),
        (("cooler", "cool box", "ice chest", "coolbox"),
         {"width": (0.35, 0.9, 0.6), "height": (0.25, 0.55, 0.4), "depth": (0.25, 0.5, 0.38)}),
        (LIDDED_NAMES, LIDDED_RANGES),
        (("toolbox", "tool box"),
         {"width": (0.3, 0.7, 0.5), "height": (0.15, 0.5, 0.3), "depth": (0.15, 0.4, 0.25)}),
        (("tool chest",),
         {"width": (0.5, 1.1, 0.66), "height": (0.3, 1.1, 0.5), "depth": (0.3, 0.5, 0.45)}),
        (("side table", "end table", "lamp table"),
         {"width": (0.35, 0.7, 0.5), "height": (0.45, 0.75, 0.6), "depth": (0.3, 0.6, 0.45)}),
        (("console table", "hall table", "entryway table"),
         {"width": (0.8, 1.6, 1.1), "height": (0.7, 0.9, 0.78), "depth": (0.25, 0.45, 0.35)}),
        (("tv stand", "tv cabinet", "tv unit", "tv console", "media console", "media cabinet"),
         {"width": (0.9, 2.0, 1.4), "height": (0.35, 0.7, 0.5), "depth": (0.3, 0.55, 0.42)}),
        (("medicine cabinet",),
         {"width": (0.3, 0.8, 0.5), "height": (0.4, 0.9, 0.65), "depth": (0.1, 0.2, 0.15)}),
        (("wall cabinet", "upper cabinet", "wall-mounted cabinet"),
         {"height": (0.3, 1.0, 0.72), "depth": (0.25, 0.4, 0.33)}),
        (("base cabinet",), {"height": (0.8, 0.95, 0.87), "depth": (0.5, 0.65, 0.58)}),
        (("vanity",), {"height": (0.75, 0.95, 0.85), "depth": (0.4, 0.6, 0.5)}),
        (("kitchen island",),
         {"width": (1.0, 2.5, 1.6), "height": (0.85, 0.95, 0.9), "depth": (0.6, 1.2, 0.9)}),
        (("pantry", "pantry cabinet", "larder"),
         {"height": (1.5, 2.3, 1.9), "depth": (0.3, 0.65, 0.5)}),
        (("china cabinet", "display cabinet", "curio cabinet", "hutch"),
         {"height": (1.4, 2.1, 1.85), "depth": (0.3, 0.55, 0.42)}),
        (("bookcase", "bookshelf"), {"height": (0.7, 2.2, 1.8), "depth": (0.25, 0.45, 0.32)}),
        (("shoe cabinet",), {"height": (0.8, 1.4, 1.0), "depth": (0.2, 0.4, 0.3)}),
        (("printer stand", "printer cabinet"),
         {"width": (0.4, 0.9, 0.6), "height": (0.5, 0.8, 0.65), "depth": (0.35, 0.6, 0.45)}),
        (("desk pedestal", "file pedestal", "mobile pedestal"),
         {"width": (0.3, 0.5, 0.4), "height": (0.5, 0.75, 0.6), "depth": (0.4, 0.65, 0.5)}),
        (("entertainment center", "entertainment centre", "entertainment unit"),
         {"width": (1.2, 2.5, 1.6), "height": (0.45, 1.9, 0.9), "depth": (0.35, 0.6, 0.45)}),
        (("buffet", "buffet cabinet"),
         {"width": (1.0, 2.2, 1.5), "height": (0.75, 1.0, 0.85), "depth": (0.4, 0.55, 0.45)}),
        (("mini fridge", "minifridge", "bar fridge"),
         {"width": (0.4, 0.6, 0.48), "height": (0.45, 0.9, 0.85), "depth": (0.4, 0.6, 0.5)}),
        # a chest freezer opens at the top (a lid: LIDDED_NAMES' usual part); before the
        # upright one
        (("chest freezer", "deep freezer", "box freezer"),
         {"width": (0.6, 1.7, 1.0), "height": (0.8, 0.92, 0.85), "depth": (0.5, 0.8, 0.65)}),
        (("refrigerator", "fridge", "fridge freezer", "freezer"),
         {"width": (0.55, 0.95, 0.7), "height": (1.4, 2.0, 1.75), "depth": (0.55, 0.8, 0.65)}),
        (("dishwasher",), _DISHWASHER),
    ],
    "Oven": [
        (("dishwasher",), _DISHWASHER),
    ],
    "Safe": [
        (("hotel safe", "in-room safe"),
         {"width": (0.3, 0.5, 0.42), "height": (0.18, 0.35, 0.25), "depth": (0.25, 0.45, 0.37)}),
        (("gun safe", "rifle safe"),
         {"width": (0.45, 1.1, 0.7), "height": (1.0, 1.9, 1.5), "depth": (0.4, 0.7, 0.55)}),
        (("wall safe",),
         {"width": (0.3, 0.6, 0.4), "height": (0.25, 0.6, 0.4), "depth": (0.1, 0.35, 0.2)}),
    ],
    "Bottle": [
        (("wine bottle",), {"width": (0.07, 0.09, 0.075), "depth": (0.07, 0.09, 0.075),
                            "height": (0.28, 0.36, 0.3)}),
        (("baby bottle",), {"width": (0.05, 0.08, 0.065), "depth": (0.05, 0.08, 0.065),
                            "height": (0.12, 0.22, 0.17)}),
    ],
}


def _named(text: str, names: tuple[str, ...]) -> bool:
    low = text.lower()
    return any(re.search(rf"\b{n}s?\b", low) for n in names)


def _unit(word: str) -> float:
    return _UNITS[word[:-1] if word.endswith("s") and word != "inches" else word]


def read_size(text: str) -> dict[str, float]:
    """The body dimensions ``text`` states, in metres (see the module docstring)."""
    low = text.lower().replace("\u201d", '"')
    out: dict[str, float] = {}
    hits = [(m.start(), m.group(1), m.group(2), m.group(3)) for m in _AFTER.finditer(low)]
    hits += [(m.start(), m.group(2), m.group(3), m.group(1)) for m in _BEFORE.finditer(low)]
    for _, num, unit, word in sorted(hits):
        value = float(num.replace(",", ".")) * _unit(unit)
        dim = _WORDS[word]
        if LIMITS[0] <= value <= LIMITS[1] and dim not in out:
            out[dim] = round(value, 4)
    return out


# --------------------------------------------------------------------------------------------
# size words: "a tall cabinet", "a small safe", "a narrow wardrobe"
# --------------------------------------------------------------------------------------------
# The data's descriptions state sizes in numbers only, so the network does not read size
# words ("a tall bathroom cabinet" decoded 0.46-0.56 m tall); they are read here and give the
# body a size in the matching quarter of its category's spread. Body sizes of synth-v6 val +
# test (model/data/synth, 2000 objects), m: per dimension (depth, width, height) and for the
# body's overall size (the geometric mean of its sides) the lowest, the 25th and 75th
# percentiles and the highest.
SIZE_SPREAD: dict[str, dict[str, tuple[float, float, float, float]]] = {
    "StorageFurniture": {"depth": (0.35, 0.408, 0.534, 0.60),
                         "width": (0.402, 0.668, 1.292, 1.60),
                         "height": (0.401, 0.744, 1.523, 1.895),
                         "size": (0.445, 0.654, 0.889, 1.179)},
    "Safe": {"depth": (0.301, 0.388, 0.533, 0.599), "width": (0.30, 0.418, 0.596, 0.699),
             "height": (0.253, 0.433, 0.745, 0.897), "size": (0.351, 0.446, 0.555, 0.677)},
    "Oven": {"depth": (0.50, 0.54, 0.607, 0.65), "width": (0.501, 0.624, 0.805, 0.90),
             "height": (0.45, 0.565, 0.805, 0.95), "size": (0.494, 0.607, 0.694, 0.79)},
    "WashingMachine": {"depth": (0.50, 0.537, 0.616, 0.65), "width": (0.551, 0.587, 0.662, 0.699),
                       "height": (0.80, 0.834, 0.907, 0.95), "size": (0.612, 0.657, 0.695, 0.741)},
    "Bottle": {"depth": (0.05, 0.068, 0.102, 0.119), "width": (0.05, 0.068, 0.102, 0.119),
               "height": (0.117, 0.169, 0.257, 0.311), "size": (0.072, 0.097, 0.128, 0.159)},
    "USB": {"depth": (0.042, 0.049, 0.061, 0.072), "width": (0.014, 0.017, 0.022, 0.024),
            "height": (0.006, 0.007, 0.010, 0.011), "size": (0.016, 0.019, 0.022, 0.025)},
}

# word -> (dimension, +1 larger / -1 smaller); "size" is the whole body (proportions kept),
# "length" its longest side as decoded. "short" is a body's height ("a short cabinet"),
# a USB stick's length ("SHORT_IS_LENGTH").
SIZE_WORDS: dict[str, tuple[str, int]] = {
    **{w: ("height", 1) for w in ("tall", "high")},
    **{w: ("height", -1) for w in ("short", "low", "squat", "low-profile")},
    **{w: ("width", 1) for w in ("wide", "broad")},
    **{w: ("width", -1) for w in ("narrow", "slim", "slender")},
    "deep": ("depth", 1), "shallow": ("depth", -1), "long": ("length", 1),
    **{w: ("size", 1) for w in ("large", "big", "huge", "giant", "oversized", "jumbo")},
    **{w: ("size", -1) for w in ("small", "little", "compact", "mini", "tiny", "miniature")},
}
SHORT_IS_LENGTH = ("USB",)
ROUND = ("Bottle",)     # width and depth are one diameter: a word for either scales both
# a named size (NAMED_SIZES: a microwave) is not the data's: a size word scales it
NAMED_SIZE_STEP = 1.25
_INTENSIFIERS = {"very", "extra", "quite", "rather", "fairly", "really", "super", "extremely",
                 "relatively", "pretty", "particularly", "especially", "slightly", "a", "bit"}
_NEGATIONS = {"not", "isn't", "never", "no", "nor", "too"}
_LINKS = {"is", "it's", "looks", "stands", "seems"}
_CLAUSE_ENDS = {"with", "of", "in", "on", "that", "which", "for", "to", "at", "has", "having",
                "featuring", "is", "are", "whose", "where", "behind", "above", "below", "under"}


def _describes_object(toks, i: int) -> bool:
    """Whether the size word ``toks[i]`` is said of the object, not of a part: before the
    object's name in its noun phrase ("a tall, narrow bathroom cabinet", "a small
    three-drawer chest", not "six small drawers"), or after "is" with the object (or "it")
    as the subject ("the cabinet is tall", not "the drawers are small")."""
    for t in toks[i + 1:i + 7]:                        # attributive: the object's name follows
        if t.kind == "CAT":
            return True
        if (t.kind == "PART" and t.plural) or t.kind in ("DET", "LOWER", "DIST") or (
                t.kind == "PUNCT" and t.text != ",") or t.text in _CLAUSE_ENDS:
            break
    j = i - 1                                          # predicative: "<subject> is (very) tall"
    while j >= 0 and (toks[j].text in _INTENSIFIERS or toks[j].text in ("and", ",")
                      or toks[j].text in SIZE_WORDS):
        j -= 1
    if j < 0 or toks[j].text not in _LINKS:
        return False
    if toks[j].text == "it's":
        return True
    for t in reversed(toks[:j]):
        if t.kind in ("CAT", "PART"):
            return t.kind == "CAT"
        if t.text in ("it", "this"):
            return True
    return False


def read_size_words(text: str) -> dict[str, int]:
    """The size words ``text`` says of the object: dimension ("height", "width", "depth",
    "length", or "size" for all of it) -> +1 (tall, wide, large, ...) or -1 (short, narrow,
    small, ...); the first word for a dimension wins, a negated one ("not too tall") counts
    for nothing."""
    from .prompt_lexicon import _sentences, _tokenize

    out: dict[str, int] = {}
    for sentence in _sentences(text):
        toks = _tokenize(sentence)
        for i, tok in enumerate(toks):
            if tok.kind != "WORD" or tok.text not in SIZE_WORDS:
                continue
            if i and toks[i - 1].text in _NEGATIONS or not _describes_object(toks, i):
                continue
            dim, sign = SIZE_WORDS[tok.text]
            out.setdefault(dim, sign)
    return out


def _into_quarter(value: float, spread: tuple[float, float, float, float], sign: int) -> float:
    """``value`` moved into the top quarter of ``spread`` (lowest, p25, p75, highest) when
    ``sign`` > 0 and it is below the 75th percentile, into the bottom quarter when ``sign`` < 0
    and it is above the 25th: mapped linearly, so decoded sizes keep their order (seeds
    still vary the size); otherwise kept."""
    lo, q1, q3, hi = spread
    if sign > 0 and value < q3:
        return q3 + float(np.clip((value - lo) / (q3 - lo), 0.0, 1.0)) * (hi - q3)
    if sign < 0 and value > q1:
        return lo + float(np.clip((value - q1) / (hi - q1), 0.0, 1.0)) * (q1 - lo)
    return value


# An open dimension this many times beyond the data's spread of its category (SIZE_SPREAD) is
# not a size the category comes in: "a thermos" (a word the data lacks) decoded as a 46 cm
# wide bottle, "a small safe with a keypad" as a 2.5 cm tall one. Gun safes 1.06 m tall
# (the data's highest: 0.90 m) and 2.05 m wardrobes (1.90 m) are real, and stay.
GROSS = 1.5
WIDTH_LABELS = ("drawer", "door", "tray", "lid")   # the parts whose rows need the body's width


def _within_data(category: str, have: dict[str, float], stated: dict) -> dict[str, float]:
    """``have`` (the decoded body's depth, width, height in m) when every dimension ``stated``
    leaves open is within ``GROSS`` of the data's spread; otherwise the decoded size says
    nothing the category's data would (its proportions neither: the thermos was wider than
    tall) and each open dimension takes the middle of the data's (between its quartiles)."""
    spread = SIZE_SPREAD.get(category)
    open_dims = [d for d in AXIS if d not in stated]
    if spread is None or all(spread[d][0] / GROSS <= have[d] <= spread[d][3] * GROSS
                             for d in open_dims):
        return dict(have)
    return {**have, **{d: (spread[d][1] + spread[d][2]) / 2 for d in open_dims}}


def _sized(category: str, words: dict[str, int], stated: dict, have: dict[str, float],
           ranges: dict | None) -> dict[str, float]:
    """``have`` (the body's depth, width, height in m) with ``words`` (read_size_words) given
    within the data's spread of ``category`` (SIZE_SPREAD, ``_into_quarter``): "tall" puts the
    height in the tallest quarter, "narrow" the width in the narrowest (a bottle's depth
    with it, ``ROUND``); "large" / "small" scale
    the whole body alike so its overall size is in the largest / smallest quarter (each side
    kept within the data's), unless the text states a dimension. Stated dimensions are kept;
    a name's range (NAMED_RANGES) bounds the result."""
    spread = SIZE_SPREAD.get(category)
    out = dict(have)
    if spread is None:
        return out
    if "size" in words and not stated:
        size = float(np.exp(np.mean(np.log([out[d] for d in AXIS]))))
        factor = _into_quarter(size, spread["size"], words["size"]) / size
        for dim in AXIS:
            out[dim] = float(np.clip(out[dim] * factor, spread[dim][0], spread[dim][3]))
    for dim, sign in words.items():
        if dim == "size":
            continue
        if dim == "length" or (dim == "height" and sign < 0 and category in SHORT_IS_LENGTH):
            dim = max(AXIS, key=lambda d: out[d])
        if dim not in stated:
            was, out[dim] = out[dim], _into_quarter(out[dim], spread[dim], sign)
            if category in ROUND and dim in ("width", "depth"):
                other = "depth" if dim == "width" else "width"
                if other not in stated:
                    out[other] *= out[dim] / was
    for dim, (lo, hi, _) in (ranges or {}).items():
        if dim not in stated:
            out[dim] = float(np.clip(out[dim], lo, hi))
    return out


# usual arrangements of everyday names whose category's data has another one (a microwave's
# door hangs on the left with its controls in a column to its right; the data's ovens have a
# control panel above the door), or which the data gives that name only with (a filing
# cabinet's drawers are one column): (names, the door's hinge they hold for or None, facts
# per label)
NAMED_LAYOUTS: dict[str, list[tuple[tuple[str, ...], str | None, dict]]] = {
    "Oven": [(("microwave",), "left",
              {"door": {"hpos": ["left"]}, **{c: {"hpos": ["right"], "layout": "column"}
                                              for c in ("knob", "button", "dial")},
               "button": {"hpos": ["right"], "layout": "column", "below": ["knob"]}})],
    "StorageFurniture": [(("filing cabinet", "file cabinet", "tool chest", "rolling tool chest",
                           "tool cabinet", "roller cabinet"), None,
                          {"drawer": {"layout": "column"}}),
                         # a wardrobe's doors stand side by side ("a four-door wardrobe" had
                         # four full-width doors stacked, 41 cm tall)
                         (("wardrobe", "armoire"), None, {"door": {"layout": "row"}}),
                         # ... as a low, wide sideboard's do ("a credenza with four doors and
                         # no drawers" had four 10 cm strips stacked, flipping down)
                         (("sideboard", "credenza", "buffet", "tv stand", "tv cabinet",
                           "tv unit", "tv console", "media console", "media cabinet",
                           "entertainment center", "entertainment centre",
                           "entertainment unit"), None,
                          {"door": {"layout": "row"}})],
}


def _clashes(stated: dict, usual: dict) -> bool:
    """Whether a label's stated facts arrange or place it otherwise than its usual facts do:
    an arrangement or side the usual layout does not give it, or another value for one it
    does ("a microwave with a column of buttons" agrees with the usual column; "... with a
    row of buttons" does not)."""
    said = {k: v for k, v in stated.items() if k in ARRANGEMENT_KEYS or k == "hpos"}
    return any(k not in usual or usual[k] != v for k, v in said.items())


def with_usual_layout(text: str, category: str | None, spatial: dict | None) -> dict | None:
    """``spatial`` (label -> facts) with the usual arrangement of an everyday name in ``text``
    (``NAMED_LAYOUTS``) where the door hangs as usual and every stated arrangement and side
    is the usual one (a stated fact is kept, the usual ones fill in the rest):
    what generation holds ("a microwave" gets its control column beside the door; "a
    microwave with a keypad on the right" its knobs in it too). Not a stated fact: the
    alignment metric checks the prompt's facts only."""
    for names, hinge, usual in NAMED_LAYOUTS.get(category or "", []):
        if not _named(text, names):
            continue
        facts = spatial or {}
        if (hinge is not None and (facts.get("door") or {}).get("hinge") != [hinge]) or any(
                _clashes(f, usual.get(lab) or {}) for lab, f in facts.items()):
            return spatial
        out = {lab: dict(f) for lab, f in facts.items()}
        for lab, f in usual.items():      # sides stated as usual ("a keypad on the right"):
            mine = out.setdefault(lab, {})            # the rest joins them (its knobs had
            for key, value in f.items():              # narrowed the door to a third)
                mine.setdefault(key, value)
        return out
    return spatial


def with_usual_size(text: str, category: str | None, stated: dict | None,
                    decoded=None, spatial: dict | None = None) -> dict:
    """``stated`` with the usual size of an everyday name in ``text`` for the dimensions it
    leaves open: what generation gives the body ("a microwave" is microwave-sized:
    ``NAMED_SIZES``). With ``decoded`` (the decoded body's depth, width, height in m), a
    name of ``NAMED_RANGES`` ("a locker") gives every open dimension outside its range the
    name's median and keeps the others as decoded, unless the text's ``spatial`` facts
    (label -> facts) arrange parts ("a filing cabinet with drawers in two columns" keeps the
    width its columns need); then the size words the text says of the object ("a tall
    cabinet", ``read_size_words``) take their dimensions within the data's spread
    (``SIZE_SPREAD``). Not a stated fact: the alignment metric checks ``stated`` only."""
    out = dict(stated or {})
    if "length" in out:
        return out
    words = read_size_words(text) if category else {}
    for names, usual in NAMED_SIZES.get(category or "", []):
        if _named(text, names):
            for dim, value in usual.items():
                sign = words.get(dim, 0) + (words.get("size", 0) if not stated else 0)
                out.setdefault(dim, round(float(value * NAMED_SIZE_STEP ** np.sign(sign)), 4))
            return out
    if decoded is None:
        return out
    have = {dim: float(decoded[ax]) for dim, ax in AXIS.items()}
    want, ranges = _within_data(category, have, out), None
    arranged = any(f.keys() & ARRANGEMENT_KEYS for lab, f in (spatial or {}).items()
                   if lab in WIDTH_LABELS)
    for names, name_ranges in (NAMED_RANGES.get(category or "", [])
                               + EVERYDAY_RANGES.get(category or "", [])):
        if not _named(text, names):
            continue
        ranges = name_ranges
        if not arranged:
            want.update({dim: mid for dim, (lo, hi, mid) in ranges.items()
                         if dim not in out and not lo <= have[dim] <= hi})
        break
    want = _sized(category, words, out, want, ranges if not arranged else None)
    if any(abs(want[dim] - have[dim]) > 1e-9 for dim in AXIS if dim not in out):
        for dim, value in want.items():       # every dimension, so an open one keeps its
            out.setdefault(dim, round(value, 4))   # size (scale_to_size would scale it)
    return out


# a chest's dimension -> the dimension of the cabinet it is decoded as (model.refine.orient)
FRONT_UP_DIMS = {"height": "depth", "depth": "height", "width": "width"}


def with_lidded_size(text: str, stated: dict | None, decoded) -> dict:
    """The body size (m: depth, width, height of the chest) of a chest with a lid, decoded as
    a cabinet with flip-up doors (model.refine.orient) and turned front up: ``stated`` with
    open dimension scaled so that together they have the usual size of the name in ``text``
    (its NAMED_RANGES or EVERYDAY_RANGES entry: "a jewelry box"; ``LIDDED_RANGES`` for any
    other chest; the geometric mean of the range's usual sides), each within its range: the
    decoded cabinet's proportions (``decoded``: the cabinet's depth, width, height) and the
    seed's variation are kept, its overall size is not (the data's cabinets are 0.4-1.9 m
    tall: a jewelry box had come out 43 cm tall). Size words ("a small trunk", "a wide
    chest") take NAMED_SIZE_STEP, within the range."""
    out = dict(stated or {})
    if "length" in out:
        return out
    ranges = next((r for names, r in NAMED_RANGES["StorageFurniture"]
                   + EVERYDAY_RANGES["StorageFurniture"] if _named(text, names)
                   and set(r) == set(AXIS)), LIDDED_RANGES)
    have = {dim: float(decoded[AXIS[FRONT_UP_DIMS[dim]]]) for dim in AXIS}
    open_dims = [dim for dim in AXIS if dim not in out]
    if not open_dims:
        return out
    scale = float(np.exp(np.mean([np.log(ranges[d][2] / max(have[d], 1e-6))
                                  for d in open_dims])))
    words = read_size_words(text)
    for dim in open_dims:
        lo, hi, _ = ranges[dim]
        sign = words.get(dim, 0) + (words.get("size", 0) if not stated else 0)
        out[dim] = round(float(np.clip(have[dim] * scale * NAMED_SIZE_STEP ** np.sign(sign),
                                       lo, hi)), 4)
    return out


_KNOBS = re.compile(r"\bknobs?\b", re.I)


def says_knobs(text: str) -> bool:
    """Whether ``text`` calls parts knobs: on storage furniture, its handles are knob pulls
    (model.refine.hardware.knob_handles)."""
    return bool(_KNOBS.search(text))


def height_said(text: str, category: str | None, stated: dict | None) -> bool:
    """Whether ``text`` gives the body's height: stated ("1.2 m tall", a length), said in size
    words ("a tall cabinet", "a small chest": ``read_size_words``), or an everyday name's
    usual height (``NAMED_SIZES``, ``NAMED_RANGES``, ``EVERYDAY_RANGES``)."""
    return _said(text, category, stated, "height")


def width_said(text: str, category: str | None, stated: dict | None) -> bool:
    """Whether ``text`` gives the body's width, as :func:`height_said` its height ("60 cm
    wide", "a wide cabinet", an everyday name's usual width)."""
    return _said(text, category, stated, "width")


def _said(text: str, category: str | None, stated: dict | None, dim: str) -> bool:
    if stated and (dim in stated or "length" in stated):
        return True
    if read_size_words(text).keys() & {dim, "length", "size"}:
        return True
    named = (NAMED_SIZES.get(category or "", []) + NAMED_RANGES.get(category or "", [])
             + EVERYDAY_RANGES.get(category or "", []))
    return any(dim in dims for names, dims in named if _named(text, names))


# A safe's keypad the text does not count ("a safe with a keypad", read as at least two
# buttons): the data's middle keypad, 3 x 3 (model/data/synth/cabinets.py draws 1x3 to 4x3 on
# a safe's door; no other category of the data has a keypad)
USUAL_KEYPAD = (3, 3)
_KEYPAD = re.compile(r"\b(?:keypad|number ?pad|numpad)s?\b", re.I)


def with_usual_keypad(text: str, expected):
    """``expected`` (a parsed prompt, ``ExpectedStructure``) with a safe's uncounted keypad's
    buttons at least ``USUAL_KEYPAD``'s keys, three to a row unless the text arranges them:
    what generation holds ("a safe with a keypad" gets a 3 x 3 keypad, not two keys). Not a
    stated fact: the alignment metric checks the prompt's own lower bound."""
    from dataclasses import replace

    if expected.category != "Safe" or not _KEYPAD.search(text) \
            or "button" in expected.counts or "button" not in expected.min_counts:
        return expected
    rows, cols = USUAL_KEYPAD
    facts = dict(expected.spatial.get("button") or {})
    if not facts.keys() & ARRANGEMENT_KEYS:
        facts["columns"] = cols
    return replace(expected, min_counts={**expected.min_counts,
                                         "button": max(expected.min_counts["button"],
                                                       rows * cols)},
                   spatial={**expected.spatial, "button": facts})


# A stove's oven door drops down, hinged at the bottom, as three quarters of the data's ovens'
# do (the rest are wall ovens hinged on a side); the network gave "a stove with an oven door
# and four knobs on the front" a side-hinged door with 4 of 4 seeds
DROP_DOOR_NAMES = ("stove", "cooker", "range")


def with_usual_hinge(text: str, expected):
    """``expected`` (a parsed prompt, ``ExpectedStructure``) with a stove's one door hinged
    at the bottom, opening downwards (``DROP_DOOR_NAMES``), where the text says nothing of
    the door's hinge or opening: what generation holds. Not a stated fact: the alignment
    metric checks the prompt's own."""
    from dataclasses import replace

    if expected.category != "Oven" or expected.counts.get("door", 1) != 1 \
            or not _named(text, DROP_DOOR_NAMES):
        return expected
    door = dict(expected.spatial.get("door") or {})
    if door.get("hinge") or door.get("opens"):
        return expected
    door.update(hinge=["bottom"], opens=["down"])
    return replace(expected, spatial={**expected.spatial, "door": door})


# The usual moving parts of a bare name ("a dresser", "an oven": a category and no part): a
# text model trained on descriptions that always list the parts decoded "a cabinet" as an
# empty carcass. First match wins; the category's default last. Counts are the data's
# typical ones for that kind of object (model/data/synth).
USUAL_PARTS = {
    "StorageFurniture": [(LIDDED_NAMES + ("jewelry box", "jewellery box", "trinket box",
                                         "chest freezer", "deep freezer", "box freezer",
                                         "cooler", "cool box", "coolbox", "ice chest",
                                         "toolbox", "tool box"),
                          {"lid": 1}),
                         (("refrigerator", "fridge", "freezer"), {"door": 2}),
                         (("dresser", "chest of drawers", "chest", "tallboy", "filing cabinet",
                           "drawer unit"), {"drawer": 4}),
                         (("nightstand", "night stand", "bedside table", "bedside cabinet"),
                          {"drawer": 1}),
                         (("wardrobe", "closet", "armoire", "cupboard", "locker"),
                          {"door": 2}),
                         ((), {"door": 2})],
    "Safe": [((), {"door": 1})],
    "Oven": [((), {"door": 1})],
    "WashingMachine": [((), {"door": 1})],      # a top loader's lid: the reader's own
    "Bottle": [((), {"cap": 1})],
    "USB": [((), {"cap": 1})],
}


def usual_parts_text(text: str, said, usual) -> str | None:
    """What the text model reads for a name given its usual parts (``usual``, from
    :func:`with_usual_parts` of the parse ``said``): the text with those parts named ("a
    cabinet" -> "a cabinet with two doors"), or None where no usual part was added. The
    network decodes a part the text never names poorly: "a cabinet", "a storage cabinet"
    and "a closet" had both their doors lying on the body's bottom with 6 of 6 seeds, "a
    refrigerator" with 5 of 6."""
    from model.data import vocab

    added = {lab: n for lab, n in usual.counts.items() if lab not in said.counts and n > 0}
    if not added:
        return None
    words = [("a" if n == 1 else vocab.number_word(n)) + " " +
             (lab if n == 1 else vocab.plural(lab)) for lab, n in added.items()]
    return f"{text.strip().rstrip('.!?')} with {' and '.join(words)}"


def with_usual_parts(text: str, expected):
    """``expected`` (a parsed prompt, ``ExpectedStructure``) with a bare name's usual parts
    (``USUAL_PARTS``) as its counts when the text names a category and no part at all (no
    count, bound, zero, joint or spatial fact): what generation holds ("a dresser" gets
    four drawers, "a cabinet" two doors; the network lays them out, and the seed varies the
    layout). An everyday name whose parts the text counts nowhere, only bounds ("a dresser
    with knobs", "a chest of drawers with knobs on every drawer"), gets its usual parts
    where they meet the bounds. Not a stated fact: the alignment metric checks the
    prompt's own structure."""
    from dataclasses import replace

    if not expected.category or expected.counts:
        return expected
    bare = not (expected.min_counts or expected.joint_types or expected.spatial)
    for names, parts in USUAL_PARTS.get(expected.category, []):
        if bare and (not names or _named(text, names)):
            return replace(expected, counts=dict(parts))
        # a named object whose parts the text only bounds ("a chest of drawers with round
        # knobs on every drawer": at least one drawer; the network made one): its usual
        # count where that meets the bound
        if names and _named(text, names):
            held = {lab: n for lab, n in parts.items()
                    if expected.min_counts.get(lab, 0) <= n}
            if not held:
                return expected
            return replace(expected, counts=held, min_counts={
                lab: n for lab, n in expected.min_counts.items() if lab not in held})
    return expected
