"""Pure conversions of the node (text/image requests, results, markers) and its parameters —
no node, no spinning."""
import json
import math
import os
import subprocess
import sys
from dataclasses import fields

import numpy as np
import pytest

from artformer_ros.conversions import (RequestError, decode_cdr_string, image_to_rgb,
                                       joint_state, markers_from_urdf, matrix_to_quaternion,
                                       mesh_visuals, parse_text_request, result_to_json, slug)
from artformer_ros.params import PARAMS, SPECS, NodeSettings, validate

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# -- text ------------------------------------------------------------------------------------
def test_cdr_string_round_trip_with_rclpy_serialization():
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    for text in ["", "a cabinet", "schrank mit tür ✓", "x" * 1001]:
        raw = serialize_message(String(data=text))
        assert decode_cdr_string(raw) == text.encode("utf-8")


def test_cdr_big_endian_and_garbage():
    body = "hé".encode() + b"\x00"
    be = b"\x00\x00\x00\x00" + len(body).to_bytes(4, "big") + body
    assert decode_cdr_string(be) == "hé".encode()
    with pytest.raises(ValueError, match="too short"):
        decode_cdr_string(b"\x00\x01")
    with pytest.raises(ValueError, match="exceeds"):
        decode_cdr_string(b"\x00\x01\x00\x00" + (99).to_bytes(4, "little") + b"ab\x00")
    with pytest.raises(ValueError, match="encapsulation"):
        decode_cdr_string(b"\x07\x09\x00\x00" + (1).to_bytes(4, "little") + b"\x00")


def test_plain_text_gets_the_assigned_id_and_is_stripped():
    req = parse_text_request(b"  a cabinet with two drawers \n", max_length=100,
                             assigned_id="text-3")
    assert (req.request_id, req.text, req.seed, req.id_given) == \
        ("text-3", "a cabinet with two drawers", None, False)


def test_json_request_fields():
    req = parse_text_request(json.dumps({"id": 42, "text": "a safe", "seed": 9}).encode(),
                             max_length=100, assigned_id="text-1")
    assert (req.request_id, req.text, req.seed, req.id_given) == ("42", "a safe", 9, True)


@pytest.mark.parametrize("payload,match,rid", [
    (b"", "empty request", "t"),
    (b" \t\n  ", "empty request", "t"),
    (b"x" * 11, "too long: 11 characters > max_text_length 10", "t"),
    ("é".encode() * 10 + b"x", "too long", "t"),
    (b"x" * 5000, "too long: 5000 bytes", "t"),
    (b"\xff\xfe a cabinet", "not valid UTF-8", "t"),
    (b"caf\xc3", "not valid UTF-8", "t"),
    (b"a\x00b", "control character", "t"),
    (b"a\x1b[31m", "control character", "t"),
    (b"{not json", "not valid JSON", "t"),
    (b'{"text": "a"} trailing', "not valid JSON", "t"),
    (b'{"id": "r1"}', "needs a string 'text'", "r1"),
    (b'{"id": "r2", "text": 5}', "needs a string 'text'", "r2"),
    (b'{"id": "r3", "text": "ok", "seed": -1}', "'seed' must be an integer", "r3"),
    (b'{"id": "r4", "text": "ok", "seed": 1.5}', "'seed' must be an integer", "r4"),
    (b'{"id": "r5", "text": "ok", "seed": true}', "'seed' must be an integer", "r5"),
    (b'{"id": "r6", "text": "ok", "colour": "red"}', "unknown key", "r6"),
    (b'{"id": "r7", "text": "   "}', "empty request", "r7"),
    (b'{"id": "", "text": "ok"}', "'id' is empty", "t"),
    (b'{"id": [1], "text": "ok"}', "'id' must be a string", "t"),
    (('{"id": "' + "i" * 200 + '", "text": "ok"}').encode(), "at most 128", "t"),
])
def test_bad_text_requests_raise_with_a_reason_and_the_right_id(payload, match, rid):
    with pytest.raises(RequestError, match=match) as info:
        parse_text_request(payload, max_length=10, assigned_id="t")
    assert info.value.request_id == rid


def test_valid_unicode_is_accepted_including_a_literal_replacement_character():
    req = parse_text_request("eine Kiste mit Tür \ufffd".encode(), max_length=100,
                             assigned_id="t")
    assert req.text.endswith("\ufffd")


def test_slug():
    assert slug("a/b c..d") == "a-b-c-d"
    assert slug("///") == "request"
    assert len(slug("x" * 100)) == 40


# -- images ----------------------------------------------------------------------------------
class Img:
    def __init__(self, h, w, enc, step=None, data=None, channels=3):
        self.height, self.width, self.encoding = h, w, enc
        self.step = w * channels if step is None else step
        self.data = bytes(self.step * h) if data is None else data
        self.is_bigendian = 0


def _rgb(h=3, w=4):
    return np.arange(h * w * 3, dtype=np.uint8).reshape(h, w, 3)


def test_rgb8_bgr8_rgba8_bgra8_mono8_with_row_padding():
    rgb = _rgb()
    alpha = np.full((3, 4, 1), 7, np.uint8)
    for enc, pix in [("rgb8", rgb), ("bgr8", rgb[:, :, ::-1]),
                     ("rgba8", np.concatenate([rgb, alpha], 2)),
                     ("bgra8", np.concatenate([rgb[:, :, ::-1], alpha], 2))]:
        ch = pix.shape[2]
        padded = np.zeros((3, 4 * ch + 5), np.uint8)      # 5 bytes of row padding
        padded[:, :4 * ch] = pix.reshape(3, -1)
        out = image_to_rgb(Img(3, 4, enc, step=4 * ch + 5, data=padded.tobytes()),
                           max_pixels=100)
        assert out.shape == (3, 4, 3) and out.dtype == np.uint8
        np.testing.assert_array_equal(out, rgb, err_msg=enc)
    data = bytearray(rgb.tobytes())
    out = image_to_rgb(Img(3, 4, "rgb8", data=data), max_pixels=100)
    data[0] = 255                                  # the result does not alias the message
    assert out[0, 0, 0] == 0 and out.flags.owndata and out.flags.c_contiguous
    mono = np.arange(12, dtype=np.uint8).reshape(3, 4)
    out = image_to_rgb(Img(3, 4, "mono8", data=mono.tobytes(), channels=1), max_pixels=100)
    np.testing.assert_array_equal(out, np.repeat(mono[:, :, None], 3, 2))


def test_image_from_a_real_sensor_msg():
    from artformer_ros.client import rgb_to_image_msg

    rgb = _rgb(5, 6)
    for enc in ("rgb8", "bgr8"):
        np.testing.assert_array_equal(image_to_rgb(rgb_to_image_msg(rgb, "id", enc),
                                                   max_pixels=100), rgb)


@pytest.mark.parametrize("img,match", [
    (Img(3, 4, "rgb16"), "unsupported image encoding"),
    (Img(3, 4, "yuv422"), "unsupported image encoding"),
    (Img(0, 4, "rgb8"), "zero size"),
    (Img(3, 0, "rgb8", step=0, data=b""), "zero size"),
    (Img(100000, 100000, "rgb8", step=300000, data=b"\x00" * 12), "too large"),
    (Img(3, 4, "rgb8", step=11), "smaller than width"),
    (Img(3, 4, "rgb8", data=b"\x00" * 35), "does not match"),
    (Img(3, 4, "rgb8", data=b"\x00" * 37), "does not match"),
])
def test_bad_images_raise_with_a_reason(img, match):
    with pytest.raises(ValueError, match=match):
        image_to_rgb(img, max_pixels=1000)


# -- results and markers ---------------------------------------------------------------------
def test_result_json_is_strict():
    text = result_to_json({"a": np.float32(1.5), "b": float("nan"), "c": np.arange(2),
                           "d": {"e": math.inf}, 3: (1, 2)})
    assert json.loads(text) == {"a": 1.5, "b": None, "c": [0, 1], "d": {"e": None}, "3": [1, 2]}


URDF = """<robot name="r">
  <material name="red"><color rgba="1 0 0 1"/></material>
  <link name="body"><visual><origin xyz="0.1 0.2 0.3" rpy="0 0 1.5707963"/>
    <geometry><mesh filename="file:///x/body.obj" scale="2"/></geometry>
    <material name="red"/></visual>
    <visual><geometry><box size="1 1 1"/></geometry></visual></link>
  <link name="door_0"><visual><geometry><mesh filename="/abs/door.obj"/></geometry>
    <material name="m"><color rgba="0 0 1 0.5"/></material></visual></link>
  <link name="helper"/>
</robot>"""


def _pose_matrix(marker):
    from scipy.spatial.transform import Rotation

    q = marker.pose.orientation
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    T[:3, 3] = [marker.pose.position.x, marker.pose.position.y, marker.pose.position.z]
    return T


def test_markers_follow_the_urdf_visuals_in_one_frame():
    from scipy.spatial.transform import Rotation
    from visualization_msgs.msg import Marker

    door_pose = np.eye(4)
    door_pose[:3, :3] = Rotation.from_euler("z", 0.7).as_matrix()
    door_pose[:3, 3] = [0.5, -0.25, 0.125]
    arr = markers_from_urdf(URDF, {"body": np.eye(4), "door_0": door_pose}, frame_id="map")
    clear, body, door = arr.markers
    assert clear.action == Marker.DELETEALL
    assert [m.header.frame_id for m in arr.markers] == ["map"] * 3
    assert all(m.type == Marker.MESH_RESOURCE and m.action == Marker.ADD and not m.frame_locked
               for m in (body, door))
    assert body.mesh_resource == "file:///x/body.obj"
    assert door.mesh_resource == "file:///abs/door.obj"
    assert (body.scale.x, body.scale.y, body.scale.z) == (2.0, 2.0, 2.0)
    assert (door.scale.x, door.scale.y, door.scale.z) == (1.0, 1.0, 1.0)
    assert (body.pose.position.x, body.pose.position.y, body.pose.position.z) == (0.1, 0.2, 0.3)
    assert body.pose.orientation.z == pytest.approx(math.sin(math.pi / 4), abs=1e-6)
    assert np.allclose(_pose_matrix(door), door_pose)        # visual origin 0: the link pose
    assert (body.color.r, body.color.b, body.color.a) == (1.0, 0.0, 1.0)
    assert (door.color.b, door.color.a) == (1.0, 0.5)
    assert len({m.id for m in (body, door)}) == 2
    again = markers_from_urdf(URDF, {"body": np.eye(4), "door_0": np.eye(4)}, clear=False)
    assert [m.id for m in again.markers] == [body.id, door.id]   # an update, no DELETEALL
    with pytest.raises(ValueError, match="door_0"):
        markers_from_urdf(URDF, {"body": np.eye(4)})


def test_quaternion_of_a_matrix_matches_scipy_including_half_turns():
    from scipy.spatial.transform import Rotation

    rots = list(Rotation.random(50, random_state=0))
    rots += [Rotation.from_rotvec(np.pi * np.array(a, float) / np.linalg.norm(a))
             for a in ([1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [0, 1, -1])]
    rots.append(Rotation.identity())
    for r in rots:
        q = np.array(matrix_to_quaternion(r.as_matrix()))
        ref = r.as_quat()
        assert np.isclose(np.linalg.norm(q), 1.0) and q[3] >= 0
        assert np.allclose(q, ref, atol=1e-9) or np.allclose(q, -ref, atol=1e-9)


@pytest.mark.parametrize("make", ["example_cabinet", "example_bottle"])
def test_object_pose_matches_the_urdf_forward_kinematics(tmp_path, make):
    """ObjectPose (the core's kinematics) against yourdfpy's FK of the exported URDF: the
    same link poses for the positions it puts on joint_states, and those positions are
    lerp(lower, upper, openness) of the URDF limits (the bottle's cap is a screw)."""
    import yourdfpy

    from artformer_ros.kinematics import ObjectPose
    from model.core import example
    from model.export import export_object

    res = export_object(getattr(example, make)(), tmp_path / "o", preview=False)
    pose = ObjectPose.from_urdf(res.urdf_path)
    urdf = yourdfpy.URDF.load(res.urdf_path, load_meshes=False,
                              build_collision_scene_graph=False, load_collision_meshes=False)
    movable = [j.name for j in urdf.robot.joints if j.type != "fixed"]
    xml = open(res.urdf_path).read()
    visuals = mesh_visuals(xml)
    assert {v["link"] for v in visuals} == set(res.mesh_paths)
    assert all(os.path.exists(v["uri"][len("file://"):]) for v in visuals)
    for openness in (0.0, 0.3, 1.0):
        names, positions = pose.joint_positions(openness)
        assert sorted(names) == sorted(movable) and movable
        for name, value in zip(names, positions):
            lim = urdf.joint_map[name].limit
            assert value == pytest.approx(lim.lower + openness * (lim.upper - lim.lower))
        urdf.update_cfg(dict(zip(names, positions)))
        links = pose.link_poses(openness)
        for link, T in links.items():
            ref = urdf.get_transform(frame_to=link, frame_from=pose.root_link)
            assert np.allclose(T, ref, atol=1e-9), (link, openness)
        arr = markers_from_urdf(xml, links, frame_id="world")
        assert len(arr.markers) == len(visuals) + 1
        for vis, m in zip(visuals, arr.markers[1:]):
            visual = urdf.link_map[vis["link"]].visuals[0].origin
            ref = urdf.get_transform(frame_to=vis["link"], frame_from=pose.root_link) @ visual
            assert np.allclose(_pose_matrix(m), ref, atol=1e-6), vis["link"]
    closed, opened = pose.link_poses(0.0), pose.link_poses(1.0)
    assert any(not np.allclose(closed[k], opened[k]) for k in closed)


def test_sweep_goes_back_and_forth():
    from artformer_ros.kinematics import sweep

    got = [sweep(t, 4.0) for t in (0.0, 1.0, 2.0, 3.0, 4.0, 5.0)]
    assert got == pytest.approx([0.0, 0.5, 1.0, 0.5, 0.0, 0.5])
    with pytest.raises(ValueError):
        sweep(1.0, 0.0)


def test_joint_state_message():
    msg = joint_state(["a_joint", "b_slide"], [0.5, np.float32(0.25)])
    assert list(msg.name) == ["a_joint", "b_slide"] and list(msg.position) == [0.5, 0.25]
    with pytest.raises(ValueError):
        joint_state(["a"], [])


# -- parameters ------------------------------------------------------------------------------
def test_node_settings_defaults_match_the_parameter_table():
    defaults = NodeSettings()
    assert {f.name for f in fields(NodeSettings)} == set(SPECS)
    for spec in PARAMS:
        assert getattr(defaults, spec.name) == spec.default, spec.name
        assert validate(spec.name, spec.default) is None, spec.name
        assert spec.description


@pytest.mark.parametrize("name,value,match", [
    ("queue_size", 0, r"\[1, 1000\]"), ("seed", -2, "seed must be in"),
    ("seed", 1.5, "type int"), ("samples", True, "type int"), ("backend", "gpu", "one of"),
    ("mesh_format", "ply", "one of"), ("device", "tpu", "one of"), ("device", "cuda:0", "one of"),
    ("output_dir", " ", "empty"), ("mesh_uri", "http://x", "package://"),
    ("mesh_uri", "package://", "package://"), ("resolution", 512, "resolution"),
    ("preview", 1, "type bool"), ("guidance", -1.0, "guidance"), ("retention", 0, "retention"),
    ("frame_id", "", "frame_id"), ("frame_id", "/world", "frame_id"),
    ("openness", 1.5, r"\[0.0, 1.0\]"),
    ("animate", "yes", "type bool"), ("publish_rate", 0.0, "publish_rate"),
])
def test_invalid_parameter_values_have_a_reason(name, value, match):
    reason = validate(name, value)
    assert reason is not None and __import__("re").search(match, reason), reason
    with pytest.raises(ValueError):
        NodeSettings.from_values({name: value})


def test_valid_parameter_values_pass():
    for name, value in [("device", "cpu"), ("guidance", 2), ("seed", -1), ("seed", 0),
                        ("mesh_format", "glb"), ("backend", "example"),
                        ("mesh_uri", "package://artformer_ros/objects"), ("preview", False)]:
        assert validate(name, value) is None
    s = NodeSettings.from_values({"guidance": 2, "queue_size": 9, "use_sim_time": False})
    assert s.guidance == 2.0 and isinstance(s.guidance, float) and s.queue_size == 9


def test_generation_config_carries_the_model_parameters():
    s = NodeSettings(checkpoint="", resolution=32, steps=7, mesh_format="stl", refine=False,
                     prompt_structure=False, sibling_room=False,
                     hold_plan=False)
    cfg = s.generation_config()
    assert (cfg.checkpoint, cfg.resolution, cfg.steps, cfg.mesh_format) == (None, 32, 7, "stl")
    assert cfg.refine is False and NodeSettings().generation_config().refine is True
    assert cfg.prompt_structure is False
    assert NodeSettings().generation_config().prompt_structure is True
    assert cfg.sibling_room is False and NodeSettings().generation_config().sibling_room is True
    assert cfg.hold_plan is False and NodeSettings().generation_config().hold_plan is True


def test_config_yaml_holds_exactly_the_declared_defaults():
    import yaml

    with open(os.path.join(REPO, "config", "artformer.yaml")) as f:
        params = yaml.safe_load(f)["/**"]["ros__parameters"]   # any name, any namespace
    assert set(params) == set(SPECS)
    for name, value in params.items():
        assert validate(name, value) is None, name
        assert value == SPECS[name].default, name


def test_launch_file_passes_namespace_params_and_remaps_to_the_node(monkeypatch):
    """Runs generate_launch_description() against recording stand-ins of launch / launch_ros
    (not installable here): the node gets the declared namespace, params file and remaps."""
    import types

    made = {}

    class Config:                                  # LaunchConfiguration("x") -> its name
        def __init__(self, name):
            self.name = name

        def __eq__(self, other):
            return isinstance(other, Config) and other.name == self.name

    def module(name, **attrs):
        m = types.ModuleType(name)
        m.__dict__.update(attrs)
        monkeypatch.setitem(sys.modules, name, m)

    module("ament_index_python")
    module("ament_index_python.packages", get_package_share_directory=lambda p: f"/share/{p}")
    module("launch", LaunchDescription=list)
    module("launch.actions", DeclareLaunchArgument=lambda name, **kw: ("arg", name, kw))
    module("launch.substitutions", LaunchConfiguration=Config)
    module("launch_ros")
    module("launch_ros.actions", Node=lambda **kw: made.setdefault("node", kw))
    path = os.path.join(REPO, "launch", "artformer.launch.py")
    ns = {}
    exec(compile(open(path).read(), path, "exec"), ns)
    entities = ns["generate_launch_description"]()
    args = {e[1]: e[2]["default_value"] for e in entities if isinstance(e, tuple)}
    assert args == {"params_file": "/share/artformer_ros/config/artformer.yaml",
                    "namespace": "", "remap_description": "robot_description",
                    "remap_joint_states": "joint_states"}
    node = made["node"]
    assert (node["package"], node["executable"], node["name"]) == (
        "artformer_ros", "artformer_generator_node", "artformer_generator")
    assert node["namespace"] == Config("namespace")
    assert node["parameters"] == [Config("params_file")]
    assert node["remappings"] == [("robot_description", Config("remap_description")),
                                  ("joint_states", Config("remap_joint_states"))]


def test_node_module_import_is_light():
    code = ("import sys, artformer_ros.generator_node; "
            "heavy = [m for m in ('torch', 'trimesh', 'transformers', 'model.pipeline.generator')"
            " if m in sys.modules]; assert not heavy, heavy; print('ok')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
