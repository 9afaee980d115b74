"""Headline tests on the real generation pipeline (backend "model"): the node in its own
process loads Generator from tiny random-weight checkpoints of all stages (text + image) —
the real code path, not the shipped weights' quality — and answers a text request (URDF
latched for a late subscriber) and an image request. Localhost, random ROS domain."""
import os
import random
import uuid

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")
torch = pytest.importorskip("torch")

from artformer_ros.client import GeneratorClient, start_node, stop_node  # noqa: E402

pytestmark = pytest.mark.ros


@pytest.fixture(scope="module")
def ros_setup(tmp_path_factory, tiny_image_model):
    tmp = tmp_path_factory.mktemp("ros_model")
    ckpt = tiny_image_model
    saved = {k: os.environ.get(k) for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")}
    os.environ["ROS_DOMAIN_ID"] = str(random.SystemRandom().randint(1, 100))
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    yield {"ctx": ctx, "tmp": tmp, "ckpt": ckpt}
    rclpy.try_shutdown(context=ctx)
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


def _start(setup, name):
    ns = f"/m_{uuid.uuid4().hex[:8]}"
    log = setup["tmp"] / f"{name}.log"
    # the client first: it sees every status and /rosout line of the node
    client = GeneratorClient(context=setup["ctx"], namespace=ns, watch_rosout=True)
    proc = start_node({"backend": "model", "checkpoint": str(setup["ckpt"]),
                       "output_dir": str(setup["tmp"] / f"{name}_out"), "resolution": 24,
                       "steps": 4, "preview": False, "threads": 1, "seed": 0},
                      log_path=str(log), extra_ros_args=["-r", f"__ns:={ns}"])
    return {"proc": proc, "client": client, "ctx": setup["ctx"], "ns": ns, "log": log}


@pytest.fixture(scope="module")
def model_node(ros_setup):
    node = _start(ros_setup, "node")
    yield node
    node["client"].close()
    rc = stop_node(node["proc"], 60)
    assert rc == 0
    assert "Traceback" not in node["log"].read_text()


def test_a_request_sent_while_the_model_loads_is_served_once_ready(model_node):
    from rcl_interfaces.msg import Log

    c = model_node["client"]
    assert c.spin_until(lambda: c.status is not None and
                        c.text_pub.get_subscription_count() > 0, 30), c.status
    assert c.status["state"] == "loading"   # torch + text/image encoders take seconds
    rid = c.send_text("a cabinet with a drawer", seed=1)
    res = c.wait_result(rid, 180)
    assert res is not None and res["status"] == "done", res
    urdf = open(res["urdf_path"]).read()
    assert c.spin_until(lambda: c.descriptions and c.descriptions[-1][1] == urdf, 30)
    # /rosout: the node had the request before the model was ready, and the core's own
    # model-loading line (Python logging in model.pipeline.generator) came through
    lines = [m for _, _, m in c.rosout]
    got = next(i for i, m in enumerate(lines) if f"text request {rid}" in m)
    ready = next(i for i, m in enumerate(lines) if m.startswith("state ready"))
    assert got < ready, lines
    assert any(n.endswith(".artformer_generator.model.pipeline.generator") and
               lv == Log.INFO and m.startswith("model loaded in") for n, lv, m in c.rosout)


def test_text_request_gives_a_urdf_that_a_late_subscriber_receives(model_node):
    c = model_node["client"]
    assert c.wait_ready(120), (c.status, model_node["log"].read_text())
    res = c.wait_result(c.send_text("a storage cabinet with two drawers", seed=3), 180)
    assert res is not None and res["status"] == "done", res
    assert res["backend"] == "model" and res["seed"] == 3 and res["kind"] == "text"
    assert {"text_encoding", "decoding", "diffusion", "meshing"} <= set(res["timings"]["stages"])
    urdf = open(res["urdf_path"]).read()
    assert "<robot" in urdf and "a storage cabinet with two drawers" in urdf   # provenance
    for path in res["mesh_paths"].values():
        assert os.path.getsize(path) > 0
    late = GeneratorClient(context=model_node["ctx"], namespace=model_node["ns"])
    assert late.spin_until(lambda: late.descriptions and late.mesh_paths, 30)
    assert late.descriptions[-1][1] == urdf
    assert late.mesh_paths[-1]["id"] == res["id"]
    assert late.mesh_paths[-1]["urdf_path"] == res["urdf_path"]
    late.close()


def test_image_request_is_answered_by_the_image_stage(model_node):
    c = model_node["client"]
    assert c.wait_ready(120)
    rgb = (np.random.default_rng(0).random((96, 128, 3)) * 255).astype(np.uint8)
    rid = c.send_image(rgb)
    res = c.wait_result(rid, 180)
    assert res is not None and res["status"] == "done", res
    assert res["kind"] == "image" and res["prompt"] == "<image 128x96>"
    assert "image_encoding" in res["timings"]["stages"]
    assert os.path.isfile(res["urdf_path"])
    assert c.spin_until(lambda: c.descriptions and
                        c.descriptions[-1][1] == open(res["urdf_path"]).read(), 30)


def test_answers_name_a_preview_only_once_it_exists(model_node):
    """preview.png is drawn after the answer went out: the answer names none, and the
    request's result.json names it once the file is there."""
    import json

    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    c = model_node["client"]
    assert c.wait_ready(120)
    pc = AsyncParameterClient(c.node, f"{model_node['ns']}/artformer_generator")
    assert pc.wait_for_services(10)

    def set_preview(on):
        fut = pc.set_parameters([Parameter("preview", value=on)])
        assert c.spin_until(fut.done, 10) and fut.result().results[0].successful

    set_preview(True)
    try:
        ids = [c.send_text(f"a cabinet with {k + 1} drawers", seed=k) for k in range(2)]
        answers = [c.wait_result(rid, 180) for rid in ids]
        assert all(a is not None and a["status"] == "done" for a in answers), answers
        assert [a["preview_path"] for a in answers] == [None, None]
        saved = [os.path.join(a["output_dir"], "result.json") for a in answers]

        def previews_recorded():
            docs = [json.load(open(p)) for p in saved]
            return all(d["preview_path"] and os.path.isfile(d["preview_path"]) for d in docs)

        assert c.spin_until(previews_recorded, 120)
    finally:
        set_preview(False)


def test_sigint_while_the_model_loads_exits_cleanly(ros_setup):
    node = _start(ros_setup, "early_stop")
    c = node["client"]
    try:
        assert c.spin_until(lambda: c.status is not None, 30)
        assert c.status["state"] == "loading"   # torch + encoders: seconds of loading left
    finally:
        c.close()
        rc = stop_node(node["proc"], 60)
    assert rc == 0
    log = node["log"].read_text()
    assert "Traceback" not in log and "Fatal" not in log
    assert "abandoned the running model load" in log
