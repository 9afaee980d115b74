"""The articulated-object model: tokens, validation, forward kinematics."""
import math

import numpy as np
import pytest

from model.core import (TOKEN_DIM, ArticulatedObject, Joint, JointType, ObjectValidationError,
                        Part, rotation_matrix)


def _obj() -> ArticulatedObject:
    """body ← drawer (prismatic x) ← knob (continuous), body ← door (revolute z) ← handle
    (fixed), body ← cap (screw z). Parts deliberately not in topological order."""
    parts = [
        Part("door", "door", 3, bbox_center=(0.3, 0.0, 0.3), bbox_size=(0.02, 0.5, 0.4),
             joint=Joint(JointType.REVOLUTE, origin=(0.3, 0.25, 0.3), axis=(0, 0, 1),
                         r_range=(0.0, 1.5))),
        Part("handle", "handle", 0, bbox_center=(0.33, -0.2, 0.3), bbox_size=(0.03, 0.01, 0.1),
             joint=Joint(JointType.FIXED, origin=(0.33, -0.2, 0.3))),
        Part("drawer", "drawer", 3, bbox_center=(0.1, 0.0, 0.7), bbox_size=(0.4, 0.5, 0.15),
             joint=Joint(JointType.PRISMATIC, origin=(0.3, 0.0, 0.7), axis=(1, 0, 0),
                         t_range=(0.0, 0.3))),
        Part("body", "body", -1, bbox_center=(0.0, 0.0, 0.45), bbox_size=(0.6, 0.6, 0.9)),
        Part("knob", "knob", 2, bbox_center=(0.32, 0.0, 0.7), bbox_size=(0.03, 0.03, 0.03),
             joint=Joint(JointType.CONTINUOUS, origin=(0.32, 0.0, 0.7), axis=(1, 0, 0),
                         r_range=(-math.pi, math.pi))),
        Part("cap", "cap", 3, bbox_center=(0.0, 0.0, 0.95), bbox_size=(0.05, 0.05, 0.03),
             joint=Joint(JointType.SCREW, origin=(0.0, 0.0, 0.94), axis=(0, 0, 1),
                         t_range=(0.0, 0.01), r_range=(0.0, 4 * math.pi))),
    ]
    return ArticulatedObject(parts=parts, category="Test", name="t").validate()


# -- tokens -----------------------------------------------------------------------------------


def test_part_token_layout_and_round_trip():
    p = _obj().parts[5]                       # the screw cap
    tok = p.token()
    assert tok.shape == (TOKEN_DIM,)
    np.testing.assert_allclose(tok[0:3], p.bbox_size)
    np.testing.assert_allclose(tok[3:6], p.bbox_center)
    np.testing.assert_allclose(tok[6:9], p.joint.origin)
    np.testing.assert_allclose(tok[9:12], p.joint.axis)
    np.testing.assert_allclose(tok[12:16], [0.0, 0.01, 0.0, 4 * math.pi])
    q = Part.from_token(tok, JointType.SCREW, name="cap", label="cap", parent=0)
    np.testing.assert_allclose(q.token(), tok)
    assert q.joint.type == JointType.SCREW


def test_from_token_normalises_axis_and_zeroes_unused_range():
    tok = np.zeros(16)
    tok[0:3] = [-0.1, 0.2, 0.3]               # negative size → abs
    tok[9:12] = [0.0, 0.0, 2.0]               # unnormalised axis
    tok[12:16] = [0.3, 0.1, 0.5, -0.5]        # swapped ranges; a revolute ignores translation
    p = Part.from_token(tok, "revolute", name="x", label="door", parent=0)
    np.testing.assert_allclose(p.joint.axis, [0, 0, 1])
    np.testing.assert_allclose(p.bbox_size, [0.1, 0.2, 0.3])
    assert p.joint.t_range == (0.0, 0.0)
    assert p.joint.r_range == (-0.5, 0.5)
    with pytest.raises(ObjectValidationError, match="16 floats"):
        Part.from_token(np.zeros(15), "fixed", name="x", label="x", parent=-1)


def test_object_tokens_round_trip_in_topological_order():
    obj = _obj()
    toks, types, parents, labels = obj.tokens()
    assert toks.shape == (6, TOKEN_DIM)
    assert labels[0] == "body" and parents[0] == -1
    assert all(parents[k] < k for k in range(1, 6))          # parents before children
    back = ArticulatedObject.from_tokens(toks, types, parents, labels, category="Test")
    back.validate()
    t2, ty2, p2, l2 = back.tokens()
    np.testing.assert_allclose(t2, toks)
    assert list(ty2) == list(types) and list(p2) == list(parents) and l2 == labels
    assert sorted(JointType(t).name for t in types) == sorted(
        ["FIXED", "FIXED", "REVOLUTE", "PRISMATIC", "CONTINUOUS", "SCREW"])
    assert back.summary()["counts"] == obj.summary()["counts"]


def test_joint_type_parse():
    assert JointType.parse("Revolute") == JointType.REVOLUTE
    assert JointType.parse(4) == JointType.SCREW
    assert JointType.SCREW.dof == 2 and JointType.FIXED.dof == 0
    with pytest.raises(ObjectValidationError, match="unknown joint type 'hinge'"):
        JointType.parse("hinge")
    with pytest.raises(ObjectValidationError, match="unknown joint type 9"):
        JointType.parse(9)


# -- validation -------------------------------------------------------------------------------


def _broken(mutate):
    obj = _obj()
    mutate(obj)
    return obj


@pytest.mark.parametrize("mutate, message", [
    (lambda o: (setattr(o.parts[3], "parent", 2), setattr(o.parts[2], "parent", 4)),
     "cycle in the part tree"),
    (lambda o: setattr(o.parts[2], "parent", 4), "cycle in the part tree"),   # drawer↔knob
    (lambda o: setattr(o.parts[1], "parent", 1), "its own parent"),
    (lambda o: setattr(o.parts[0].joint, "origin", np.array([np.nan, 0, 0])), "NaN"),
    (lambda o: setattr(o.parts[2], "bbox_size", np.array([np.inf, 0, 0])), "non-finite"),
    (lambda o: setattr(o.parts[2].joint, "t_range", (0.3, 0.0)), "translation limits inverted"),
    (lambda o: setattr(o.parts[0].joint, "r_range", (1.0, -1.0)), "rotation limits inverted"),
    (lambda o: setattr(o.parts[2], "parent", -1), "exactly one root part, found 2"),
    (lambda o: setattr(o.parts[1], "parent", 17), "parent index 17 does not exist"),
    (lambda o: setattr(o.parts[0].joint, "axis", np.array([0, 0, 2.0])), "unit vector"),
    (lambda o: setattr(o.parts[3].joint, "type", JointType.REVOLUTE), "must have a fixed joint"),
    (lambda o: setattr(o.parts[1], "name", "door"), "duplicate part names"),
    (lambda o: setattr(o.parts[1], "name", "bad name!"), "letters, digits"),
    (lambda o: setattr(o.parts[2].joint, "effort", 0.0), "effort and velocity"),
])
def test_validation_errors_name_the_problem(mutate, message):
    obj = _broken(mutate)
    with pytest.raises(ObjectValidationError, match=message):
        obj.validate()


def test_full_cycle_without_root_is_reported_as_cycle():
    obj = _obj()
    obj.parts[3].parent = 0                # body → door → body: every part has a parent
    with pytest.raises(ObjectValidationError, match="cycle"):
        obj.validate()
    with pytest.raises(ObjectValidationError, match="cycle"):
        obj.depth(3)                       # used to loop forever


def test_no_parts_and_empty_object():
    with pytest.raises(ObjectValidationError, match="no parts"):
        ArticulatedObject(parts=[]).validate()


def test_vec3_shape_is_checked():
    with pytest.raises(ObjectValidationError, match="3 components"):
        Joint(JointType.REVOLUTE, origin=(0, 0))


# -- kinematics -------------------------------------------------------------------------------


def _apply(T, p):
    return (T @ np.append(p, 1.0))[:3]


def test_rotation_matrix_is_right_handed():
    R = rotation_matrix(np.array([0.0, 0.0, 1.0]), math.pi / 2)
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-12)


def test_fk_at_openness_ratio():
    obj = _obj()
    T = obj.link_transforms(ratio=1.0)
    np.testing.assert_allclose(T["body"], np.eye(4))
    # Drawer slides its full 0.3 m along +x; the knob (its child) goes with it.
    np.testing.assert_allclose(T["drawer"][:3, 3], [0.3, 0, 0], atol=1e-12)
    np.testing.assert_allclose(_apply(T["knob"], [0.32, 0, 0.7]), [0.62, 0, 0.7], atol=1e-12)
    # Door at 1.5 rad about the hinge line: the hinge point is fixed, the handle swings.
    hinge = np.array([0.3, 0.25, 0.3])
    np.testing.assert_allclose(_apply(T["door"], hinge), hinge, atol=1e-12)
    h = np.array([0.33, -0.2, 0.3])
    want = hinge + rotation_matrix(np.array([0, 0, 1.0]), 1.5) @ (h - hinge)
    np.testing.assert_allclose(_apply(T["handle"], h), want, atol=1e-12)
    np.testing.assert_allclose(T["handle"], T["door"], atol=1e-12)   # fixed child
    # ratio 0 = lower limits (all 0 here except the knob at -pi).
    T0 = obj.link_transforms(ratio=0.0)
    np.testing.assert_allclose(T0["door"], np.eye(4), atol=1e-12)
    np.testing.assert_allclose(T0["drawer"], np.eye(4), atol=1e-12)
    vals = obj.joint_values_at(0.5)
    assert vals["drawer"] == pytest.approx((0.15, 0.0))
    assert vals["cap"] == pytest.approx((0.005, 2 * math.pi))
    assert vals["knob"] == pytest.approx((0.0, 0.0))


def test_fk_explicit_values_move_the_whole_subtree_and_screw_takes_pair():
    obj = _obj()
    T = obj.link_transforms({"drawer": 0.2, "knob": math.pi / 2})
    # Knob rotates about its own axis line (x through (0.32, 0, 0.7)) after the drawer slid.
    p = np.array([0.32, 0.0, 0.75])
    np.testing.assert_allclose(_apply(T["knob"], p), [0.52, -0.05, 0.7], atol=1e-12)
    assert np.allclose(T["door"], np.eye(4))                       # unnamed parts stay at 0
    Ts = obj.link_transforms({"cap": (0.01, math.pi)})
    q = np.array([0.02, 0.0, 0.95])
    np.testing.assert_allclose(_apply(Ts["cap"], q), [-0.02, 0.0, 0.96], atol=1e-12)
    with pytest.raises(ObjectValidationError, match="screw joint needs"):
        obj.link_transforms({"cap": 0.01})
    with pytest.raises(ObjectValidationError, match="takes one value"):
        obj.link_transforms({"door": (0.1, 0.2)})
    with pytest.raises(KeyError, match="unknown parts"):
        obj.link_transforms({"nope": 0.1})
    with pytest.raises(ValueError, match="not both"):
        obj.link_transforms({"door": 0.1}, ratio=0.5)


def test_fk_per_part_ratio_and_posed_meshes():
    import trimesh
    obj = _obj()
    obj.parts[2].mesh = trimesh.creation.box(extents=(0.4, 0.5, 0.15),
                                             transform=trimesh.transformations.translation_matrix((0.1, 0, 0.7)))
    T = obj.link_transforms(ratio={"drawer": 1.0})
    np.testing.assert_allclose(T["drawer"][:3, 3], [0.3, 0, 0])
    np.testing.assert_allclose(T["door"], np.eye(4))
    meshes = obj.posed_meshes(ratio={"drawer": 0.5})
    assert set(meshes) == {"drawer"}
    np.testing.assert_allclose(meshes["drawer"].bounds.mean(axis=0), [0.25, 0, 0.7], atol=1e-9)
    np.testing.assert_allclose(obj.parts[2].mesh.bounds.mean(axis=0), [0.1, 0, 0.7])  # untouched


def test_structure_helpers():
    obj = _obj()
    assert obj.root == 3
    assert obj.depth(4) == 2 and obj.depth(3) == 0
    assert sorted(obj.children(3)) == [0, 2, 5]
    assert obj.index_of("knob") == 4
    assert sorted(obj.movable_parts()) == [0, 2, 4, 5]
    order = obj.topological_order()
    assert order[0] == 3 and order.index(0) < order.index(1)
    s = obj.summary()
    assert s["num_parts"] == 6 and s["num_movable"] == 4
    assert s["joint_types"]["cap"] == ["screw"]
