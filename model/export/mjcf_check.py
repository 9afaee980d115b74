"""Drive check of a converted MJCF scene: each position actuator commanded to both ends of
its range (``artformer convert --to mjcf --check``)."""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np


@dataclass
class DriveReport:
    """What ``drive_check`` saw: each actuator driven to each end of its range."""
    loaded: bool = False
    missing_joints: list[str] = field(default_factory=list)
    finite: bool = True
    within_limits: bool = True
    reached: dict[str, float] = field(default_factory=dict)   # actuator -> worst share of the
                                                              # commanded travel achieved
    error: str = ""

    @property
    def ok(self) -> bool:
        return (self.loaded and not self.missing_joints and self.finite and self.within_limits
                and not self.error and all(v >= 0.9 for v in self.reached.values()))


def drive_check(scene_xml: os.PathLike, joints=(), *, seconds: float = 1.5,
                limit_tol: float = 0.02) -> DriveReport:
    """Load an MJCF scene, then, per actuator, command one end of its range and the other
    (the rest at their rest value), simulate ``seconds`` each, and record how much of the
    commanded travel its joint made, whether the state stayed finite and every limited joint
    stayed within its range (``limit_tol`` of the range). ``joints``: names that must exist."""
    import mujoco
    rep = DriveReport()
    try:
        m = mujoco.MjModel.from_xml_path(str(scene_xml))
    except Exception as e:
        rep.error = f"load: {e}"
        return rep
    rep.loaded = True
    have = {m.joint(k).name for k in range(m.njnt)}
    rep.missing_joints = sorted(set(joints) - have)
    d = mujoco.MjData(m)
    steps = max(1, int(round(seconds / m.opt.timestep)))
    rest = np.array([float(np.clip(0.0, *m.actuator_ctrlrange[k])) for k in range(m.nu)])
    lim = [(m.jnt_qposadr[k], m.jnt_range[k]) for k in range(m.njnt)
           if m.jnt_limited[k] and m.jnt_type[k] in (mujoco.mjtJoint.mjJNT_HINGE,
                                                     mujoco.mjtJoint.mjJNT_SLIDE)]
    for k in range(m.nu):
        jid = int(m.actuator_trnid[k, 0])
        adr = int(m.jnt_qposadr[jid])
        lo, hi = m.actuator_ctrlrange[k]
        worst = 1.0
        for target in (hi, lo):
            mujoco.mj_resetData(m, d)
            for j in range(m.nu):
                d.qpos[m.jnt_qposadr[int(m.actuator_trnid[j, 0])]] = rest[j]
            d.ctrl[:] = rest
            if target == lo:                 # start the way back from the upper end
                d.qpos[adr] = hi
                d.ctrl[k] = hi
            mujoco.mj_forward(m, d)
            start = float(d.qpos[adr])
            d.ctrl[k] = target
            for _ in range(steps):
                mujoco.mj_step(m, d)
            if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
                rep.finite = False
                break
            for a, (rlo, rhi) in lim:
                tol = limit_tol * max(rhi - rlo, 1e-9)
                if not (rlo - tol <= d.qpos[a] <= rhi + tol):
                    rep.within_limits = False
            travel = target - start
            if abs(travel) > 1e-12:
                worst = min(worst, float((d.qpos[adr] - start) / travel))
        rep.reached[m.actuator(k).name] = worst
    return rep
