"""ROS conventions of the generator node, each in its own node process (example backend): the
shipped parameter file edited and used under a namespace, log lines on /rosout, a best-effort
(camera-style) image publisher, markers + joint_states in one fixed frame at an openness (and
animated), answers that name existing files only. Localhost discovery, a random ROS domain."""
import json
import os
import random
import uuid
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from artformer_ros.client import GeneratorClient, rgb_to_image_msg, start_node  # noqa: E402
from artformer_ros.client import stop_node  # noqa: E402

pytestmark = pytest.mark.ros
REPO = Path(__file__).resolve().parent.parent


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


@pytest.fixture
def launch(ros_context, tmp_path):
    """launch(params, ns=None, extra=(), **client_kw) -> (process, client, log path); the
    client exists before the node starts (so it sees everything the node publishes)."""
    running = []

    def start(params, ns=None, extra=(), **client_kw):
        ns = ns or f"/c_{uuid.uuid4().hex[:8]}"
        client = GeneratorClient(context=ros_context, namespace=ns, **client_kw)
        log = tmp_path / f"node_{len(running)}.log"
        proc = start_node(params, log_path=str(log),
                          extra_ros_args=["-r", f"__ns:={ns}", *extra])
        running.append((proc, client, log))
        return proc, client, log

    yield start
    for proc, client, log in running:
        client.close()
        assert stop_node(proc, 60) == 0
        assert "Traceback" not in log.read_text()


def _example(tmp_path, **params):
    return {"backend": "example", "output_dir": str(tmp_path / "out"), **params}


def _ready(client, log, timeout=60):
    assert client.wait_ready(timeout), f"status={client.status}\n{log.read_text()}"


def _parameters(client, node_name, names):
    from rclpy.parameter import parameter_value_to_python
    from rclpy.parameter_client import AsyncParameterClient

    pc = AsyncParameterClient(client.node, node_name)
    assert pc.wait_for_services(10)
    fut = pc.get_parameters(names)
    assert client.spin_until(fut.done, 10)
    return {n: parameter_value_to_python(v) for n, v in zip(names, fut.result().values)}


def _set_parameter(client, node_name, name, value):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    pc = AsyncParameterClient(client.node, node_name)
    assert pc.wait_for_services(10)
    fut = pc.set_parameters([Parameter(name, value=value)])
    assert client.spin_until(fut.done, 10)
    assert fut.result().results[0].successful, fut.result().results[0].reason


def _watch(client):
    """Collect markers and joint_states of the generator (with the node's QoS)."""
    from sensor_msgs.msg import JointState
    from visualization_msgs.msg import MarkerArray

    from artformer_ros.generator_node import JOINT_STATES, LATCHED

    seen = {"markers": [], "joints": []}
    client.node.create_subscription(MarkerArray, "markers", seen["markers"].append, LATCHED)
    client.node.create_subscription(JointState, "joint_states", seen["joints"].append,
                                    JOINT_STATES)
    return seen


def _pose(marker):
    from scipy.spatial.transform import Rotation

    q = marker.pose.orientation
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    T[:3, 3] = [marker.pose.position.x, marker.pose.position.y, marker.pose.position.z]
    return T


class UrdfReference:
    """yourdfpy's forward kinematics of a URDF file: the independent reference."""

    def __init__(self, path):
        import yourdfpy

        self.urdf = yourdfpy.URDF.load(path, load_meshes=False,
                                       build_collision_scene_graph=False,
                                       load_collision_meshes=False)
        self.movable = {j.name: j for j in self.urdf.robot.joints if j.type != "fixed"}
        self.root = self.urdf.base_link

    def positions(self, openness):
        return {n: j.limit.lower + openness * (j.limit.upper - j.limit.lower)
                for n, j in self.movable.items()}

    def marker_poses(self, positions):
        """mesh resource -> 4x4 pose of its visual in the root link frame."""
        self.urdf.update_cfg(positions)
        out = {}
        for link in self.urdf.robot.links:
            for vis in link.visuals:
                if vis.geometry.mesh is not None:
                    T = self.urdf.get_transform(frame_to=link.name, frame_from=self.root)
                    out[vis.geometry.mesh.filename] = T @ vis.origin
        return out


def _meshes(arr):
    from visualization_msgs.msg import Marker

    return [m for m in arr.markers if m.action == Marker.ADD]


def _markers_match(arr, ref, positions):
    """Every mesh marker sits where the URDF's FK at ``positions`` puts its visual."""
    expected = ref.marker_poses(positions)
    meshes = _meshes(arr)
    return (sorted(m.mesh_resource for m in meshes) == sorted(expected)
            and all(np.allclose(_pose(m), expected[m.mesh_resource], atol=1e-6)
                    for m in meshes))


def _check_markers(arr, ref, openness, frame_id):
    assert _meshes(arr) and all(m.header.frame_id == frame_id for m in arr.markers)
    assert _markers_match(arr, ref, ref.positions(openness))


# ---------------------------------------------------------------------------------------------
def test_the_shipped_params_file_edited_is_honoured_under_a_namespace(launch, tmp_path):
    import yaml

    doc = yaml.safe_load((REPO / "config" / "artformer.yaml").read_text())
    assert list(doc) == ["/**"]
    values = doc["/**"]["ros__parameters"]
    edited = {"backend": "example", "output_dir": str(tmp_path / "gen_out"), "queue_size": 7,
              "seed": 1234, "retention": 3, "frame_id": "gen_frame", "openness": 0.5,
              "max_text_length": 300}
    assert set(edited) <= set(values)
    assert all(values[k] != v for k, v in edited.items())   # every one differs from default
    values.update(edited)
    params_file = tmp_path / "edited.yaml"
    params_file.write_text(yaml.safe_dump(doc))

    proc, c, log = launch({}, ns="/gen", extra=["--params-file", str(params_file)])
    seen = _watch(c)
    _ready(c, log)
    assert c.status["node"] == "/gen/artformer_generator"
    assert _parameters(c, "/gen/artformer_generator", list(edited)) == edited
    res = c.wait_result(c.send_text("a cabinet with a door"), 60)
    assert res["status"] == "done" and res["seed"] == 1234
    assert res["urdf_path"].startswith(str(tmp_path / "gen_out") + os.sep)
    assert c.spin_until(lambda: seen["markers"], 10)
    assert {m.header.frame_id for m in seen["markers"][-1].markers} == {"gen_frame"}
    too_long = c.wait_result(c.send_text("x" * 301), 30)
    assert "max_text_length 300" in too_long["message"]


def test_log_lines_reach_rosout_with_their_levels(launch, tmp_path):
    from rcl_interfaces.msg import Log

    proc, c, log = launch(_example(tmp_path), watch_rosout=True)
    _ready(c, log)
    c.send_raw_text("   ")                       # -> the node warns about the error answer
    assert c.spin_until(lambda: "text-1" in c.results, 30)
    prefix = c.node.get_namespace().strip("/") + ".artformer_generator"

    def line(name_suffix, level, text):
        return lambda: any(n == prefix + name_suffix and lv == level and text in m
                           for n, lv, m in c.rosout)

    # Python logging of the serving core (artformer_ros.service) and of the example backend's
    # load, with levels, under the node's logger; the node's own rclpy lines as before
    assert c.spin_until(line(".artformer_ros.service", Log.INFO,
                             "loading the example backend"), 20), c.rosout
    assert c.spin_until(line(".artformer_ros.service", Log.INFO, "state ready"), 20)
    assert c.spin_until(line("", Log.WARN, "request text-1 error: empty request"), 20)
    assert c.spin_until(line("", Log.INFO, "backend=example"), 20)
    # printed once on the console (rcutils), not once more by Python's own handler
    assert log.read_text().count("loading the example backend") == 1


def test_a_best_effort_image_publisher_gets_an_answer(launch, tmp_path):
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Image

    proc, c, log = launch(_example(tmp_path))
    _ready(c, log)
    camera = c.node.create_publisher(Image, "image_request", qos_profile_sensor_data)
    assert c.spin_until(lambda: camera.get_subscription_count() > 0, 20)
    rgb = (np.random.default_rng(1).random((48, 64, 3)) * 255).astype(np.uint8)
    # best effort may drop a frame (the reader can match a moment after the writer does), so
    # publish like a camera: a new frame every half second until one of them is answered
    sent = []
    for k in range(120):
        sent.append(f"camera-frame-{k}")
        camera.publish(rgb_to_image_msg(rgb, sent[-1], encoding="bgr8"))
        if c.spin_until(lambda: any(f in c.results for f in sent), 0.5):
            break
    answered = [c.results[f] for f in sent if f in c.results]
    assert answered, f"no frame of {len(sent)} answered\n{log.read_text()}"
    res = answered[0]
    assert res["status"] == "done", res
    assert res["kind"] == "image" and res["prompt"] == "<image 64x48>"


def test_markers_and_joint_states_at_the_openness_match_the_urdf(launch, tmp_path):
    proc, c, log = launch(_example(tmp_path, openness=0.4, frame_id="object_view",
                                   publish_rate=20.0))
    seen = _watch(c)
    _ready(c, log)
    res = c.wait_result(c.send_text("a cabinet with two drawers and a door"), 60)
    assert res["status"] == "done", res
    ref = UrdfReference(res["urdf_path"])
    assert len(ref.movable) == 3                       # two drawers and a door
    assert c.spin_until(lambda: seen["markers"] and seen["joints"], 20)
    _check_markers(seen["markers"][-1], ref, 0.4, "object_view")
    js = seen["joints"][-1]
    assert sorted(js.name) == sorted(ref.movable)
    expected = ref.positions(0.4)
    assert np.allclose([expected[n] for n in js.name], js.position)
    # joint_states keep coming (robot_state_publisher's TF stays fresh)
    n = len(seen["joints"])
    assert c.spin_until(lambda: len(seen["joints"]) >= n + 5, 10)
    # a live openness change re-poses the object
    k = len(seen["markers"])
    _set_parameter(c, f"{c.node.get_namespace()}/artformer_generator", "openness", 1.0)
    assert c.spin_until(lambda: len(seen["markers"]) > k, 10)
    _check_markers(seen["markers"][-1], ref, 1.0, "object_view")
    assert c.spin_until(lambda: np.allclose(
        [ref.positions(1.0)[n] for n in seen["joints"][-1].name], seen["joints"][-1].position), 10)


def test_animate_sweeps_the_object_back_and_forth(launch, tmp_path):
    proc, c, log = launch(_example(tmp_path, animate=True, animate_period=1.0,
                                   publish_rate=20.0))
    seen = _watch(c)
    _ready(c, log)
    res = c.wait_result(c.send_text("a bottle with a cap"), 60)   # a screw: slide + turn
    assert res["status"] == "done", res
    ref = UrdfReference(res["urdf_path"])
    assert c.spin_until(lambda: len(seen["joints"]) >= 2, 20)
    m0, j0 = len(seen["markers"]), len(seen["joints"])
    c.spin_until(lambda: False, 1.5)
    joints, markers = seen["joints"][j0:], seen["markers"][m0:]
    assert len(joints) >= 15 and len(markers) >= 15, (len(joints), len(markers))
    for a, b in zip(markers, markers[1:]):            # successive messages differ
        assert any(not np.allclose(_pose(p), _pose(q)) for p, q in zip(_meshes(a), _meshes(b)))
    for a, b in zip(joints, joints[1:]):
        assert list(a.position) != list(b.position)
    names = list(joints[0].name)
    assert sorted(names) == sorted(ref.movable)
    slide = np.array([j.position[names.index("cap_slide")] for j in joints])
    lim = ref.movable["cap_slide"].limit
    span = lim.upper - lim.lower
    assert slide.min() >= lim.lower - 1e-9 and slide.max() <= lim.upper + 1e-9
    assert slide.min() < lim.lower + 0.25 * span and slide.max() > lim.upper - 0.25 * span
    # a marker update and a joint_states message go out together at each tick, with the
    # same pose: each marker message is the URDF's FK at the positions of one of them
    # (not the very last: its joint_states twin may still be in flight when the window ends)
    for arr in markers[-4:-1]:
        assert {m.header.frame_id for m in arr.markers} == {"world"}
        assert any(_markers_match(arr, ref, dict(zip(js.name, js.position)))
                   for js in joints), "no joint_states pose fits the markers"


PATH_KEYS = ("urdf_path", "metadata_path", "preview_path")


def _missing_paths(result):
    """Paths named by an answer that do not exist (checked the moment it arrives)."""
    missing = []
    for entry in [result] + list(result.get("samples", [])):
        if entry.get("output_dir") and not os.path.isdir(entry["output_dir"]):
            missing.append(entry["output_dir"])
        for key in PATH_KEYS:
            if entry.get(key) and not os.path.isfile(entry[key]):
                missing.append(entry[key])
        missing += [p for p in (entry.get("mesh_paths") or {}).values()
                    if not os.path.isfile(p)]
    return missing


def test_no_answer_names_a_missing_file(launch, tmp_path):
    from std_msgs.msg import String

    from artformer_ros.generator_node import RESULTS

    proc, c, log = launch(_example(tmp_path, queue_size=12, samples=2, preview=True))
    checked = []
    c.node.create_subscription(
        String, "generation_result",
        lambda m: checked.append(_missing_paths(json.loads(m.data))), RESULTS)
    _ready(c, log)
    ids = [c.send_text(f"cabinet {i}", request_id=f"p{i}") for i in range(10)]
    assert c.spin_until(lambda: all(i in c.results for i in ids) and len(checked) == 10, 120)
    assert [c.results[i]["status"] for i in ids] == ["done"] * 10
    assert checked == [[]] * 10, checked
    for i in ids:   # the example backend draws no preview: the answer names none
        assert c.results[i]["preview_path"] is None
        assert len(c.results[i]["samples"]) == 2
