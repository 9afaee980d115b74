"""The sim-ready verdict of the physical audit: would a roboticist accept this object in a sim?

For one object (in memory, or imported from a URDF: ours or anyone's) it measures

* **interpenetration** — exact intersection volume / the smaller part's volume (manifold3d)
  for every pair of parts except a parent and a child rigidly fixed together, at rest, at
  ``states`` openness ratios of all joints together, and with each joint alone swept over
  ``states`` ratios while the others stay at rest (a part behind a closed door or lid is
  not required to pass through it or its handle: those pairs count in the all-joints sweep
  only);
* **attachment** — a sliding part's gap to its parent at rest and fully open; a turning
  part's axis line to the part, and to its parent less the part's thickness (a hinge
  bridges a door's thickness);
* **hinges** — a door's or lid's revolute axis lies along an edge of its box (angle to the
  nearest principal axis, distance to the nearest parallel edge / the panel's width);
* **drawers** — a drawer's (or tray's) opening direction against the outward normal of the
  parent-box face it leaves through (the face its open box crosses furthest);
* **mesh health** — connected components, floater faces (components under 1 % of the part's
  surface), watertightness, faces and bytes;
* **physics** — MuJoCo on a floor with every joint driven (``model.export.physics``).

Each object gets a **sim-ready** verdict: every check within the thresholds of
:class:`AuditConfig` (documented in docs/audit.md). The measurements themselves are in
model.export.audit_checks. It sits in export, below the data layer, because the procedural
generator redraws the objects it fails and a batch run records it; the folders, table, JSON
and contact sheet of ``artformer audit`` are model.metrics.audit's (which re-exports these
names).

    rep = audit_object(obj)                 # ObjectAudit; rep.sim_ready, rep.failures
"""
from __future__ import annotations

import logging
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional

from model.core import ArticulatedObject, JointType

from .audit_checks import (HINGED_LABELS, SLIDING_LABELS, _manifolds, attachment_gaps,
                           axis_angle_deg, hinge_offset, mesh_health, overlaps, panel_cover,
                           slide_angle_deg)

log = logging.getLogger(__name__)


@dataclass
class AuditConfig:
    states: int = 10               # openness ratios of the sweeps (0..1, rest included)
    max_overlap: float = 0.01      # intersection / smaller part volume, any pair, any state
    max_gap: float = 0.01          # m: a moving part's gap to its parent, rest and open
    max_axis_deg: float = 5.0      # hinge / drawer axis off its principal direction
    max_hinge_offset: float = 0.08 # hinge axis to the nearest door edge / panel width
    min_panel_cover: float = 0.02  # a door's or lid's area over its parent's face (the
                                   # data's smallest: 2.9 %; audit_checks.panel_cover)
    floater_area: float = 0.01     # a component under this share of its part's area floats
    face_budget: int = 30000       # faces per object (0: not checked)
    physics: bool = True           # run the MuJoCo check (needs a URDF; objects get exported)
    physics_floor: str = "vertices"  # PhysicsConfig.floor_under ("boxes": synth-7's gate)


@dataclass
class ObjectAudit:
    name: str
    path: str = ""                                   # URDF audited ("" for in-memory only)
    category: str = ""
    parts: int = 0
    max_overlap: float = 0.0
    worst_pair: Optional[tuple] = None               # (a, b, state description)
    max_gap: float = 0.0
    worst_gap_part: str = ""
    hinges: list = field(default_factory=list)       # {part, angle_deg, offset, ok}
    slides: list = field(default_factory=list)       # {part, angle_deg, ok}
    worst_components: int = 0
    floater_faces: int = 0
    watertight: bool = True
    faces: int = 0
    bytes: Optional[int] = None
    physics: Optional[dict] = None
    failures: list = field(default_factory=list)
    error: str = ""
    seconds: float = 0.0

    @property
    def sim_ready(self) -> bool:
        return not self.failures and not self.error

    def to_dict(self) -> dict:
        d = asdict(self)
        d["sim_ready"] = self.sim_ready
        return d


def audit_object(obj: ArticulatedObject, *, urdf: Optional[str] = None,
                 config: Optional[AuditConfig] = None, mesh_bytes: Optional[int] = None
                 ) -> ObjectAudit:
    """Audit one object. ``urdf``: its exported URDF for the physics check (without one the
    object is exported to a temporary folder when ``config.physics``)."""
    import time

    cfg = config or AuditConfig()
    t0 = time.perf_counter()
    rep = ObjectAudit(name=obj.name, path=str(urdf or ""), category=obj.category,
                      parts=len(obj.parts), bytes=mesh_bytes)
    try:
        _geometry_checks(obj, rep, cfg)
        if cfg.physics:
            _physics(obj, urdf, rep, cfg.physics_floor)
    except Exception as e:  # an unreadable object fails the audit with the reason
        rep.error = f"{type(e).__name__}: {e}"
        log.debug("audit of %s failed", obj.name, exc_info=True)
    rep.seconds = time.perf_counter() - t0
    return rep


def _geometry_checks(obj: ArticulatedObject, rep: ObjectAudit, cfg: AuditConfig) -> None:
    mans, hulls = _manifolds(obj)
    rep.max_overlap, rep.worst_pair = overlaps(obj, cfg.states, mans)
    if rep.max_overlap > cfg.max_overlap:
        a, b, where = rep.worst_pair
        rep.failures.append(f"{a} and {b} overlap by {rep.max_overlap:.1%} ({where})")
    gaps = attachment_gaps(obj, mans)
    if gaps:
        rep.worst_gap_part = max(gaps, key=gaps.get)
        rep.max_gap = gaps[rep.worst_gap_part]
        if rep.max_gap > cfg.max_gap:
            rep.failures.append(f"{rep.worst_gap_part} is {rep.max_gap * 1000:.0f} mm from "
                                f"its parent")
    for k in obj.movable_parts():
        p = obj.parts[k]
        if p.label in HINGED_LABELS and p.joint.type == JointType.REVOLUTE:
            ang, off = axis_angle_deg(p.joint.axis)[0], hinge_offset(p)
            cover = panel_cover(obj, k)
            ok = ang <= cfg.max_axis_deg and off <= cfg.max_hinge_offset
            rep.hinges.append({"part": p.name, "angle_deg": ang, "offset": off, "cover": cover,
                               "ok": ok and cover >= cfg.min_panel_cover})
            if not ok:
                rep.failures.append(f"{p.name} hinge {ang:.0f} deg off its axis, "
                                    f"{off:.0%} of its width from an edge")
            if cover < cfg.min_panel_cover:
                rep.failures.append(f"{p.name} covers {cover:.1%} of its parent's face "
                                    f"(a door or lid: at least {cfg.min_panel_cover:.0%})")
        if p.label in SLIDING_LABELS and p.joint.type == JointType.PRISMATIC and p.parent >= 0:
            ang = slide_angle_deg(obj, k)
            ok = ang <= cfg.max_axis_deg
            rep.slides.append({"part": p.name, "angle_deg": ang, "ok": ok})
            if not ok:
                rep.failures.append(f"{p.name} slides {ang:.0f} deg off its opening's normal")
    health = [mesh_health(p.mesh, cfg.floater_area) for p in obj.parts if p.mesh is not None]
    rep.worst_components = max((h["components"] for h in health), default=0)
    rep.floater_faces = sum(h["floater_faces"] for h in health)
    rep.watertight = all(h["watertight"] for h in health) and not hulls
    rep.faces = sum(h["faces"] for h in health)
    if rep.floater_faces:
        rep.failures.append(f"{rep.floater_faces} floater faces")
    if not rep.watertight:
        rep.failures.append("a part mesh is not watertight")
    if cfg.face_budget and rep.faces > cfg.face_budget:
        rep.failures.append(f"{rep.faces} faces (budget {cfg.face_budget})")


def _physics(obj: ArticulatedObject, urdf: Optional[str], rep: ObjectAudit,
             floor: str = "vertices") -> None:
    from .physics import PhysicsConfig, physics_check

    pc = PhysicsConfig(floor_under=floor)
    if urdf:
        res = physics_check(urdf, pc)
    else:
        from .urdf import export_object
        with tempfile.TemporaryDirectory(prefix="artformer_audit_") as tmp:
            out = export_object(obj, Path(tmp) / "obj", preview=False, mesh_uri="relative")
            res = physics_check(out.urdf_path, pc)
    rep.physics = res.to_dict()
    rep.failures.extend(f"physics: {f}" for f in res.failures)


__all__ = ["AuditConfig", "ObjectAudit", "audit_object"]
