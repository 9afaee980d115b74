"""Matching hardware: the handles on one body's doors (or on its drawers) made one size, and
knob pulls where the text calls the handles knobs.

The network decodes each handle's box on its own, so a pantry's four doors came out with a
long bar on three and a small knob on the fourth, and a chest's four drawers with bars and
knobs mixed; built furniture has one kind of pull on its fronts, and the pipeline then meshes
that one shape once (``model.pipeline.generator.instances``). Run after the handles' places
are final (``free_edge_handles``).
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from model.core import ArticulatedObject, JointType

from .arrange import _place
from .layout import _lohi, face_of

SAME = 0.005     # m: handle boxes within this on every side are one size already
MARGIN = 0.005   # m: a handle stays this far inside its front's outline
FRONTS = ("door", "drawer")
# a knob pull's box: its depth off the front and its diameter (m), as the data's knob-style
# handles (model/data/synth/builder.py: 1.9-4.7 cm across, about 2.9 cm proud), and the
# largest share of its front's smaller side it takes
KNOB_DEPTH, KNOB_ACROSS, KNOB_SHARE = 0.028, 0.032, 0.5


def _groups(obj: ArticulatedObject) -> dict[tuple, list[int]]:
    """Fixed, childless handles on doors (or on drawers) of one parent, by (parent of the
    fronts, front label)."""
    out: dict[tuple, list[int]] = {}
    for i, h in enumerate(obj.parts):
        if h.label != "handle" or h.parent < 0 or h.joint.type != JointType.FIXED \
                or obj.children(i):
            continue
        front = obj.parts[h.parent]
        if front.label in FRONTS and front.parent >= 0:
            out.setdefault((front.parent, front.label), []).append(i)
    return out


def _representative(obj: ArticulatedObject, group: list[int]) -> int:
    """The handle whose size most of ``group`` share (within ``SAME``); of equals, the
    smallest (it fits the most fronts)."""
    def votes(i):
        return sum(np.all(np.abs(obj.parts[i].bbox_size - obj.parts[j].bbox_size) <= SAME)
                   for j in group)
    return max(group, key=lambda i: (votes(i), -float(np.prod(obj.parts[i].bbox_size))))


def _fitted(obj: ArticulatedObject, i: int, size: np.ndarray, standoff: float,
            face: tuple[int, float]) -> Optional[np.ndarray]:
    """Handle ``i``'s centre with box ``size``: in the plane of its front where it was,
    moved inside the front's outline by ``MARGIN``; ``standoff`` out of the front's face.
    None where the size does not fit the front."""
    h, front = obj.parts[i], obj.parts[obj.parts[i].parent]
    k, side = face
    lo, hi = _lohi(front)
    centre = h.bbox_center.copy()
    for a in range(3):
        if a == k:
            continue
        room = (hi[a] - lo[a]) / 2 - MARGIN - size[a] / 2
        if room < 0:
            return None
        centre[a] = np.clip(centre[a], front.bbox_center[a] - room, front.bbox_center[a] + room)
    centre[k] = front.bbox_center[k] + side * (front.bbox_size[k] / 2 + standoff)
    return centre


def match_handles(obj: ArticulatedObject, stated: Optional[dict] = None) -> int:
    """Every handle of a group (the fixed handles on one parent's doors, or on its drawers)
    given the size most of them share and the same stand-off from its front, each kept where
    it sits on its front (moved inside the outline where the new size would cross it).
    A group is left as decoded where the size does not fit one of its fronts or would make
    two handles on one front overlap; handles the prompt places (``stated``) are left.
    -> handles resized."""
    if (stated or {}).get("handle"):
        return 0
    changed = 0
    for group in _groups(obj).values():
        if len(group) < 2:
            continue
        rep = _representative(obj, group)
        r = obj.parts[rep]
        face = face_of(obj, rep)
        if face is None:
            continue
        k, side = face
        rf = obj.parts[r.parent]
        standoff = side * (r.bbox_center[k] - rf.bbox_center[k]) - rf.bbox_size[k] / 2
        todo = [i for i in group if i != rep]
        if any(face_of(obj, i) != face for i in todo):
            continue
        placed = {i: _fitted(obj, i, r.bbox_size, standoff, face) for i in todo}
        if any(c is None for c in placed.values()):
            continue
        boxes = {i: (c - r.bbox_size / 2, c + r.bbox_size / 2) for i, c in placed.items()}
        if any(obj.parts[i].parent == obj.parts[j].parent
               and np.all((boxes[i][0] < boxes[j][1]) & (boxes[j][0] < boxes[i][1]))
               for i in boxes for j in boxes if i < j):
            continue
        for i, centre in placed.items():
            h = obj.parts[i]
            if np.allclose(h.bbox_size, r.bbox_size) and np.allclose(h.bbox_center, centre):
                continue
            _place(obj, i, centre, r.bbox_size.copy())
            changed += 1
    return changed


def knob_handles(obj: ArticulatedObject) -> list[str]:
    """The fixed handles on a body's doors and drawers as knob pulls, for a text that calls
    them knobs ("a nightstand with two drawers and a small knob on each"): the network gave
    them bars with every seed (the data has knob handles, but its text model decodes the
    bar's box whatever the text says). Each handle's box becomes a knob's (``KNOB_DEPTH``
    off its front, ``KNOB_ACROSS`` across, at most ``KNOB_SHARE`` of the front's smaller
    side), centred where it was, inside its front's outline; after meshing it is turned
    into a solid of revolution about its front's normal (model.refine.meshes
    ``revolve_knobs``). Returns the names of the handles made knobs (kept in the object's
    metadata as ``knob_handles``)."""
    done = []
    for group in _groups(obj).values():
        for i in group:
            face = face_of(obj, i)
            if face is None:
                continue
            k, _ = face
            front = obj.parts[obj.parts[i].parent]
            across = min(KNOB_ACROSS, KNOB_SHARE * float(min(
                front.bbox_size[a] for a in range(3) if a != k)))
            size = np.full(3, across)
            size[k] = KNOB_DEPTH * across / KNOB_ACROSS
            centre = _fitted(obj, i, size, size[k] / 2, face)
            if centre is None:
                continue
            _place(obj, i, centre, size)
            done.append(obj.parts[i].name)
    obj.metadata["knob_handles"] = done
    return done
