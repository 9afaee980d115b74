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

import contextlib
import logging
import math
import os
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Optional

import numpy as np

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


@dataclass
class _UJoint:
    name: str
    type: str
    lower: float
    upper: float
    child: str


def _urdf_joints(path: Path) -> list[_UJoint]:
    from lxml import etree
    root = etree.parse(str(path)).getroot()
    out = []
    for j in root.findall("joint"):
        t = j.get("type")
        lim = j.find("limit")
        lo = float(lim.get("lower", 0.0)) if lim is not None else 0.0
        hi = float(lim.get("upper", 0.0)) if lim is not None else 0.0
        if t == "continuous":
            lo, hi = -math.pi, math.pi
        out.append(_UJoint(j.get("name"), t, lo, hi, j.find("child").get("link")))
    return out


def _poses_to_test(obj, joints: list[_UJoint]):
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


def _quat_xyzw_to_matrix(q) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _pose(pos, R) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = pos
    return T


# -- per simulator ----------------------------------------------------------------------------
# Each backend: load(path) -> handle, returns (set_values(dict) -> link poses dict,
# joint names -> (lower, upper) as the simulator sees them, close()).


def _backend_yourdfpy(path: Path):
    import warnings

    import yourdfpy
    with warnings.catch_warnings():  # yourdfpy 0.0.58 float()s 1-element arrays
        warnings.simplefilter("ignore", DeprecationWarning)
        urdf = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False)
    # yourdfpy only warns about meshes it cannot find; a consumer would get no geometry.
    from .importer import resolve_mesh_path
    missing = sorted({g.geometry.mesh.filename for link in urdf.robot.links
                      for g in [*link.visuals, *link.collisions]
                      if g.geometry is not None and g.geometry.mesh is not None
                      and not resolve_mesh_path(g.geometry.mesh.filename, path.parent).exists()})
    if missing:
        raise RuntimeError(f"mesh files not found: {missing[:5]}"
                           f"{' and %d more' % (len(missing) - 5) if len(missing) > 5 else ''}")
    movable = {n: (j.limit.lower if j.limit is not None else None,
                   j.limit.upper if j.limit is not None else None)
               for n, j in urdf.joint_map.items() if j.type != "fixed"}
    names = list(urdf.actuated_joint_names)
    base = urdf.base_link

    def set_values(vals: dict) -> dict:
        cfg = np.array([vals.get(n, 0.0) for n in names], dtype=np.float64)
        with warnings.catch_warnings():  # yourdfpy 0.0.58 float()s 1-element arrays
            warnings.simplefilter("ignore", DeprecationWarning)
            urdf.update_cfg(cfg)
        return {ln: urdf.get_transform(ln, base) for ln in urdf.link_map}

    return set_values, movable, lambda: None


@contextlib.contextmanager
def _captured_native_output():
    """Collect what C code writes to fds 1 and 2 (pybullet's b3Warning / b3Error lines) so it
    goes into the report instead of the terminal. Held only around the load call."""
    sys.stdout.flush()
    sys.stderr.flush()
    buf = tempfile.TemporaryFile(mode="w+b")
    saved = [os.dup(1), os.dup(2)]
    lines: list[str] = []
    try:
        os.dup2(buf.fileno(), 1)
        os.dup2(buf.fileno(), 2)
        yield lines
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in saved:
            os.close(fd)
        buf.seek(0)
        text = buf.read().decode(errors="replace")
        buf.close()
        lines.extend(ln.strip() for ln in text.splitlines() if ln.strip())


def _backend_pybullet(path: Path):
    with _captured_native_output():
        import pybullet as pb                    # prints its build time on first import
    cid = pb.connect(pb.DIRECT)
    try:
        with _captured_native_output() as native:
            body = pb.loadURDF(str(path), useFixedBase=True, physicsClientId=cid)
    except Exception as e:
        pb.disconnect(cid)
        detail = " ".join(ln for ln in native if "rror" in ln or "cannot" in ln or "invalid" in ln)
        raise RuntimeError(f"pybullet could not load the URDF: {e}"
                           f"{' (' + detail[:300] + ')' if detail else ''}") from None
    n = pb.getNumJoints(body, physicsClientId=cid)
    index, movable, links = {}, {}, {}
    for k in range(n):
        info = pb.getJointInfo(body, k, physicsClientId=cid)
        jname, jtype = info[1].decode(), info[2]
        links[info[12].decode()] = k
        if jtype in (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC):
            index[jname] = k
            movable[jname] = (info[8], info[9])
    base_name = pb.getBodyInfo(body, physicsClientId=cid)[0].decode()
    # getBasePositionAndOrientation gives the base's inertial frame; undo its local offset.
    dyn = pb.getDynamicsInfo(body, -1, physicsClientId=cid)
    inv_local = np.linalg.inv(_pose(dyn[3], _quat_xyzw_to_matrix(dyn[4])))

    def set_values(vals: dict) -> dict:
        for jname, k in index.items():
            pb.resetJointState(body, k, float(vals.get(jname, 0.0)), physicsClientId=cid)
        for jname, v in vals.items():
            got = pb.getJointState(body, index[jname], physicsClientId=cid)[0]
            if abs(got - v) > 1e-9:
                raise RuntimeError(f"pybullet joint {jname!r} did not take value {v} (has {got})")
        pos, orn = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
        out = {base_name: _pose(pos, _quat_xyzw_to_matrix(orn)) @ inv_local}
        states = pb.getLinkStates(body, list(links.values()), computeForwardKinematics=True,
                                  physicsClientId=cid) if links else []
        for lname, st in zip(links, states):
            out[lname] = _pose(st[4], _quat_xyzw_to_matrix(st[5]))
        return out

    return set_values, movable, lambda: pb.disconnect(cid)


def _backend_mujoco(path: Path):
    import mujoco
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    movable, adr = {}, {}
    for k in range(m.njnt):
        jname = m.joint(k).name
        if m.jnt_type[k] in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            adr[jname] = int(m.jnt_qposadr[k])
            lim = m.jnt_range[k] if m.jnt_limited[k] else (-math.pi, math.pi)
            movable[jname] = (float(lim[0]), float(lim[1]))
    bodies = {m.body(b).name: b for b in range(1, m.nbody)}
    deepest = [0.0]

    def set_values(vals: dict) -> dict:
        d.qpos[:] = 0.0
        for jname, v in vals.items():
            d.qpos[adr[jname]] = v
        # Position stage incl. collision detection: poses, and how deep collision geometry of
        # different bodies interpenetrates in this state (informational).
        mujoco.mj_fwdPosition(m, d)
        if d.ncon:
            deepest[0] = max(deepest[0], float(-d.contact.dist[:d.ncon].min()))
        return {name: _pose(d.xpos[b], d.xmat[b].reshape(3, 3)) for name, b in bodies.items()}

    set_values.max_penetration = lambda: deepest[0]
    return set_values, movable, lambda: None


def _package_dirs() -> list[str]:
    """Folders Pinocchio searches for ``package://<pkg>/...``: each ament prefix's share/."""
    dirs = []
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        share = Path(prefix) / "share"
        if prefix and share.is_dir():
            dirs.append(str(share))
    return dirs


def _backend_pinocchio(path: Path):
    """Pinocchio's kinematic model (fixed base) plus its collision geometry model, which
    loads every collision mesh (a missing one raises). Link poses are its BODY frames."""
    import pinocchio as pin
    model = pin.buildModelFromUrdf(str(path))
    pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.COLLISION,
                          package_dirs=_package_dirs() + [str(path.parent)])
    data = model.createData()
    movable = {}
    for jid in range(1, model.njoints):
        j = model.joints[jid]
        if j.nq == 1:
            movable[model.names[jid]] = (float(model.lowerPositionLimit[j.idx_q]),
                                         float(model.upperPositionLimit[j.idx_q]))
        else:                        # continuous: (cos, sin) of the angle, no limits
            movable[model.names[jid]] = (None, None)
    frames = {f.name: k for k, f in enumerate(model.frames) if f.type == pin.FrameType.BODY}

    def set_values(vals: dict) -> dict:
        q = pin.neutral(model)
        for jname, v in vals.items():
            jid = model.getJointId(jname)
            if jid >= model.njoints:
                raise KeyError(f"pinocchio model has no joint {jname!r}")
            j = model.joints[jid]
            if j.nq == 1:
                q[j.idx_q] = v
            else:
                q[j.idx_q:j.idx_q + 2] = (math.cos(v), math.sin(v))
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        return {name: np.array(data.oMf[k].homogeneous) for name, k in frames.items()}

    return set_values, movable, lambda: None


_BACKENDS: dict[str, Callable] = {"yourdfpy": _backend_yourdfpy, "pybullet": _backend_pybullet,
                                  "mujoco": _backend_mujoco, "pinocchio": _backend_pinocchio}


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


def _resolved_copy(path: Path, tmpdir: str, sim: str, drop_visuals: bool) -> Path:
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
                load_path = path
                if sim in ("mujoco", "pybullet"):
                    bad = _unreadable_visuals(path, sim)
                    if bad:
                        res.note = (f"{len(bad)} visual mesh(es) in a format {sim} cannot read "
                                    f"(e.g. {Path(bad[0]).name}); checked without visuals")
                    if bad or not _has_mujoco_element(path) or (
                            sim == "pybullet" and _has_package_uri(path)):
                        load_path = _resolved_copy(path, tmpdir, sim, drop_visuals=bool(bad))
                elif sim == "pinocchio" and _has_package_uri(path):
                    # package:// resolved as for the others (ament index, then beside the URDF)
                    load_path = _resolved_copy(path, tmpdir, sim, drop_visuals=False)
                set_values, sim_movable, close = _BACKENDS[sim](load_path)
                res.loaded = True
                res.num_joints = len(sim_movable)
                missing = sorted(set(moving) - set(sim_movable))
                if missing:
                    raise RuntimeError(f"joints not movable in {sim}: {missing}")
                for jn, j in moving.items():
                    lo, hi = sim_movable[jn]
                    if j.type != "continuous" and lo is not None and (
                            abs(lo - j.lower) > 1e-6 or abs(hi - j.upper) > 1e-6):
                        raise RuntimeError(f"{sim} limits of joint {jn!r} are ({lo}, {hi}), "
                                           f"URDF says ({j.lower}, {j.upper})")
                for jn, j in moving.items():  # each joint must move its child link
                    if j.upper - j.lower <= 1e-9:
                        continue
                    # Several points of the range: a revolute over whole turns (a screw cap)
                    # is back at its rest pose at its upper limit.
                    moved = False
                    for f in (1.0, 0.5, 0.3, 0.1):
                        v = j.lower + f * (j.upper - j.lower)
                        posed = set_values({jn: v})
                        if np.abs(posed[j.child] - set_values({jn: j.lower})[j.child]).max() > MOVE_TOL:
                            moved = True
                            break
                    if not moved:
                        raise RuntimeError(f"joint {jn!r} does not move link {j.child!r} in {sim}")
                res.joints_movable = True
                if obj is not None:
                    dp = dr = 0.0
                    for vals, want in cases:
                        got = set_values(vals)
                        p, r = _pose_errors(got, want)
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
