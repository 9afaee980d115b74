"""URDF export of the example objects: files, URDF content, inertia, collision, real consumers
(yourdfpy, pybullet, MuJoCo) with every joint moved and poses against our FK, atomic writes."""
import json
import os
from pathlib import Path

import numpy as np
import pytest

from model.core import JointType, ObjectValidationError
from model.core.example import example_objects
from model.export.simcheck import check_urdf
from model.export.urdf import CollisionConfig, export_object, mass_properties


@pytest.fixture(scope="module")
def objects():
    return example_objects()


@pytest.fixture(scope="module")
def exported(objects, tmp_path_factory):
    root = tmp_path_factory.mktemp("export")
    out = {}
    for name, obj in objects.items():
        out[name] = export_object(obj, root / name,
                                  provenance={"prompt": "a test -- object", "seed": 7,
                                              "checkpoint_sha256": "abc123"})
    return out


def _xml(path):
    from lxml import etree
    return etree.parse(str(path)).getroot()


def test_folder_layout(exported):
    for name, res in exported.items():
        d = Path(res.out_dir)
        assert Path(res.urdf_path).is_file() and Path(res.metadata_path).is_file()
        assert Path(res.preview_path).is_file()
        assert all(Path(p).is_file() and p.endswith(".obj") for p in res.mesh_paths.values())
        leftovers = [p for p in d.parent.iterdir() if p.name.startswith(".")]
        assert not leftovers, leftovers                         # atomic: no temp folders
        for f in [d, *d.rglob("*")]:                            # readable by other users
            assert f.stat().st_mode & 0o004, f


def test_urdf_content(exported, objects):
    root = _xml(exported["cabinet"].urdf_path)
    links = {l.get("name") for l in root.findall("link")}
    assert links == {p.name for p in objects["cabinet"].parts}
    types = {j.get("name"): j.get("type") for j in root.findall("joint")}
    assert types == {"drawer_0_joint": "prismatic", "drawer_1_joint": "prismatic",
                     "door_joint": "revolute", "door_handle_joint": "fixed"}
    door = [j for j in root.findall("joint") if j.get("name") == "door_joint"][0]
    assert float(door.find("limit").get("upper")) == pytest.approx(np.radians(100))
    assert float(door.find("limit").get("effort")) > 0
    # Joint origin is origin_child - origin_parent; visuals sit at -origin_child.
    cab = objects["cabinet"]
    handle = cab.parts[cab.index_of("door_handle")]
    door_part = cab.parts[cab.index_of("door")]
    hj = [j for j in root.findall("joint") if j.get("name") == "door_handle_joint"][0]
    np.testing.assert_allclose([float(v) for v in hj.find("origin").get("xyz").split()],
                               handle.bbox_center - door_part.joint.origin, atol=1e-12)
    for link in root.findall("link"):
        assert link.find("visual/geometry/mesh").get("filename").startswith("file:///")
        assert link.findall("collision"), link.get("name")
    # Provenance comment (the "--" of the prompt is made XML-safe).
    comments = [c.text for c in root.iter() if c.tag is __import__("lxml").etree.Comment]
    assert comments and '"seed": 7' in comments[0] and "abc123" in comments[0]
    assert "package_version" in comments[0] and "a test - - object" in comments[0]


def test_screw_becomes_prismatic_helper_revolute(exported):
    root = _xml(exported["bottle"].urdf_path)
    joints = {j.get("name"): j for j in root.findall("joint")}
    assert joints["cap_slide"].get("type") == "prismatic"
    assert joints["cap_slide"].find("child").get("link") == "cap_screw_helper"
    assert joints["cap_joint"].get("type") == "revolute"
    assert joints["cap_joint"].find("parent").get("link") == "cap_screw_helper"
    helper = [l for l in root.findall("link") if l.get("name") == "cap_screw_helper"][0]
    assert 0 < float(helper.find("inertial/mass").get("value")) < 1e-5
    assert helper.find("visual") is None


def test_metadata(exported, objects):
    meta = json.loads(Path(exported["cabinet"].metadata_path).read_text())
    assert meta["category"] == "StorageFurniture"
    assert meta["summary"] == objects["cabinet"].summary()
    assert {p["label"] for p in meta["parts"]} == {"body", "drawer", "door", "handle"}
    assert meta["provenance"]["seed"] == 7 and meta["provenance"]["prompt"] == "a test -- object"
    bottle = json.loads(Path(exported["bottle"].metadata_path).read_text())
    cap = [p for p in bottle["parts"] if p["name"] == "cap"][0]
    assert cap["joint_type"] == "screw" and cap["urdf_joints"] == ["cap_slide", "cap_joint"]


def test_inertia_positive_definite_and_mass_from_volume(exported, objects):
    root = _xml(exported["cabinet"].urdf_path)
    for link in root.findall("link"):
        i = link.find("inertial/inertia").attrib
        I = np.array([[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]],
                      [i["ixz"], i["iyz"], i["izz"]]], dtype=float)
        w = np.linalg.eigvalsh(I)
        assert w.min() > 0, link.get("name")
        assert w[0] + w[1] >= w[2] * (1 - 1e-9)                     # triangle inequality
    body = objects["cabinet"].parts[0]
    mass = float(root.find("link[@name='body']/inertial/mass").get("value"))
    assert mass == pytest.approx(600.0 * body.mesh.volume, rel=1e-6)


def test_mass_properties_robust_for_open_and_flat_meshes():
    import trimesh
    box = trimesh.creation.box(extents=(0.2, 0.1, 0.05))
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-2])         # one face missing
    assert not open_box.is_watertight
    m, com, I = mass_properties(open_box, 1000.0)
    assert m == pytest.approx(1000 * 0.2 * 0.1 * 0.05, rel=1e-6)    # via the convex hull
    assert np.linalg.eigvalsh(I).min() > 0
    flat = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    m, com, I = mass_properties(flat, 1000.0)
    assert m > 0 and np.linalg.eigvalsh(I).min() > 0
    m, com, I = mass_properties(None, 1000.0)
    assert m > 0 and np.linalg.eigvalsh(I).min() > 0


def test_body_collision_keeps_the_openings(exported, objects):
    """The carcass collision is several convex pieces, not one hull a gripper cannot enter."""
    import trimesh
    mesh_dir = Path(exported["cabinet"].out_dir) / "meshes"
    pieces = [trimesh.load(p, force="mesh") for p in sorted(mesh_dir.glob("body_collision_*.obj"))]
    assert len(pieces) > 4
    probes = np.array([[0.0, 0.0, 0.25], [0.0, 0.0, 0.57], [0.0, 0.0, 0.78]])  # compartments
    inside = np.zeros(len(probes), dtype=bool)
    for p in pieces:
        inside |= p.contains(probes)
    assert not inside.any()
    # Nearly convex parts (the door panel) get a single hull.
    assert len(list(mesh_dir.glob("door_collision_*.obj"))) == 1


@pytest.mark.parametrize("name", ["cabinet", "bottle"])
def test_collision_geometry_is_clear_at_rest_and_stays_put(exported, name):
    """No collision piece touches another part at rest (MuJoCo finds no contact), so under
    gravity the drawers stay shut instead of being pushed out by overlapping hulls."""
    import mujoco
    m = mujoco.MjModel.from_xml_path(exported[name].urdf_path)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert d.ncon == 0, [(m.body(m.geom_bodyid[c.geom1]).name, m.body(m.geom_bodyid[c.geom2]).name)
                         for c in d.contact[:d.ncon]]
    mujoco.mj_step(m, d, nstep=250)                     # 0.5 s with gravity
    assert np.abs(d.qpos).max() < 2e-3, d.qpos


def test_collision_methods(objects):
    from model.export.collision import cells_decompose, collision_pieces, vhacd_decompose
    from model.core import meshops
    cab = objects["cabinet"]
    body, drawer = cab.parts[0].mesh, cab.parts[1].mesh
    cells = cells_decompose(body)
    assert 3 < len(cells) <= 32
    assert sum(p.volume for p in cells) == pytest.approx(body.volume, rel=0.02)   # tight
    assert sum(meshops.intersection_volume(p, drawer) for p in cells) < 1e-9
    hull = collision_pieces(body, CollisionConfig(method="hull"))
    assert len(hull) == 1 and meshops.intersection_volume(hull[0], drawer) > 1e-3  # a block
    assert collision_pieces(body, CollisionConfig(method="none")) == []
    # The bottle body is nearly convex, but its hull would swallow the cap: not used.
    bottle = objects["bottle"]
    pcs = collision_pieces(bottle.parts[0].mesh, obstacles=[bottle.parts[1].mesh])
    assert len(pcs) > 1
    assert len(collision_pieces(bottle.parts[0].mesh)) == 1
    v = vhacd_decompose(cab.parts[cab.index_of("door_handle")].mesh, CollisionConfig(max_hulls=4))
    assert 1 <= len(v) <= 4 and all(p.is_volume for p in v)
    with pytest.raises(ValueError, match="unknown collision method"):
        collision_pieces(body, CollisionConfig(method="magic"))


@pytest.mark.parametrize("name", ["cabinet", "bottle"])
def test_loads_in_simulators_joints_move_and_poses_match(exported, objects, name):
    rep = check_urdf(exported[name].urdf_path, objects[name])
    assert set(rep.sims) == {"yourdfpy", "pybullet", "mujoco", "pinocchio"}
    for sim, r in rep.sims.items():
        assert r.loaded and r.joints_movable, (sim, r.error)
        assert r.num_joints == (3 if name == "cabinet" else 2)
        assert r.max_position_error < 1e-4 and r.max_rotation_error < 1e-4, (sim, r)
    assert rep.ok, rep.summary()
    assert rep.to_dict()["ok"] is True


def test_fixed_part_frame_sits_on_the_part_whatever_its_decoded_origin(objects, tmp_path):
    # A decoded fixed joint's origin is noise (metres off at times); the handle's link frame
    # (its TF frame in RViz) is at its box centre, and the simulators still agree with our FK.
    cab = objects["cabinet"].copy()
    handle = cab.parts[cab.index_of("door_handle")]
    handle.joint.origin = np.array([-2.0, 0.8, -4.4])
    res = export_object(cab, tmp_path / "far")
    hj = [j for j in _xml(res.urdf_path).findall("joint") if j.get("name") == "door_handle_joint"][0]
    door = cab.parts[cab.index_of("door")]
    np.testing.assert_allclose([float(v) for v in hj.find("origin").get("xyz").split()],
                               handle.bbox_center - door.joint.origin, atol=1e-12)
    rep = check_urdf(res.urdf_path, cab)
    assert rep.ok, rep.summary()


def test_simcheck_detects_pose_mismatch(exported, objects):
    wrong = objects["cabinet"].copy()
    d = wrong.parts[wrong.index_of("drawer_0")]
    d.joint.t_range = (0.0, 0.25)                 # the URDF says 0.30
    rep = check_urdf(exported["cabinet"].urdf_path, wrong)
    assert not rep.ok
    assert rep.sims["mujoco"].max_position_error == pytest.approx(0.05, abs=1e-6)


def test_simcheck_reports_instead_of_raising(tmp_path):
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/>")
    rep = check_urdf(bad)
    assert not rep.ok and all("cannot read URDF" in r.error for r in rep.sims.values())


def test_package_uri(objects, tmp_path):
    res = export_object(objects["bottle"], tmp_path / "b", mesh_uri="package://my_pkg/objects/b",
                        preview=False, collision=CollisionConfig(method="hull"))
    root = _xml(res.urdf_path)
    fns = [m.get("filename") for m in root.iter("mesh")]
    assert fns and all(f.startswith("package://my_pkg/objects/b/meshes/") for f in fns)
    assert check_urdf(res.urdf_path, objects["bottle"]).ok          # resolves beside the URDF
    with pytest.raises(ValueError, match="mesh_uri"):
        export_object(objects["bottle"], tmp_path / "c", mesh_uri="http://x")


@pytest.mark.parametrize("fmt", ["stl", "glb"])
def test_stl_and_glb_export(objects, tmp_path, fmt):
    res = export_object(objects["bottle"], tmp_path / fmt, mesh_format=fmt, preview=False,
                        collision=CollisionConfig(method="hull"))
    assert all(p.endswith("." + fmt) for p in res.mesh_paths.values())
    coll = list((Path(res.out_dir) / "meshes").glob("*_collision_*"))
    assert coll and all(p.suffix == ".stl" for p in coll)           # simulators read STL
    rep = check_urdf(res.urdf_path, objects["bottle"])
    assert rep.ok, rep.summary()
    if fmt == "glb":
        assert "cannot read" in rep.sims["mujoco"].note


def test_reexport_replaces_atomically(objects, tmp_path, monkeypatch):
    out = tmp_path / "obj"
    cfg = CollisionConfig(method="hull")
    export_object(objects["bottle"], out, preview=False, collision=cfg)
    (out / "stale.txt").write_text("old")
    export_object(objects["bottle"], out, preview=False, collision=cfg)
    assert not (out / "stale.txt").exists()                         # replaced as a whole
    # A failure half-way leaves the previous folder intact and no temp folders behind.
    (out / "marker.txt").write_text("keep")
    import model.export.render as render

    def boom(*a, **k):
        raise RuntimeError("renderer exploded")
    monkeypatch.setattr(render, "write_preview", boom)
    with pytest.raises(RuntimeError, match="exploded"):
        export_object(objects["bottle"], out, preview=True, collision=cfg)
    assert (out / "marker.txt").read_text() == "keep"
    assert sorted(os.listdir(tmp_path)) == ["obj"]


@pytest.mark.parametrize("mutate, message", [
    (lambda o: setattr(o.parts[1], "parent", 1), "own parent"),
    (lambda o: setattr(o.parts[1].joint, "origin", np.array([0, np.nan, 0])), "NaN"),
    (lambda o: setattr(o.parts[1].joint, "t_range", (0.3, 0.0)), "limits inverted"),
])
def test_broken_objects_are_refused_before_writing(objects, tmp_path, mutate, message):
    obj = objects["cabinet"].copy()
    mutate(obj)
    with pytest.raises(ObjectValidationError, match=message):
        export_object(obj, tmp_path / "x")
    assert os.listdir(tmp_path) == []


def test_continuous_joint_has_no_position_limits(objects, tmp_path):
    obj = objects["bottle"].copy()
    cap = obj.parts[1]
    cap.joint.type = JointType.CONTINUOUS
    cap.joint.t_range = (0.0, 0.0)
    res = export_object(obj, tmp_path / "c", preview=False, collision=CollisionConfig(method="hull"))
    j = _xml(res.urdf_path).find("joint")
    assert j.get("type") == "continuous"
    assert j.find("limit").get("lower") is None and j.find("limit").get("upper") is None
    assert check_urdf(res.urdf_path, obj).ok


def test_object_without_meshes_exports_and_loads(objects, tmp_path):
    """Tokens only (no geometry yet): links without visuals, still valid for the simulators."""
    from model.core import ArticulatedObject
    toks, types, parents, labels = objects["cabinet"].tokens()
    obj = ArticulatedObject.from_tokens(toks, types, parents, labels, category="StorageFurniture")
    res = export_object(obj, tmp_path / "bare")
    assert res.mesh_paths == {}
    rep = check_urdf(res.urdf_path, obj)
    assert rep.ok, rep.summary()


@pytest.mark.parametrize("kind", ["flat_quad", "one_triangle", "open_box"])
def test_degenerate_part_meshes_still_load_everywhere(objects, tmp_path, kind):
    """Generated geometry can be flat or open: collision becomes a thin box, MuJoCo (which
    rejects flat visual meshes) gets collision geometry only, the others keep the visuals."""
    import trimesh
    box = trimesh.creation.box(extents=(0.1, 0.2, 0.05),
                               transform=trimesh.transformations.translation_matrix((0.2, 0, 0.5)))
    mesh = {"flat_quad": trimesh.Trimesh([[0.2, 0, 0.5], [0.2, 0.1, 0.5], [0.2, 0.1, 0.6],
                                          [0.2, 0, 0.6]], [[0, 1, 2], [0, 2, 3]]),
            "one_triangle": trimesh.Trimesh([[0.2, 0, 0.5], [0.2, 0.1, 0.5], [0.2, 0.1, 0.6]],
                                            [[0, 1, 2]]),
            "open_box": trimesh.Trimesh(box.vertices, box.faces[:-2])}[kind]
    obj = objects["cabinet"].copy()
    obj.parts[obj.index_of("drawer_0")].mesh = mesh
    res = export_object(obj, tmp_path / kind, preview=False)
    rep = check_urdf(res.urdf_path, obj)
    assert rep.ok, rep.summary()
    meta = json.loads(Path(res.metadata_path).read_text())
    flat = kind != "open_box"
    assert meta["mujoco_visuals_discarded_for"] == (["drawer_0"] if flat else [])
    comp = _xml(res.urdf_path).find("mujoco/compiler")
    assert comp.get("discardvisual") == ("true" if flat else "false")


def test_simcheck_reports_collision_penetration(exported, objects, tmp_path):
    """Informational MuJoCo figure: our collision pieces never interpenetrate over the tested
    motion; a single hull per part (a solid carcass block) does, by decimetres."""
    rep = check_urdf(exported["cabinet"].urdf_path, objects["cabinet"])
    assert rep.sims["mujoco"].max_penetration == 0.0
    assert rep.sims["pybullet"].max_penetration is None
    res = export_object(objects["cabinet"], tmp_path / "hull", preview=False,
                        collision=CollisionConfig(method="hull"))
    rep = check_urdf(res.urdf_path, objects["cabinet"])
    assert rep.ok and rep.sims["mujoco"].max_penetration > 0.1


def test_folder_with_a_space_relative_uris_load_everywhere(objects, tmp_path, caplog):
    """file:// URIs of a folder with a space need %20, which pybullet does not decode: the
    exporter says so, and mesh_uri='relative' gives a URDF every simulator loads."""
    import logging
    folder = tmp_path / "with space"
    with caplog.at_level(logging.WARNING, logger="model.export.urdf"):
        export_object(objects["bottle"], folder / "file", preview=False,
                      collision=CollisionConfig(method="hull"))
    assert "pybullet does not" in caplog.text
    res = export_object(objects["bottle"], folder / "rel", preview=False, mesh_uri="relative",
                        collision=CollisionConfig(method="hull"))
    xml = Path(res.urdf_path).read_text()
    assert 'filename="./meshes/' in xml and "file://" not in xml
    rep = check_urdf(res.urdf_path, objects["bottle"])
    assert rep.ok, rep.summary()
