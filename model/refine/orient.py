"""Objects that open at the top: a chest, a trunk or a toy box with a lid.

The training data's storage furniture opens at the front only; it has doors hinged at the
top of their opening (a flip-up wall cabinet), but no lid. A chest is such a cabinet turned
onto its back: its front faces up, the top of its front is the back of the chest, and the
flip-up door is a lid hinged at the back. The pipeline decodes, lays out and meshes the
cabinet in the data's frame and then turns the whole object (boxes, joints, meshes and
collision pieces) with :func:`turn_front_up`; its front doors become lids
(:func:`doors_to_lids`).
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from model.core import ArticulatedObject

# the rotation (about the y axis, left unchanged) that takes the front (+x) up (+z) and the
# top (+z) to the back (-x); the bottom becomes the front
FRONT_UP = np.array([[0.0, 0.0, -1.0],
                     [0.0, 1.0, 0.0],
                     [1.0, 0.0, 0.0]])

# a lid's hinge side -> the hinge side of the front door that turns into it
LID_TO_DOOR_HINGE = {"back": "top", "front": "bottom", "left": "left", "right": "right"}


def turn_front_up(obj: ArticulatedObject, prepared: Optional[dict] = None) -> list[float]:
    """Turn ``obj`` in place by FRONT_UP (boxes, joint origins and axes, meshes, collision
    pieces, and the part index -> ``PreparedMesh`` arrays of ``prepared``), then place it on
    the floor as the layout does (``model.refine.size.place_on_floor``). Returns the
    translation of that placing (m)."""
    from .size import place_on_floor

    T = np.eye(4)
    T[:3, :3] = FRONT_UP
    for k, p in enumerate(obj.parts):
        p.bbox_center = FRONT_UP @ np.asarray(p.bbox_center, dtype=np.float64)
        p.bbox_size = np.abs(FRONT_UP) @ np.asarray(p.bbox_size, dtype=np.float64)
        p.joint.origin = FRONT_UP @ np.asarray(p.joint.origin, dtype=np.float64)
        p.joint.axis = FRONT_UP @ np.asarray(p.joint.axis, dtype=np.float64)
        if p.mesh is not None:
            p.mesh.apply_transform(T)
        p.collision = [_turned_piece(c, T) for c in p.collision] if p.collision else \
            p.collision
        if prepared and k in prepared:
            prepared[k] = prepared[k].turned(FRONT_UP)
    move = place_on_floor(obj)
    if prepared:
        for k in prepared:
            prepared[k] = prepared[k].moved(move)
    return move


def _turned_piece(piece, T: np.ndarray):
    """A collision piece turned by ``T`` (4x4, a quarter-turn rotation): a box stays an
    axis-aligned box (the exporter writes a box's size and centre only), its sides swapped."""
    import trimesh

    if isinstance(piece, trimesh.primitives.Box):
        M = np.asarray(piece.primitive.transform, dtype=np.float64)
        if not np.allclose(M[:3, :3], np.eye(3), atol=1e-9):
            raise ValueError("a collision box that is not axis-aligned cannot be turned")
        out = np.eye(4)
        out[:3, 3] = T[:3, :3] @ M[:3, 3]
        return trimesh.primitives.Box(
            extents=np.abs(T[:3, :3]) @ np.asarray(piece.primitive.extents, dtype=np.float64),
            transform=out)
    piece.apply_transform(T)
    return piece


def doors_to_lids(obj: ArticulatedObject) -> list[str]:
    """The doors on the body of a turned object (:func:`turn_front_up`) are its lids: label
    and name ("door_0" -> "lid_0"). Returns the new names."""
    out = []
    for p in obj.parts:
        if p.label == "door" and p.parent == obj.root:
            p.label = "lid"
            p.name = "lid" + p.name[len("door"):] if p.name.startswith("door") else p.name
            out.append(p.name)
    return out


__all__ = ["FRONT_UP", "LID_TO_DOOR_HINGE", "turn_front_up", "doors_to_lids"]
