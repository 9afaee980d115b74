"""The size a prompt states, given to a decoded layout before it is refined and meshed, and
the frame every layout ends in.

``scale_to_size(obj, {"width": 0.6})`` scales the object about the bottom centre of its body so
the body's box takes the stated dimensions (width along y, height along z, depth along x;
"length" is the body's longest side). An axis the prompt leaves open takes the geometric mean
of the stated axes' factors, so one stated dimension keeps the proportions. The body and its
panels (doors, drawers, lids, trays) take the factors per axis; handles, knobs, dials,
buttons and caps keep their own size when the object grows and shrink with it (by the mean
factor, so a knob stays round) when it shrinks; joint origins and slide travel follow.

``place_on_floor(obj)`` moves a layout into the data's frame (DESIGN §2): its lowest box at
rest on z = 0 and its body's box centred on the z axis. The network places objects in that
frame only roughly (bodies decoded up to 15 cm below or 11 cm above the floor), so a URDF
spawned at the origin of a simulator would sink into its ground plane or drop onto it.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from model.core import ArticulatedObject
from model.data.prompt_size import AXIS

from .arrange import FRONT
from .layout import _lohi, _move_subtree, _union, face_of

PANELS = ("body", "door", "drawer", "lid", "tray")


def size_factors(extent: np.ndarray, size: dict) -> np.ndarray:
    """Per-axis (x, y, z) factors that take a box of ``extent`` to the stated ``size``."""
    extent = np.maximum(np.asarray(extent, dtype=np.float64), 1e-6)
    s = np.full(3, np.nan)
    for dim, value in size.items():
        ax = int(np.argmax(extent)) if dim == "length" else AXIS[dim]
        if np.isnan(s[ax]):
            s[ax] = float(value) / extent[ax]
    stated = s[~np.isnan(s)]
    s[np.isnan(s)] = float(np.exp(np.log(stated).mean()))
    return s


def scale_to_size(obj: ArticulatedObject, size: dict | None) -> dict | None:
    """Scale ``obj`` in place so its body has the stated ``size`` (m); the factors applied,
    or None when nothing is stated."""
    if not size:
        return None
    body = obj.parts[obj.root]
    s = size_factors(body.bbox_size, size)
    small = min(1.0, float(np.prod(s)) ** (1.0 / 3.0))
    _scale_layout(obj, s, small)
    return {"factors": [round(float(v), 4) for v in s], "controls": round(small, 4)}


def _scale_layout(obj: ArticulatedObject, s: np.ndarray, small: float) -> None:
    """Scale ``obj``'s layout in place by ``s`` per axis about the bottom centre of its body's
    box: panels per axis, the other parts' sizes by ``small``; joint origins and slide travel
    follow."""
    body = obj.parts[obj.root]
    pivot = body.bbox_center - np.array([0.0, 0.0, body.bbox_size[2] / 2.0])
    for p in obj.parts:
        p.bbox_center = pivot + (p.bbox_center - pivot) * s
        p.bbox_size = p.bbox_size * (s if p.label in PANELS else small)
        j = p.joint
        j.origin = pivot + (j.origin - pivot) * s
        if j.type.translates:
            a = np.asarray(j.axis, dtype=np.float64)
            f = float(np.linalg.norm(a * s) / max(np.linalg.norm(a), 1e-9))
            j.t_range = (j.t_range[0] * f, j.t_range[1] * f)


# the data's drawers (model/data/synth/cabinets.py): a front at most DRAWER_ASPECT times as
# tall as it is wide, in bands under DRAWER_BAND; storage bodies 0.4-1.9 m tall
DRAWER_ASPECT = 1.2
DRAWER_BAND = 0.45    # m
MIN_HEIGHT = 0.4      # m


def lower_drawer_row(obj: ArticulatedObject) -> Optional[float]:
    """A storage body whose front holds only drawers, all in one row, each taller than
    ``DRAWER_ASPECT`` times its width, is lowered (the layout scaled along z about the bottom
    of the body, handles and knobs keeping their size) until its drawers are no taller than
    that and than ``DRAWER_BAND``, the body no lower than ``MIN_HEIGHT``: the fill grows the
    fronts to the body's height, and "a wide cabinet with four drawers side by side" had
    drawers 1.3 m tall and 0.35 m wide where the data's rows of drawers are bands under
    0.45 m. The pipeline does not call it where the prompt gives the height (a stated size,
    a size word, an everyday name's usual height: ``prompt_size.height_said``). Returns the
    factor applied, or None."""
    if obj.category != "StorageFurniture":
        return None
    root = obj.root
    fronts = [i for i in obj.children(root) if obj.parts[i].label in ("drawer", "door")
              and (face_of(obj, i) or (None,))[0] == FRONT]
    if len(fronts) < 2 or any(obj.parts[i].label != "drawer" for i in fronts):
        return None
    boxes = [_lohi(obj.parts[i]) for i in fronts]
    if min(hi[2] for _, hi in boxes) <= max(lo[2] for lo, _ in boxes):
        return None                                    # not one row
    want = [min(DRAWER_ASPECT * (hi[1] - lo[1]), DRAWER_BAND) / (hi[2] - lo[2])
            for lo, hi in boxes]
    f = min(1.0, min(want))
    H = float(obj.parts[root].bbox_size[2])
    f = max(f, MIN_HEIGHT / H) if H > MIN_HEIGHT else 1.0
    if f > 0.99:
        return None
    _scale_layout(obj, np.array([1.0, 1.0, f]), 1.0)
    for p in obj.parts:          # a part that kept its size fits on its parent
        if p.label not in PANELS and p.parent >= 0:
            p.bbox_size[2] = min(p.bbox_size[2], 0.8 * obj.parts[p.parent].bbox_size[2])
    return round(f, 4)


DOOR_ASPECT = 4.0     # a storage door at most this many times as tall as wide (a wardrobe's)
MAX_WIDTH = 1.6       # m: the data's widest storage body


def widen_door_row(obj: ArticulatedObject) -> Optional[float]:
    """A storage body whose front has a row of two or more doors side by side, each taller
    than ``DOOR_ASPECT`` times its width, is widened (the layout scaled along y about the
    body's centre, handles and knobs keeping their size) until they are no taller than that,
    the body no wider than ``MAX_WIDTH``: "a wardrobe with four doors side by side" had
    doors 17 cm wide and 1.63 m tall on a 0.76 m body. The pipeline does not call it where
    the prompt gives the width (``prompt_size.width_said``). Returns the factor, or None."""
    if obj.category != "StorageFurniture":
        return None
    root = obj.root
    doors = [i for i in obj.children(root) if obj.parts[i].label == "door"
             and (face_of(obj, i) or (None,))[0] == FRONT]
    if len(doors) < 2:
        return None
    boxes = sorted((_lohi(obj.parts[i]) for i in doors), key=lambda b: b[0][1])
    if min(hi[2] for _, hi in boxes) <= max(lo[2] for lo, _ in boxes) or any(
            a[1][1] > b[0][1] + 0.01 for a, b in zip(boxes, boxes[1:])):
        return None                                    # not one row side by side
    need = max((hi[2] - lo[2]) / (DOOR_ASPECT * (hi[1] - lo[1])) for lo, hi in boxes)
    W = float(obj.parts[root].bbox_size[1])
    f = min(need, MAX_WIDTH / W) if W < MAX_WIDTH else 1.0
    if f < 1.01:
        return None
    _scale_layout(obj, np.array([1.0, f, 1.0]), 1.0)
    return round(f, 4)


def cap_drawer_height(obj: ArticulatedObject) -> int:
    """A storage drawer whose front is taller than ``DRAWER_ASPECT`` times its width (none of
    the data's is: synth-7) is made that tall, its top edge kept (its bottom edge where that
    is nearer its parent's bottom: a bottom row stays at the bottom), the rest of its cell
    left open; its handles stay on its front. The fill tiles a column with the one drawer stated
    beside a door ("a cabinet with a drawer on the left and a door on the right": a drawer
    1.2 m tall and 0.43 m wide), and a stated height keeps a row of drawers from being
    lowered ("a low TV stand with three drawers side by side": 0.5 m tall, 0.34 m wide).
    Run after the fill and ``lower_drawer_row``. -> drawers shortened."""
    if obj.category != "StorageFurniture":
        return 0
    done = 0
    for i, p in enumerate(obj.parts):
        face = face_of(obj, i) if p.label == "drawer" else None
        if face is None or face[0] == 2:
            continue
        width = float(p.bbox_size[1 - face[0]])        # across the face, level
        height = DRAWER_ASPECT * width
        if p.bbox_size[2] <= height + 1e-6:
            continue
        lo, hi = float(p.bbox_center[2] - p.bbox_size[2] / 2), \
            float(p.bbox_center[2] + p.bbox_size[2] / 2)
        plo, phi = _lohi(obj.parts[p.parent])
        if lo - plo[2] < phi[2] - hi - 1e-6:      # nearer its parent's bottom: kept there
            hi = lo + height
        else:
            lo = hi - height
        p.bbox_size = p.bbox_size.copy()
        p.bbox_size[2] = height
        p.bbox_center = p.bbox_center.copy()
        p.bbox_center[2] = (lo + hi) / 2
        origin = np.asarray(p.joint.origin, dtype=np.float64).copy()
        origin[2] = np.clip(origin[2], lo, hi)
        p.joint.origin = origin
        for c in obj.children(i):                      # handles stay on the front
            q = obj.parts[c]
            half = min(float(q.bbox_size[2]) / 2, height / 2)
            z = float(np.clip(q.bbox_center[2], lo + half, hi - half))
            if z != q.bbox_center[2]:
                _move_subtree(obj, c, np.array([0.0, 0.0, z - q.bbox_center[2]]))
        done += 1
    return done


THIN_DRAWER = 0.07   # m: the data's drawer fronts are at least about 9 cm tall (bands of 10-12
                     # cm, model/data/synth/cabinets.py); a stack of thinner ones is re-laid


def row_thin_drawers(obj: ArticulatedObject, stated: Optional[dict] = None) -> int:
    """A column of drawers on a storage front whose fronts are thinner than ``THIN_DRAWER``
    (the network's stack of four 4-5 cm strips in "a kitchen cabinet with four doors on the
    bottom and four drawers on top", or "... 4 drawers total") is laid out side by side in
    the rectangle it covers: one row, or two rows of half of them where one row's fronts
    would be taller than ``DRAWER_ASPECT`` times their width (model.refine.arrange
    ``_lay_out``; handles move with their drawers). Left where neither gives fronts at least
    ``THIN_DRAWER`` tall, and where the prompt arranges the drawers. -> columns re-laid."""
    from .arrange import H, V, _lay_out
    from model.data.expected_structure import ARRANGEMENT_KEYS

    if obj.category != "StorageFurniture" or \
            set((stated or {}).get("drawer") or {}) & set(ARRANGEMENT_KEYS):
        return 0
    root = obj.root
    drawers = sorted((i for i in obj.children(root) if obj.parts[i].label == "drawer"
                      and face_of(obj, i) == (FRONT, 1.0)),
                     key=lambda i: obj.parts[i].bbox_center[H])
    columns: list[list[int]] = []
    for i in drawers:                 # drawers whose centres line up across the front
        p = obj.parts[i]
        if columns and abs(obj.parts[columns[-1][0]].bbox_center[H] - p.bbox_center[H]) \
                < 0.25 * p.bbox_size[H]:
            columns[-1].append(i)
        else:
            columns.append([i])
    done = 0
    for col in columns:
        if len(col) < 2 or np.median([obj.parts[i].bbox_size[V] for i in col]) >= THIN_DRAWER:
            continue
        lo, hi = _union([obj.parts[i] for i in col])
        n, W, Hh = len(col), hi[H] - lo[H], hi[V] - lo[V]
        options = [[n]] + ([[n // 2, n // 2]] if n % 2 == 0 and n >= 4 else [])
        for per_row in options:
            w, h = W / max(per_row), Hh / len(per_row)
            if THIN_DRAWER <= h <= DRAWER_ASPECT * w:
                _lay_out(obj, col, per_row)
                done += 1
                break
    return done


# m: where the data puts the centre of a body's box in x, y (model/data/synth): a USB stick's
# casing is centred and its plug reaches 1.1-1.3 cm past it (synth-v6: the box centre sits
# 5.6-6.4 mm in front of the axis); every other category's body is centred
BODY_CENTRE = {"USB": (0.006, 0.0)}


def place_on_floor(obj: ArticulatedObject) -> list[float]:
    """Translate ``obj`` in place (boxes, joint origins, any meshes and collision pieces) so
    the lowest point of its boxes at rest is on z = 0 and its body's box is centred on the
    z axis as the data's are (``BODY_CENTRE``); the translation applied (m)."""
    body = obj.parts[obj.root]
    bottom = min(float(p.bbox_center[2] - p.bbox_size[2] / 2.0) for p in obj.parts)
    cx, cy = BODY_CENTRE.get(obj.category, (0.0, 0.0))
    move = np.array([cx - body.bbox_center[0], cy - body.bbox_center[1], -bottom],
                    dtype=np.float64)
    _move_subtree(obj, obj.root, move)
    return [round(float(v), 5) for v in move]
