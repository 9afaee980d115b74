"""Verification of a generated object: exact intersection volumes of every part pair over
openness states, attachment of moving parts, and the audit gate."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from model.core import meshops
from model.core.objects import ArticulatedObject, Joint, JointType

# =============================================================================================
# verification
# =============================================================================================
@dataclass
class CheckReport:
    collisions: list[tuple[str, str, float, float]] = field(default_factory=list)  # a, b, ratio, m³
    detached: list[tuple[str, float, float]] = field(default_factory=list)         # part, ratio, gap

    @property
    def ok(self) -> bool:
        return not self.collisions and not self.detached


def check_object(obj: ArticulatedObject, states: int = 10, *, attach_distance: float = 0.004,
                 abs_tol: float = 1e-9, depth_tol: float = 2e-4, manifolds: Optional[dict] = None,
                 stop_early: bool = False) -> CheckReport:
    """Exact pairwise intersection volumes of all parts at ``states`` openness ratios, and the
    distance of every moving part to its parent.

    A pair collides when their intersection exceeds ``abs_tol`` m³, or when it is non-empty
    (> 1e-12 m³) and its mean thickness 2·volume / area exceeds ``depth_tol`` (a real
    interpenetration, however small). Parts touching at faces pass (float32 noise only)."""
    names = [p.name for p in obj.parts]
    mans = manifolds or {p.name: meshops.to_manifold(p.mesh) for p in obj.parts}
    rep = CheckReport()
    moving = set(names[i] for i in obj.movable_parts())
    for r in np.linspace(0.0, 1.0, states):
        T = obj.link_transforms(ratio=float(r))
        posed = {n: mans[n].transform(meshops.affine34(T[n])) for n in names}
        boxes = {n: np.asarray(posed[n].bounding_box()) for n in names}
        for i in range(len(names)):
            a = names[i]
            for j in range(i + 1, len(names)):
                bn = names[j]
                ba, bb = boxes[a], boxes[bn]
                if np.any(ba[:3] >= bb[3:]) or np.any(bb[:3] >= ba[3:]):
                    continue
                x = posed[a] ^ posed[bn]
                v = float(x.volume())
                if v <= 1e-12:
                    continue
                # mean thickness of the overlap: a contact sheet (float noise of touching faces,
                # at any orientation) is ~0 thick; a real interpenetration is not
                thick = 2.0 * v / max(float(x.surface_area()), 1e-18)
                if v > abs_tol or thick > depth_tol:
                    rep.collisions.append((a, bn, float(r), v))
                    if stop_early:
                        return rep
        for p in obj.parts:
            if p.name in moving and p.parent >= 0 and p.joint.type.translates:
                gap = posed[p.name].min_gap(posed[names[p.parent]], attach_distance * 3)
                if gap > attach_distance:
                    rep.detached.append((p.name, float(r), float(gap)))
                    if stop_early:
                        return rep
    # A rotating joint keeps its axis line fixed in both frames: it is attached when that line
    # passes within attach_distance of the part and of its parent (checked at rest).
    extent = float(np.max([np.ptp(np.asarray(mans[n].bounding_box()).reshape(2, 3), axis=0).max()
                           for n in names]))
    for p in obj.parts:
        if p.name in moving and p.parent >= 0 and not p.joint.type.translates:
            line = meshops.axis_line(p.joint.origin, p.joint.axis, 2.5 * extent)
            for other in (p.name, names[p.parent]):
                gap = line.min_gap(mans[other], attach_distance * 3)
                if gap > attach_distance:
                    rep.detached.append((p.name, 0.0, float(gap)))
                    if stop_early:
                        return rep
    return rep


def _audit_failures(obj: ArticulatedObject, physics: bool) -> list[str]:
    """What the sim-ready audit finds wrong with a drawn object."""
    from model.export.simready import AuditConfig, audit_object
    # the floor rule synth-7 was made with, so its data versions rebuild the same
    rep = audit_object(obj, config=AuditConfig(physics=physics, physics_floor="boxes"))
    return ([rep.error] if rep.error else []) + rep.failures


def _moving_ancestor(obj: ArticulatedObject, name: str) -> Optional[int]:
    i = obj.index_of(name)
    while i >= 0:
        if obj.parts[i].joint.type != JointType.FIXED:
            return i
        i = obj.parts[i].parent
    return None


def _shrink(joint: Joint, factor: float) -> None:
    if joint.type.translates:
        joint.t_range = (joint.t_range[0], joint.t_range[0] + (joint.t_range[1] - joint.t_range[0]) * factor)
    if joint.type.rotates and joint.type != JointType.CONTINUOUS:
        joint.r_range = (joint.r_range[0], joint.r_range[0] + (joint.r_range[1] - joint.r_range[0]) * factor)


