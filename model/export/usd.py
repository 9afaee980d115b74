"""URDF folder → one USD stage with UsdPhysics rigid bodies, collision, mass and joints.

    res = export_usd("out/cabinet")           # out/cabinet/usd/<name>.usd
    stage = pxr.Usd.Stage.Open(res.path)

Stage layout (Z up, metres, kilograms), the object's prims flat under its root as URDF
importers lay out articulations::

    /<name>                          Xform, default prim, PhysicsArticulationRootAPI
    /<name>/<link>                   Xform at the link's rest pose, PhysicsRigidBodyAPI +
                                     PhysicsMassAPI (mass, centre of mass, principal inertia)
    /<name>/<link>/visuals/<geom>    Mesh (display colour from the URDF material)
    /<name>/<link>/collisions/<geom> Mesh (PhysicsCollisionAPI, convex-hull approximation)
                                     or Cube (URDF boxes), purpose "guide"
    /<name>/joints/<joint>           PhysicsRevoluteJoint / PhysicsPrismaticJoint /
                                     PhysicsFixedJoint with body0 = parent, body1 = child
    /<name>/joints/root_joint        PhysicsFixedJoint to the world (unless floating)
    /physicsScene                    PhysicsScene, gravity -Z 9.81 m/s²

UsdPhysics joints move along the X, Y or Z axis of their joint frame. The converter picks the
frame as the URDF joint origin rotated so that its X axis is the URDF axis, and sets
``physics:axis = "X"``. Revolute limits are in degrees (the UsdPhysics unit), prismatic
limits in metres. A continuous joint is a revolute joint without limits. A screw keeps the
URDF's helper link and its two joints.
"""
from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from .urdfmodel import ConvertError, Geom, URDFModel, load_mesh, quat_wxyz, read_urdf_folder

log = logging.getLogger(__name__)

USD_SUFFIXES = (".usd", ".usda", ".usdc")


@dataclass
class USDResult:
    path: str
    root: str                         # prim path of the articulation root
    joints: list[str]                 # moving joints written (URDF names)
    links: list[str]


def _ident(name: str) -> str:
    from pxr import Tf
    return Tf.MakeValidIdentifier(name)


def _align_x(axis: np.ndarray) -> np.ndarray:
    """A rotation whose first column (X) is ``axis`` (unit)."""
    x = np.asarray(axis, dtype=np.float64)
    x = x / np.linalg.norm(x)
    helper = np.array([0.0, 0.0, 1.0]) if abs(x[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    y = np.cross(helper, x)
    y /= np.linalg.norm(y)
    z = np.cross(x, y)
    return np.stack([x, y, z], axis=1)


def _gf_quatf(R: np.ndarray):
    from pxr import Gf
    w, x, y, z = quat_wxyz(R)
    return Gf.Quatf(float(w), Gf.Vec3f(float(x), float(y), float(z)))


def _set_transform(xformable, T: np.ndarray, scale=None) -> None:
    from pxr import Gf, UsdGeom
    xf = UsdGeom.Xformable(xformable)
    xf.ClearXformOpOrder()
    xf.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(*map(float, T[:3, 3])))
    w, x, y, z = quat_wxyz(T[:3, :3])
    xf.AddOrientOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Quatd(float(w), float(x), float(y), float(z)))
    if scale is not None:
        xf.AddScaleOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(*map(float, scale)))


def _mesh_prim(stage, path: str, g: Geom, rgba=None):
    from pxr import Gf, UsdGeom, Vt
    m = load_mesh(g.mesh, g.scale)
    if len(m.faces) == 0:
        return None
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(m.vertices, dtype=np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(m.faces), 3, dtype=np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.asarray(m.faces, dtype=np.int32).ravel()))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    lo, hi = m.bounds
    mesh.CreateExtentAttr([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))])
    if rgba is not None:
        mesh.CreateDisplayColorAttr([Gf.Vec3f(*map(float, rgba[:3]))])
    _set_transform(mesh, g.origin)
    return mesh


def _primitive_prim(stage, path: str, g: Geom, rgba=None):
    from pxr import Gf, UsdGeom
    if g.kind == "box":
        prim = UsdGeom.Cube.Define(stage, path)
        prim.CreateSizeAttr(1.0)
        _set_transform(prim, g.origin, scale=np.maximum(np.asarray(g.size), 1e-9))
    elif g.kind == "cylinder":
        prim = UsdGeom.Cylinder.Define(stage, path)
        prim.CreateRadiusAttr(float(g.size[0]))
        prim.CreateHeightAttr(float(g.size[1]))
        prim.CreateAxisAttr(UsdGeom.Tokens.z)
        _set_transform(prim, g.origin)
    else:
        prim = UsdGeom.Sphere.Define(stage, path)
        prim.CreateRadiusAttr(float(g.size[0]))
        _set_transform(prim, g.origin)
    if rgba is not None:
        prim.CreateDisplayColorAttr([Gf.Vec3f(*map(float, rgba[:3]))])
    return prim


def _geom_prim(stage, path: str, g: Geom, rgba=None):
    return _mesh_prim(stage, path, g, rgba) if g.kind == "mesh" else _primitive_prim(stage, path, g, rgba)


def _write_stage(model: URDFModel, path: Path, floating: bool):
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    root_path = "/" + _ident(model.name)
    root = UsdGeom.Xform.Define(stage, root_path)
    stage.SetDefaultPrim(root.GetPrim())
    root.GetPrim().SetDocumentation(f"converted by artformer_ros from {model.path.name}")
    UsdPhysics.ArticulationRootAPI.Apply(root.GetPrim())
    scene = UsdPhysics.Scene.Define(stage, "/physicsScene")
    scene.CreateGravityDirectionAttr(Gf.Vec3f(0.0, 0.0, -1.0))
    scene.CreateGravityMagnitudeAttr(9.81)

    frames = model.rest_link_frames()
    link_paths: dict[str, str] = {}
    for name, link in model.links.items():
        ident = _ident(name)
        if ident in {Path(lp).name for lp in link_paths.values()} or ident == "joints":
            raise ConvertError(f"link name {name!r} clashes with another prim name in USD")
        link_paths[name] = f"{root_path}/{ident}"
        _link_prim(stage, link_paths[name], link, frames[name])
    UsdGeom.Scope.Define(stage, f"{root_path}/joints")
    moving = [j.name for j in model.joints if j.type != "fixed"]
    for j in model.joints:
        _joint_prim(stage, f"{root_path}/joints/{_ident(j.name)}", j, link_paths)
    if not floating:
        fix = UsdPhysics.FixedJoint.Define(stage, f"{root_path}/joints/root_joint")
        fix.CreateBody1Rel().SetTargets([Sdf.Path(link_paths[model.root])])
    stage.GetRootLayer().Save()
    return root_path, moving


def _link_prim(stage, lp: str, link, frame: np.ndarray) -> None:
    """A rigid body Xform with its mass properties, visual meshes and collision pieces."""
    from pxr import Gf, UsdGeom, UsdPhysics

    xf = UsdGeom.Xform.Define(stage, lp)
    _set_transform(xf, frame)
    prim = xf.GetPrim()
    UsdPhysics.RigidBodyAPI.Apply(prim)
    mass = UsdPhysics.MassAPI.Apply(prim)
    if link.mass > 0:
        mass.CreateMassAttr(float(link.mass))
        mass.CreateCenterOfMassAttr(Gf.Vec3f(*map(float, link.com[:3, 3])))
        if link.inertia is not None:
            w, V = np.linalg.eigh(link.inertia_in_link_frame())
            if np.linalg.det(V) < 0:
                V[:, 2] = -V[:, 2]
            mass.CreateDiagonalInertiaAttr(Gf.Vec3f(*map(float, np.maximum(w, 0.0))))
            mass.CreatePrincipalAxesAttr(_gf_quatf(V))
    if link.visuals:
        UsdGeom.Scope.Define(stage, f"{lp}/visuals")
    for k, g in enumerate(link.visuals):
        _geom_prim(stage, f"{lp}/visuals/{_ident(g.name or f'visual_{k}')}_{k}", g, g.rgba)
    if link.collisions:
        UsdGeom.Scope.Define(stage, f"{lp}/collisions")
    for k, g in enumerate(link.collisions):
        gp = _geom_prim(stage, f"{lp}/collisions/{_ident(g.name or f'collision_{k}')}_{k}", g)
        if gp is None:
            continue
        p = gp.GetPrim()
        UsdGeom.Imageable(p).CreatePurposeAttr(UsdGeom.Tokens.guide)
        UsdPhysics.CollisionAPI.Apply(p)
        if g.kind == "mesh":
            UsdPhysics.MeshCollisionAPI.Apply(p).CreateApproximationAttr(
                UsdPhysics.Tokens.convexHull)


def _joint_prim(stage, jp: str, j, link_paths: dict) -> None:
    """A UsdPhysics joint whose frames put X along the URDF axis (limits in degrees for
    revolute joints, none for continuous ones); the URDF's name, effort and velocity go into
    customData."""
    from pxr import Gf, Sdf, UsdPhysics

    if j.type == "fixed":
        joint = UsdPhysics.FixedJoint.Define(stage, jp)
        R = np.eye(3)
    else:
        R = _align_x(j.axis)
        if j.type == "prismatic":
            joint = UsdPhysics.PrismaticJoint.Define(stage, jp)
            joint.CreateLowerLimitAttr(float(j.lower))
            joint.CreateUpperLimitAttr(float(j.upper))
        else:
            joint = UsdPhysics.RevoluteJoint.Define(stage, jp)
            if j.type == "revolute":
                joint.CreateLowerLimitAttr(float(math.degrees(j.lower)))
                joint.CreateUpperLimitAttr(float(math.degrees(j.upper)))
        joint.CreateAxisAttr(UsdPhysics.Tokens.x)
    joint.CreateBody0Rel().SetTargets([Sdf.Path(link_paths[j.parent])])
    joint.CreateBody1Rel().SetTargets([Sdf.Path(link_paths[j.child])])
    joint.CreateLocalPos0Attr(Gf.Vec3f(*map(float, j.origin[:3, 3])))
    joint.CreateLocalRot0Attr(_gf_quatf(j.origin[:3, :3] @ R))
    joint.CreateLocalPos1Attr(Gf.Vec3f(0.0, 0.0, 0.0))
    joint.CreateLocalRot1Attr(_gf_quatf(R))
    joint.GetPrim().SetCustomDataByKey("urdf:joint_name", j.name)
    if j.effort > 0:
        joint.GetPrim().SetCustomDataByKey("urdf:effort", float(j.effort))
    if j.velocity > 0:
        joint.GetPrim().SetCustomDataByKey("urdf:velocity", float(j.velocity))


def export_usd(folder: os.PathLike, out: Optional[os.PathLike] = None, *,
               floating: bool = False) -> USDResult:
    """Convert the URDF folder ``folder`` (or a .urdf file) to one USD file.

    ``out``: a .usd / .usda / .usdc path (default ``<folder>/usd/<name>.usd``, binary).
    ``floating``: no fixed joint from the root link to the world.
    Raises ConvertError when the URDF cannot be read or the path has another suffix.
    """
    from .urdf import object_slug

    src = Path(folder).expanduser()
    model = read_urdf_folder(src)
    if out is None:
        out = (src if src.is_dir() else src.parent) / "usd" / f"{object_slug(model.name)}.usd"
    out = Path(out).expanduser().resolve()
    if out.suffix.lower() not in USD_SUFFIXES:
        raise ConvertError(f"USD output must end in {', '.join(USD_SUFFIXES)}, got {out.name}")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.stem}.tmp-{os.getpid()}{out.suffix}")
    try:
        root, moving = _write_stage(model, tmp, floating)
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
    log.info("USD of %s written to %s (%d moving joints)", model.name, out, len(moving))
    return USDResult(str(out), root, moving, list(model.links))


def _matrix(gf) -> np.ndarray:
    """A Gf.Matrix4d (row-vector convention) as a column-vector 4x4 numpy matrix."""
    return np.array(gf, dtype=np.float64).T


def _pose(pos, rot) -> np.ndarray:
    T = np.eye(4)
    q = rot.GetImaginary()
    w = rot.GetReal()
    x, y, z = q[0], q[1], q[2]
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = [pos[0], pos[1], pos[2]]
    return T


def check_usd(path: os.PathLike, urdf: Optional[os.PathLike] = None, *,
              tol: float = 1e-5) -> list[str]:
    """Open a stage with pxr and list what is wrong (empty: fine).

    Checks: a default prim with PhysicsArticulationRootAPI; every joint's bodies are rigid
    bodies with a positive mass; at rest each joint's two frames coincide in the world
    (``tol`` in metres and in quaternion distance); limits are ordered. With ``urdf`` (a
    URDF file or object folder): the same moving joints as the URDF, with its limits, parents
    and children."""
    from pxr import Usd, UsdGeom, UsdPhysics

    from .urdfmodel import find_urdf, read_urdf
    problems: list[str] = []
    stage = Usd.Stage.Open(str(path))
    if stage is None:
        return [f"pxr cannot open {path}"]
    root = stage.GetDefaultPrim()
    if not root or not root.HasAPI(UsdPhysics.ArticulationRootAPI):
        problems.append("no default prim with PhysicsArticulationRootAPI")
    cache = UsdGeom.XformCache()
    joints = {}
    for prim in stage.Traverse():
        if prim.IsA(UsdPhysics.Joint):
            name = prim.GetCustomDataByKey("urdf:joint_name") or prim.GetName()
            joints[name] = _check_joint(stage, prim, name, cache, tol, problems)
    if urdf is not None:
        problems += _against_urdf(read_urdf(find_urdf(urdf)), joints)
    return problems


def _check_joint(stage, prim, name: str, cache, tol: float, problems: list) -> tuple:
    """(kind, lower, upper, [body0, body1] names) of a USD joint; what is wrong with its
    bodies, frames or limits goes into ``problems``."""
    from pxr import UsdPhysics

    j = UsdPhysics.Joint(prim)
    bodies = []
    for rel in (j.GetBody0Rel().GetTargets(), j.GetBody1Rel().GetTargets()):
        if not rel:
            bodies.append(None)
            continue
        body = stage.GetPrimAtPath(rel[0])
        if not body or not body.HasAPI(UsdPhysics.RigidBodyAPI):
            problems.append(f"joint {name}: {rel[0]} is not a rigid body")
            bodies.append(None)
            continue
        m = UsdPhysics.MassAPI(body).GetMassAttr().Get()
        if not m or m <= 0:
            problems.append(f"joint {name}: body {rel[0]} has no positive mass")
        bodies.append(body)
    if bodies[0] is not None and bodies[1] is not None:
        W0 = _matrix(cache.GetLocalToWorldTransform(bodies[0])) @ _pose(
            j.GetLocalPos0Attr().Get(), j.GetLocalRot0Attr().Get())
        W1 = _matrix(cache.GetLocalToWorldTransform(bodies[1])) @ _pose(
            j.GetLocalPos1Attr().Get(), j.GetLocalRot1Attr().Get())
        if np.abs(W0 - W1).max() > tol:
            problems.append(f"joint {name}: its two frames differ at rest by "
                            f"{np.abs(W0 - W1).max():.2e}")
    kind, lo, hi = "fixed", None, None
    if prim.IsA(UsdPhysics.RevoluteJoint):
        r = UsdPhysics.RevoluteJoint(prim)
        kind, lo, hi = "revolute", r.GetLowerLimitAttr().Get(), r.GetUpperLimitAttr().Get()
        lo = math.radians(lo) if lo is not None else None
        hi = math.radians(hi) if hi is not None else None
    elif prim.IsA(UsdPhysics.PrismaticJoint):
        r = UsdPhysics.PrismaticJoint(prim)
        kind, lo, hi = "prismatic", r.GetLowerLimitAttr().Get(), r.GetUpperLimitAttr().Get()
    lo = lo if lo is not None and math.isfinite(lo) else None   # fallback: -inf / inf
    hi = hi if hi is not None and math.isfinite(hi) else None
    if lo is not None and hi is not None and lo > hi:
        problems.append(f"joint {name}: lower limit {lo} > upper {hi}")
    return kind, lo, hi, [b.GetName() if b is not None else None for b in bodies]


def _against_urdf(model, joints: dict) -> list[str]:
    """The USD's moving joints against the URDF's: the same set, types, limits, bodies."""
    problems = []
    want = {j.name: j for j in model.moving_joints()}
    have = {n: v for n, v in joints.items() if v[0] != "fixed"}
    if sorted(want) != sorted(have):
        problems.append(f"moving joints differ: URDF {sorted(want)}, USD {sorted(have)}")
    for n, j in want.items():
        if n not in have:
            continue
        kind, lo, hi, bodies = have[n]
        if kind != ("prismatic" if j.type == "prismatic" else "revolute"):
            problems.append(f"joint {n}: URDF type {j.type}, USD {kind}")
        if j.type != "continuous" and (lo is None or hi is None or abs(lo - j.lower) > 1e-6
                                       or abs(hi - j.upper) > 1e-6):
            problems.append(f"joint {n}: USD limits ({lo}, {hi}), URDF ({j.lower}, {j.upper})")
        if j.type == "continuous" and (lo is not None or hi is not None):
            problems.append(f"joint {n}: continuous in the URDF but limited in USD")
        if bodies != [_ident(j.parent), _ident(j.child)]:
            problems.append(f"joint {n}: USD bodies {bodies}, URDF {j.parent} -> {j.child}")
    return problems
