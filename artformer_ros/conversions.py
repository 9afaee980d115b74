"""Pure message conversions of the generator node (no rclpy, no node, no spinning).

* ``decode_cdr_string``     raw serialized std_msgs/String -> the exact UTF-8 bytes sent
* ``parse_text_request``    bytes of a text request -> ``TextRequest`` (or ``RequestError``)
* ``image_to_rgb``          sensor_msgs/Image (anything with its fields) -> (H, W, 3) uint8 RGB
* ``result_to_json``        result dict -> strict JSON text (no NaN, no numpy types)
* ``markers_at`` / ``markers_from_urdf``  mesh visuals (of a URDF) + posed link frames ->
                            visualization_msgs/MarkerArray of MESH_RESOURCE markers, one frame
* ``joint_state``           joint names + positions -> sensor_msgs/JointState

Message classes (``visualization_msgs``, ``sensor_msgs``) are plain rosidl Python types;
building them needs no ROS context, so all of this is unit-tested without a node.
"""
from __future__ import annotations

import json
import math
import struct
import unicodedata
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from model.core import files
from model.core.files import jsonable

# encoding -> number of 8-bit channels (sensor_msgs/image_encodings.hpp names)
IMAGE_ENCODINGS: dict[str, int] = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono8": 1}

MAX_ID_LENGTH = 128
SEED_MAX = 2**31 - 1
_TEXT_KEYS = ("id", "text", "seed", "structure", "size")


class RequestError(ValueError):
    """A request is malformed; ``str(err)`` is the message sent back, ``request_id`` its id."""

    def __init__(self, message: str, request_id: str):
        super().__init__(message)
        self.request_id = request_id


@dataclass
class TextRequest:
    request_id: str
    text: str
    seed: Optional[int]       # None = use the node's seed policy
    id_given: bool            # the client chose the id (JSON payload) vs. assigned by the node
    structure: Optional[dict] = None   # parts to force (model.pipeline.api.parse_structure)
    size: Optional[dict] = None        # the body's dimensions, m (model.data.prompt_size)


# ---------------------------------------------------------------------------------------------
# text requests
# ---------------------------------------------------------------------------------------------
def decode_cdr_string(raw: bytes) -> bytes:
    """Payload bytes of a serialized std_msgs/String, without decoding them.

    rclpy decodes a String with UTF-8 *replacement* (invalid bytes arrive as U+FFFD), so the
    node subscribes raw and decodes strictly itself. Layout: 4-byte encapsulation header
    (byte 1: 0x00/0x06 big endian, 0x01/0x07 little endian), uint32 length including the
    terminating NUL, the bytes, NUL.
    """
    if len(raw) < 8:
        raise ValueError(f"serialized message too short ({len(raw)} bytes)")
    kind = raw[1]
    if kind not in (0x00, 0x01, 0x06, 0x07) or raw[0] != 0:
        raise ValueError(f"unsupported CDR encapsulation {raw[:2].hex()}")
    (n,) = struct.unpack("<I" if kind & 1 else ">I", raw[4:8])
    if n == 0:  # some writers encode the empty string with length 0
        return b""
    if 8 + n > len(raw):
        raise ValueError(f"string length {n} exceeds the message ({len(raw) - 8} bytes)")
    body = raw[8:8 + n]
    return body[:-1] if body.endswith(b"\x00") else body


def _clean_id(value: Any, fallback: str) -> str:
    if isinstance(value, bool) or not isinstance(value, (str, int)):
        raise RequestError("request 'id' must be a string or an integer", fallback)
    rid = str(value).strip()
    if not rid:
        raise RequestError("request 'id' is empty", fallback)
    if len(rid) > MAX_ID_LENGTH or not rid.isprintable():
        raise RequestError(f"request 'id' must be printable and at most {MAX_ID_LENGTH} "
                           "characters", fallback)
    return rid


def _check_text(text: str, max_length: int, rid: str) -> str:
    text = text.strip()
    if not text:
        raise RequestError("empty request: the text is empty or only whitespace", rid)
    if len(text) > max_length:
        raise RequestError(f"text too long: {len(text)} characters > max_text_length "
                           f"{max_length}", rid)
    bad = [c for c in text if unicodedata.category(c) == "Cc" and c not in "\t\n\r"]
    if bad:
        raise RequestError(f"text contains {len(bad)} control character(s) "
                           f"(first {bad[0]!r})", rid)
    return text


def parse_text_request(payload: bytes | str, *, max_length: int, assigned_id: str) -> TextRequest:
    """Validate one text request.

    ``payload`` is plain text (the id becomes ``assigned_id``) or a JSON object
    ``{"text": str, "id": str|int (optional), "seed": int (optional), "structure": object
    (optional, docs/ros.md), "size": object (optional, e.g. {"width": 0.6})}``; a payload
    whose first non-blank character is ``{`` must be such an object. The form of a structure
    or size is checked here; whether the model can produce it, by the backend.
    """
    if isinstance(payload, (bytes, bytearray)):
        # Bound the work before decoding: a UTF-8 character is at most 4 bytes; JSON adds keys.
        if len(payload) > 4 * max_length + 4096:
            raise RequestError(f"text too long: {len(payload)} bytes > max_text_length "
                               f"{max_length} characters", assigned_id)
        try:
            text = bytes(payload).decode("utf-8", errors="strict")
        except UnicodeDecodeError as err:
            bad = bytes(payload)[err.start:err.start + 1]
            raise RequestError(f"text is not valid UTF-8 (byte {err.start}: {bad!r})",
                               assigned_id) from None
    else:
        text = payload
    if not text.lstrip().startswith("{"):
        return TextRequest(assigned_id, _check_text(text, max_length, assigned_id), None, False)
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as err:
        raise RequestError(f"request starts with '{{' but is not valid JSON: {err.msg} at "
                           f"character {err.pos}", assigned_id) from None
    if not isinstance(obj, dict):
        raise RequestError("a JSON request must be an object", assigned_id)
    rid = _clean_id(obj["id"], assigned_id) if "id" in obj else assigned_id
    unknown = sorted(set(obj) - set(_TEXT_KEYS))
    if unknown:
        raise RequestError(f"unknown key(s) {unknown} in JSON request; allowed: "
                           f"{list(_TEXT_KEYS)}", rid)
    if not isinstance(obj.get("text"), str):
        raise RequestError("JSON request needs a string 'text'", rid)
    seed = obj.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)
                             or not 0 <= seed <= SEED_MAX):
        raise RequestError(f"'seed' must be an integer in [0, {SEED_MAX}]", rid)
    from model.pipeline.api import parse_size, parse_structure
    structure = _checked(obj, "structure", lambda v: parse_structure(v).to_dict(), rid)
    size = _checked(obj, "size", parse_size, rid)
    return TextRequest(rid, _check_text(obj["text"], max_length, rid), seed, "id" in obj,
                       structure, size)


def _checked(obj: dict, key: str, parse, rid: str):
    """``parse(obj[key])``, None when absent; its GenerationError as this request's error."""
    from model.pipeline.api import GenerationError
    if obj.get(key) is None:
        return None
    try:
        return parse(obj[key])
    except GenerationError as err:
        raise RequestError(str(err), rid) from None


def slug(text: str, max_length: int = 40) -> str:
    """File-name-safe version of a request id."""
    return files.slug(text, default="request", keep="_-", sep="-", collapse=True,
                      max_length=max_length)


# ---------------------------------------------------------------------------------------------
# image requests
# ---------------------------------------------------------------------------------------------
def image_to_rgb(msg: Any, *, max_pixels: int) -> np.ndarray:
    """sensor_msgs/Image -> (H, W, 3) uint8 RGB (a copy). Raises ValueError with the reason.

    Rows may be padded (``step`` > width * channels); the data must be exactly step * height.
    """
    enc = str(msg.encoding).strip().lower()
    if enc not in IMAGE_ENCODINGS:
        raise ValueError(f"unsupported image encoding {msg.encoding!r}; supported: "
                         f"{sorted(IMAGE_ENCODINGS)}")
    ch = IMAGE_ENCODINGS[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    if h <= 0 or w <= 0:
        raise ValueError(f"image has zero size ({h}x{w})")
    if h * w > max_pixels:
        raise ValueError(f"image too large: {h}x{w} = {h * w} pixels > max_image_pixels "
                         f"{max_pixels}")
    if step < w * ch:
        raise ValueError(f"image step {step} is smaller than width*channels = {w * ch}")
    n = len(msg.data)
    if n != step * h:
        raise ValueError(f"image data length {n} does not match step*height = {step * h}")
    buf = np.frombuffer(msg.data, dtype=np.uint8)               # (step * H,)
    img = buf.reshape(h, step)[:, :w * ch].reshape(h, w, ch)    # (H, W, C)
    if enc == "mono8":
        return np.repeat(img, 3, axis=2)                        # (H, W, 3)
    if enc.startswith("bgr"):
        img = img[:, :, 2::-1]                                  # BGR(A) -> RGB
    return np.array(img[:, :, :3], order="C", copy=True)        # (H, W, 3), owns its data


# ---------------------------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------------------------
def result_to_json(result: dict) -> str:
    """Strict JSON (NaN/inf -> null, numpy -> Python, paths -> str) of a result dict."""
    return json.dumps(jsonable(result), allow_nan=False, ensure_ascii=False, sort_keys=True)


# ---------------------------------------------------------------------------------------------
# markers
# ---------------------------------------------------------------------------------------------
_PALETTE = [(0.80, 0.80, 0.82), (0.90, 0.55, 0.25), (0.30, 0.60, 0.90), (0.40, 0.75, 0.40),
            (0.85, 0.35, 0.45), (0.65, 0.50, 0.85), (0.95, 0.80, 0.30), (0.35, 0.80, 0.80)]


def _floats(text: Optional[str], n: int, default: float) -> list[float]:
    if not text:
        return [default] * n
    vals = [float(v) for v in text.split()]
    if len(vals) == 1 and n == 3:  # a scalar mesh scale
        vals = vals * 3
    if len(vals) != n:
        raise ValueError(f"expected {n} numbers, got {text!r}")
    return vals


def _rgba(material) -> Optional[list[float]]:
    color = material.find("color") if material is not None else None
    if color is None or not color.get("rgba"):
        return None
    vals = [float(v) for v in color.get("rgba").split()]
    return vals if len(vals) == 4 else None


def mesh_visuals(urdf_xml: str) -> list[dict]:
    """Every mesh visual of a URDF: link, resource URI, xyz, rpy, scale, rgba or None
    (inline colour, else the robot-level material of that name), in document order."""
    from lxml import etree  # lazy: only when markers are built

    root = etree.fromstring(urdf_xml.encode("utf-8"))
    named = {m.get("name"): _rgba(m) for m in root.findall("material")}
    out = []
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            mesh = visual.find("geometry/mesh")
            if mesh is None or not mesh.get("filename"):
                continue
            origin = visual.find("origin")
            material = visual.find("material")
            rgba = _rgba(material)
            if rgba is None and material is not None:
                rgba = named.get(material.get("name"))
            uri = mesh.get("filename")
            if "://" not in uri:
                uri = "file://" + uri
            out.append({"link": link.get("name"), "uri": uri,
                        "xyz": _floats(origin.get("xyz") if origin is not None else None, 3, 0.0),
                        "rpy": _floats(origin.get("rpy") if origin is not None else None, 3, 0.0),
                        "scale": _floats(mesh.get("scale"), 3, 1.0), "rgba": rgba})
    return out


def matrix_to_quaternion(R) -> tuple[float, float, float, float]:
    """Rotation part of a 3x3 or 4x4 matrix -> unit quaternion (x, y, z, w), w >= 0."""
    m = np.asarray(R, dtype=np.float64)[:3, :3]
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    # Shepperd: divide by the largest of the four candidates for numerical safety
    if tr > max(m[0, 0], m[1, 1], m[2, 2]):
        w = math.sqrt(max(1.0 + tr, 0.0)) / 2
        x, y, z = (m[2, 1] - m[1, 2]) / (4 * w), (m[0, 2] - m[2, 0]) / (4 * w), \
            (m[1, 0] - m[0, 1]) / (4 * w)
    elif m[0, 0] >= m[1, 1] and m[0, 0] >= m[2, 2]:
        x = math.sqrt(max(1.0 + m[0, 0] - m[1, 1] - m[2, 2], 0.0)) / 2
        w, y, z = (m[2, 1] - m[1, 2]) / (4 * x), (m[0, 1] + m[1, 0]) / (4 * x), \
            (m[0, 2] + m[2, 0]) / (4 * x)
    elif m[1, 1] >= m[2, 2]:
        y = math.sqrt(max(1.0 - m[0, 0] + m[1, 1] - m[2, 2], 0.0)) / 2
        w, x, z = (m[0, 2] - m[2, 0]) / (4 * y), (m[0, 1] + m[1, 0]) / (4 * y), \
            (m[1, 2] + m[2, 1]) / (4 * y)
    else:
        z = math.sqrt(max(1.0 - m[0, 0] - m[1, 1] + m[2, 2], 0.0)) / 2
        w, x, y = (m[1, 0] - m[0, 1]) / (4 * z), (m[0, 2] + m[2, 0]) / (4 * z), \
            (m[1, 2] + m[2, 1]) / (4 * z)
    q = np.array([x, y, z, w])
    q /= np.linalg.norm(q)
    return tuple(float(v) for v in (q if q[3] >= 0 else -q))


def visual_matrix(vis: dict) -> np.ndarray:
    """4x4 of a visual's origin in its link frame (a ``mesh_visuals`` entry)."""
    from artformer_ros.kinematics import origin_matrix

    return origin_matrix(vis["xyz"], vis["rpy"])


def markers_at(visuals: list[dict], link_poses: dict, *, frame_id: str = "world",
               stamp=None, clear: bool = True, namespace: str = "artformer",
               alpha: float = 1.0):
    """MarkerArray for RViz, everything in the one fixed frame ``frame_id``: a DELETEALL
    first when ``clear`` (a new object replaces the previous one), then one MESH_RESOURCE
    marker per mesh visual at ``link_poses[link] @ visual origin`` (``link_poses``: link ->
    4x4 posed link frame in the object frame, e.g. ``ObjectPose.link_poses``). Scale = the
    mesh scale, colour = the URDF material (a palette colour when it has none). ``stamp`` is a
    builtin_interfaces/Time (None: 0, RViz then draws the latest). Marker ids are the visual
    indices, so re-publishing a new pose modifies the markers in place."""
    from visualization_msgs.msg import Marker, MarkerArray

    arr = MarkerArray()
    if clear:
        wipe = Marker()
        wipe.header.frame_id = frame_id
        wipe.ns = namespace
        wipe.action = Marker.DELETEALL
        arr.markers.append(wipe)
    for i, vis in enumerate(visuals):
        if vis["link"] not in link_poses:
            raise ValueError(f"no pose for link {vis['link']!r}")
        T = np.asarray(link_poses[vis["link"]]) @ visual_matrix(vis)     # (4, 4)
        m = Marker()
        m.header.frame_id = frame_id
        if stamp is not None:
            m.header.stamp = stamp
        m.ns = namespace
        m.id = i
        m.type = Marker.MESH_RESOURCE
        m.action = Marker.ADD
        m.mesh_resource = vis["uri"]
        m.mesh_use_embedded_materials = False
        m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in T[:3, 3])
        qx, qy, qz, qw = matrix_to_quaternion(T)
        m.pose.orientation.x, m.pose.orientation.y = qx, qy
        m.pose.orientation.z, m.pose.orientation.w = qz, qw
        m.scale.x, m.scale.y, m.scale.z = vis["scale"]
        r, g, b, a = vis["rgba"] or (*_PALETTE[i % len(_PALETTE)], 1.0)
        m.color.r, m.color.g, m.color.b, m.color.a = r, g, b, a * float(alpha)
        arr.markers.append(m)
    return arr


def markers_from_urdf(urdf_xml: str, link_poses: dict, **kwargs):
    """``markers_at`` for the mesh visuals of a URDF text (see there for the keywords)."""
    return markers_at(mesh_visuals(urdf_xml), link_poses, **kwargs)


def joint_state(names: list[str], positions: list[float], stamp=None):
    """sensor_msgs/JointState with names and positions (velocity and effort left empty, as
    joint_state_publisher does for a pose that is set, not measured)."""
    from sensor_msgs.msg import JointState

    if len(names) != len(positions):
        raise ValueError(f"{len(names)} joint names but {len(positions)} positions")
    msg = JointState()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.name = list(names)
    msg.position = [float(p) for p in positions]
    return msg
