"""The loaders model.export.simcheck drives: each takes a URDF path and returns
``(set_values, movable, close)``: ``set_values({joint: value})`` poses the model (other joints
at their lower limit) and returns link name -> 4x4 pose in the root frame, ``movable`` maps
each movable joint to its (lower, upper) limits as the loader read them."""
from __future__ import annotations

import contextlib
import logging
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import Callable

import numpy as np

log = logging.getLogger(__name__)


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


BACKENDS: dict[str, Callable] = {"yourdfpy": _backend_yourdfpy, "pybullet": _backend_pybullet,
                                  "mujoco": _backend_mujoco, "pinocchio": _backend_pinocchio}

