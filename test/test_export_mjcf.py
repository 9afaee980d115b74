"""MJCF conversion: Menagerie layout, loads in MuJoCo with every URDF joint, body poses match
the URDF's kinematics (yourdfpy), each actuator drives its joint across its range."""
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")
from lxml import etree  # noqa: E402

from model.core.example import example_objects  # noqa: E402
from model.export.mjcf import drive_check, export_mjcf  # noqa: E402
from model.export.urdf import export_object  # noqa: E402
from model.export.urdfmodel import ConvertError, read_urdf_folder  # noqa: E402


@pytest.fixture(scope="module")
def examples(tmp_path_factory, exported_examples):
    root = tmp_path_factory.mktemp("mjcf")
    out = {}
    for name, (_, res) in exported_examples.items():
        shutil.copytree(res.out_dir, root / name)
        out[name] = (root / name, export_mjcf(root / name))
    return out


def _yourdfpy_frames(urdf_path, values):
    import yourdfpy
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        u = yourdfpy.URDF.load(str(urdf_path), build_scene_graph=True, load_meshes=False)
        u.update_cfg(np.array([values.get(n, 0.0) for n in u.actuated_joint_names]))
        return {ln: u.get_transform(ln, u.base_link) for ln in u.link_map}


@pytest.mark.parametrize("name", ["cabinet", "bottle"])
def test_menagerie_layout(examples, name):
    folder, res = examples[name]
    out = Path(res.out_dir)
    assert out == folder / "mjcf"
    assert Path(res.model_xml).is_file() and Path(res.scene_xml).name == "scene.xml"
    scene = etree.parse(res.scene_xml).getroot()
    assert scene.find("include").get("file") == Path(res.model_xml).name
    assert scene.find("worldbody/geom[@type='plane']") is not None
    assert scene.find("worldbody/light") is not None
    model = etree.parse(res.model_xml).getroot()
    assert model.find("compiler").get("meshdir") == "assets"
    files = {m.get("file") for m in model.iter("mesh")}
    assert files and files == {p.name for p in (out / "assets").iterdir()}
    # every URDF collision piece is there, boxes as boxes and meshes as meshes
    urdf = read_urdf_folder(folder)
    for link in urdf.links.values():
        body = model.find(f".//body[@name='{link.name}']")
        if link.name.endswith("_screw_helper"):
            assert body is None            # merged into its child body
            continue
        cols = body.findall("geom[@class='collision']")
        assert [g.get("type") for g in cols] == [c.kind for c in link.collisions]
        inert = body.find("inertial")
        assert float(inert.get("mass")) == pytest.approx(link.mass, rel=1e-6)
    # one position actuator per actuated joint, kp > 0, range = joint range
    for act in model.find("actuator"):
        assert act.tag == "position" and float(act.get("kp")) > 0
        j = model.find(f".//joint[@name='{act.get('joint')}']")
        assert act.get("ctrlrange") == j.get("range")


@pytest.mark.parametrize("name", ["cabinet", "bottle"])
def test_loads_with_every_joint_and_matches_urdf_kinematics(examples, name):
    folder, res = examples[name]
    urdf = read_urdf_folder(folder)
    m = mujoco.MjModel.from_xml_path(res.scene_xml)
    d = mujoco.MjData(m)
    for j in urdf.moving_joints():
        jm = m.joint(j.name)
        assert jm.range.tolist() == pytest.approx([j.lower, j.upper])
    lift = m.body(urdf.root).pos.copy()
    assert lift[:2].tolist() == [0.0, 0.0] and lift[2] >= 0
    for r in (0.0, 0.5, 1.0):
        vals = {j.name: j.lower + r * (j.upper - j.lower) for j in urdf.moving_joints()}
        d.qpos[:] = 0
        for n, v in vals.items():
            d.qpos[m.joint(n).qposadr[0]] = v
        mujoco.mj_kinematics(m, d)
        want = _yourdfpy_frames(urdf.path, vals)
        for link in urdf.links:
            if link.endswith("_screw_helper"):
                continue
            b = m.body(link).id
            assert np.allclose(d.xpos[b] - lift, want[link][:3, 3], atol=1e-6), (link, r)
            assert np.allclose(d.xmat[b].reshape(3, 3), want[link][:3, :3], atol=1e-6)


@pytest.mark.parametrize("name", ["cabinet", "bottle"])
def test_every_actuator_drives_its_joint(examples, name):
    _, res = examples[name]
    rep = drive_check(res.scene_xml, res.joints)
    assert rep.ok, rep
    assert set(rep.reached) == set(res.actuators)


def test_object_stands_on_the_floor(examples):
    _, res = examples["cabinet"]
    m = mujoco.MjModel.from_xml_path(res.scene_xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    lows = [d.geom_xpos[g][2] - m.geom_rbound[g] for g in range(m.ngeom)
            if m.geom_bodyid[g] > 0]
    # lowest collision/visual point sits on z = 0 (bounding spheres reach below it)
    assert min(lows) < 0.05
    floor = m.geom("floor").id
    deepest = [-d.contact.dist[i] for i in range(d.ncon)
               if floor in (d.contact.geom1[i], d.contact.geom2[i])]
    assert max(deepest, default=0.0) < 1e-3


def test_screw_is_one_body_with_a_coupled_slide(examples):
    _, res = examples["bottle"]
    assert res.couplings == {"cap_slide": "cap_joint"}
    assert res.actuators == ["cap_joint"]
    m = mujoco.MjModel.from_xml_path(res.scene_xml)
    d = mujoco.MjData(m)
    hinge, slide = m.joint("cap_joint"), m.joint("cap_slide")
    assert hinge.bodyid[0] == slide.bodyid[0] == m.body("cap").id
    d.ctrl[m.actuator("cap_joint").id] = hinge.range[1]
    for _ in range(1500):
        mujoco.mj_step(m, d)
    q_h, q_s = d.qpos[hinge.qposadr[0]], d.qpos[slide.qposadr[0]]
    assert q_h == pytest.approx(hinge.range[1], rel=0.02)
    ratio = (slide.range[1] - slide.range[0]) / (hinge.range[1] - hinge.range[0])
    assert q_s == pytest.approx(slide.range[0] + ratio * (q_h - hinge.range[0]), abs=2e-4)


def test_floating_base_falls_onto_the_floor(tmp_path, examples):
    folder, _ = examples["cabinet"]
    res = export_mjcf(folder, tmp_path / "floating", floating=True)
    m = mujoco.MjModel.from_xml_path(res.scene_xml)
    d = mujoco.MjData(m)
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    z0 = float(d.qpos[2])
    d.qpos[2] += 0.05                       # drop it from 5 cm
    for _ in range(1000):
        mujoco.mj_step(m, d)
    assert np.all(np.isfinite(d.qpos))
    assert abs(d.qpos[2] - z0) < 0.01       # back on the floor, not through it


def test_glb_visuals_become_obj(tmp_path):
    obj = example_objects()["cabinet"]
    export_object(obj, tmp_path / "glb", mesh_format="glb", preview=False)
    res = export_mjcf(tmp_path / "glb")
    assets = sorted(p.suffix for p in (Path(res.out_dir) / "assets").iterdir())
    assert ".glb" not in assets and ".obj" in assets and ".stl" in assets
    assert drive_check(res.scene_xml, res.joints).loaded


def test_bad_input_is_a_clear_error(tmp_path):
    with pytest.raises(ConvertError, match="does not exist"):
        export_mjcf(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ConvertError, match="0 .urdf files"):
        export_mjcf(tmp_path / "empty")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "x.urdf").write_text("<robot name='x'><link name='a'/><joint name='j' type='planar'>"
                                "<parent link='a'/><child link='b'/></joint></robot>")
    with pytest.raises(ConvertError, match="planar"):
        export_mjcf(bad)


def test_cli(examples, tmp_path):
    folder, _ = examples["bottle"]
    out = subprocess.run([sys.executable, "-m", "model", "convert", str(folder), "--to", "mjcf",
                          "--out", str(tmp_path / "m"), "--check"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "check:     ok" in out.stdout and (tmp_path / "m" / "scene.xml").is_file()
    out = subprocess.run([sys.executable, "-m", "model", "convert", str(tmp_path / "nope"),
                          "--to", "mjcf"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 1 and "does not exist" in out.stderr


def test_continuous_joint_and_primitives(wheel_urdf_dir):
    res = export_mjcf(wheel_urdf_dir)
    m = mujoco.MjModel.from_xml_path(res.scene_xml)
    j = m.joint("wheel_joint")
    assert j.type[0] == mujoco.mjtJoint.mjJNT_HINGE and not m.jnt_limited[j.id]
    assert {mujoco.mjtGeom(t).name for t in m.geom_type} >= {"mjGEOM_BOX", "mjGEOM_CYLINDER"}
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    lift = m.body("base").pos[2]
    assert np.allclose(d.xpos[m.body("wheel").id] - [0, 0, lift], [0.2, 0.12, -0.05], atol=1e-9)
    assert drive_check(res.scene_xml, res.joints).ok


def test_flat_visual_kept_degenerate_collision_dropped(tmp_path):
    import trimesh
    (tmp_path / "meshes").mkdir()
    trimesh.Trimesh(vertices=[[0, 0, 0], [0.2, 0, 0], [0, 0.2, 0], [0.2, 0.2, 0]],
                    faces=[[0, 1, 2], [1, 3, 2]]).export(tmp_path / "meshes" / "panel.obj")
    trimesh.Trimesh(vertices=[[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]],
                    faces=[[0, 1, 2]]).export(tmp_path / "meshes" / "sliver.obj")
    (tmp_path / "p.urdf").write_text(
        "<robot name='p'><link name='base'><inertial><mass value='1'/>"
        "<inertia ixx='0.01' iyy='0.01' izz='0.01' ixy='0' ixz='0' iyz='0'/></inertial>"
        "<visual><geometry><mesh filename='meshes/panel.obj'/></geometry></visual>"
        "<collision><geometry><mesh filename='meshes/sliver.obj'/></geometry></collision>"
        "<collision><geometry><box size='0.2 0.2 0.01'/></geometry></collision></link></robot>")
    res = export_mjcf(tmp_path)
    assert res.dropped_meshes == ["base: sliver.obj"]
    m = mujoco.MjModel.from_xml_path(res.scene_xml)
    types = [mujoco.mjtGeom(t).name for t, b in zip(m.geom_type, m.geom_bodyid) if b > 0]
    assert sorted(types) == ["mjGEOM_BOX", "mjGEOM_MESH"]      # the flat panel is shown


@pytest.mark.parametrize("name", ["cabinet", "bottle"])
def test_mjcf_passes_the_audit_physics_check_as_its_urdf_does(examples, name):
    from model.export.physics import physics_check

    folder, res = examples[name]
    urdf = physics_check(next(folder.glob("*.urdf")))
    mjcf = physics_check(res.model_xml)
    assert urdf.ok, urdf.failures
    assert mjcf.ok, mjcf.failures


def test_effort_and_servo_gains_follow_the_shared_rule(examples):
    from model.export.mjcf import servo_gains

    folder, res = examples["cabinet"]
    urdf = read_urdf_folder(folder)
    root = etree.parse(res.model_xml).getroot()
    joints = {j.name: j for j in urdf.joints}
    for act in root.find("actuator"):
        j = joints[act.get("joint")]
        el = root.find(f".//joint[@name='{j.name}']")
        assert [float(v) for v in el.get("actuatorfrcrange").split()] == [-j.effort, j.effort]
        # the stiffer of the two rules: the effort at a tenth of the range off target
        assert float(act.get("kp")) >= j.effort / (0.1 * (j.upper - j.lower)) * (1 - 1e-5)
        assert float(el.get("armature")) >= 0.01
    kp, kv, arm = servo_gains(0.02, 10.0, 1.0, hz=4.0)
    assert kp == pytest.approx(100.0) and arm >= 0.01
    assert kv == pytest.approx(2 * np.sqrt(kp * (0.02 + arm)))
    kp, _, _ = servo_gains(2.0, 0.0, 1.0, hz=4.0)
    assert kp == pytest.approx(2.0 * (2 * np.pi * 4.0) ** 2)
