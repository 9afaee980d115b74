"""Physics check of an articulated URDF in MuJoCo: does it behave on a floor when its joints
are driven?

The URDF is compiled with MjSpec (visual meshes left out: only collision geometry takes
part), a ground plane is added under its lowest collision point at rest (2 mm lower for
the welded base, which the floor does not carry) and every hinge / slide joint gets a position
actuator with the gains the MJCF export writes (``model.export.mjcf.servo_gains``: critically
damped, at least as stiff as 4 Hz on the joint's effective inertia and as the URDF's effort
limit at a tenth of the range off target, a motor-like armature keeping such a servo stable
on a 5 g cap), and whose controller cancels gravity on the
moving links (MuJoCo's actuator gravity compensation, as a robot's joint controller would),
so a 5 g cap is not left sagging on a vertical slide. All joints are swept together from their
lower limit to their upper limit and back (a triangle wave over ``seconds``), once with the
root welded to the world (fixed base) and once with a free joint on the root (free base,
resting on the floor).

A run passes when no state becomes NaN, no velocity or position blows up, every joint stays
within its limits (up to a tolerance for MuJoCo's soft limits), every joint reaches at least
``reach`` of its range (a part blocked by overlapping collision geometry does not), and, for
the free base, the root neither tips nor walks.

    res = physics_check("out/cabinet/cabinet.urdf")     # or an MJCF model's .xml
    res.ok, res.runs["free"].max_tilt_deg

An MJCF model (the object file of ``artformer convert --to mjcf``, not its scene) is read as
it is, its actuators replaced by the servos above.
"""
from __future__ import annotations

import logging
import math
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from model.export.mjcf import servo_gains

log = logging.getLogger(__name__)


# a welded base does not stand on the floor: the floor sits this far under its lowest point,
# so a part that moves along the base's underside (a swivel cap's plate) does not scrape it
FIXED_CLEARANCE = 0.002
FLOOR = "audit_floor"


@dataclass
class PhysicsConfig:
    seconds: float = 5.0          # simulated time of one sweep (lower -> upper -> lower)
    timestep: float = 0.002
    drive_hz: float = 4.0         # bandwidth of the position servos
    max_speed: float = 50.0       # m/s or rad/s: above this a joint or the base has blown up
    limit_tol: float = 0.05       # fraction of a joint's range it may overshoot a limit
    reach: float = 0.9            # fraction of its range every joint must reach
    max_tilt_deg: float = 15.0    # free base: largest tilt of the root from upright (rocking
                                  # a few degrees is not tipping over)
    max_walk: float = 0.03        # free base: largest horizontal drift of the root (m)
    hold: float = 0.5             # seconds to settle (on the floor) before the sweep
    min_inertia: float = 0.01     # armature floor (kg or kg m^2) of a driven joint
    # where the floor goes under a mesh piece: "vertices" (its lowest vertex) or "boxes" (the
    # corner of its box in MuJoCo's principal frame: the rule the procedural generator's
    # gate of synth-7 was made with, which it keeps so its data rebuilds the same)
    floor_under: str = "vertices"


@dataclass
class PhysicsRun:
    base: str                                   # "fixed" | "free"
    ok: bool = False
    finite: bool = True
    max_speed: float = 0.0
    limit_violation: float = 0.0                # worst overshoot, as a fraction of the range
    min_reach: float = 1.0                      # worst joint's reached fraction of its range
    max_tilt_deg: float = 0.0
    walk: float = 0.0
    failures: list[str] = field(default_factory=list)


@dataclass
class PhysicsResult:
    ok: bool = False
    joints: int = 0
    runs: dict[str, PhysicsRun] = field(default_factory=dict)
    error: str = ""
    seconds: float = 0.0

    def to_dict(self) -> dict:
        return {"ok": self.ok, "joints": self.joints, "error": self.error,
                "seconds": round(self.seconds, 3),
                "runs": {k: asdict(v) for k, v in self.runs.items()}}

    @property
    def failures(self) -> list[str]:
        if self.error:
            return [self.error]
        return [f"{k} base: {f}" for k, r in self.runs.items() for f in r.failures]


def _spec(urdf: Path, tmpdir: str, free: bool, cfg: PhysicsConfig):
    import mujoco

    from model.export.simcheck import resolved_copy

    if urdf.suffix.lower() == ".xml":          # an MJCF model (artformer convert --to mjcf)
        spec = mujoco.MjSpec.from_file(str(urdf))
        for a in list(spec.actuators):           # our own servos replace its actuators
            spec.delete(a)
    else:
        spec = mujoco.MjSpec.from_file(str(resolved_copy(urdf, tmpdir, "mujoco",
                                                          drop_visuals=True)))
    spec.option.timestep = cfg.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    roots = [b for b in spec.worldbody.bodies]
    if len(roots) != 1:
        raise ValueError(f"expected one root link under the world, found {len(roots)}")
    if free:
        roots[0].add_freejoint()
    for b in spec.bodies:
        if b.name not in ("world", roots[0].name):
            b.gravcomp = 1.0
            # MuJoCo filters parent/child contacts except against bodies welded to the world,
            # which the fixed-base root is; exclude them explicitly so both runs agree. A
            # link without geometry (a screw's helper) passes the exclusion on: a cap and
            # its bottle are parent and child through one screw joint
            spec.add_exclude(bodyname1=b.parent.name, bodyname2=b.name)
            if not b.parent.geoms and b.parent.parent.name != "world":
                spec.add_exclude(bodyname1=b.parent.parent.name, bodyname2=b.name)
    # placed under the object's lowest point once the model is compiled (_run)
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], name=FLOOR)
    # a joint an equality ties to another (an MJCF screw's slide follows its hinge) moves
    # through that one and gets no servo of its own
    coupled = {e.name1 for e in spec.equalities if e.type == mujoco.mjtEq.mjEQ_JOINT}
    joints = [j for j in spec.joints if j.type in (mujoco.mjtJoint.mjJNT_HINGE,
                                                   mujoco.mjtJoint.mjJNT_SLIDE)
              and j.name not in coupled]
    for j in joints:
        j.actgravcomp = True
        j.armature = cfg.min_inertia
        a = spec.add_actuator()
        a.name = f"audit_drive_{j.name}"
        a.trntype = mujoco.mjtTrn.mjTRN_JOINT
        a.target = j.name
        a.set_to_position(kp=1.0, kv=0.0)       # gains set per joint once inertia is known
    return spec, [j.name for j in joints]


MESH_GEOM = 7      # mujoco.mjtGeom.mjGEOM_MESH


def _lowest_point(m, d, skip: int, vertices: bool = True) -> float:
    """Height of the lowest point of the collision geometry in ``d``'s pose, geom ``skip``
    (the floor) left out; with ``vertices`` False a mesh counts as its box in its frame."""
    low = np.inf
    for g in range(m.ngeom):
        if g == skip or (m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0):
            continue
        R = d.geom_xmat[g].reshape(3, 3)
        if vertices and m.geom_type[g] == MESH_GEOM and m.geom_dataid[g] >= 0:
            # a mesh's own vertices: the corners of its box in its (principal) frame reach
            # below it, 13 cm under a slanted piece of a carcass, which then fell that far
            k = m.geom_dataid[g]
            V = m.mesh_vert[m.mesh_vertadr[k]:m.mesh_vertadr[k] + m.mesh_vertnum[k]]
            low = min(low, float(d.geom_xpos[g, 2] + (V @ R[2]).min()))
            continue
        c, half = m.geom_aabb[g, :3], m.geom_aabb[g, 3:]
        low = min(low, float(d.geom_xpos[g, 2] + R[2] @ c - np.abs(R[2]) @ half))
    return 0.0 if not np.isfinite(low) else low


def _ranges(m, names: list[str]) -> list[tuple[float, float, int, int]]:
    """(lower, upper, qpos address, dof address) per driven joint; continuous joints sweep
    one turn."""
    out = []
    for n in names:
        jid = m.joint(n).id
        lo, hi = (float(m.jnt_range[jid][0]), float(m.jnt_range[jid][1])) \
            if m.jnt_limited[jid] else (0.0, 2 * math.pi)
        out.append((lo, hi, int(m.jnt_qposadr[jid]), int(m.jnt_dofadr[jid])))
    return out


def _tilt_deg(quat_wxyz: np.ndarray) -> float:
    w, x, y, z = quat_wxyz / max(np.linalg.norm(quat_wxyz), 1e-12)
    zz = 1.0 - 2.0 * (x * x + y * y)            # R[2, 2]: the body's z axis against world z
    return math.degrees(math.acos(max(-1.0, min(1.0, zz))))


def _run(urdf: Path, free: bool, cfg: PhysicsConfig, tmpdir: str) -> tuple[PhysicsRun, int]:
    import mujoco

    spec, names = _spec(urdf, tmpdir, free, cfg)
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)                       # the rest pose
    # The floor goes into the spec and the model is compiled again: a world geom's pose is
    # fixed at compile time (writing m.geom_pos afterwards leaves it at z = 0, through the
    # object of any URDF whose root frame is not at its bottom).
    low = _lowest_point(m, d, m.geom(FLOOR).id, cfg.floor_under == "vertices") \
        - (0.0 if free else FIXED_CLEARANCE)
    spec.geom(FLOOR).pos = [0.0, 0.0, low]
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    run = PhysicsRun(base="free" if free else "fixed")
    rng = _ranges(m, names)
    # start every joint at its lower limit (the rest state of our exports is 0 = lower)
    for lo, hi, qa, _ in rng:
        d.qpos[qa] = min(max(0.0, lo), hi)
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, M, d.qM)
    for k, (lo, hi, _, da) in enumerate(rng):
        jid = m.joint(names[k]).id
        inertia = max(float(M[da, da]) - float(m.dof_armature[da]), 1e-9)
        effort = float(np.abs(m.jnt_actfrcrange[jid]).max()) if m.jnt_actfrclimited[jid] else 0.0
        kp, kv, m.dof_armature[da] = servo_gains(inertia, effort, hi - lo, hz=cfg.drive_hz,
                                                 timestep=cfg.timestep,
                                                 min_armature=cfg.min_inertia)
        m.actuator_gainprm[k, 0] = kp
        m.actuator_biasprm[k, 1] = -kp
        m.actuator_biasprm[k, 2] = -kv
    root = 1
    extent = float(np.ptp(m.geom_aabb[:, 3:], axis=0).max()) if m.ngeom else 1.0
    start_xy = d.xpos[root, :2].copy()
    reached = np.zeros(len(rng))
    hold = int(round(cfg.hold / cfg.timestep))
    n = int(round(cfg.seconds / cfg.timestep))
    for step in range(hold + n):
        phase = max(0, step - hold) / n
        sweeping = step >= hold
        tri = 1.0 - abs(1.0 - 2.0 * phase)         # 0 -> 1 -> 0
        for k, (lo, hi, qa, _) in enumerate(rng):
            d.ctrl[k] = lo + tri * (hi - lo)
        mujoco.mj_step(m, d)
        if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
            run.finite = False
            run.failures.append(f"state became NaN/inf at t = {step * cfg.timestep:.3f} s")
            break
        run.max_speed = max(run.max_speed, float(np.abs(d.qvel).max()) if m.nv else 0.0)
        for k, (lo, hi, qa, _) in enumerate(rng if sweeping else ()):
            span = max(hi - lo, 1e-9)
            q = float(d.qpos[qa])
            run.limit_violation = max(run.limit_violation, (lo - q) / span, (q - hi) / span)
            reached[k] = max(reached[k], (q - lo) / span)
        if free:
            run.max_tilt_deg = max(run.max_tilt_deg, _tilt_deg(d.xquat[root]))
            run.walk = max(run.walk, float(np.linalg.norm(d.xpos[root, :2] - start_xy)))
        if run.max_speed > cfg.max_speed or np.abs(d.xpos).max() > 10 * extent + 1.0:
            run.failures.append(f"blew up at t = {step * cfg.timestep:.3f} s "
                                f"(speed {run.max_speed:.3g})")
            break
    run.min_reach = float(reached.min()) if len(rng) else 1.0
    if run.limit_violation > cfg.limit_tol:
        run.failures.append(f"a joint left its limits by {run.limit_violation:.0%} of its range")
    if run.finite and not any("blew" in f for f in run.failures) and run.min_reach < cfg.reach:
        worst = names[int(np.argmin(reached))]
        run.failures.append(f"joint {worst} reached only {run.min_reach:.0%} of its range")
    if run.max_tilt_deg > cfg.max_tilt_deg:
        run.failures.append(f"base tipped {run.max_tilt_deg:.1f} deg")
    if run.walk > cfg.max_walk:
        run.failures.append(f"base walked {run.walk * 100:.1f} cm")
    run.ok = not run.failures
    return run, len(names)


def physics_check(urdf: "str | Path", config: Optional[PhysicsConfig] = None) -> PhysicsResult:
    """Fixed-base and free-base sweeps of a URDF (or an MJCF object model, ``.xml``) in
    MuJoCo; never raises for a bad file."""
    import time

    cfg = config or PhysicsConfig()
    res = PhysicsResult()
    t0 = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory(prefix="artformer_physics_") as tmp:
            for free in (False, True):
                run, res.joints = _run(Path(urdf).resolve(), free, cfg, tmp)
                res.runs[run.base] = run
        res.ok = all(r.ok for r in res.runs.values())
    except Exception as e:  # a URDF MuJoCo cannot compile fails the check, with the reason
        res.error = f"MuJoCo could not load or run it: {type(e).__name__}: {e}"
        log.debug("physics check failed on %s", urdf, exc_info=True)
    res.seconds = time.perf_counter() - t0
    return res


__all__ = ["PhysicsConfig", "PhysicsResult", "PhysicsRun", "physics_check"]
