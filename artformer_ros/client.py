"""Client side of the generator node, shared by the ``request`` demo, the benchmark and the
tests: a small rclpy node that sends requests and collects answers, plus helpers to run the
generator node in its own process and read its memory from /proc.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import uuid
from typing import Any, Callable, Optional

import numpy as np

from model.core.runtime import proc_memory_kb  # noqa: F401  (part of this module's API)

LOCALHOST_ENV = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}


def rgb_to_image_msg(rgb: np.ndarray, request_id: str = "", encoding: str = "rgb8"):
    """(H, W, 3) uint8 RGB -> sensor_msgs/Image (rgb8 or bgr8); header.frame_id = request id."""
    from sensor_msgs.msg import Image

    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) uint8 array, got {rgb.dtype} {rgb.shape}")
    if encoding not in ("rgb8", "bgr8"):
        raise ValueError(f"encoding must be rgb8 or bgr8, got {encoding!r}")
    data = rgb if encoding == "rgb8" else rgb[:, :, ::-1]
    msg = Image()
    msg.header.frame_id = request_id
    msg.height, msg.width = int(rgb.shape[0]), int(rgb.shape[1])
    msg.encoding, msg.is_bigendian, msg.step = encoding, 0, int(rgb.shape[1]) * 3
    msg.data = np.ascontiguousarray(data).tobytes()
    return msg


def load_rgb(path: str) -> np.ndarray:
    """An image file as (H, W, 3) uint8 RGB."""
    from PIL import Image as PILImage

    with PILImage.open(path) as im:
        return np.asarray(im.convert("RGB"), dtype=np.uint8)


class GeneratorClient:
    """Talks to one generator node (topics relative to ``namespace``)."""

    def __init__(self, *, context=None, namespace: str = "", name: Optional[str] = None,
                 watch_description: bool = True, watch_rosout: bool = False):
        """``watch_rosout``: collect the generator node's /rosout lines in ``self.rosout``
        as (logger name, level, message), earlier ones included (/rosout is latched)."""
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from sensor_msgs.msg import Image
        from std_msgs.msg import String

        from artformer_ros.generator_node import (IMAGE_PUBLISHER, LATCHED, RESULTS,
                                                  TEXT_REQUESTS)

        self._context = context
        self.node = rclpy.create_node(name or f"artformer_client_{uuid.uuid4().hex[:8]}",
                                      namespace=namespace, context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.results: dict[str, dict] = {}
        self.result_order: list[dict] = []
        self.status: Optional[dict] = None
        self.descriptions: list[tuple[float, str]] = []   # (monotonic arrival, URDF)
        self.mesh_paths: list[dict] = []
        self.node.create_subscription(String, "generation_result", self._on_result, RESULTS)
        self.node.create_subscription(String, "status", self._on_status, LATCHED)
        self.node.create_subscription(String, "mesh_paths",
                                      lambda m: self.mesh_paths.append(json.loads(m.data)),
                                      LATCHED)
        if watch_description:
            self.node.create_subscription(
                String, "robot_description",
                lambda m: self.descriptions.append((time.monotonic(), m.data)), LATCHED)
        self.rosout: list[tuple[str, int, str]] = []
        if watch_rosout:
            from rcl_interfaces.msg import Log
            from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

            prefix = ".".join([p for p in namespace.split("/") if p] + ["artformer_generator"])
            qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)

            def on_log(m):
                if m.name == prefix or m.name.startswith(prefix + "."):
                    self.rosout.append((m.name, int(m.level), m.msg))

            self.node.create_subscription(Log, "/rosout", on_log, qos)
        self.text_pub = self.node.create_publisher(String, "text_request", TEXT_REQUESTS)
        self.image_pub = self.node.create_publisher(Image, "image_request", IMAGE_PUBLISHER)
        self._String = String

    # -- plumbing -------------------------------------------------------------------------
    def _on_result(self, msg) -> None:
        res = json.loads(msg.data)
        res["_received"] = time.monotonic()
        self.results[str(res.get("id"))] = res
        self.result_order.append(res)

    def _on_status(self, msg) -> None:
        self.status = json.loads(msg.data)

    def spin_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        end = time.monotonic() + timeout
        while not predicate():
            left = end - time.monotonic()
            if left <= 0:
                return False
            self.executor.spin_once(timeout_sec=min(0.05, left))
        return True

    def wait_ready(self, timeout: float) -> bool:
        """Until the node says 'ready' and listens on both request topics (False: timeout or
        the model failed to load — see ``self.status``)."""
        ok = self.spin_until(lambda: self.status is not None
                             and self.status.get("state") in ("ready", "failed"), timeout)
        if not ok or self.status.get("state") != "ready":
            return False
        return self.spin_until(lambda: self.text_pub.get_subscription_count() > 0
                               and self.image_pub.get_subscription_count() > 0, timeout)

    # -- requests -------------------------------------------------------------------------
    def send_text(self, text: str, *, request_id: Optional[str] = None,
                  seed: Optional[int] = None) -> str:
        """Send a JSON text request and return its id (a fresh uuid unless given)."""
        rid = request_id or uuid.uuid4().hex[:12]
        payload: dict[str, Any] = {"id": rid, "text": text}
        if seed is not None:
            payload["seed"] = seed
        self.text_pub.publish(self._String(data=json.dumps(payload)))
        return rid

    def send_raw_text(self, data: str | bytes) -> None:
        """Publish exactly ``data`` (bytes are sent as a pre-serialized CDR String, which is
        the only way to put invalid UTF-8 on the wire from Python)."""
        if isinstance(data, bytes):
            body = data + b"\x00"
            raw = b"\x00\x01\x00\x00" + len(body).to_bytes(4, "little") + body
            self.text_pub.publish(raw)
        else:
            self.text_pub.publish(self._String(data=data))

    def send_image(self, image, *, request_id: Optional[str] = None) -> str:
        """Send an (H, W, 3) RGB array (as rgb8) or a ready sensor_msgs/Image."""
        if isinstance(image, np.ndarray):
            rid = request_id or uuid.uuid4().hex[:12]
            image = rgb_to_image_msg(image, rid)
        else:
            rid = request_id or image.header.frame_id
            if request_id:
                image.header.frame_id = request_id
        self.image_pub.publish(image)
        return rid

    def wait_result(self, request_id: str, timeout: float) -> Optional[dict]:
        self.spin_until(lambda: request_id in self.results, timeout)
        return self.results.get(request_id)

    def close(self) -> None:
        self.executor.remove_node(self.node)
        self.node.destroy_node()
        self.executor.shutdown()


# ---------------------------------------------------------------------------------------------
# the node in its own process
# ---------------------------------------------------------------------------------------------
def node_command(params: dict[str, Any], *, executable: Optional[list[str]] = None,
                 extra_ros_args: Optional[list[str]] = None) -> list[str]:
    cmd = list(executable or [sys.executable, "-m", "artformer_ros.generator_node"])
    cmd.append("--ros-args")
    for k, v in params.items():
        if isinstance(v, bool):
            v = "true" if v else "false"
        cmd += ["-p", f"{k}:={v}"]
    return cmd + list(extra_ros_args or [])


def start_node(params: dict[str, Any], *, env: Optional[dict] = None,
               log_path: Optional[str] = None, executable: Optional[list[str]] = None,
               extra_ros_args: Optional[list[str]] = None) -> subprocess.Popen:
    """Start the generator node as a subprocess (stdout+stderr to ``log_path`` or DEVNULL)."""
    full_env = {**os.environ, **LOCALHOST_ENV, **(env or {})}
    out = open(log_path, "w") if log_path else subprocess.DEVNULL
    try:
        return subprocess.Popen(node_command(params, executable=executable,
                                             extra_ros_args=extra_ros_args),
                                env=full_env, stdout=out, stderr=subprocess.STDOUT)
    finally:
        if log_path:
            out.close()


def stop_node(proc: subprocess.Popen, timeout: float = 30.0, sig: int = 2) -> int:
    """Send SIGINT (default) and wait; kill after ``timeout``. Returns the exit code."""
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            return proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
            return -9
    return proc.returncode
