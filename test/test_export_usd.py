"""USD conversion: pxr opens the stage; joints, limits, bodies, masses, collision and link
poses match the URDF (read independently with yourdfpy)."""
import math
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom, UsdPhysics  # noqa: E402

from model.export.urdfmodel import ConvertError  # noqa: E402
from model.export.usd import check_usd, export_usd  # noqa: E402


@pytest.fixture(scope="module")
def examples(tmp_path_factory, exported_examples):
    root = tmp_path_factory.mktemp("usd")
    out = {}
    for name, (_, res) in exported_examples.items():
        shutil.copytree(res.out_dir, root / name)
        out[name] = (root / name, export_usd(root / name))
    return out


def _urdf(folder):
    import yourdfpy
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return yourdfpy.URDF.load(str(next(Path(folder).glob("*.urdf"))), build_scene_graph=True,
                                  load_meshes=False)


def _world(prim):
    return np.array(UsdGeom.XformCache().GetLocalToWorldTransform(prim), dtype=np.float64).T


@pytest.mark.parametrize("name", ["cabinet", "bottle"])
def test_stage_joints_and_limits_match_the_urdf(examples, name):
    folder, res = examples[name]
    u = _urdf(folder)
    stage = Usd.Stage.Open(res.path)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    root = stage.GetDefaultPrim()
    assert root.HasAPI(UsdPhysics.ArticulationRootAPI)
    joints = {p.GetName(): p for p in stage.Traverse() if p.IsA(UsdPhysics.Joint)}
    moving = {n: p for n, p in joints.items() if not p.IsA(UsdPhysics.FixedJoint)}
    urdf_moving = {n: j for n, j in u.joint_map.items() if j.type != "fixed"}
    assert sorted(moving) == sorted(urdf_moving)
    assert len(joints) == len(u.joint_map) + 1          # + the fixed joint to the world
    for n, j in urdf_moving.items():
        p = moving[n]
        if j.type == "prismatic":
            pj = UsdPhysics.PrismaticJoint(p)
            lo, hi = pj.GetLowerLimitAttr().Get(), pj.GetUpperLimitAttr().Get()
        else:
            pj = UsdPhysics.RevoluteJoint(p)
            lo = math.radians(pj.GetLowerLimitAttr().Get())
            hi = math.radians(pj.GetUpperLimitAttr().Get())
        assert (lo, hi) == pytest.approx((j.limit.lower, j.limit.upper), abs=1e-6)
        b0 = stage.GetPrimAtPath(pj.GetBody0Rel().GetTargets()[0])
        b1 = stage.GetPrimAtPath(pj.GetBody1Rel().GetTargets()[0])
        assert (b0.GetName(), b1.GetName()) == (j.parent, j.child)
        # the joint's X axis, seen from the child at rest, is the URDF axis in world
        q = pj.GetLocalRot1Attr().Get()
        R = np.array(pxr.Gf.Matrix3d(pxr.Gf.Quatd(q.GetReal(), pxr.Gf.Vec3d(q.GetImaginary()))),
                     dtype=np.float64).T
        axis_world = _world(b1)[:3, :3] @ R[:, 0]
        want = u.get_transform(j.child, u.base_link)[:3, :3] @ np.asarray(j.axis)
        assert np.allclose(axis_world, want, atol=1e-6)
    assert check_usd(res.path, folder) == []


@pytest.mark.parametrize("name", ["cabinet", "bottle"])
def test_bodies_masses_collision_and_poses(examples, name):
    folder, res = examples[name]
    u = _urdf(folder)
    stage = Usd.Stage.Open(res.path)
    root = stage.GetDefaultPrim()
    for lname, link in u.link_map.items():
        prim = root.GetChild(lname)
        assert prim.HasAPI(UsdPhysics.RigidBodyAPI), lname
        assert UsdPhysics.MassAPI(prim).GetMassAttr().Get() == pytest.approx(link.inertial.mass,
                                                                            rel=1e-5)
        assert np.allclose(_world(prim), u.get_transform(lname, u.base_link), atol=1e-6)
        cols = [p for p in Usd.PrimRange(prim) if p.HasAPI(UsdPhysics.CollisionAPI)]
        assert len(cols) == len(link.collisions)
        meshes = [p for p in Usd.PrimRange(prim.GetChild("visuals")) if p.IsA(UsdGeom.Mesh)] \
            if link.visuals else []
        assert len(meshes) == len(link.visuals)
        for m in meshes:
            assert len(UsdGeom.Mesh(m).GetPointsAttr().Get()) > 3
    if name == "bottle":
        assert root.GetChild("cap_screw_helper").HasAPI(UsdPhysics.RigidBodyAPI)


def test_check_usd_finds_a_wrong_limit(examples, tmp_path):
    folder, res = examples["cabinet"]
    stage = Usd.Stage.Open(res.path)
    j = UsdPhysics.PrismaticJoint(stage.GetDefaultPrim().GetChild("joints").GetChild("drawer_0_joint"))
    j.GetUpperLimitAttr().Set(j.GetUpperLimitAttr().Get() + 0.1)
    j.CreateLocalPos0Attr(j.GetLocalPos0Attr().Get() + pxr.Gf.Vec3f(0.01, 0, 0))
    stage.Export(str(tmp_path / "bad.usda"))
    problems = check_usd(tmp_path / "bad.usda", folder)
    assert any("limits" in p for p in problems) and any("frames differ" in p for p in problems)


def test_usda_output_floating_and_bad_suffix(examples, tmp_path):
    folder, _ = examples["cabinet"]
    res = export_usd(folder, tmp_path / "c.usda", floating=True)
    text = Path(res.path).read_text()
    assert text.startswith("#usda") and "root_joint" not in text
    with pytest.raises(ConvertError, match="must end in"):
        export_usd(folder, tmp_path / "c.obj")


def test_cli(examples, tmp_path):
    folder, _ = examples["bottle"]
    out = subprocess.run([sys.executable, "-m", "model", "convert", str(folder), "--to", "usd",
                          "--out", str(tmp_path / "b.usd"), "--check"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "check:     ok" in out.stdout and (tmp_path / "b.usd").is_file()


def test_continuous_joint_and_primitives(wheel_urdf_dir):
    res = export_usd(wheel_urdf_dir)
    assert res.joints == ["wheel_joint"]
    assert check_usd(res.path, wheel_urdf_dir) == []
    stage = Usd.Stage.Open(res.path)
    wheel = stage.GetDefaultPrim().GetChild("wheel")
    assert any(p.IsA(UsdGeom.Cylinder) for p in Usd.PrimRange(wheel))
    j = UsdPhysics.RevoluteJoint(stage.GetDefaultPrim().GetChild("joints").GetChild("wheel_joint"))
    assert j.GetLowerLimitAttr().Get() == -math.inf and j.GetUpperLimitAttr().Get() == math.inf
