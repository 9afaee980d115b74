"""PartNet-Mobility writer/loader: round trip of generated objects, yourdfpy loading, and a
hand-made folder with the real data's difficulties (y-up, multi-piece open OBJ links, nested
link frames, junk/free joints, a screw slider)."""
import json
import math

import numpy as np
import pytest
import yourdfpy

from model.core import JointType
from model.data import partnet, synth
from model.data.describe import describe

from helpers import built_object


@pytest.mark.parametrize("cat", list(synth.GENERATORS))
def test_round_trip_and_urdf_loads(tmp_path, cat):
    obj = built_object(5, 1, cat)
    folder = partnet.write_partnet(obj, tmp_path / cat, descriptions=describe(obj))
    for f in ("mobility.urdf", "mobility_v2.json", "semantics.txt", "meta.json", "descriptions.json"):
        assert (folder / f).exists(), f
    assert len(list((folder / "textured_objs").glob("*.obj"))) == len(obj.parts)
    urdf = yourdfpy.URDF.load(str(folder / "mobility.urdf"))
    n_dof = sum(p.joint.type.dof for p in obj.parts)
    assert len(urdf.actuated_joints) == n_dof          # a screw is two URDF joints
    back = partnet.load_partnet(folder)
    assert back.category == cat and [p.name for p in back.parts] == [p.name for p in obj.parts]
    for a, b in zip(obj.parts, back.parts):
        assert (a.label, a.parent, a.joint.type) == (b.label, b.parent, b.joint.type)
        assert np.allclose(a.token(), b.token(), atol=1e-5)
        assert np.allclose(a.mesh.vertices, b.mesh.vertices, atol=1e-5)
    assert back.metadata["descriptions"]["words"]
    # the URDF's own kinematics agrees with ours at an open pose
    cfg = {}
    T = obj.link_transforms(ratio=0.6)
    for i, p in enumerate(obj.parts):
        t, r = p.joint.value_at(0.6)
        if p.joint.type == JointType.SCREW:
            cfg[f"joint_{i}_slide"], cfg[f"joint_{i}"] = t, r
        elif p.joint.type != JointType.FIXED:
            cfg[f"joint_{i}"] = t if p.joint.type.translates else r
    urdf.update_cfg(cfg)
    for i, p in enumerate(obj.parts):
        M = urdf.get_transform(f"link_{i}", "base")
        v = p.mesh.vertices[:5]
        vis = urdf.link_map[f"link_{i}"].visuals[0].origin
        ours = (T[p.name] @ np.c_[v, np.ones(len(v))].T).T[:, :3]
        theirs = (M @ vis @ np.c_[v, np.ones(len(v))].T).T[:, :3]
        assert np.allclose(ours, theirs, atol=1e-6), p.name


# ---------------------------------------------------------------------------------------------
# hand-made y-up folder
# ---------------------------------------------------------------------------------------------
def _quad_obj(quads):
    """OBJ text of open quads (each its own 4 vertices: a non-watertight soup)."""
    lines, n = [], 0
    for q in quads:
        lines += [f"v {x} {y} {z}" for x, y, z in q]
        lines += [f"f {n + 1} {n + 2} {n + 3}", f"f {n + 1} {n + 3} {n + 4}"]
        n += 4
    return "\n".join(lines) + "\n"


def _box_quads(lo, hi, skip=()):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = {
        "-x": [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],
        "+x": [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],
        "-y": [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],
        "+y": [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],
        "-z": [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],
        "+z": [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
    }
    return [v for k, v in faces.items() if k not in skip]


@pytest.fixture()
def real_like_folder(tmp_path):
    """Cabinet in PartNet-Mobility conventions: OBJ y-up, front towards -z, metres-ish units.

    body (link_2) = 3 open pieces; drawer (link_0) slides along -z; door (link_1) hinges about
    +y at x = 0.4; handle (link_5) is fixed to the drawer through a nested link frame; cap
    (link_3) is a slider that rotates (screw); knob (link_4) hangs on a 'floating' junk joint.
    """
    d = tmp_path / "7128"
    (d / "textured_objs").mkdir(parents=True)
    W, H, D = 0.8, 1.0, 0.5                          # x, y (up), z (depth; front at z = -0.25)
    side = _box_quads((-0.4, 0, -0.25), (-0.38, H, 0.25)) + _box_quads((0.38, 0, -0.25), (0.4, H, 0.25))
    topbot = _box_quads((-0.38, 0, -0.25), (0.38, 0.02, 0.25)) + _box_quads((-0.38, H - 0.02, -0.25), (0.38, H, 0.25))
    back = _box_quads((-0.38, 0.02, 0.23), (0.38, H - 0.02, 0.25), skip=("-z",))   # open sheet set
    (d / "textured_objs" / "original-1.obj").write_text(_quad_obj(side))
    (d / "textured_objs" / "original-2.obj").write_text(_quad_obj(topbot))
    (d / "textured_objs" / "original-3.obj").write_text(_quad_obj(back))
    (d / "textured_objs" / "drawer.obj").write_text(_quad_obj(_box_quads((-0.37, 0.03, -0.25), (0.0, 0.3, 0.2), skip=("+y",))))
    (d / "textured_objs" / "door.obj").write_text(_quad_obj(_box_quads((0.0, 0.32, -0.25), (0.38, 0.97, -0.23))))
    (d / "textured_objs" / "handle.obj").write_text(_quad_obj(_box_quads((-0.25, 0.15, -0.28), (-0.1, 0.17, -0.25))))
    (d / "textured_objs" / "cap.obj").write_text(_quad_obj(_box_quads((-0.1, H, -0.05), (0.1, H + 0.05, 0.05))))
    (d / "textured_objs" / "knob.obj").write_text(_quad_obj(_box_quads((0.3, 0.9, -0.27), (0.34, 0.94, -0.25))))
    urdf = f"""<?xml version="1.0"?>
<robot name="partnet_7128">
  <link name="base"/>
  <link name="link_2">
    <visual name="frame-1"><origin xyz="0 0 0"/><geometry><mesh filename="textured_objs/original-1.obj"/></geometry></visual>
    <visual name="frame-2"><origin xyz="0 0 0"/><geometry><mesh filename="textured_objs/original-2.obj"/></geometry></visual>
    <visual name="frame-3"><origin xyz="0 0 0"/><geometry><mesh filename="textured_objs/original-3.obj"/></geometry></visual>
    <visual name="missing"><origin xyz="0 0 0"/><geometry><mesh filename="textured_objs/does-not-exist.obj"/></geometry></visual>
  </link>
  <joint name="joint_2" type="fixed">
    <origin rpy="1.570796326794897 0 -1.570796326794897" xyz="0 0 0"/>
    <child link="link_2"/><parent link="base"/>
  </joint>
  <link name="link_0">
    <visual><origin xyz="0 -0.1 0.25"/><geometry><mesh filename="textured_objs/drawer.obj"/></geometry></visual>
  </link>
  <joint name="joint_0" type="prismatic">
    <origin xyz="0 0.1 -0.25"/><axis xyz="0 0 -1"/>
    <child link="link_0"/><parent link="link_2"/><limit lower="0" upper="0.3"/>
  </joint>
  <link name="link_5">
    <visual><origin xyz="-0.1 -0.1 0.25"/><geometry><mesh filename="textured_objs/handle.obj"/></geometry></visual>
  </link>
  <joint name="joint_5" type="fixed">
    <origin xyz="0.1 0 0"/><child link="link_5"/><parent link="link_0"/>
  </joint>
  <link name="link_1">
    <visual><origin xyz="-0.38 0 0.25"/><geometry><mesh filename="textured_objs/door.obj"/></geometry></visual>
  </link>
  <joint name="joint_1" type="revolute">
    <origin xyz="0.38 0 -0.25"/><axis xyz="0 1 0"/>
    <child link="link_1"/><parent link="link_2"/><limit lower="-1.5707963" upper="0"/>
  </joint>
  <link name="link_3">
    <visual><origin xyz="0 -{H} 0"/><geometry><mesh filename="textured_objs/cap.obj"/></geometry></visual>
  </link>
  <joint name="joint_3" type="prismatic">
    <origin xyz="0 {H} 0"/><axis xyz="0 1 0"/>
    <child link="link_3"/><parent link="link_2"/><limit lower="0" upper="0.02"/>
  </joint>
  <link name="link_4">
    <visual><origin xyz="0 0 0"/><geometry><mesh filename="textured_objs/knob.obj"/></geometry></visual>
  </link>
  <joint name="joint_4" type="floating">
    <origin xyz="0 0 0"/><child link="link_4"/><parent link="link_2"/>
  </joint>
</robot>
"""
    (d / "mobility.urdf").write_text(urdf)
    v2 = [
        {"id": 2, "parent": -1, "joint": "heavy", "name": "furniture_body", "parts": [], "jointData": {}},
        {"id": 0, "parent": 2, "joint": "slider", "name": "drawer", "parts": [],
         "jointData": {"axis": {"origin": [0, 0.1, -0.25], "direction": [0, 0, -1]},
                       "limit": {"a": 0, "b": 0.3, "noLimit": False, "rotates": False}}},
        {"id": 1, "parent": 2, "joint": "hinge", "name": "rotation_door", "parts": [],
         "jointData": {"axis": {"origin": [0.38, 0, -0.25], "direction": [0, 1, 0]},
                       "limit": {"a": -90, "b": 0, "noLimit": False}}},
        {"id": 3, "parent": 2, "joint": "slider", "name": "cap", "parts": [],
         "jointData": {"axis": {"origin": [0, H, 0], "direction": [0, 1, 0]},
                       "limit": {"a": 0, "b": 0.02, "noLimit": False, "rotates": True,
                                 "rotates_limit": {"a": 0, "b": 720, "noLimit": False}}}},
        {"id": 4, "parent": 2, "joint": "junk", "name": "knob", "parts": [], "jointData": {}},
        {"id": 5, "parent": 0, "joint": "static", "name": "handle", "parts": [], "jointData": {}},
    ]
    (d / "mobility_v2.json").write_text(json.dumps(v2))
    (d / "semantics.txt").write_text("link_0 slider drawer\nlink_1 hinge rotation_door\nlink_2 heavy furniture_body\n"
                                     "link_3 slider cap\nlink_4 junk knob\nlink_5 static handle\n")
    (d / "meta.json").write_text(json.dumps({"model_cat": "StorageFurniture", "anno_id": "7128"}))
    (d / "description.txt").write_text("A cabinet with one drawer and one door.\n")
    return d


def test_loader_reads_real_like_folder(real_like_folder):
    obj = partnet.load_partnet(real_like_folder)
    by = {p.label: p for p in obj.parts}
    assert obj.category == "StorageFurniture"
    assert sorted(by) == ["body", "cap", "door", "drawer", "handle", "knob"]
    body = by["body"]
    # three open pieces merged into one part; missing OBJ skipped without a crash
    assert len(body.mesh.faces) == 2 * (12 + 12 + 5) and not body.mesh.is_watertight
    # y-up → z-up: height (OBJ y = 1.0) is now z; width (OBJ x = 0.8) is y; depth 0.5 is x
    assert np.allclose(body.bbox_size, [0.5, 0.8, 1.0], atol=1e-6)
    assert np.allclose(body.bbox_center, [-0.015, 0.0, 0.5], atol=1e-6)   # handle sticks out 3 cm in front
    lo = np.min([p.mesh.bounds[0] for p in obj.parts], axis=0)
    hi = np.max([p.mesh.bounds[1] for p in obj.parts], axis=0)
    assert abs(lo[2]) < 1e-9 and np.allclose((lo[:2] + hi[:2]) / 2, 0, atol=1e-9)
    # the front (OBJ -z) faces +x: the drawer slides along +x, the handle sits in front
    dr = by["drawer"].joint
    assert dr.type == JointType.PRISMATIC and np.allclose(dr.axis, [1, 0, 0]) and dr.t_range == (0.0, 0.3)
    assert by["handle"].mesh.bounds[1][0] > body.mesh.bounds[1][0]
    assert obj.parts[by["handle"].parent].label == "drawer"
    door = by["door"].joint
    assert door.type == JointType.REVOLUTE and np.allclose(np.abs(door.axis), [0, 0, 1])
    assert door.r_range == pytest.approx((-math.pi / 2, 0.0))
    cap = by["cap"].joint
    assert cap.type == JointType.SCREW and np.allclose(cap.axis, [0, 0, 1])
    assert cap.t_range == (0.0, 0.02) and cap.r_range == pytest.approx((0.0, 4 * math.pi))
    assert by["knob"].joint.type == JointType.FIXED               # floating / junk → fixed
    # nested frames: the handle mesh lands where the OBJ put it (x ≈ -0.25..-0.1 in OBJ → y)
    h = by["handle"].mesh.bounds
    assert np.allclose([h[0][1], h[1][1]], [0.1, 0.25], atol=1e-6)
    assert obj.metadata["descriptions"]["sentence"] == ["A cabinet with one drawer and one door."]
    # moving the drawer by its limit moves it (and its handle) 0.3 along +x
    T = obj.link_transforms(ratio=1.0)
    assert np.allclose(T[by["handle"].name][:3, 3], [0.3, 0, 0])
    obj.validate()


def test_loader_dataset_walk_never_raises(tmp_path, real_like_folder):
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "mobility.urdf").write_text("<robot><link name='a'/><link name='b'/></robot>")  # two roots
    got = list(partnet.iter_partnet_dataset(tmp_path))
    assert len(got) == 2
    errs = {f.name: e for f, o, e in got}
    assert errs["7128"] is None and "root" in errs["broken"]


def test_prepare_makes_real_like_folder_watertight(tmp_path, real_like_folder):
    from model.data.format import load_part_arrays, load_record
    from model.data.preprocess import PrepareConfig, prepare_dataset
    m = prepare_dataset(PrepareConfig(src=str(real_like_folder.parent), out=str(tmp_path / "prep"), points=256,
                                      samples=1024, workers=1, shell_resolution=48), progress=False)
    assert not m["errors"]
    oid = [i for s in m["splits"].values() for i in s][0]
    rec = load_record(tmp_path / "prep", oid)
    arr = load_part_arrays(tmp_path / "prep", oid)
    assert arr["sdf"].shape == (6, 1024, 4) and arr["points"].shape == (6, 256, 3)
    body_k = rec.labels.index("body")
    # the shell has an inside: some samples are negative, and surface points are within ~2 voxels
    assert (arr["sdf"][body_k, :, 3] < 0).any()
    assert rec.descriptions["sentence"] == ["A cabinet with one drawer and one door."]
    import trimesh
    from model.core import meshops
    mesh = trimesh.load(str(tmp_path / "prep" / "meshes" / oid / f"{body_k}.obj"), force="mesh")
    assert meshops.volume(mesh) > 0


def test_every_written_urdf_loads(tmp_path):
    """A synthesized sample (the `artformer data synth` path): every mobility.urdf loads in
    yourdfpy with its meshes, and our loader reads every folder back."""
    from model.data.synth import synthesize_dataset
    info = synthesize_dataset(str(tmp_path / "s"), 6, seed=21, workers=1, progress=False)
    assert not info["errors"]
    folders = partnet.find_object_folders(tmp_path / "s")
    assert len(folders) == 6
    for f in folders:
        urdf = yourdfpy.URDF.load(str(f / "mobility.urdf"))
        assert urdf.scene is not None and len(urdf.scene.geometry) == len(list((f / "textured_objs").glob("*.obj")))
        assert urdf.actuated_joints
        partnet.load_partnet(f).validate()
