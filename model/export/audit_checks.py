"""The measurements of the physical audit (model.export.simready): interpenetration over joint
sweeps, attachment of moving parts, hinge and drawer axes, and mesh health. Each returns
numbers; the thresholds and the verdict are model.export.simready's."""
from __future__ import annotations

from typing import Iterable, Optional

import numpy as np

from model.core import ArticulatedObject, JointType, meshops
from model.core.contacts import checked_pairs, pair_overlaps

HINGED_LABELS = ("door", "lid")
SLIDING_LABELS = ("drawer", "tray")


# ---------------------------------------------------------------------------------------------
# interpenetration and attachment
# ---------------------------------------------------------------------------------------------
def _closed_panel(obj: ArticulatedObject, i: int) -> bool:
    """Part ``i`` is a door or lid, or rides on one (its handle)."""
    while i >= 0:
        p = obj.parts[i]
        if p.label in HINGED_LABELS and p.joint.type == JointType.REVOLUTE:
            return True
        if p.joint.type != JointType.FIXED:
            return False
        i = p.parent
    return False


def _moving_chain(obj: ArticulatedObject, i: int) -> frozenset:
    out = set()
    while i >= 0:
        if obj.parts[i].joint.type != JointType.FIXED:
            out.add(i)
        i = obj.parts[i].parent
    return frozenset(out)


def _states(obj: ArticulatedObject, n: int) -> Iterable[tuple[str, dict, Optional[set]]]:
    """(description, ratio per part name, parts that moved or None for all)."""
    ratios = np.linspace(0.0, 1.0, max(2, n))
    for r in ratios:
        yield f"all joints at {r:.2f}", {p.name: float(r) for p in obj.parts}, None
    for k in obj.movable_parts():
        moved = set(obj.subtree(k))
        for r in ratios[1:]:
            yield f"{obj.parts[k].name} alone at {r:.2f}", {obj.parts[k].name: float(r)}, moved


def _manifolds(obj: ArticulatedObject) -> tuple[dict, list[str]]:
    from model.core import meshops
    mans, hulls = {}, []
    for i, p in enumerate(obj.parts):
        if p.mesh is None or len(p.mesh.faces) == 0:
            continue
        try:
            mans[i] = meshops.to_manifold(p.mesh)
        except meshops.NotWatertightError:
            mans[i] = meshops.to_manifold(p.mesh, fallback="hull")
            hulls.append(p.name)
    return mans, hulls


def overlaps(obj: ArticulatedObject, states: int = 10, mans: Optional[dict] = None
             ) -> tuple[float, Optional[tuple]]:
    """Worst intersection / smaller-volume ratio over the checked pairs and the sweep, and
    (part a, part b, state) where it happens."""
    mans = mans if mans is not None else _manifolds(obj)[0]
    vol = {i: max(float(m.volume()), 1e-15) for i, m in mans.items()}
    pairs = [(i, j) for i, j in checked_pairs(obj) if i in mans and j in mans]
    # pairs whose parts hang off the same moving joints never move relative to each other:
    # checked at rest only
    chains = [_moving_chain(obj, i) for i in range(len(obj.parts))]
    relative = [(i, j) for i, j in pairs if chains[i] != chains[j]]
    worst, where = 0.0, None
    for n, (desc, ratio, moved) in enumerate(_states(obj, states)):
        T = obj.link_transforms(ratio=ratio)
        if moved is None:
            todo = pairs if n == 0 else relative
        else:
            # a part behind a closed door or lid need not open through it (or its handle)
            todo = [(i, j) for i, j in relative if (i in moved) != (j in moved)
                    and not _closed_panel(obj, j if i in moved else i)]
        for i, j, r in pair_overlaps(obj, mans, vol, todo, T):
            if r > worst:
                worst, where = r, (obj.parts[i].name, obj.parts[j].name, desc)
    return worst, where


def attachment_gaps(obj: ArticulatedObject, mans: Optional[dict] = None, search: float = 0.05
                    ) -> dict[str, float]:
    """Gap (m, capped at ``search``) of each moving part to its parent. A sliding part: its
    mesh to the parent's, at rest and with every joint fully open. A turning part: its axis
    line to the part and to the parent (the line stays put in both, so this holds at every
    angle)."""
    mans = mans if mans is not None else _manifolds(obj)[0]
    gaps: dict[str, float] = {}
    if not mans:
        return gaps
    extent = max(float(np.ptp(np.asarray(m.bounding_box()).reshape(2, 3), axis=0).max())
                 for m in mans.values())
    for ratio in (0.0, 1.0):
        T = obj.link_transforms(ratio=ratio)
        for k in obj.movable_parts():
            p = obj.parts[k]
            if p.parent < 0 or k not in mans or p.parent not in mans:
                continue
            if p.joint.type.translates:
                pairs = [(mans[k].transform(meshops.affine34(T[p.name])),
                          mans[p.parent].transform(meshops.affine34(T[obj.parts[p.parent].name])))]
            elif ratio == 0.0:
                # a hinge bridges the panel's thickness between the part and its parent
                line = meshops.axis_line(p.joint.origin, p.joint.axis, 2.5 * extent)
                thick = float(np.min(_bounds(p)[1] - _bounds(p)[0]))
                g = max(float(line.min_gap(mans[k], search)),
                        float(line.min_gap(mans[p.parent], search)) - thick)
                gaps[p.name] = max(gaps.get(p.name, 0.0), min(g, search))
                continue
            else:
                continue
            for a, b in pairs:
                g = min(float(a.min_gap(b, search)), search)
                gaps[p.name] = max(gaps.get(p.name, 0.0), g)
    return gaps


# ---------------------------------------------------------------------------------------------
# hinges and drawers
# ---------------------------------------------------------------------------------------------
def _bounds(part) -> tuple[np.ndarray, np.ndarray]:
    if part.mesh is not None and len(part.mesh.faces):
        lo, hi = np.asarray(part.mesh.bounds, dtype=np.float64)
        return lo, hi
    return part.bbox_center - part.bbox_size / 2, part.bbox_center + part.bbox_size / 2


def axis_angle_deg(axis: np.ndarray) -> tuple[float, int]:
    """Angle (deg) of an axis to its nearest principal axis, and that axis' index."""
    a = np.abs(np.asarray(axis, dtype=np.float64))
    a = a / max(np.linalg.norm(a), 1e-12)
    k = int(np.argmax(a))
    return float(np.degrees(np.arccos(min(1.0, a[k])))), k


def hinge_offset(part) -> float:
    """Distance from a revolute axis to the nearest edge of the part's box parallel to it,
    over the panel's width (0: on an edge; 0.5: through the middle)."""
    _, k = axis_angle_deg(part.joint.axis)
    lo, hi = _bounds(part)
    u, v = [d for d in range(3) if d != k]
    o = part.joint.origin
    d = min(np.hypot(o[u] - cu, o[v] - cv) for cu in (lo[u], hi[u]) for cv in (lo[v], hi[v]))
    width = max(hi[u] - lo[u], hi[v] - lo[v], 1e-9)
    return float(d / width)


def panel_cover(obj: ArticulatedObject, k: int) -> float:
    """A door's or lid's area over its parent's: the panel's two largest sides against the
    parent's extent along the same two axes (meshes where there are, else boxes). A lid
    of a few centimetres on a washer's back face covers 0.1-0.4 %; the training data's
    smallest 2.9 % (25,487 doors and lids of synth-v1, v4 and v5)."""
    p = obj.parts[k]
    if p.parent < 0:
        return 1.0
    lo, hi = _bounds(p)
    plo, phi = _bounds(obj.parts[p.parent])
    size, parent = hi - lo, phi - plo
    axes = np.argsort(size)[1:]
    return float(np.prod(size[axes]) / max(float(np.prod(parent[axes])), 1e-12))


def opening_normal(obj: ArticulatedObject, k: int) -> np.ndarray:
    """Outward normal of the parent-box face a sliding part leaves through: the face its
    box, fully open, crosses furthest."""
    p = obj.parts[k]
    clo, chi = _bounds(p)
    move = p.joint.transform(p.joint.value_at(1.0)[0], 0.0)[:3, 3]
    clo, chi = clo + move, chi + move
    plo, phi = _bounds(obj.parts[p.parent])
    out = np.concatenate([chi - phi, plo - clo])            # protrusion past each face
    d = int(np.argmax(out))
    return np.eye(3)[d % 3] * (1.0 if d < 3 else -1.0)


def slide_angle_deg(obj: ArticulatedObject, k: int) -> float:
    """Angle (deg) between a prismatic part's opening direction and its opening's normal."""
    p = obj.parts[k]
    a = np.asarray(p.joint.axis, dtype=np.float64)
    a = a / max(np.linalg.norm(a), 1e-12)
    lo, hi = p.joint.t_range
    direction = a if abs(hi) >= abs(lo) else -a
    n = opening_normal(obj, k)
    return float(np.degrees(np.arccos(np.clip(direction @ n, -1.0, 1.0))))


# ---------------------------------------------------------------------------------------------
# mesh health
# ---------------------------------------------------------------------------------------------
def mesh_health(mesh, floater_area: float = 0.01) -> dict:
    """components, floater faces (in components under ``floater_area`` of the surface),
    watertight, faces of one mesh."""
    F = len(mesh.faces)
    if F == 0:
        return {"components": 0, "floater_faces": 0, "watertight": False, "faces": 0}
    labels, area = meshops.edge_pieces(mesh)
    small = area < floater_area * max(float(area.sum()), 1e-18)
    return {"components": len(area), "floater_faces": int(np.isin(labels, np.where(small)[0]).sum()),
            "watertight": bool(mesh.is_watertight), "faces": int(F)}
