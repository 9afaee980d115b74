"""Text descriptions of articulated objects at four lengths (DESIGN §3.1), from ground truth.

``describe(obj, rng)`` returns ``{length: [variants...]}`` for the lengths of
``model.data.format.DESCRIPTION_LENGTHS``: "detailed" (a paragraph with sizes, sides and
ranges), "sentences" (two or three sentences), "sentence" (one), "words" (a few words).
Every variant names the category and, for every countable part kind, its count and how it
moves, with wording drawn from the synonym tables in :mod:`model.data.vocab` — so a parser
that knows those tables reads back :func:`structured_summary`.
"""
from __future__ import annotations

import math
import re
from typing import Optional

import numpy as np

from model.core.objects import ArticulatedObject, JointType
from model.data import vocab
from model.data.format import DESCRIPTION_LENGTHS

VARIANTS_PER_LENGTH = 3

# Which parts a viewer reads first.
_ORDER = ("drawer", "door", "lid", "cap", "tray", "knob", "dial", "button", "handle", "other")


SPATIAL_LABELS = ("drawer", "door", "lid", "tray", "knob", "dial", "button")   # arranged groups
HINGED_LABELS = ("door", "lid")                                                # hinge / opening
HPOS_MARGIN = 0.2   # |offset| from the body's centre, in half-widths, that counts as left/right
VPOS_MARGIN = 0.2   # ... in half-heights, that counts as top/bottom


def structured_summary(obj: ArticulatedObject) -> dict:
    """``ArticulatedObject.summary()`` (category, counts, joint_types, num_parts, num_movable)
    plus ``spatial``: the spatial facts of every part group (:func:`spatial_summary`)."""
    out = obj.summary()
    out["spatial"] = spatial_summary(obj)
    return out


# ---------------------------------------------------------------------------------------------
# spatial facts, read from the geometry and joints (never from generator metadata, so they hold
# for generated and real objects too). "left"/"right": the viewer's (vocab.SIDE_DIRECTIONS).
# ---------------------------------------------------------------------------------------------
def _body_box(obj: ArticulatedObject) -> tuple[np.ndarray, np.ndarray]:
    """(centre, size) of the root part's box (the object's carcass)."""
    r = obj.parts[obj.root]
    size = np.maximum(np.abs(r.bbox_size), 1e-6)
    return np.asarray(r.bbox_center, float), size


def hinge_side(obj: ArticulatedObject, i: int) -> Optional[str]:
    """Side of the part's box its rotation axis runs along ("left", "right", "top", "bottom",
    "back", "front"), or None when the part does not rotate about an edge (a knob's own axis)."""
    p = obj.parts[i]
    if p.joint.type not in (JointType.REVOLUTE, JointType.CONTINUOUS):
        return None
    a = p.joint.axis / max(np.linalg.norm(p.joint.axis), 1e-12)
    c = np.asarray(p.bbox_center, float)
    d = p.joint.origin - c
    d = d - (d @ a) * a                      # centre -> axis line, perpendicular to the axis
    n = float(np.linalg.norm(d))
    # an edge hinge sits about half the box's extent (along d) from the centre; an axis
    # through the part (a knob's) much nearer
    half = 0.5 * float(np.abs(p.bbox_size) @ np.abs(d / max(n, 1e-12)))
    if n < 0.5 * max(half, 1e-6):
        return None
    return vocab.side_of(d)


def opening_direction(obj: ArticulatedObject, i: int) -> Optional[str]:
    """Where a hinged part's free edge goes when it opens: "down", "up" or "sideways"."""
    p = obj.parts[i]
    if hinge_side(obj, i) is None:
        return None
    j = p.joint
    a = j.axis / max(np.linalg.norm(j.axis), 1e-12)
    lo, hi = j.r_range
    ang = hi if abs(hi) >= abs(lo) else lo
    ang = float(np.clip(ang, -math.pi / 2, math.pi / 2))
    if abs(ang) < 1e-3:
        return None
    c = np.asarray(p.bbox_center, float)
    d = c - j.origin
    d = d - (d @ a) * a
    free = c + d                                   # the edge opposite the hinge
    T = j.transform(0.0, ang)
    moved = T[:3, :3] @ free + T[:3, 3]
    delta = moved - free
    n = float(np.linalg.norm(delta))
    if n < 1e-9:
        return None
    if delta[2] < -0.35 * n:
        return "down"
    if delta[2] > 0.35 * n:
        return "up"
    return "sideways"


def part_position(obj: ArticulatedObject, i: int) -> tuple[str, str]:
    """(horizontal, vertical) place of a part on the body: left/middle/right (the viewer's),
    top/middle/bottom."""
    bc, bs = _body_box(obj)
    c = np.asarray(obj.parts[i].bbox_center, float)
    u = (c[1] - bc[1]) / (bs[1] / 2)
    v = (c[2] - bc[2]) / (bs[2] / 2)
    h = vocab.side_of((0.0, u, 0.0)) if abs(u) > HPOS_MARGIN else "middle"
    w = vocab.side_of((0.0, 0.0, v)) if abs(v) > VPOS_MARGIN else "middle"
    return h, w


def _clusters(centres: np.ndarray, sizes: np.ndarray) -> list[list[int]]:
    """Group 1-D positions: a part joins a cluster when its centre is within half the smaller
    extent of the cluster's mean. Clusters sorted by position, members by index."""
    order = np.argsort(centres, kind="stable")
    out: list[list[int]] = []
    for k in order:
        if out:
            cl = out[-1]
            m = float(np.mean(centres[cl]))
            if abs(centres[k] - m) < 0.5 * min(float(sizes[k]), float(np.min(sizes[cl]))):
                cl.append(int(k))
                continue
        out.append([int(k)])
    return [sorted(c) for c in out]


def arrangement(obj: ArticulatedObject, idx: list[int]) -> dict:
    """Rows and columns of a group of parts seen from the front.

    ``layout``: "single" (one part), "row" (one row), "column" (one above the other), "grid"
    (every row and every column equally full), "irregular" (rows of different lengths);
    ``rows``; ``columns`` (None for "irregular"); ``per_row``: parts per row, top row first.
    """
    n = len(idx)
    if n == 0:
        return {}
    if n == 1:
        return {"layout": "single", "rows": 1, "columns": 1, "per_row": [1]}
    cen = np.array([obj.parts[i].bbox_center for i in idx], float)
    siz = np.array([np.abs(obj.parts[i].bbox_size) for i in idx], float)
    rows = _clusters(-cen[:, 2], np.maximum(siz[:, 2], 1e-6))        # top row first
    cols = _clusters(cen[:, 1], np.maximum(siz[:, 1], 1e-6))         # viewer's left first
    R, C = len(rows), len(cols)
    per_row = [len(r) for r in rows]
    if R == 1:
        layout = "row"
    elif C == 1:
        layout = "column"
    elif R * C == n and all(len(r) == C for r in rows) and all(len(c) == R for c in cols):
        layout = "grid"
    else:
        layout, C = "irregular", None
    return {"layout": layout, "rows": R, "columns": C, "per_row": per_row}


def spatial_summary(obj: ArticulatedObject) -> dict[str, dict]:
    """Spatial facts per countable part label present (sets as sorted lists):

    ``hinge`` (doors, lids): sides their hinges are on; ``opens``: where they open (down, up,
    sideways); ``layout`` / ``rows`` / ``columns`` / ``per_row`` (see :func:`arrangement`);
    ``hpos`` / ``vpos``: where the parts sit on the body; ``z``: [lowest bottom, highest top]
    of the group's boxes (for "above" / "below" between groups).
    """
    out: dict[str, dict] = {}
    for label in vocab.COUNTABLE_LABELS:
        idx = [i for i, p in enumerate(obj.parts) if p.label == label]
        if not idx:
            continue
        f: dict = {}
        if label in HINGED_LABELS:
            hs = {hinge_side(obj, i) for i in idx}
            op = {opening_direction(obj, i) for i in idx}
            f["hinge"] = sorted(h for h in hs if h)
            f["opens"] = sorted(o for o in op if o)
        if label in SPATIAL_LABELS:
            f.update(arrangement(obj, idx))
        pos = [part_position(obj, i) for i in idx]
        f["hpos"] = sorted({h for h, _ in pos})
        f["vpos"] = sorted({v for _, v in pos})
        lo = [float(obj.parts[i].bbox_center[2] - abs(obj.parts[i].bbox_size[2]) / 2) for i in idx]
        hi = [float(obj.parts[i].bbox_center[2] + abs(obj.parts[i].bbox_size[2]) / 2) for i in idx]
        f["z"] = [min(lo), max(hi)]
        f["z_centres"] = [min(float(obj.parts[i].bbox_center[2]) for i in idx),
                          max(float(obj.parts[i].bbox_center[2]) for i in idx)]
        out[label] = f
    return out


def is_above(spatial: dict, a: str, b: str) -> Optional[bool]:
    """Every part of group ``a`` sits above every part of group ``b``: the lowest ``a`` box
    bottom is no more than 1 cm below the highest ``b`` box top (parts *on* a door are not
    above or below it). None when either group is missing."""
    if a not in spatial or b not in spatial:
        return None
    return spatial[a]["z"][0] > spatial[b]["z"][1] - 0.01


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


def everyday_names(obj: ArticulatedObject, spatial: Optional[dict] = None) -> list[str]:
    """Names a person would use for this object, each only where it is true of its shape and
    parts (a dresser has drawers and no doors, a nightstand is small and low, a top loader has
    a lid, ...). The first entries are the plain names of the category."""
    cat = obj.category
    spatial = spatial if spatial is not None else spatial_summary(obj)
    counts = obj.summary()["counts"]
    _, size = _body_box(obj)
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


def _article(noun: str) -> str:
    return "an" if noun[:1] in "aeiou" and not noun.startswith(("usb", "one", "uni")) else "a"


def _groups(obj: ArticulatedObject) -> list[tuple[str, int, list[str], list[int]]]:
    """(label, count, sorted joint type names, part indices) per countable label, fixed order."""
    out = []
    for label in _ORDER:
        idx = [i for i, p in enumerate(obj.parts) if p.label == label]
        if idx and label in vocab.COUNTABLE_LABELS:
            types = sorted({obj.parts[i].joint.type.name.lower() for i in idx})
            out.append((label, len(idx), types, idx))
    return out


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
        cat = _category_noun(rng, obj, spatial)
        # -- words: "cabinet, 3 drawers, 2 doors" / "three-drawer dresser, a door" ------------
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
        out["words"].append(words)
        # -- sentence --------------------------------------------------------------------
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
        out["sentence"].append(_cap_first(sent))
        # -- sentences: pronouns refer back to the object, then to a part ---------------------
        s1 = _choice(rng, [f"{_cap_first(_article(cat))} {cat}.", f"The object is {_article(cat)} {cat}.",
                           f"This is {_article(cat)} {cat}."])
        if groups:
            nps = []
            for label, n, types, idx in groups:
                arranged: list = []
                np_ = _group_np(rng, obj, label, n, types, idx, spatial, arranged=arranged)
                nps.append(np_ + _post(rng, label, n, spatial, bool(arranged), 0.5, 0.5, 0.0))
            there = "there is" if len(groups) == 1 and groups[0][1] == 1 else "there are"
            s2 = _choice(rng, [f"It has {_join(nps)}.", f"It comes with {_join(nps)}.",
                               f"On it {there} {_join(nps)}."])
            motions = []
            for label, n, types, idx in groups:
                noun = _noun(rng, label, n)
                hinge = _hinge_phrase(rng, spatial.get(label, {}), verbal=True) \
                    if label in HINGED_LABELS else ""
                if hinge:
                    noun = _unhinged(noun)
                mv = _motion(rng, label, types, n, _opens(spatial, label))
                if hinge and n == 1:
                    # a second sentence that names the part again by pronoun
                    motions.append(f"The {noun} is{hinge}. It {mv}.")
                elif hinge:
                    motions.append(f"The {noun} are{hinge} and {mv}.")
                else:
                    motions.append(f"The {noun} {mv}.")
            rel = _relation_sentence(rng, obj, groups, spatial)
            sentences = " ".join([s1, s2] + motions + ([rel] if rel else []))
        else:
            sentences = s1 + " " + _choice(rng, ["It has no moving parts.", "Nothing on it moves."])
        out["sentences"].append(sentences)
        # -- detailed --------------------------------------------------------------------
        facts = _facts(rng, obj, groups, spatial)
        size = _size_phrase(rng, obj)
        lines = [f"{_cap_first(_article(cat))} {cat}" + (f", {size}" if size else "") + "."]
        total = summ["num_movable"]
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
        out["detailed"].append(" ".join(lines))
    return out
