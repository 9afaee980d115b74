"""The generator node in its own process (example backend: fast plumbing) — malformed input,
bursts against the bounded queue, memory, files, parameters, clean shutdown. Localhost
discovery only, a random ROS domain for this module."""
import json
import os
import random
import signal
import subprocess
import sys
import time
import uuid

import pytest

rclpy = pytest.importorskip("rclpy")

from artformer_ros.client import (GeneratorClient, proc_memory_kb, start_node,  # noqa: E402
                                  stop_node)
from artformer_ros.service import OWNER_MARKER, RESULT_FILE, owned_folders  # noqa: E402

pytestmark = pytest.mark.ros


@pytest.fixture(scope="module")
def ros_context():
    saved = {k: os.environ.get(k) for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")}
    os.environ["ROS_DOMAIN_ID"] = str(random.SystemRandom().randint(1, 100))
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


class RunningNode:
    """A generator node subprocess in its own namespace plus a client talking to it."""

    def __init__(self, ctx, tmp_path, **params):
        self.ns = f"/t_{uuid.uuid4().hex[:8]}"
        self.out = tmp_path / "out"
        self.log = tmp_path / "node.log"
        self.params = {"backend": "example", "output_dir": str(self.out), **params}
        self.proc = start_node(self.params, log_path=str(self.log),
                               extra_ros_args=["-r", f"__ns:={self.ns}"])
        self.client = GeneratorClient(context=ctx, namespace=self.ns)

    def ready(self, timeout=60):
        ok = self.client.wait_ready(timeout)
        assert ok, f"node not ready: status={self.client.status}\n{self.log_text()}"
        return self

    def log_text(self):
        return self.log.read_text() if self.log.exists() else ""

    def stop(self, sig=signal.SIGINT):
        rc = stop_node(self.proc, 60, sig)
        self.client.close()
        return rc


@pytest.fixture
def node_factory(ros_context, tmp_path):
    nodes = []

    def make(**params):
        n = RunningNode(ros_context, tmp_path, **params)
        nodes.append(n)
        return n

    yield make
    for n in nodes:
        if n.proc.poll() is None:
            n.stop()


def _image_msg(h, w, enc, step, data, rid):
    from sensor_msgs.msg import Image

    m = Image()
    m.header.frame_id = rid
    m.height, m.width, m.encoding, m.step = h, w, enc, step
    m.data = data
    return m


def test_100_malformed_requests_each_get_an_error_and_the_node_keeps_serving(node_factory):
    node = node_factory(max_text_length=200, max_image_pixels=1_000_000).ready()
    c = node.client
    # 60 text requests without a usable id: the node numbers them text-1 ... text-60
    plain = ([""] * 10 + ["   \t\n "] * 10 + ["x" * 201] * 10
             + [b"\xff\xfe\xfd bad utf8"] * 5 + [b"caf\xc3 truncated"] * 5
             + ['{"text": "a cabinet", '] * 10 + [b"a\x00b"] * 5 + ["a\x1b[31mred"] * 5)
    for p in plain:
        c.send_raw_text(p)
    assert c.spin_until(lambda: len(c.result_order) >= 60, 30), len(c.result_order)
    # 40 bad images, with ids in header.frame_id, sent in groups of 10 (images are not burst)
    bad_images = []
    for i in range(10):
        bad_images += [_image_msg(4, 4, "yuv422", 8, bytes(32), f"enc{i}"),
                       _image_msg(0, 0, "rgb8", 0, b"", f"zero{i}"),
                       _image_msg(4, 4, "rgb8", 12, bytes(47), f"len{i}"),
                       _image_msg(100000, 100000, "rgb8", 300000, bytes(12), f"huge{i}")]
    for k in range(0, 40, 10):
        for m in bad_images[k:k + 10]:
            c.image_pub.publish(m)
        assert c.spin_until(lambda: len(c.result_order) >= 60 + k + 10, 30)
    answers = c.result_order
    assert len(answers) == 100
    assert all(a["status"] == "error" and a["message"] for a in answers), \
        [a for a in answers if a["status"] != "error"]
    text_ids = sorted(int(a["id"].split("-")[1]) for a in answers[:60])
    assert text_ids == list(range(1, 61))
    messages = " | ".join(a["message"] for a in answers)
    for needle in ("empty request", "text too long", "not valid UTF-8", "not valid JSON",
                   "control character", "unsupported image encoding", "zero size",
                   "does not match step*height", "image too large"):
        assert needle in messages, needle
    by_id = c.results
    assert "huge3" in by_id and "image too large" in by_id["huge3"]["message"]
    # ... and it still serves a valid request
    rid = c.send_text("a cabinet with a door")
    res = c.wait_result(rid, 60)
    assert res is not None and res["status"] == "done", res
    assert os.path.exists(res["urdf_path"])
    assert node.stop() == 0
    assert "Traceback" not in node.log_text()


def test_burst_of_50_with_queue_4_gets_50_answers_bounded_memory_no_stray_files(node_factory):
    # samples=8 makes each job take long enough (~0.3 s) for the burst to overrun the queue
    node = node_factory(queue_size=4, retention=3, samples=8).ready()
    c = node.client
    warm = c.wait_result(c.send_text("warm up"), 60)   # first export pays one-off imports
    assert warm["status"] == "done"
    base_kb = proc_memory_kb(node.proc.pid)["VmRSS"]
    ids = [c.send_text(f"cabinet number {i}", request_id=f"burst{i}") for i in range(50)]
    peak_kb = base_kb
    end = time.monotonic() + 150
    while not all(i in c.results for i in ids) and time.monotonic() < end:
        c.spin_until(lambda: False, 0.2)
        peak_kb = max(peak_kb, proc_memory_kb(node.proc.pid)["VmRSS"])
    answers = [c.results.get(i) for i in ids]
    assert all(a is not None for a in answers), sum(a is None for a in answers)
    done = [a for a in answers if a["status"] == "done"]
    rejected = [a for a in answers if a["status"] == "rejected"]
    assert len(done) + len(rejected) == 50
    assert len(done) >= 5 and rejected   # the running one + a full queue at least
    assert all("queue full" in a["message"] for a in rejected)
    # memory: a burst must not grow the node by more than a few in-flight requests' worth
    assert peak_kb - base_kb < 150_000, (base_kb, peak_kb)
    # files: exactly `retention` complete folders, nothing partial, no temp leftovers
    complete, partial = owned_folders(str(node.out))
    assert partial == [] and len(complete) == 3
    assert sorted(os.listdir(node.out)) == sorted(os.path.basename(p) for p in complete)
    newest = {a["output_dir"] for a in done[-3:]}
    assert set(complete) == newest
    for folder in complete:
        assert sorted(os.listdir(folder)) == sorted([OWNER_MARKER, RESULT_FILE] +
                                                    [f"sample_{k}" for k in range(8)])
        for root, dirs, files in os.walk(folder):
            for name in dirs + files:
                assert ".tmp" not in name and not name.endswith("~"), os.path.join(root, name)
        saved = json.load(open(os.path.join(folder, RESULT_FILE)))
        assert saved["status"] == "done" and saved["output_dir"] == folder
    assert node.stop() == 0


def test_latched_outputs_reach_a_late_subscriber(node_factory, ros_context):
    node = node_factory().ready()
    res = node.client.wait_result(node.client.send_text("a bottle with a cap"), 60)
    assert res["status"] == "done"
    urdf = open(res["urdf_path"]).read()
    late = GeneratorClient(context=ros_context, namespace=node.ns)   # created after publishing
    from visualization_msgs.msg import Marker, MarkerArray

    from artformer_ros.generator_node import LATCHED
    markers = []
    late.node.create_subscription(MarkerArray, "markers", markers.append, LATCHED)
    assert late.spin_until(lambda: late.descriptions and late.mesh_paths and markers, 20)
    assert late.descriptions[-1][1] == urdf
    assert late.mesh_paths[-1]["id"] == res["id"]
    assert late.mesh_paths[-1]["mesh_paths"] == res["mesh_paths"]
    arr = markers[-1].markers
    assert arr[0].action == Marker.DELETEALL
    assert {m.header.frame_id for m in arr} == {"world"}   # the frame_id parameter
    assert {m.mesh_resource for m in arr[1:]} == {"file://" + p for p in res["mesh_paths"].values()}
    late.close()
    assert node.stop() == 0


def test_sigint_during_work_rejects_the_queue_and_exits_cleanly(node_factory):
    node = node_factory(queue_size=4, samples=16).ready()   # ~0.5 s per job
    c = node.client
    ids = [c.send_text(f"cabinet {i}", request_id=f"s{i}") for i in range(4)]
    assert c.spin_until(lambda: "text request s3" in node.log_text(), 10)
    node.proc.send_signal(signal.SIGINT)
    assert c.spin_until(lambda: all(i in c.results for i in ids), 30), c.results.keys()
    assert node.proc.wait(30) == 0
    statuses = [c.results[i]["status"] for i in ids]
    assert statuses.count("rejected") >= 2, statuses
    # queued: rejected; the one generating when the signal came (if any): abandoned
    rejected = [c.results[i]["message"] for i in ids if c.results[i]["status"] == "rejected"]
    assert rejected.count("rejected: node shutting down") >= 2, rejected
    assert all(m in ("rejected: node shutting down",
                     "abandoned: node shutting down before the result was written")
               for m in rejected), rejected
    complete, partial = owned_folders(str(node.out))
    assert partial == [] and len(complete) == statuses.count("done")
    assert not [n for n in os.listdir(node.out) if n.startswith(".")]
    log = node.log_text()
    assert "Traceback" not in log and "shutting down" in log
    node.client.close()


def test_sigterm_when_idle_exits_zero(node_factory):
    node = node_factory().ready()
    assert node.stop(signal.SIGTERM) == 0
    assert "Traceback" not in node.log_text()


def test_parameters_are_validated_at_run_time(node_factory):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    node = node_factory(queue_size=4).ready()
    c = node.client
    pc = AsyncParameterClient(c.node, f"{node.ns}/artformer_generator")
    assert pc.wait_for_services(10)

    def set_(name, value):
        fut = pc.set_parameters([Parameter(name, value=value)])
        assert c.spin_until(fut.done, 10)
        return fut.result().results[0]

    r = set_("queue_size", 0)
    assert not r.successful and "queue_size" in r.reason
    r = set_("resolution", 32)
    assert not r.successful and "read-only" in r.reason.lower()
    r = set_("mesh_format", "ply")
    assert not r.successful
    r = set_("seed", 1.5)
    assert not r.successful
    assert set_("retention", 2).successful
    fut = pc.describe_parameters(["queue_size", "backend"])
    assert c.spin_until(fut.done, 10)
    qd, bd = fut.result().descriptors
    assert (qd.integer_range[0].from_value, qd.integer_range[0].to_value) == (1, 1000)
    assert qd.description and bd.read_only and "example" in bd.additional_constraints
    fut = pc.get_parameters(["retention"])
    assert c.spin_until(fut.done, 10)
    assert fut.result().values[0].integer_value == 2
    # a live change reaches the next request: package:// mesh URIs in the URDF
    assert not set_("mesh_uri", "http://x").successful
    assert set_("mesh_uri", "package://artformer_ros/objects").successful
    res = c.wait_result(c.send_text("a cabinet"), 60)
    assert res["status"] == "done"
    urdf = open(res["urdf_path"]).read()
    assert 'filename="package://artformer_ros/objects/meshes/' in urdf and "file://" not in urdf
    assert node.stop() == 0


def test_invalid_start_parameters_exit_with_a_reason(tmp_path):
    out = subprocess.run([sys.executable, "-m", "artformer_ros.generator_node", "--ros-args",
                          "-p", "queue_size:=0", "-p", "backend:=example",
                          "-p", f"output_dir:={tmp_path}"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2
    assert "queue_size" in out.stderr and "Traceback" not in out.stderr
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    out = subprocess.run([sys.executable, "-m", "artformer_ros.generator_node", "--ros-args",
                          "-p", "backend:=example", "-p", f"output_dir:={blocker}/out"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 1
    assert "cannot start" in out.stderr and "Traceback" not in out.stderr


def test_request_client_reports_errors_with_its_exit_code(node_factory, ros_context, tmp_path):
    node = node_factory().ready()
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    base = [sys.executable, "-m", "artformer_ros.request", "--timeout", "30"]
    ros = ["--ros-args", "-r", f"__ns:={node.ns}"]
    bad = subprocess.run(base + ["--text", "   "] + ros, capture_output=True, text=True,
                         env=env, timeout=60)
    assert bad.returncode == 1 and "empty request" in bad.stderr
    good = subprocess.run(base + ["--text", "a cabinet"] + ros, capture_output=True,
                          text=True, env=env, timeout=60)
    assert good.returncode == 0, good.stderr
    lines = dict(line.split(":", 1) for line in good.stdout.splitlines() if ":" in line)
    assert os.path.isfile(lines["URDF"].strip())
    from PIL import Image as PILImage
    png = tmp_path / "photo.png"
    PILImage.new("RGBA", (40, 30), (200, 10, 10, 255)).save(png)
    img = subprocess.run(base + ["--image", str(png), "--json"] + ros, capture_output=True,
                         text=True, env=env, timeout=60)
    assert img.returncode == 0, img.stderr
    answer = json.loads(img.stdout)
    assert answer["kind"] == "image" and answer["prompt"] == "<image 40x30>"
    missing = subprocess.run(base + ["--image", str(tmp_path / "nope.png")] + ros,
                             capture_output=True, text=True, env=env, timeout=60)
    assert missing.returncode == 2 and "cannot read image" in missing.stderr
    assert node.stop() == 0
    none = subprocess.run(base[:-1] + ["3", "--text", "x"] + ros, capture_output=True,
                          text=True, env=env, timeout=60)
    assert none.returncode == 3 and "no ready generator" in none.stderr


def test_demo_command_starts_a_node_requests_and_stops_it(tmp_path, ros_context):
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    out = subprocess.run([sys.executable, "-m", "artformer_ros.demo", "a bottle", "--backend",
                          "example", "--output-dir", str(tmp_path / "demo"), "--timeout", "60"],
                         capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    lines = dict(line.split(":", 1) for line in out.stdout.splitlines() if ":" in line)
    urdf = lines["URDF"].strip()
    assert urdf.startswith(str(tmp_path / "demo" / "objects")) and os.path.isfile(urdf)
    assert "exit code 0" in out.stdout
