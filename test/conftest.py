"""Shared test setup: offline, single-threaded torch, localhost-only ROS, temp outputs."""
import os
import random

os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_DOMAIN_ID", str(random.Random(os.getpid()).randint(1, 100)))

import pytest  # noqa: E402


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: long end-to-end run (deselected by default)")
    config.addinivalue_line("markers", "ros: needs rclpy and spawns ROS processes")


def pytest_collection_modifyitems(config, items):
    """Without -m, tests marked slow are deselected (`make test`); any -m expression selects
    by itself (`make test-all` passes -m "slow or not slow")."""
    if config.getoption("-m"):
        return
    slow = [item for item in items if "slow" in item.keywords]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if "slow" not in item.keywords]


@pytest.fixture(autouse=True, scope="session")
def _torch_threads():
    try:
        import torch
        torch.set_num_threads(1)
    except ImportError:
        pass
    yield


# -- shared objects (read-only: copy a folder before writing into it) -----------------------------
@pytest.fixture(scope="session")
def tiny_model_factory(tmp_path_factory):
    """build_tiny_model(folder, **kw) into a fresh temp folder: ``tiny_model_factory(**kw)``
    for the variants a test changes (ablation, count labels, image head, ...)."""
    from helpers import build_tiny_model

    def make(name: str = "tiny", **kw):
        return build_tiny_model(tmp_path_factory.mktemp(name) / "ckpt", **kw)
    return make


@pytest.fixture(scope="session")
def tiny_model(tiny_model_factory):
    """Random transformer + octahedron SDF decoder: instant, for smoke runs of eval / bench."""
    return tiny_model_factory("tiny_model")


@pytest.fixture(scope="session")
def tiny_trained_model(tiny_model_factory):
    """Random transformer + shape stages trained for a few seconds (decoded SDFs follow the
    latents): the pipeline, batch and studio tests."""
    return tiny_model_factory("tiny_trained", seed=1, shape="trained")


@pytest.fixture(scope="session")
def tiny_image_model(tiny_model_factory):
    """Text and image stages on a sphere-fitted SDF decoder: the ROS node and image reports."""
    return tiny_model_factory("tiny_image", shape="sphere", image=True)


@pytest.fixture(scope="session")
def exported_examples(tmp_path_factory):
    """The example cabinet and bottle exported as URDF folders: {name: (object, ExportResult)}."""
    from model.core.example import example_objects
    from model.export.urdf import export_object
    root = tmp_path_factory.mktemp("examples")
    objs = example_objects()
    return {name: (objs[name], export_object(objs[name], root / name, preview=False))
            for name in ("cabinet", "bottle")}


@pytest.fixture
def wheel_urdf_dir(tmp_path):
    """A folder holding cart.urdf: a hand-written URDF with a continuous wheel joint and
    primitive (box / cylinder) geometry."""
    from helpers import WHEEL_URDF
    (tmp_path / "cart.urdf").write_text(WHEEL_URDF)
    return tmp_path
