"""Pinocchio as the 4th loader of the simulator check and of the validity metric."""
import pytest

pytest.importorskip("pinocchio")

from model.core.example import example_objects  # noqa: E402
from model.export.simcheck import SIMULATORS, check_urdf  # noqa: E402
from model.export.urdf import export_object  # noqa: E402
from model.metrics.validity import validity  # noqa: E402


@pytest.fixture(scope="module")
def cabinet(exported_examples):
    return exported_examples["cabinet"]        # (object, ExportResult), read-only


def test_pinocchio_loads_moves_and_matches_our_fk(cabinet):
    obj, res = cabinet
    assert "pinocchio" in SIMULATORS
    r = check_urdf(res.urdf_path, obj, simulators=("pinocchio",)).sims["pinocchio"]
    assert r.ok and r.num_joints == 3, r
    assert r.max_position_error < 1e-9 and r.max_rotation_error < 1e-9


def test_pinocchio_sees_a_wrong_range(cabinet):
    obj, res = cabinet
    wrong = obj.copy()
    wrong.parts[wrong.index_of("drawer_0")].joint.t_range = (0.0, 0.25)   # the URDF says 0.30
    r = check_urdf(res.urdf_path, wrong, simulators=("pinocchio",)).sims["pinocchio"]
    assert not r.ok and r.max_position_error == pytest.approx(0.05, abs=1e-6)


def test_pinocchio_continuous_joint(wheel_urdf_dir):
    r = check_urdf(wheel_urdf_dir / "cart.urdf", simulators=("pinocchio",)).sims["pinocchio"]
    assert r.loaded and r.joints_movable and r.num_joints == 1, r


def test_pinocchio_missing_collision_mesh_is_an_error(tmp_path):
    obj = example_objects()["bottle"]
    res = export_object(obj, tmp_path / "b", preview=False)
    next((tmp_path / "b" / "meshes").glob("*_collision_0.*")).unlink()
    r = check_urdf(res.urdf_path, obj, simulators=("pinocchio",)).sims["pinocchio"]
    assert not r.loaded and r.error


def test_validity_counts_pinocchio(cabinet):
    obj, res = cabinet
    v = validity([res.urdf_path], [obj])
    assert v.per_simulator == {s: 1.0 for s in SIMULATORS} and v.share == 1.0
