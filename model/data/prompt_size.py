"""The size a prompt states: "60 cm wide", "1.2 m tall", "a depth of 40 cm", "24 inches high".

``read_size(text)`` -> {"width": m, "height": m, "depth": m} with the dimensions the
text states, in metres, of the object's body (width across the front, the viewer's left to
right; height bottom to top; depth front to back). "long" / "length" is the body's longest
side. A value outside 1 cm - 5 m is not a size a generated object can take and is ignored.

``with_usual_size`` adds the usual size of everyday objects the data lacks at their size for
the dimensions the text leaves open (``NAMED_SIZES``: a microwave is read as an oven, whose
data is 45-95 cm tall, so without it "a microwave" came out oven-sized), and keeps the
data's everyday names within the body sizes the data gives them (``NAMED_RANGES``: a locker
is over 1.2 m tall); ``with_usual_layout``
their usual arrangement (``NAMED_LAYOUTS``: a microwave's controls beside its door);
``with_usual_keypad`` a keypad the text does not count its usual keys.
"""
from __future__ import annotations

import re

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
    "StorageFurniture": [(("filing cabinet", "file cabinet"), None,
                          {"drawer": {"layout": "column"}})],
}


def with_usual_layout(text: str, category: str | None, spatial: dict | None) -> dict | None:
    """``spatial`` (label -> facts) with the usual arrangement of an everyday name in ``text``
    (``NAMED_LAYOUTS``) where the door hangs as usual and nothing about the sides is stated:
    what generation holds ("a microwave" gets its control column beside the door). Not a
    stated fact: the alignment metric checks the prompt's facts only."""
    for names, hinge, usual in NAMED_LAYOUTS.get(category or "", []):
        if not _named(text, names):
            continue
        facts = spatial or {}
        if (hinge is not None and (facts.get("door") or {}).get("hinge") != [hinge]) or any(
                f.get("hpos") or f.keys() & ARRANGEMENT_KEYS for f in facts.values()):
            return spatial
        out = {lab: dict(f) for lab, f in facts.items()}
        for lab, f in usual.items():
            out.setdefault(lab, {}).update(f)
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
    width its columns need). Not a stated fact: the alignment metric checks ``stated``
    only."""
    out = dict(stated or {})
    if "length" in out:
        return out
    for names, usual in NAMED_SIZES.get(category or "", []):
        if _named(text, names):
            for dim, value in usual.items():
                out.setdefault(dim, value)
            return out
    if decoded is None or any(f.keys() & ARRANGEMENT_KEYS for f in (spatial or {}).values()):
        return out
    for names, ranges in NAMED_RANGES.get(category or "", []):
        if not _named(text, names):
            continue
        have = {dim: float(decoded[ax]) for dim, ax in AXIS.items()}
        fixed = {dim: mid for dim, (lo, hi, mid) in ranges.items()
                 if dim not in out and not lo <= have[dim] <= hi}
        if fixed:       # the other dimensions keep their decoded size (scale_to_size would
            for dim, value in have.items():          # scale an open one with the rest)
                out.setdefault(dim, fixed.get(dim, round(value, 4)))
        break
    return out


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


# The usual moving parts of a bare name ("a dresser", "an oven": a category and no part): a
# text model trained on descriptions that always list the parts decoded "a cabinet" as an
# empty carcass. First match wins; the category's default last. Counts are the data's
# typical ones for that kind of object (model/data/synth).
USUAL_PARTS = {
    "StorageFurniture": [(("dresser", "chest of drawers", "chest", "tallboy", "filing cabinet",
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


def with_usual_parts(text: str, expected):
    """``expected`` (a parsed prompt, ``ExpectedStructure``) with a bare name's usual parts
    (``USUAL_PARTS``) as its counts when the text names a category and no part at all (no
    count, bound, zero, joint or spatial fact): what generation holds ("a dresser" gets
    four drawers, "a cabinet" two doors; the network lays them out, and the seed varies the
    layout). Not a stated fact: the alignment metric checks the prompt's own structure."""
    from dataclasses import replace

    if not expected.category or expected.counts or expected.min_counts \
            or expected.joint_types or expected.spatial:
        return expected
    for names, parts in USUAL_PARTS.get(expected.category, []):
        if not names or _named(text, names):
            return replace(expected, counts=dict(parts))
    return expected
