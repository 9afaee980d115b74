"""The physical audit on known cases: exact overlap ratios, a detached part, a hinge through a
door's middle, a floater, a URDF that falls over in MuJoCo, and the shipped examples."""
import json
import math
import os

import numpy as np
import pytest
import trimesh

from model.core import ArticulatedObject, Joint, JointType, Part
from model.metrics.audit import (AuditConfig, audit_object, audit_paths, audit_table,
                                 hinge_offset, mesh_health, overlaps, slide_angle_deg,
                                 write_contact_sheet)
from model.metrics.physics import physics_check

GEOMETRY_ONLY = AuditConfig(physics=False)


def _box(size, centre):
    m = trimesh.creation.box(extents=size)
    m.apply_translation(centre)
    return m


def _part(name, label, parent, size, centre, joint=None):
    p = Part(name=name, label=label, parent=parent, joint=joint or Joint(), mesh=_box(size, centre))
    p.fit_bbox_to_mesh()
    return p


def _two_boxes(shift: float) -> ArticulatedObject:
    """Two 0.2 m cubes fixed side by side on a far-away base; they overlap by 0.2 - shift
    along x."""
    parts = [_part("base_0", "body", -1, (0.1, 0.1, 0.1), (0, 2, 0.05)),
             _part("a_0", "other", 0, (0.2, 0.2, 0.2), (0, 0, 0.1)),
             _part("b_0", "other", 0, (0.2, 0.2, 0.2), (shift, 0, 0.1))]
    return ArticulatedObject(parts=parts, category="Test", name="two_boxes")


def test_overlap_ratio_is_exact():
    ratio, where = overlaps(_two_boxes(0.15))
    assert ratio == pytest.approx(0.05 / 0.2, rel=1e-4)      # 0.05 x 0.2 x 0.2 of 0.2³
    assert where[:2] == ("a_0", "b_0")
    assert overlaps(_two_boxes(0.2))[0] == pytest.approx(0.0, abs=1e-6)   # touching faces
    rep = audit_object(_two_boxes(0.15), config=GEOMETRY_ONLY)
    assert not rep.sim_ready and "overlap by 25.0%" in rep.failures[0]


def _cabinet(door_origin_y: float = -0.25, drawer_gap: float = 0.0, drawer_axis=(1, 0, 0)):
    """A 0.5 m box body, a door on its front (hinge at ``door_origin_y``), a drawer on top."""
    body = _part("body_0", "body", -1, (0.5, 0.5, 0.5), (0, 0, 0.25))
    door = _part("door_0", "door", 0, (0.02, 0.5, 0.5), (0.26, 0, 0.25),
                 Joint(JointType.REVOLUTE, (0.25, door_origin_y, 0.25), (0, 0, -1),
                       r_range=(0, 1.5)))
    drawer = _part("drawer_0", "drawer", 0, (0.4, 0.4, 0.1), (0, 0, 0.55 + drawer_gap),
                   Joint(JointType.PRISMATIC, (0, 0, 0.55), np.asarray(drawer_axis, float)
                         / np.linalg.norm(drawer_axis), t_range=(0, 0.2)))
    return ArticulatedObject(parts=[body, door, drawer], category="StorageFurniture", name="cab")


def test_sound_cabinet_passes_geometry():
    rep = audit_object(_cabinet(), config=GEOMETRY_ONLY)
    assert rep.sim_ready, rep.failures
    assert rep.hinges[0]["offset"] == pytest.approx(0.0, abs=1e-9)


def test_detached_part_is_reported():
    rep = audit_object(_cabinet(drawer_gap=0.05), config=GEOMETRY_ONLY)
    assert rep.max_gap == pytest.approx(0.05, abs=1e-4)
    assert any("drawer_0 is 50 mm from its parent" in f for f in rep.failures)


def test_hinge_through_the_middle_of_a_door():
    obj = _cabinet(door_origin_y=0.0)
    assert hinge_offset(obj.parts[1]) == pytest.approx(0.5, abs=1e-6)
    rep = audit_object(obj, config=GEOMETRY_ONLY)
    assert any("door_0 hinge" in f for f in rep.failures)
    # swinging about its middle, the door also sweeps into the body
    assert rep.max_overlap > 0.01


def test_a_postage_stamp_lid_is_no_lid():
    """A washer lid decoded 6 x 4 cm on the back face of a 60 cm machine passed every other
    check: a door or lid covers at least 2 % of its parent's face (the data's smallest
    2.9 %); the sound cabinet's door covers all of it."""
    from model.export.audit_checks import panel_cover
    assert panel_cover(_cabinet(), 1) == pytest.approx(1.0)
    obj = ArticulatedObject(category="WashingMachine", name="w", parts=[
        _part("body_0", "body", -1, (0.6, 0.6, 1.0), (0, 0, 0.5)),
        _part("lid_0", "lid", 0, (0.006, 0.06, 0.04), (-0.303, 0, 0.9),
              Joint(JointType.REVOLUTE, (-0.306, -0.03, 0.92), (0, 0, 1), r_range=(0, 1.5)))])
    assert panel_cover(obj, 1) == pytest.approx(0.06 * 0.04 / (0.6 * 1.0))
    rep = audit_object(obj, config=GEOMETRY_ONLY)
    assert "lid_0 covers 0.4% of its parent's face" in " ".join(rep.failures)
    assert not rep.hinges[0]["ok"] and not rep.sim_ready
    assert audit_object(obj, config=AuditConfig(physics=False, min_panel_cover=0.0)).sim_ready


def test_tilted_drawer_axis():
    obj = _cabinet(drawer_axis=(1, 0, 1))          # the top drawer leaves through the top face
    assert slide_angle_deg(obj, 2) == pytest.approx(45.0, abs=1e-6)
    assert slide_angle_deg(_cabinet(drawer_axis=(0, 0, 1)), 2) == pytest.approx(0.0, abs=1e-6)


def test_floater_faces_counted():
    main = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    speck = _box((0.01, 0.01, 0.01), (1, 1, 1))
    h = mesh_health(trimesh.util.concatenate([main, speck]))
    assert h["components"] == 2 and h["floater_faces"] == 12 and h["watertight"]
    assert mesh_health(main)["floater_faces"] == 0


def test_urdf_that_falls_over_fails_physics(tmp_path):
    """A 50 kg arm driven on a 0.1 g base: the free base flips and flies off."""
    urdf = tmp_path / "topple.urdf"
    urdf.write_text("""<robot name="topple">
  <link name="base">
    <inertial><mass value="0.0001"/><inertia ixx="1e-9" iyy="1e-9" izz="1e-9" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.1 0.1 0.1"/></geometry></collision>
  </link>
  <link name="arm">
    <inertial><origin xyz="1 0 0"/><mass value="50"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="1 0 0"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
  </link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.5"/>
    <axis xyz="0 1 0"/><limit lower="0" upper="3" effort="100000" velocity="1"/></joint>
</robot>""")
    res = physics_check(urdf)
    assert not res.ok
    assert any("tipped" in f for f in res.failures) and any("walked" in f for f in res.failures)
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'/><joint name='j' type='revolute'>")
    res = physics_check(broken)
    assert not res.ok and "could not load" in res.error


def test_the_floor_is_under_an_object_whose_root_frame_is_at_its_centre(tmp_path):
    """A 0.4 m cube centred on its root frame, a drawer in its lower half: the floor goes
    under the cube's bottom (z = -0.2), not through the drawer at z = 0."""
    urdf = tmp_path / "centred.urdf"
    box = '<inertial><mass value="{m}"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ' \
          'ixz="0" iyz="0"/></inertial><collision><geometry><box size="{s}"/></geometry>' \
          '</collision>'
    urdf.write_text(f"""<robot name="centred">
  <link name="body">{box.format(m=5, s="0.4 0.4 0.4")}</link>
  <link name="drawer">{box.format(m=0.5, s="0.3 0.3 0.05")}</link>
  <joint name="slide" type="prismatic"><parent link="body"/><child link="drawer"/>
    <origin xyz="0.36 0 -0.1"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.2" effort="100" velocity="1"/></joint>
</robot>""")
    res = physics_check(urdf)
    assert res.ok, res.failures
    assert res.runs["free"].walk < 1e-3 and res.runs["free"].max_tilt_deg < 1.0


def test_examples_are_sim_ready_with_physics(tmp_path):
    from model.core.example import example_objects
    from model.export import export_object
    objs = example_objects()
    for name, obj in objs.items():
        export_object(obj, tmp_path / name, preview=False)
    reps = audit_paths([str(tmp_path)])
    assert len(reps) == len(objs)
    for r in reps:
        assert r.sim_ready, (r.name, r.failures)
        assert r.physics["ok"] and set(r.physics["runs"]) == {"fixed", "free"}
        assert r.bytes > 0
    table = audit_table(reps)
    assert "sim-ready: 100.0% of 2 objects" in table
    json.dumps([r.to_dict() for r in reps])
    sheet = write_contact_sheet(reps, tmp_path / "sheet.png", size=64)
    assert (tmp_path / "sheet.png").stat().st_size > 1000 and sheet


def test_broken_urdf_gets_an_error_row(tmp_path):
    d = tmp_path / "bad"
    d.mkdir()
    (d / "bad.urdf").write_text("<robot name='bad'><link name='a'>")
    [rep] = audit_paths([str(d)])
    assert not rep.sim_ready and "cannot import" in rep.error


def test_audit_command(tmp_path, capsys):
    from model.cli import main
    from model.core.example import example_cabinet
    from model.export import export_object
    export_object(example_cabinet(), tmp_path / "cab", preview=False)
    assert main(["audit", str(tmp_path), "--json", str(tmp_path / "a.json"), "--no-physics"]) == 0
    out = capsys.readouterr().out
    assert "| example_cabinet | yes |" in out
    data = json.loads((tmp_path / "a.json").read_text())
    assert data["summary"]["sim_ready"] == 1.0 and data["objects"][0]["physics"] is None
    assert main(["audit", str(tmp_path / "missing")]) == 2


def test_physics_check_reads_an_mjcf_model(tmp_path):
    """`artformer convert --to mjcf` output goes through the same physics check."""
    from model.core.example import example_cabinet
    from model.export import export_object
    from model.export.mjcf import export_mjcf
    out = export_object(example_cabinet(), tmp_path / "cab", preview=False)
    mj = export_mjcf(out.out_dir)
    model_xml = [p for p in (tmp_path / "cab" / "mjcf").glob("*.xml") if p.name != "scene.xml"]
    assert len(model_xml) == 1, mj
    res = physics_check(model_xml[0])
    assert res.ok, res.failures
    assert res.joints == 3


def test_old_module_names_re_export_the_verdict_below_data():
    """The verdict, its measurements and the MuJoCo check live in model.export (the data
    layer gates its objects with them); model.metrics.audit / audit_checks / physics give the
    same objects."""
    from model.export import audit_checks, physics, simready
    from model.metrics import audit
    from model.metrics import audit_checks as old_checks
    from model.metrics import physics as old_physics
    assert audit.audit_object is simready.audit_object and audit.AuditConfig is simready.AuditConfig
    assert audit.ObjectAudit is simready.ObjectAudit and audit.overlaps is audit_checks.overlaps
    assert old_checks.mesh_health is audit_checks.mesh_health
    assert old_physics.physics_check is physics.physics_check is physics_check
    assert old_physics.PhysicsConfig is physics.PhysicsConfig


def test_physics_check_of_a_relative_path_with_relative_mesh_uris(tmp_path, monkeypatch):
    """A folder named relative to the working directory whose URDF names its meshes relative
    to itself (as PartNet-Mobility folders do) loads in MuJoCo."""
    from model.core.example import example_bottle
    from model.export import export_object
    from model.export.physics import physics_check
    out = export_object(example_bottle(), tmp_path / "ds" / "bottle", preview=False,
                        mesh_uri="relative")
    monkeypatch.chdir(tmp_path)
    rel = os.path.relpath(out.urdf_path, tmp_path)
    res = physics_check(rel)
    assert not res.error and res.ok, res.to_dict()


def test_the_physics_floor_goes_under_a_slanted_mesh_pieces_lowest_vertex():
    """A mesh geom's box in its principal frame reaches below the mesh when the piece is
    skewed; the floor goes under the lowest vertex, so the object does not fall onto it."""
    import mujoco

    from model.export.physics import _lowest_point
    # a slab 40 x 20 x 10 cm sheared along x as it rises (its principal axes then run
    # across its faces; their box reached 4 cm below it), its lowest vertex at z = 0.1
    V = np.array([[x + 2 * z, y, z + 0.1] for x in (-0.2, 0.2) for y in (-0.1, 0.1)
                  for z in (0, 0.1)])
    verts = " ".join(f"{v:.6f}" for v in V.ravel())
    xml = (f'<mujoco><asset><mesh name="slab" vertex="{verts}"/></asset><worldbody>'
           f'<body><freejoint/><geom type="mesh" mesh="slab"/></body></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert _lowest_point(m, d, skip=-1) == pytest.approx(0.1, abs=1e-6)
