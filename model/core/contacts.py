"""Which part pairs of an articulated object must not interpenetrate, and how much they do
in a pose (exact, manifold3d): shared by the refinement stage and the audit."""
from __future__ import annotations

from model.core import meshops
from model.core.objects import ArticulatedObject, JointType


def checked_pairs(obj: ArticulatedObject) -> list[tuple[int, int]]:
    """Every pair of parts except a parent and child fixed rigidly together."""
    pairs = []
    for i in range(len(obj.parts)):
        for j in range(i + 1, len(obj.parts)):
            a, b = obj.parts[i], obj.parts[j]
            rigid = ((a.parent == j and a.joint.type == JointType.FIXED)
                     or (b.parent == i and b.joint.type == JointType.FIXED))
            if not rigid:
                pairs.append((i, j))
    return pairs



def pair_overlaps(obj: ArticulatedObject, mans: dict, vol: dict, pairs, T: dict):
    """(i, j, intersection / smaller volume) of each pair of parts posed by ``T`` (link
    transforms), skipping pairs whose bounding boxes are apart."""
    posed: dict[int, object] = {}
    for i, j in pairs:
        for k in (i, j):
            if k not in posed:
                posed[k] = mans[k].transform(meshops.affine34(T[obj.parts[k].name]))
        ba, bb = posed[i].bounding_box(), posed[j].bounding_box()
        if any(ba[d] >= bb[d + 3] or bb[d] >= ba[d + 3] for d in range(3)):
            continue
        yield i, j, max(0.0, float((posed[i] ^ posed[j]).volume())) / min(vol[i], vol[j])
