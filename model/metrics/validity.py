"""Validity (DESIGN §7): the share of generated URDFs that load in yourdfpy, pybullet, MuJoCo
and Pinocchio with every joint movable. Built on ``model.export.simcheck.check_urdf``.

A URDF counts as valid when every simulator loaded it without error and moved all its joints.
When the source object is given, simcheck also compares link poses with our forward
kinematics; that agreement is reported separately (``pose_agreement``) and is not part of
validity as DESIGN §7 defines it.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Sequence

log = logging.getLogger(__name__)


@dataclass
class ValidityResult:
    valid: list[bool]                       # per URDF
    per_simulator: dict[str, float]         # share loaded + joints movable, per simulator
    pose_agreement: float | None            # share whose poses match our FK (objects given)
    errors: list[str] = field(default_factory=list)

    @property
    def share(self) -> float:
        return float(sum(self.valid) / len(self.valid)) if self.valid else 0.0

    def to_json(self) -> dict:
        return {"validity": self.share, "n": len(self.valid), "per_simulator": self.per_simulator,
                "pose_agreement": self.pose_agreement, "errors": self.errors[:20]}


def urdf_valid(report) -> bool:
    return bool(report.sims) and all(r.loaded and r.joints_movable and not r.error
                                     for r in report.sims.values())


def validity(urdf_paths: Sequence[str], objects: Sequence | None = None) -> ValidityResult:
    """Check every URDF (``objects[i]`` is the object URDF i was exported from, or None)."""
    from model.export.simcheck import SIMULATORS, check_urdf
    valid, errors = [], []
    per_sim = {s: 0 for s in SIMULATORS}
    poses = []
    for i, path in enumerate(urdf_paths):
        obj = objects[i] if objects is not None else None
        try:
            rep = check_urdf(path, obj)
        except Exception as e:  # a crash of a checker is an invalid URDF, not a crashed eval
            log.warning("validity: %s: %s", path, e)
            valid.append(False)
            errors.append(f"{path}: {type(e).__name__}: {e}")
            continue
        ok = urdf_valid(rep)
        valid.append(ok)
        for s, r in rep.sims.items():
            per_sim[s] = per_sim.get(s, 0) + int(r.loaded and r.joints_movable and not r.error)
            if r.error:
                errors.append(f"{path} [{s}]: {r.error}")
        if obj is not None:
            poses.append(rep.ok)
    n = max(len(urdf_paths), 1)
    return ValidityResult(valid, {s: c / n for s, c in per_sim.items()},
                          float(sum(poses) / len(poses)) if poses else None, errors)
