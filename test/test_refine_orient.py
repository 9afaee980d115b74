"""A chest with a lid: decoded as a cabinet with a flip-up door, turned front up
(model.refine.orient)."""
import numpy as np
import pytest
import trimesh

from model.core import ArticulatedObject, Joint, JointType, Part
from model.refine.orient import FRONT_UP, doors_to_lids, turn_front_up


def _flip_cabinet() -> ArticulatedObject:
    """A 0.4 deep, 0.8 wide, 0.5 tall cabinet (front +x) whose door is hinged at the top of
    its front, with a handle near the door's bottom edge."""
    body = Part("body_0", "body", -1, [0.0, 0.0, 0.25], [0.4, 0.8, 0.5])
    door = Part("door_0", "door", 0, [0.21, 0.0, 0.25], [0.02, 0.76, 0.46],
                Joint(JointType.REVOLUTE, origin=[0.22, 0.0, 0.48], axis=[0, -1, 0],
                      r_range=(0.0, 1.4)))
    handle = Part("handle_0", "handle", 1, [0.23, 0.0, 0.06], [0.02, 0.2, 0.02])
    obj = ArticulatedObject(parts=[body, door, handle], category="StorageFurniture")
    for p in obj.parts:
        p.mesh = trimesh.creation.box(extents=p.bbox_size)
        p.mesh.apply_translation(p.bbox_center)
    T = np.eye(4)
    T[:3, 3] = [-0.19, 0.0, 0.25]
    body.collision = [trimesh.primitives.Box(extents=[0.02, 0.8, 0.5], transform=T)]  # back
    return obj


def test_turning_a_flip_up_cabinet_front_up_makes_a_chest_hinged_at_the_back():
    obj = _flip_cabinet()
    assert np.allclose(FRONT_UP @ [1, 0, 0], [0, 0, 1])      # front -> up
    assert np.allclose(FRONT_UP @ [0, 0, 1], [-1, 0, 0])     # top -> back
    assert np.isclose(np.linalg.det(FRONT_UP), 1.0)
    move = turn_front_up(obj)
    body, door, handle = obj.parts
    # the chest: 0.5 deep, 0.8 wide, 0.4 tall, on the floor, centred
    np.testing.assert_allclose(body.bbox_size, [0.5, 0.8, 0.4])
    np.testing.assert_allclose(body.bbox_center, [0.0, 0.0, 0.2], atol=1e-9)
    np.testing.assert_allclose(body.mesh.bounds, [[-0.25, -0.4, 0.0], [0.25, 0.4, 0.4]],
                               atol=1e-9)
    # the door lies on the top, hinged along the back edge, the handle at its front edge
    assert door.bbox_size[2] == pytest.approx(0.02) and door.bbox_center[2] > 0.4
    assert door.joint.origin[0] == pytest.approx(-0.23) and door.joint.origin[2] > 0.4
    assert abs(door.joint.axis[1]) == pytest.approx(1.0)
    assert handle.bbox_center[0] > 0.15
    np.testing.assert_allclose(door.mesh.bounds.mean(0), door.bbox_center, atol=1e-9)
    # the back panel's collision box is now the floor panel: still an axis-aligned box
    [box] = body.collision
    assert isinstance(box, trimesh.primitives.Box)
    np.testing.assert_allclose(box.primitive.extents, [0.5, 0.8, 0.02])
    np.testing.assert_allclose(np.asarray(box.primitive.transform)[:3, 3], [0.0, 0.0, 0.01],
                               atol=1e-9)
    assert len(move) == 3
    # opening the lid lifts its front edge: it swings up about the back edge
    assert obj.posed_meshes({"door_0": 1.4})["door_0"].bounds[1][2] > 0.8
    assert doors_to_lids(obj) == ["lid_0"]
    assert [p.label for p in obj.parts] == ["body", "lid", "handle"]


def test_prepared_meshes_turn_with_their_parts():
    from model.refine.prepare import prepare_mesh
    obj = _flip_cabinet()
    prepared = {1: prepare_mesh(obj.parts[1].mesh, steps=0)}
    turn_front_up(obj, prepared)
    np.testing.assert_allclose(np.asarray(prepared[1].whole[0]).min(0),
                               obj.parts[1].mesh.bounds[0], atol=1e-6)
    np.testing.assert_allclose(np.asarray(prepared[1].whole[0]).max(0),
                               obj.parts[1].mesh.bounds[1], atol=1e-6)


@pytest.fixture(scope="module")
def shipped():
    from model.pipeline.api import GenerationConfig
    from model.pipeline.generator import Generator
    return Generator.load(GenerationConfig())


def test_shipped_model_makes_a_chest_whose_lid_is_hinged_at_the_back(shipped):
    """"a chest with a lid hinged at the back" had been a bare carcass, open at the front,
    with no lid, with every seed."""
    from model.data.spatial import hinge_side
    from model.export.simready import AuditConfig, audit_object
    from model.metrics.alignment import alignment_of
    results = shipped.generate("a chest with a lid hinged at the back", seed=0, samples=2)
    for res in results:
        obj = res.obj
        labels = [p.label for p in obj.parts]
        assert labels.count("lid") == 1 and "door" not in labels, labels
        k = labels.index("lid")
        lid, body = obj.parts[k], obj.parts[obj.root]
        top = body.bbox_center[2] + body.bbox_size[2] / 2
        assert lid.bbox_size[2] < 0.05 and lid.bbox_center[2] > top - 0.05   # on the top
        assert hinge_side(obj, k) == "back"
        assert lid.joint.origin[0] < body.bbox_center[0] - 0.3 * body.bbox_size[0]
        assert body.bbox_size[2] < 0.75 and body.bbox_size[1] > body.bbox_size[2]
        al = alignment_of("a chest with a lid hinged at the back", obj)
        assert al.aligned, al.failures
    rep = audit_object(results[0].obj, config=AuditConfig(physics=False))
    assert rep.sim_ready, rep.failures


def test_a_structure_given_outright_is_not_turned_into_a_chest(shipped):
    """A structure the user gives is held as given: "a toy chest" with a door asked for
    outright is a cabinet with that door, not a chest with a lid."""
    [res] = shipped.generate("a toy chest", seed=0,
                             structure={"category": "StorageFurniture", "door": 1,
                                        "drawer": 0})
    labels = [p.label for p in res.obj.parts]
    assert labels.count("door") == 1 and "lid" not in labels
    assert "turned_front_up" not in res.obj.metadata
