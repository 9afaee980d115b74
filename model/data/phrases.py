"""The phrase builders of the descriptions (model.data.describe): counts and nouns, motion
verb phrases, a part group's noun phrase ("three sliding drawers", "a pair of doors"), its
spatial phrases ("stacked one above the other", "on the left", "hinged on the left"), a
relation sentence, movement ranges and sizes. Every wording comes from the tables of
:mod:`model.data.vocab`; every draw comes from the caller's ``rng``, in a fixed order, so a
description is deterministic for a given generator.

A group is ``(label, count, sorted joint type names, part indices)`` (``describe._groups``).
"""
from __future__ import annotations

import math
import re
from typing import Optional

from model.core.objects import ArticulatedObject, JointType
from model.data import vocab
from model.data.spatial import HINGED_LABELS, is_above


def _count(rng, n: int) -> str:
    if n == 1:
        return _choice(rng, ["a", "one", "a single"])
    return _choice(rng, [vocab.number_word(n), vocab.number_word(n), str(n)])


def _choice(rng, items):
    return items[int(rng.integers(len(items)))]


def _noun(rng, label: str, n: int, canonical_share: float = 0.5) -> str:
    """Singular or plural synonym of a part label (canonical wording half of the time)."""
    table = vocab.PART_SYNONYMS[label] if n == 1 else vocab.PART_PLURALS[label]
    if rng.random() < canonical_share:
        return table[0]
    return _choice(rng, list(table))


def _article(noun: str) -> str:
    return "an" if noun[:1] in "aeiou" and not noun.startswith(("usb", "one", "uni")) else "a"


def _motion(rng, label: str, types: list[str], n: int, opens: Optional[str] = None) -> str:
    """Verb phrase for a group ('slide out', 'swing open', 'stay fixed'), plural when n > 1.
    ``opens``: the group's one opening direction (hinged parts), said half of the time."""
    if types == ["fixed"]:
        return _choice(rng, ["are fixed", "are rigidly attached", "do not move"]) if n > 1 else \
            _choice(rng, ["is fixed", "is rigidly attached", "does not move"])
    kinds = [t for t in types if t != "fixed"]
    if len(kinds) > 1:
        names = " or ".join(_motion_word(rng, k, label) for k in kinds)
        return "can " + names
    if opens and kinds == ["revolute"] and rng.random() < 0.5:
        phrase = _choice(rng, list(vocab.OPENING_PHRASES[opens]))
        return _pluralise_verb(phrase) if n > 1 else phrase
    table = vocab.LABEL_MOTION_SYNONYMS.get((label, kinds[0]), vocab.MOTION_SYNONYMS[kinds[0]])
    phrase = _choice(rng, [p for p in table if p != "is hinged"] or list(table))
    return _pluralise_verb(phrase) if n > 1 else phrase


def _motion_word(rng, jt: str, label: str = "") -> str:
    if jt == "revolute" and label in ("knob", "dial"):
        return _choice(rng, ["turn to a stop", "turn within a range"])
    return {"revolute": _choice(rng, ["swing on a hinge", "pivot", "rotate on a hinge"]),
            "prismatic": _choice(rng, ["slide", "slide in and out", "translate"]),
            "continuous": _choice(rng, ["spin freely", "turn without limit", "rotate continuously"]),
            "screw": _choice(rng, ["screw on and off", "twist off"])}[jt]


_VERB_PLURAL = {"is": "are", "slides": "slide", "pulls": "pull", "moves": "move", "translates": "translate",
                "swings": "swing", "rotates": "rotate", "pivots": "pivot", "opens": "open", "spins": "spin",
                "turns": "turn", "screws": "screw", "twists": "twist", "unscrews": "unscrew",
                "does": "do", "can": "can", "presses": "press", "pushes": "push", "swivels": "swivel",
                "drops": "drop", "folds": "fold", "flips": "flip", "lifts": "lift", "sits": "sit"}


def _pluralise_verb(phrase: str) -> str:
    first, _, rest = phrase.partition(" ")
    first = _VERB_PLURAL.get(first, first)
    return f"{first} {rest}".strip()


def _keypad(obj: ArticulatedObject, label: str, idx: list[int], spatial: dict) -> bool:
    """Buttons in a grid on a door: a keypad."""
    return label == "button" and spatial.get("button", {}).get("layout") == "grid" and \
        all(obj.parts[obj.parts[i].parent].label == "door" for i in idx if obj.parts[i].parent >= 0)


def _group_np(rng, obj: ArticulatedObject, label: str, n: int, types: list[str], idx: list[int],
              spatial: dict, *, arranged: Optional[list] = None) -> str:
    """'three sliding drawers' / 'a pair of doors' / 'a keypad of nine buttons'. When the
    arrangement is said inside the phrase ('three stacked drawers'), ``arranged`` gets True."""
    f = spatial.get(label, {})
    layout = f.get("layout")
    if _keypad(obj, label, idx, spatial) and rng.random() < 0.6:
        if arranged is not None:
            arranged.append(True)
        if rng.random() < 0.5:
            return f"a {f['rows']} x {f['columns']} keypad"
        return f"a keypad of {vocab.number_word(n)} {_noun(rng, label, n)}"
    role = vocab.ROLE_NAMES.get((obj.category, label))
    if role and rng.random() < 0.4:
        noun = _choice(rng, list(role)) if n == 1 else vocab.plural(_choice(rng, list(role)))
    else:
        noun = _noun(rng, label, n)
    adj = ""
    moving = [t for t in types if t != "fixed"]
    if len(moving) == 1 and rng.random() < 0.4 and not any(w in noun for w in ("sliding", "hinged", "pull-out", "flip", "rotary")):
        adj = _choice(rng, list(vocab.LABEL_MOTION_ADJECTIVES.get((label, moving[0]),
                                                                  vocab.MOTION_ADJECTIVES[moving[0]])))
        # no "push push-buttons" / "swinging swing doors"
        adj = "" if adj[:4] in noun or any(w[:4] in adj for w in noun.split()) else adj + " "
    if layout == "column" and rng.random() < 0.3 and arranged is not None:
        adj = "stacked " + adj
        arranged.append(True)
    r = rng.random()
    if n == 2 and r < 0.3:
        count = "a pair of"
    elif n == 4 and layout == "grid" and f.get("rows") == 2 and r < 0.5:
        count = "two pairs of"
    else:
        count = _count(rng, n)
    return f"{count} {adj}{noun}"


def _words(n: int) -> str:
    return vocab.number_word(n)


def _arrangement_phrase(rng, f: dict) -> str:
    """' stacked one above the other' / ' side by side' / ' in two columns' (or '')."""
    layout = f.get("layout")
    if layout == "row":
        return " " + _choice(rng, list(vocab.ROW_PHRASES))
    if layout == "column":
        return " " + _choice(rng, list(vocab.COLUMN_PHRASES))
    if layout == "grid":
        R, C = f["rows"], f["columns"]
        return " " + _choice(rng, [f"in {_words(C)} columns", f"in {_words(R)} rows of {_words(C)}",
                                   f"in a {R} x {C} grid", f"in {_words(R)} rows"])
    if layout == "irregular":
        return f" in {_words(f['rows'])} rows"
    return ""


def _hinge_phrase(rng, f: dict, verbal: bool = False) -> str:
    """' hinged on the left' / ' with a rear hinge' (``verbal``: only the 'hinged ...' forms)."""
    sides = f.get("hinge") or []
    if not sides:
        return ""
    if len(sides) == 1:
        s = sides[0]
        if s in ("left", "right"):
            return " " + _choice(rng, [f"hinged on the {s}", f"hinged on its {s} side",
                                       f"hinged on the {s}-hand side"]
                                 + ([] if verbal else [f"with a {s} hinge"]))
        if s == "back":
            return " " + _choice(rng, ["hinged at the back", "hinged at the rear"]
                                 + ([] if verbal else ["with a rear hinge"]))
        return " " + _choice(rng, [f"hinged at the {s}", f"hinged along its {s} edge"])
    if len(sides) == 2:
        return " hinged at the " + " and ".join(sides)
    return ""


def _position_phrase(rng, f: dict, n: int) -> str:
    """' on the left' when every part of the group is on one side (the viewer's)."""
    h = f.get("hpos") or []
    if len(h) == 1 and h[0] in ("left", "right") and n <= 3:
        return " " + _choice(rng, [f"on the {h[0]}", f"on the {h[0]}-hand side", f"at the {h[0]}"])
    return ""


def _post(rng, label, n, spatial, arranged: bool, p_arrangement: float = 0.7,
          p_position: float = 0.6, p_hinge: float = 0.8) -> str:
    """Spatial phrases after a group's noun phrase, each with its probability: arrangement,
    side, hinge (``p_hinge`` 0: none, and no draw for it)."""
    f = spatial.get(label, {})
    out = ""
    if n > 1 and not arranged and rng.random() < p_arrangement:
        out += _arrangement_phrase(rng, f)
    if rng.random() < p_position:
        out += _position_phrase(rng, f, n)
    if p_hinge and label in HINGED_LABELS and rng.random() < p_hinge:
        out += _hinge_phrase(rng, f)
    return out


def _relation_sentence(rng, obj, groups, spatial) -> str:
    """'The knobs sit above the door.' for one pair of groups where it is true (or '')."""
    labels = [g[0] for g in groups]
    for a in ("knob", "dial", "button", "drawer"):
        for b in ("door", "drawer", "lid"):
            if a == b or a not in labels or b not in labels:
                continue
            cnt_a = dict((g[0], g[1]) for g in groups)[a]
            cnt_b = dict((g[0], g[1]) for g in groups)[b]
            subj = _noun(rng, a, cnt_a, 0.8)
            obj_ = vocab.PART_SYNONYMS[b][0] if cnt_b == 1 else vocab.PART_PLURALS[b][0]
            verb = "sits" if cnt_a == 1 else "sit"
            be = "is" if cnt_a == 1 else "are"
            if is_above(spatial, a, b):
                return _choice(rng, [f"The {subj} {verb} above the {obj_}.",
                                     f"The {subj} {be} above the {obj_}."])
            if is_above(spatial, b, a):
                return _choice(rng, [f"The {subj} {verb} below the {obj_}.",
                                     f"The {subj} {be} below the {obj_}."])
    return ""


def _range_clause(obj: ArticulatedObject, idx: list[int]) -> str:
    js = [obj.parts[i].joint for i in idx]
    jt = js[0].type
    if jt == JointType.PRISMATIC:
        hi = max(j.t_range[1] - j.t_range[0] for j in js)
        return f"by up to {hi * 100:.0f} cm" if hi >= 0.01 else f"by {hi * 1000:.0f} mm"
    if jt == JointType.REVOLUTE:
        hi = max(j.r_range[1] - j.r_range[0] for j in js)
        return f"through up to {math.degrees(hi):.0f} degrees"
    if jt == JointType.SCREW:
        turns = js[0].r_range[1] / (2 * math.pi)
        return f"over {turns:.1f} turns while lifting {js[0].t_range[1] * 1000:.0f} mm"
    return ""


def _join(items: list[str]) -> str:
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


def _size_phrase(rng, obj: ArticulatedObject) -> str:
    size = obj.metadata.get("size")
    if not size:
        return ""
    d, w, h = size
    if max(size) < 0.3:
        return f"about {h * 100:.0f} cm tall" if obj.category == "Bottle" else f"about {max(size) * 100:.0f} cm long"
    return _choice(rng, [f"{w:.2f} m wide, {d:.2f} m deep and {h:.2f} m tall",
                         f"about {w * 100:.0f} cm wide and {h * 100:.0f} cm high"])


def _opens(spatial: dict, label: str) -> Optional[str]:
    o = spatial.get(label, {}).get("opens") or []
    return o[0] if len(o) == 1 else None


def _facts(rng, obj, groups, spatial) -> list[str]:
    """One clause per group: 'three drawers stacked one above the other that slide out'."""
    out = []
    for label, n, types, idx in groups:
        arranged: list = []
        np_ = _group_np(rng, obj, label, n, types, idx, spatial, arranged=arranged)
        post = _post(rng, label, n, spatial, bool(arranged))
        out.append(f"{_unhinged(np_) if 'hinge' in post else np_}{post} that "
                   f"{_motion(rng, label, types, n, _opens(spatial, label))}")
    return out


def _unhinged(np_: str) -> str:
    """'a pair of hinged doors' -> 'a pair of doors' (when a hinge phrase follows)."""
    return re.sub(r"\bhinged (?=\w)", "", np_, count=1)


def _cap_first(s: str) -> str:
    return s[:1].upper() + s[1:]


def _compound(rng, groups) -> Optional[str]:
    """'three-drawer' for the first group when it is drawers or doors (a quarter of the time)."""
    if groups and groups[0][0] in ("drawer", "door") and 2 <= groups[0][1] <= 12 \
            and rng.random() < 0.25:
        return f"{vocab.number_word(groups[0][1])}-{groups[0][0]}"
    return None
