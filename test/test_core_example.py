"""The hand-built example objects: structure, watertight meshes, no collisions in motion."""
import itertools

import numpy as np
import pytest

from model.core import JointType
from model.core.example import example_bottle, example_cabinet, example_objects


@pytest.fixture(scope="module")
def objects():
    return example_objects()


def test_cabinet_structure(objects):
    cab = objects["cabinet"]
    assert cab.category == "StorageFurniture"
    s = cab.summary()
    assert s["counts"] == {"body": 1, "drawer": 2, "door": 1, "handle": 1}
    assert s["joint_types"] == {"body": ["fixed"], "drawer": ["prismatic"],
                                "door": ["revolute"], "handle": ["fixed"]}
    handle = cab.parts[cab.index_of("door_handle")]
    assert cab.parts[handle.parent].label == "door"           # the handle is the door's child
    lo, hi = cab.parts[cab.root].mesh.bounds
    assert lo[2] == pytest.approx(0.0) and abs(lo[0] + hi[0]) < 1e-9 and abs(lo[1] + hi[1]) < 1e-9
    assert 0.3 < hi[2] - lo[2] < 2.5                           # furniture sized, in metres


def test_bottle_structure(objects):
    b = objects["bottle"]
    assert b.category == "Bottle"
    cap = b.parts[b.index_of("cap")]
    assert cap.joint.type == JointType.SCREW
    assert cap.joint.t_range[1] > 0 and cap.joint.r_range[1] >= 2 * np.pi
    np.testing.assert_allclose(cap.joint.axis, [0, 0, 1])
    assert b.parts[b.root].mesh.bounds[0][2] == pytest.approx(0.0)


@pytest.mark.parametrize("name", ["cabinet", "bottle"])
def test_meshes_watertight_and_bbox_fitted(objects, name):
    obj = objects[name]
    for p in obj.parts:
        assert p.mesh is not None and p.mesh.is_watertight and p.mesh.volume > 0, p.name
        lo, hi = p.mesh.bounds
        np.testing.assert_allclose(p.bbox_center, (lo + hi) / 2)
        np.testing.assert_allclose(p.bbox_size, hi - lo)


def test_cabinet_body_is_hollow(objects):
    body = objects["cabinet"].parts[0].mesh
    # A solid block of the same bounds would be ~0.24 m³; the carcass is a small fraction.
    assert body.volume < 0.25 * body.convex_hull.volume
    # Points in the middle of each compartment are outside the carcass (real openings).
    probes = np.array([[0.0, 0.0, 0.25], [0.0, 0.0, 0.56], [0.0, 0.0, 0.78], [0.3, 0.0, 0.56]])
    assert not body.contains(probes).any()


@pytest.mark.parametrize("name", ["cabinet", "bottle"])
def test_no_interpenetration_over_the_motion(objects, name):
    from model.core import meshops
    obj = objects[name]
    for r in np.linspace(0.0, 1.0, 10):
        ms = obj.posed_meshes(ratio=float(r))
        for a, b in itertools.combinations(ms, 2):
            v = meshops.intersection_volume(ms[a], ms[b])
            assert v < 1e-9, f"{a} and {b} overlap by {v} m³ at openness {r:.2f}"


def test_overlap_check_detects_a_collision():
    """The check above can fail: push a drawer 5 cm into the back wall."""
    from model.core import meshops
    cab = example_cabinet()
    ms = cab.posed_meshes({"drawer_0": -0.05})
    assert meshops.intersection_volume(ms["body"], ms["drawer_0"]) > 1e-6


def test_examples_are_deterministic():
    a, b = example_bottle(), example_bottle()
    np.testing.assert_allclose(a.tokens()[0], b.tokens()[0])
    np.testing.assert_allclose(a.parts[1].mesh.vertices, b.parts[1].mesh.vertices)
