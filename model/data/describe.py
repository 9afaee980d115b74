"""Text descriptions of articulated objects at four lengths (DESIGN §3.1), from ground truth.

``describe(obj, rng)`` returns ``{length: [variants...]}`` for the lengths of
``model.data.format.DESCRIPTION_LENGTHS``: "detailed" (a paragraph with sizes, sides and
ranges), "sentences" (two or three sentences), "sentence" (one), "words" (a few words).
Every variant names the category and, for every countable part kind, its count and how it
moves, with wording drawn from the synonym tables in :mod:`model.data.vocab` — so a parser
that knows those tables reads back :func:`structured_summary`.

The spatial facts they state are read in :mod:`model.data.spatial`, the phrases built in
:mod:`model.data.phrases`; this module names the object and puts the phrases together.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from model.core.objects import ArticulatedObject
from model.data import vocab
from model.data.format import DESCRIPTION_LENGTHS
from model.data.phrases import (_article, _cap_first, _choice, _compound, _facts, _group_np,
                                _hinge_phrase, _join, _motion, _noun, _opens, _post,
                                _range_clause, _relation_sentence, _size_phrase, _unhinged)
from model.data.phrases import _pluralise_verb  # noqa: F401  (re-exported: it lived here)
# the spatial facts lived in this module before model.data.spatial: still importable from it
from model.data.spatial import (HINGED_LABELS, HPOS_MARGIN, SPATIAL_LABELS,  # noqa: F401
                                VPOS_MARGIN, arrangement, body_box, hinge_side, is_above,
                                opening_direction, part_position, spatial_summary)

VARIANTS_PER_LENGTH = 3

# Which parts a viewer reads first.
_ORDER = ("drawer", "door", "lid", "cap", "tray", "knob", "dial", "button", "handle", "other")


def structured_summary(obj: ArticulatedObject) -> dict:
    """``ArticulatedObject.summary()`` (category, counts, joint_types, num_parts, num_movable)
    plus ``spatial``: the spatial facts of every part group (:func:`spatial_summary`)."""
    out = obj.summary()
    out["spatial"] = spatial_summary(obj)
    return out


def _groups(obj: ArticulatedObject) -> list[tuple[str, int, list[str], list[int]]]:
    """(label, count, sorted joint type names, part indices) per countable label, fixed order."""
    out = []
    for label in _ORDER:
        idx = [i for i, p in enumerate(obj.parts) if p.label == label]
        if idx and label in vocab.COUNTABLE_LABELS:
            types = sorted({obj.parts[i].joint.type.name.lower() for i in idx})
            out.append((label, len(idx), types, idx))
    return out


def everyday_names(obj: ArticulatedObject, spatial: Optional[dict] = None) -> list[str]:
    """Names a person would use for this object, each only where it is true of its shape and
    parts (a dresser has drawers and no doors, a nightstand is small and low, a top loader has
    a lid, ...). The first entries are the plain names of the category."""
    cat = obj.category
    spatial = spatial if spatial is not None else spatial_summary(obj)
    counts = obj.summary()["counts"]
    _, size = body_box(obj)
    D, W, H = (float(x) for x in size)
    names: list[str] = []
    if cat == "StorageFurniture":
        names += ["cabinet", "storage cabinet", "cupboard", "storage unit"]
        drawers, doors = counts.get("drawer", 0), counts.get("door", 0)
        if drawers and not doors:
            names += ["dresser", "chest of drawers", "chest"]
            if spatial.get("drawer", {}).get("layout") in ("column", "single") and W < 0.6 \
                    and H > 0.6:
                names += ["filing cabinet", "file cabinet"]
        if H < 0.75 and W < 0.65 and drawers + doors <= 3:
            names += ["nightstand", "bedside table", "bedside cabinet"]
        if W > 1.0 and H < 1.1:
            names += ["sideboard", "credenza"]
        if H > 1.5 and doors:
            names += ["wardrobe", "armoire"]
        if H > 1.2 and W < 0.65 and doors and not drawers:
            names += ["locker"]
    elif cat == "Safe":
        names += ["safe", "strongbox", "lockbox", "security safe", "safe box"]
        if W < 0.6 and H < 0.45:
            names += ["microwave-sized safe", "small safe", "compact safe"]
    elif cat == "Oven":
        names += ["oven", "cooker", "kitchen oven", "stove"]
        door = spatial.get("door", {})
        if counts.get("knob", 0) >= 4 and door.get("opens") == ["down"]:
            names += ["range", "kitchen range"]
        if door.get("hinge") and set(door["hinge"]) <= {"left", "right"}:
            names += ["wall oven"]
    elif cat == "WashingMachine":
        names += ["washing machine", "washer", "laundry machine", "clothes washer"]
        if counts.get("door") and spatial["door"].get("opens") == ["sideways"]:
            names += ["front-loader", "front-loading washer", "front-loading washing machine"]
        if counts.get("lid") and spatial["lid"].get("opens") == ["up"]:
            names += ["top loader", "top-loader", "top-loading washer"]
    elif cat == "Bottle":
        names += ["bottle", "flask", "water bottle", "drink bottle"]
        types = obj.summary()["joint_types"]
        if counts.get("cap") and types.get("cap") == ["screw"]:
            names += ["screw-top bottle"]
        if counts.get("lid") and spatial["lid"].get("opens") == ["up"]:
            names += ["flip-top bottle", "sports bottle"]
    elif cat == "USB":
        names += ["usb stick", "usb drive", "flash drive", "thumb drive", "memory stick",
                  "pen drive", "usb flash drive"]
        if obj.summary()["joint_types"].get("cap") == ["revolute"]:
            names += ["swivel usb stick", "swivel flash drive"]
    else:
        names += list(vocab.CATEGORY_SYNONYMS.get(cat, (cat.lower(),)))
    return names


def _category_noun(rng, obj: ArticulatedObject, spatial: dict) -> str:
    names = everyday_names(obj, spatial)
    plain = {"StorageFurniture": 4, "Safe": 5, "Oven": 4, "WashingMachine": 4, "Bottle": 4,
             "USB": 7}.get(obj.category, len(names))
    special = names[plain:]
    if special and rng.random() < 0.6:        # an everyday name when one fits, most of the time
        return _choice(rng, special)
    return _choice(rng, names[:plain])


def describe(obj: ArticulatedObject, rng: Optional[np.random.Generator] = None,
             variants: int = VARIANTS_PER_LENGTH) -> dict[str, list[str]]:
    """Descriptions per length (``variants`` each), deterministic for a given ``rng``.

    Every phrase is true of the object: counts, how parts move, and the spatial facts of
    :func:`spatial_summary` (arrangement, the viewer's left/right, hinge side, opening
    direction, one group above another) read from its geometry and joints."""
    rng = rng if rng is not None else np.random.default_rng(0)
    summ = obj.summary()
    spatial = spatial_summary(obj)
    groups = _groups(obj)
    out: dict[str, list[str]] = {k: [] for k in DESCRIPTION_LENGTHS}
    for _ in range(variants):
        # one variant of every length, drawn in this order from the same rng
        cat = _category_noun(rng, obj, spatial)
        out["words"].append(_words_text(rng, cat, groups))
        out["sentence"].append(_sentence_text(rng, obj, cat, groups, spatial))
        out["sentences"].append(_sentences_text(rng, obj, cat, groups, spatial))
        out["detailed"].append(_detailed_text(rng, obj, cat, groups, spatial,
                                              summ["num_movable"]))
    return out


def _words_text(rng, cat: str, groups) -> str:
    """The "words" length: "cabinet, 3 drawers, 2 doors" / "three-drawer dresser, a door"."""
    style = int(rng.integers(3))
    comp = _compound(rng, groups)
    rest = groups[1:] if comp else groups
    words_nps = [f"{n if style != 1 else vocab.number_word(n)} {_noun(rng, l, n, 0.7)}"
                 for l, n, _, _ in rest]
    head = f"{comp} {cat}" if comp else cat
    if style == 2:
        words = f"{head} with " + _join(words_nps) if words_nps else head
    else:
        words = ", ".join([head] + words_nps)
    return words


def _sentence_text(rng, obj: ArticulatedObject, cat: str, groups, spatial: dict) -> str:
    """The "sentence" length: one sentence with a clause per group (and, after a compound
    name like "three-drawer dresser", a second one saying how those parts move)."""
    comp = _compound(rng, groups)
    facts = _facts(rng, obj, groups[1:] if comp else groups, spatial)
    head = f"{comp} {cat}" if comp else cat
    opener = _choice(rng, ["A {c} with {f}.", "This is {a} {c} with {f}.", "{A} {c} that has {f}.",
                           "{A} {c} featuring {f}."])
    a = _article(head)
    if comp and not facts:
        sent = f"{_cap_first(a)} {head}."
    else:
        sent = opener.format(c=head, f=_join(facts) if facts else "no moving parts", a=a,
                             A=_cap_first(a))
    if comp:
        label, n, types, idx = groups[0]
        sent += f" Its {vocab.PART_PLURALS[label][0]} {_motion(rng, label, types, n, _opens(spatial, label))}."
    return _cap_first(sent)


def _sentences_text(rng, obj: ArticulatedObject, cat: str, groups, spatial: dict) -> str:
    """The "sentences" length: pronouns refer back to the object, then to a part."""
    s1 = _choice(rng, [f"{_cap_first(_article(cat))} {cat}.", f"The object is {_article(cat)} {cat}.",
                       f"This is {_article(cat)} {cat}."])
    if not groups:
        return s1 + " " + _choice(rng, ["It has no moving parts.", "Nothing on it moves."])
    nps = []
    for label, n, types, idx in groups:
        arranged: list = []
        np_ = _group_np(rng, obj, label, n, types, idx, spatial, arranged=arranged)
        nps.append(np_ + _post(rng, label, n, spatial, bool(arranged), 0.5, 0.5, 0.0))
    there = "there is" if len(groups) == 1 and groups[0][1] == 1 else "there are"
    s2 = _choice(rng, [f"It has {_join(nps)}.", f"It comes with {_join(nps)}.",
                       f"On it {there} {_join(nps)}."])
    motions = [_motion_sentence(rng, label, n, types, spatial) for label, n, types, _ in groups]
    rel = _relation_sentence(rng, obj, groups, spatial)
    return " ".join([s1, s2] + motions + ([rel] if rel else []))


def _motion_sentence(rng, label: str, n: int, types: list[str], spatial: dict) -> str:
    """"The drawers slide out." / "The door is hinged on the left. It swings open."."""
    noun = _noun(rng, label, n)
    hinge = _hinge_phrase(rng, spatial.get(label, {}), verbal=True) \
        if label in HINGED_LABELS else ""
    if hinge:
        noun = _unhinged(noun)
    mv = _motion(rng, label, types, n, _opens(spatial, label))
    if hinge and n == 1:
        # a second sentence that names the part again by pronoun
        return f"The {noun} is{hinge}. It {mv}."
    if hinge:
        return f"The {noun} are{hinge} and {mv}."
    return f"The {noun} {mv}."


def _detailed_text(rng, obj: ArticulatedObject, cat: str, groups, spatial: dict,
                   total: int) -> str:
    """The "detailed" length: size, the number of moving parts (``total``), a sentence per
    group with its movement range (and a handle's style), the relation sentence."""
    facts = _facts(rng, obj, groups, spatial)
    size = _size_phrase(rng, obj)
    lines = [f"{_cap_first(_article(cat))} {cat}" + (f", {size}" if size else "") + "."]
    lines.append(_choice(rng, [f"It has {total} moving part{'s' if total != 1 else ''} in total.",
                               f"Altogether {total} of its parts can move.",
                               f"In total {total} part{'s' if total != 1 else ''} move."]))
    for (label, n, types, idx), fact in zip(groups, facts):
        rng_txt = _range_clause(obj, idx)
        extra = ""
        styles = {obj.metadata.get("parts", {}).get(obj.parts[i].name, {}).get("style", "") for i in idx}
        styles.discard("")
        if label == "handle" and styles:
            extra = f" ({_join(sorted(styles))} style)"
        lines.append(_cap_first(f"there {'is' if n == 1 else 'are'} {fact}{extra}"
                                + (f", {rng_txt}" if rng_txt else "") + "."))
    rel = _relation_sentence(rng, obj, groups, spatial)
    if rel:
        lines.append(rel)
    return " ".join(lines)
