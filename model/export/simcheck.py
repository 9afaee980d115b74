"""Load a URDF in real consumers (yourdfpy, pybullet, MuJoCo, Pinocchio), move every joint
across its range, and compare link poses with our own forward kinematics.

    report = check_urdf("out/cabinet/example_cabinet.urdf", obj)
    report.ok                      # every simulator loaded, every joint moved, poses agree
    report.sims["mujoco"].max_position_error

Poses are compared at the openness ratios 0, 0.5, 1 and with each joint alone at its lower
and upper limit. ``obj`` must be the object the URDF was exported from (link and joint names
follow ``model.export.urdf``); without it only loading and joint motion are checked.

MuJoCo reads the ``<mujoco><compiler meshdir=... strippath=.../></mujoco>`` element our
exporter writes into the URDF. A URDF without that element (a foreign file) is given to
MuJoCo and pybullet as a temporary copy whose mesh paths are resolved to absolute paths;
visual meshes an engine cannot read (GLB) are left out of its copy (noted in the report).
"""
from __future__ import annotations

import logging
import math
import os
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from .simcheck_backends import BACKENDS

log = logging.getLogger(__name__)

SIMULATORS = ("yourdfpy", "pybullet", "mujoco", "pinocchio")
POSE_TOL = 1e-4          # metres / radians
MOVE_TOL = 1e-6


@dataclass
class SimResult:
    simulator: str
    loaded: bool = False
    joints_movable: bool = False
    num_joints: int = 0                     # movable (non-fixed) joints found
    max_position_error: Optional[float] = None   # metres, vs our FK (None: not compared)
    max_rotation_error: Optional[float] = None   # radians
    seconds: float = 0.0
    error: str = ""
    note: str = ""                          # e.g. visuals left out for this simulator
    # MuJoCo only, informational (does not affect ``ok``): deepest interpenetration of
    # collision geometry of different bodies over every tested state, metres.
    max_penetration: Optional[float] = None

    @property
    def ok(self) -> bool:
        pose_ok = (self.max_position_error is None
                   or (self.max_position_error <= POSE_TOL and self.max_rotation_error <= POSE_TOL))
        return self.loaded and self.joints_movable and pose_ok and not self.error


@dataclass
class SimReport:
    path: str
    sims: dict[str, SimResult] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return bool(self.sims) and all(r.ok for r in self.sims.values())

    @property
    def max_pose_error(self) -> Optional[float]:
        errs = [r.max_position_error for r in self.sims.values() if r.max_position_error is not None]
        return max(errs) if errs else None

    def to_dict(self) -> dict:
        return {"path": self.path, "ok": self.ok,
                "sims": {k: {**asdict(v), "ok": v.ok} for k, v in self.sims.items()}}

    def summary(self) -> str:
        rows = []
        for k, r in self.sims.items():
            err = "" if r.max_position_error is None else \
                f" pose err {r.max_position_error:.2e} m / {r.max_rotation_error:.2e} rad"
            rows.append(f"{k}: {'ok' if r.ok else 'FAIL'} loaded={r.loaded} "
                        f"joints={r.num_joints} movable={r.joints_movable}{err}"
                        f"{' error: ' + r.error if r.error else ''} ({r.seconds:.2f} s)"
                        f"{' [' + r.note + ']' if r.note else ''}")
        return "\n".join(rows)


# -- the joint set to test -------------------------------------------------------------------


def _urdf_joints(path: Path) -> list:
    """The URDF's joints (model.export.urdfmodel; meshes are not read: a missing mesh is
    each simulator's finding)."""
    from .urdfmodel import read_urdf
    return read_urdf(path, geometry=False).joints


def _poses_to_test(obj, joints: list):
    """[(urdf joint values, expected link frames or None)]: ratios 0/0.5/1 and each joint
    alone at each limit."""
    moving = [j for j in joints if j.type in ("revolute", "prismatic", "continuous")]
    cases = []
    if obj is None:
        for r in (0.0, 0.5, 1.0):
            cases.append(({j.name: j.lower + r * (j.upper - j.lower) for j in moving}, None))
        for j in moving:
            for v in (j.lower, j.upper):
                cases.append(({j.name: v}, None))
        return cases
    from model.core.objects import JointType
    from .urdf import JOINT_SUFFIX, SLIDE_SUFFIX, posed_link_frames

    # Drive the simulator with the URDF's own limits at a ratio and expect our FK at the same
    # ratio: a wrong limit in the file shows up as a pose error, not only a wrong frame.
    by_name = {j.name: j for j in joints}

    def urdf_values(ratios: dict) -> dict:
        vals = {}
        for p in obj.parts:
            if p.parent < 0 or p.joint.type == JointType.FIXED:
                continue
            r = ratios.get(p.name, 0.0)
            names = ([p.name + SLIDE_SUFFIX, p.name + JOINT_SUFFIX]
                     if p.joint.type == JointType.SCREW else [p.name + JOINT_SUFFIX])
            for n in names:
                if n not in by_name:
                    raise KeyError(f"URDF has no joint {n!r} for part {p.name!r}")
            if p.joint.type == JointType.CONTINUOUS:   # the URDF has no range: use ours
                vals[names[0]] = p.joint.value_at(r)[1]
                continue
            for n in names:
                j = by_name[n]
                vals[n] = j.lower + r * (j.upper - j.lower)
        return vals

    movable = [p.name for p in obj.parts if p.parent >= 0 and p.joint.type != JointType.FIXED]
    for r in (0.0, 0.5, 1.0):
        ratios = {n: r for n in movable}
        cases.append((urdf_values(ratios), posed_link_frames(obj, ratio=ratios)))
    for name in movable:
        for r in (0.0, 1.0):
            ratios = {n: 0.0 for n in movable}
            ratios[name] = r
            cases.append((urdf_values(ratios), posed_link_frames(obj, ratio=ratios)))
    return cases


def _pose_errors(got: dict[str, np.ndarray], want: dict[str, np.ndarray]) -> tuple[float, float]:
    dp, dr = 0.0, 0.0
    for name, W in want.items():
        if name not in got:
            raise KeyError(f"link {name!r} missing in the simulator model")
        G = got[name]
        dp = max(dp, float(np.linalg.norm(G[:3, 3] - W[:3, 3])))
        R = G[:3, :3].T @ W[:3, :3]
        # atan2 form: acos((tr - 1) / 2) loses all precision near 0 (float32 quaternions).
        s = np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
        dr = max(dr, float(math.atan2(s, (np.trace(R) - 1.0) / 2.0)))
    return dp, dr



def _has_package_uri(path: Path) -> bool:
    """pybullet only strips ``package://`` and searches beside the URDF; a package URI that
    names a folder hierarchy needs the resolved copy."""
    from lxml import etree
    return any(m.get("filename", "").startswith("package://")
               for m in etree.parse(str(path)).getroot().iter("mesh"))


def _has_mujoco_element(path: Path) -> bool:
    from lxml import etree
    return etree.parse(str(path)).getroot().find("mujoco") is not None


# Mesh formats the physics engines read (pybullet: obj/stl/dae; MuJoCo: obj/stl/msh).
_SIM_MESH_EXT = {"pybullet": (".obj", ".stl", ".dae"), "mujoco": (".obj", ".stl", ".msh")}


def _unreadable_visuals(path: Path, sim: str) -> list[str]:
    from lxml import etree
    root = etree.parse(str(path)).getroot()
    bad = []
    for vis in root.iter("visual"):
        for mesh in vis.iter("mesh"):
            fn = mesh.get("filename", "")
            if not fn.lower().endswith(_SIM_MESH_EXT[sim]):
                bad.append(fn)
    return bad


def resolved_copy(path: Path, tmpdir: str, sim: str, drop_visuals: bool) -> Path:
    """A copy of a URDF for a simulator: absolute mesh paths, a MuJoCo compiler element
    (kept if present, with strippath off), and optionally no visuals (GLB visuals: the
    engines cannot read them and visuals do not change kinematics)."""
    from lxml import etree
    from .importer import resolve_mesh_path
    tree = etree.parse(str(path))
    root = tree.getroot()
    if drop_visuals:
        for link in root.findall("link"):
            for vis in link.findall("visual"):
                link.remove(vis)
    for mesh in root.iter("mesh"):
        mesh.set("filename", str(resolve_mesh_path(mesh.get("filename", ""), path.parent)))
    mj = root.find("mujoco")
    if mj is None:
        mj = etree.SubElement(root, "mujoco")
    comp = mj.find("compiler")
    if comp is None:
        comp = etree.SubElement(mj, "compiler")
    comp.attrib.update({"strippath": "false", "discardvisual": "false", "fusestatic": "false",
                        "balanceinertia": "true"})
    comp.attrib.pop("meshdir", None)
    out = Path(tmpdir) / f"{sim}_{path.name}"
    tree.write(str(out))
    return out


def check_urdf(path: os.PathLike, obj=None, *, simulators=SIMULATORS) -> SimReport:
    """Load ``path`` in each simulator, move every joint across its range, compare poses.

    Never raises for a bad URDF: failures are recorded per simulator in the report.
    """
    path = Path(path)
    report = SimReport(path=str(path))
    try:
        joints = _urdf_joints(path)
        cases = _poses_to_test(obj, joints)
    except Exception as e:
        for s in simulators:
            report.sims[s] = SimResult(s, error=f"cannot read URDF: {e}")
        return report
    moving = {j.name: j for j in joints if j.type in ("revolute", "prismatic", "continuous")}
    with tempfile.TemporaryDirectory(prefix="artformer_simcheck_") as tmpdir:
        for sim in simulators:
            res = SimResult(sim)
            report.sims[sim] = res
            t0 = time.perf_counter()
            close = lambda: None  # noqa: E731
            try:
                set_values, sim_movable, close = BACKENDS[sim](_load_path(path, sim, tmpdir, res))
                res.loaded = True
                res.num_joints = len(sim_movable)
                _check_joints(sim, moving, sim_movable, set_values)
                res.joints_movable = True
                if obj is not None:
                    dp = dr = 0.0
                    for vals, want in cases:
                        p, r = _pose_errors(set_values(vals), want)
                        dp, dr = max(dp, p), max(dr, r)
                    res.max_position_error, res.max_rotation_error = dp, dr
                probe = getattr(set_values, "max_penetration", None)
                if probe is not None:
                    res.max_penetration = probe()
            except Exception as e:  # record and go on with the next simulator
                res.error = f"{type(e).__name__}: {e}"
                log.debug("simcheck %s failed on %s", sim, path, exc_info=True)
            finally:
                try:
                    close()
                except Exception:
                    pass
                res.seconds = time.perf_counter() - t0
    return report


def _load_path(path: Path, sim: str, tmpdir: str, res: SimResult) -> Path:
    """The file ``sim`` loads: the URDF itself, or a copy with package:// resolved, MuJoCo's
    compiler element added, or visuals it cannot read left out (noted in ``res``)."""
    if sim in ("mujoco", "pybullet"):
        bad = _unreadable_visuals(path, sim)
        if bad:
            res.note = (f"{len(bad)} visual mesh(es) in a format {sim} cannot read "
                        f"(e.g. {Path(bad[0]).name}); checked without visuals")
        if bad or not _has_mujoco_element(path) or (sim == "pybullet" and _has_package_uri(path)):
            return resolved_copy(path, tmpdir, sim, drop_visuals=bool(bad))
    elif sim == "pinocchio" and _has_package_uri(path):
        # package:// resolved as for the others (ament index, then beside the URDF)
        return resolved_copy(path, tmpdir, sim, drop_visuals=False)
    return path


def _check_joints(sim: str, moving: dict, sim_movable: dict, set_values) -> None:
    """Every URDF moving joint is movable in ``sim`` with the URDF's limits and moves its
    child link; raises RuntimeError saying which is not."""
    missing = sorted(set(moving) - set(sim_movable))
    if missing:
        raise RuntimeError(f"joints not movable in {sim}: {missing}")
    for jn, j in moving.items():
        lo, hi = sim_movable[jn]
        if j.type != "continuous" and lo is not None and (
                abs(lo - j.lower) > 1e-6 or abs(hi - j.upper) > 1e-6):
            raise RuntimeError(f"{sim} limits of joint {jn!r} are ({lo}, {hi}), "
                               f"URDF says ({j.lower}, {j.upper})")
    for jn, j in moving.items():
        if j.upper - j.lower <= 1e-9:
            continue
        # Several points of the range: a revolute over whole turns (a screw cap) is back at
        # its rest pose at its upper limit.
        rest = set_values({jn: j.lower})[j.child]
        if not any(np.abs(set_values({jn: j.lower + f * (j.upper - j.lower)})[j.child] - rest).max()
                   > MOVE_TOL for f in (1.0, 0.5, 0.3, 0.1)):
            raise RuntimeError(f"joint {jn!r} does not move link {j.child!r} in {sim}")
