"""Known-answer tests of POR, Instantiation Distance and MMD / COV / 1-NNA."""
import numpy as np
import pytest
import trimesh

from model.core import ArticulatedObject, Joint, JointType, Part
from model.metrics import (coverage, id_matrix, instantiation_distance, mmd, one_nna,
                           part_overlap_ratio, posed_clouds, set_metrics)


def box(size, center):
    m = trimesh.creation.box(extents=size)
    m.apply_translation(center)
    return m


def two_box_object(offset: float, travel: float, name="obj") -> ArticulatedObject:
    """A fixed unit cube at the origin and a unit cube at x = offset sliding +x by `travel`."""
    body = Part("body", "body", -1, mesh=box([1, 1, 1], [0, 0, 0]))
    slider = Part("drawer", "drawer", 0, bbox_center=[offset, 0, 0],
                  joint=Joint(JointType.PRISMATIC, [offset, 0, 0], [1, 0, 0], (0.0, travel)),
                  mesh=box([1, 1, 1], [offset, 0, 0]))
    for p in (body, slider):
        p.fit_bbox_to_mesh()
    return ArticulatedObject([body, slider], category="StorageFurniture", name=name).validate()


def cabinet(width: float, door_angle: float = 1.5, name="cab") -> ArticulatedObject:
    """A body box and a door panel in front of it, hinged at its left edge (no contact)."""
    body = Part("body", "body", -1, mesh=box([0.5, width, 0.8], [0, 0, 0.4]))
    door = Part("door", "door", 0,
                joint=Joint(JointType.REVOLUTE, [0.27, width / 2, 0], [0, 0, 1], (0, 0),
                            (0.0, door_angle)),
                mesh=box([0.02, width, 0.8], [0.27, 0, 0.4]))
    for p in (body, door):
        p.fit_bbox_to_mesh()
    return ArticulatedObject([body, door], category="StorageFurniture", name=name).validate()


def test_two_overlapping_boxes_exact_iou():
    from model.core import meshops
    a, b = box([1, 1, 1], [0, 0, 0]), box([1, 1, 1], [0.5, 0, 0])
    assert meshops.volume_iou(a, b) == pytest.approx(0.5 / 1.5, abs=1e-6)
    # POR at a single state (r = 0, slider at rest) is that IoU: one pair.
    res = part_overlap_ratio(two_box_object(0.5, 1.0), n_states=1)
    assert res.num_pairs == 1
    assert res.mean == pytest.approx(1 / 3, abs=1e-6)


def test_por_matches_analytic_sliding_overlap():
    obj = two_box_object(0.5, 1.0)
    res = part_overlap_ratio(obj)
    r = np.linspace(0, 1, 10)
    inter = np.clip(1.0 - (0.5 + r), 0, None)
    expected = inter / (2.0 - inter)
    assert res.per_state == pytest.approx(expected.tolist(), abs=1e-6)
    assert res.mean == pytest.approx(expected.mean(), abs=1e-6)
    assert res.max == pytest.approx(expected.max(), abs=1e-6)
    assert res.mean > 0
    assert res.worst_pair == ("body", "drawer")


def test_por_zero_for_separated_parts():
    # Slider starts just clear of the body (touching face at offset 1.0 -> gap 0.01).
    res = part_overlap_ratio(two_box_object(1.01, 0.5))
    assert res.mean == 0.0 and res.max == 0.0
    # A door swinging open in front of its body never enters it.
    res = part_overlap_ratio(cabinet(0.6))
    assert res.mean == 0.0


def test_por_detects_collision_while_moving():
    # The door swings the wrong way (negative angle range) into the body.
    obj = cabinet(0.6)
    obj.parts[1].joint.r_range = (-1.5, 0.0)
    res = part_overlap_ratio(obj)
    assert res.mean > 0 and res.max > res.per_state[-1] - 1e-12


def test_por_single_part_is_zero():
    obj = ArticulatedObject([Part("body", "body", -1, mesh=box([1, 1, 1], [0, 0, 0.5]))])
    assert part_overlap_ratio(obj).mean == 0.0


def test_instantiation_distance_identical_and_symmetric():
    a, b = cabinet(0.6, name="a"), cabinet(0.9, name="b")
    kw = dict(n_points=512, seed=3)
    assert instantiation_distance(a, a.copy(), **kw) == 0.0
    dab = instantiation_distance(a, b, **kw)
    dba = instantiation_distance(b, a, **kw)
    assert dab > 0
    assert dab == pytest.approx(dba, rel=1e-12)


def test_instantiation_distance_grows_with_shape_difference():
    kw = dict(n_points=512, seed=0)
    ref = cabinet(0.6)
    near = instantiation_distance(ref, cabinet(0.65), **kw)
    far = instantiation_distance(ref, cabinet(1.2), **kw)
    assert 0 < near < far


def test_posed_clouds_move_with_joints():
    obj = two_box_object(1.0, 2.0)
    c = posed_clouds(obj, n_poses=10, n_points=2000, seed=1)
    assert c.points.shape == (10, 2000, 3)
    xmax = c.points[..., 0].max(axis=1)        # (10,) far face of the slider per pose
    assert np.ptp(xmax) > 0.5                  # the slider visits different positions
    assert xmax.min() >= 1.5 - 1e-9 and xmax.max() <= 3.5 + 1e-9


def test_set_against_itself_mmd0_cov1():
    objs = [cabinet(w, name=f"c{i}") for i, w in enumerate([0.4, 0.6, 0.8, 1.0])]
    clouds = [posed_clouds(o, n_points=256, seed=0) for o in objs]
    D = id_matrix(clouds)
    D_gr = id_matrix(clouds, clouds)
    assert np.allclose(D, D_gr) and np.allclose(D, D.T)
    assert mmd(D_gr) == 0.0
    assert coverage(D_gr) == 1.0
    m = set_metrics(D, D_gr, D)
    assert m.mmd == 0.0 and m.cov == 1.0 and m.nna == 0.0   # exact copies: never separable


def test_disjoint_sets_nna_near_one():
    gen = [cabinet(w, name=f"g{i}") for i, w in enumerate([0.30, 0.32, 0.34, 0.36])]
    ref = [cabinet(w, name=f"r{i}") for i, w in enumerate([1.30, 1.32, 1.34, 1.36])]
    cg = [posed_clouds(o, n_points=256) for o in gen]
    cr = [posed_clouds(o, n_points=256) for o in ref]
    m = set_metrics(id_matrix(cg), id_matrix(cg, cr), id_matrix(cr))
    assert m.nna == 1.0
    assert m.cov == 0.25            # every generated object picks the same nearest reference
    assert m.mmd > 0


def test_orientation_is_reference_major():
    # 3 generated x 2 reference: generated 0 and 1 sit on reference 0, generated 2 is far.
    D_gr = np.array([[0.0, 5.0], [0.1, 4.0], [9.0, 3.0]])
    assert mmd(D_gr) == pytest.approx((0.0 + 3.0) / 2)      # per reference column
    assert coverage(D_gr) == 1.0                            # refs {0, 1} both chosen
    D_gr2 = np.array([[0.0, 5.0], [0.1, 4.0], [0.2, 3.0]])
    assert coverage(D_gr2) == 0.5
    D_gg = np.array([[0, 1, 1], [1, 0, 1], [1, 1, 0.0]])
    D_rr = np.array([[0, 1], [1, 0.0]])
    # gen0 -> ref0 (0.0 < 1) wrong, gen1 -> ref0 wrong, gen2 -> gen (1 < 3) right,
    # ref0 -> gen0 wrong, ref1 -> gen2 (3) vs ref0 (1) right.
    assert one_nna(D_gg, D_gr, D_rr) == pytest.approx(2 / 5)
