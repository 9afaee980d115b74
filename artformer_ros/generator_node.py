"""ROS 2 node ``artformer_generator``: text / image requests in, URDF + meshes out.

Topics (relative names, remappable):
  sub  text_request       std_msgs/String     plain text, or JSON {"text", "id"?, "seed"?}
  sub  image_request      sensor_msgs/Image   rgb8 | bgr8 | rgba8 | bgra8 | mono8;
                                              request id = header.frame_id (else image-<n>)
  pub  robot_description  std_msgs/String     latest URDF (RELIABLE + TRANSIENT_LOCAL, depth 1)
  pub  mesh_paths         std_msgs/String     JSON {id, output_dir, urdf_path, mesh_paths} (latched)
  pub  markers            visualization_msgs/MarkerArray   meshes per link for RViz (latched)
  pub  generation_result  std_msgs/String     JSON per request: status done | error | rejected
  pub  status             std_msgs/String     JSON {state: loading|ready|failed|stopping} (latched)

The subscription callbacks only validate and queue (``GenerationService``); generation runs on
its worker thread. SIGINT / SIGTERM stop the node cleanly with exit code 0.
"""
from __future__ import annotations

import json
import logging
import os
import signal
import sys
import threading
from functools import partial
from typing import Callable, Optional

import rclpy
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.exceptions import ParameterException
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Image
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from artformer_ros.conversions import (MAX_ID_LENGTH, RequestError, decode_cdr_string,
                                       image_to_rgb, markers_from_urdf, parse_text_request,
                                       result_to_json)
from artformer_ros.params import PARAMS, NodeSettings, ParamSpec, validate
from artformer_ros.service import GenerationService, Job, answer

NODE_NAME = "artformer_generator"

# The latched convention of robot_state_publisher: late subscribers get the last message.
LATCHED = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Results of a burst must all arrive: a deep reliable history (answers are small).
RESULTS = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)
# Transport buffers of the requests; admission control is the node's own queue_size.
TEXT_REQUESTS = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_LAST,
                           reliability=ReliabilityPolicy.RELIABLE)
IMAGE_REQUESTS = QoSProfile(depth=16, history=HistoryPolicy.KEEP_LAST,
                            reliability=ReliabilityPolicy.RELIABLE)


def _descriptor(spec: ParamSpec) -> ParameterDescriptor:
    kind = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER,
            float: ParameterType.PARAMETER_DOUBLE,
            str: ParameterType.PARAMETER_STRING}[type(spec.default)]
    d = ParameterDescriptor(name=spec.name, type=kind, description=spec.description,
                            read_only=spec.read_only)
    if spec.int_range:
        d.integer_range = [IntegerRange(from_value=spec.int_range[0],
                                        to_value=spec.int_range[1], step=0)]
    if spec.float_range:
        d.floating_point_range = [FloatingPointRange(from_value=spec.float_range[0],
                                                     to_value=spec.float_range[1], step=0.0)]
    if spec.choices:
        d.additional_constraints = "one of: " + ", ".join(spec.choices)
    return d


class GeneratorNode(Node):
    """Plumbing only: parameters, topics, message conversion; the work is in the service."""

    def __init__(self, load_backend: Optional[Callable] = None, **node_kwargs):
        super().__init__(NODE_NAME, **node_kwargs)
        self._pub_lock = threading.Lock()
        self._counters = {"text": 0, "image": 0}
        self.add_on_set_parameters_callback(self._check_parameters)
        for spec in PARAMS:   # the callback above also vets the initial (-p / YAML) values
            self.declare_parameter(spec.name, spec.default, _descriptor(spec))
        self.settings = NodeSettings.from_values(
            {spec.name: self.get_parameter(spec.name).value for spec in PARAMS})
        self.add_post_set_parameters_callback(self._apply_parameters)

        self._pub_description = self.create_publisher(String, "robot_description", LATCHED)
        self._pub_meshes = self.create_publisher(String, "mesh_paths", LATCHED)
        self._pub_markers = self.create_publisher(MarkerArray, "markers", LATCHED)
        self._pub_status = self.create_publisher(String, "status", LATCHED)
        self._pub_result = self.create_publisher(String, "generation_result", RESULTS)

        if load_backend is None:
            from artformer_ros.backends import load_backend as default_loader
            load_backend = default_loader
        self.service = GenerationService(self.settings, partial(load_backend, self.settings),
                                         self._emit, self._publish_status)
        # raw: rclpy would decode invalid UTF-8 with replacement characters; we check it.
        self.create_subscription(String, "text_request", self._on_text, TEXT_REQUESTS, raw=True)
        self.create_subscription(Image, "image_request", self._on_image, IMAGE_REQUESTS)
        self.get_logger().info(
            f"backend={self.settings.backend} output_dir={self.settings.output_path} "
            f"queue_size={self.settings.queue_size} retention={self.settings.retention}")
        self.service.start()

    # -- parameters -----------------------------------------------------------------------
    def _check_parameters(self, params) -> SetParametersResult:
        for p in params:
            reason = validate(p.name, p.value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, params) -> None:
        if not hasattr(self, "settings"):
            return
        for p in params:   # only live (not read-only) parameters can get here after start
            if hasattr(self.settings, p.name):
                value = float(p.value) if isinstance(getattr(self.settings, p.name), float) \
                    else p.value
                setattr(self.settings, p.name, value)
                self.get_logger().info(f"parameter {p.name} = {value!r}")

    # -- requests -------------------------------------------------------------------------
    def _next_id(self, kind: str) -> str:
        self._counters[kind] += 1
        return f"{kind}-{self._counters[kind]}"

    def _on_text(self, raw: bytes) -> None:
        rid = self._next_id("text")
        try:
            payload = decode_cdr_string(bytes(raw))
            req = parse_text_request(payload, max_length=self.settings.max_text_length,
                                     assigned_id=rid)
        except RequestError as err:
            self._emit(answer(err.request_id, "error", str(err)), None)
            return
        except ValueError as err:
            self._emit(answer(rid, "error", f"malformed message: {err}"), None)
            return
        self.get_logger().info(f"text request {req.request_id}: {req.text[:80]!r}")
        self.service.submit(Job(req.request_id, "text", text=req.text, seed=req.seed))

    def _on_image(self, msg: Image) -> None:
        rid = msg.header.frame_id.strip()
        if not rid or len(rid) > MAX_ID_LENGTH or not rid.isprintable():
            rid = self._next_id("image")
        try:
            rgb = image_to_rgb(msg, max_pixels=self.settings.max_image_pixels)
        except ValueError as err:
            self._emit(answer(rid, "error", f"bad image: {err}", kind="image"), None)
            return
        self.get_logger().info(f"image request {rid}: {rgb.shape[1]}x{rgb.shape[0]} "
                               f"{msg.encoding}")
        self.service.submit(Job(rid, "image", image=rgb))

    # -- outputs --------------------------------------------------------------------------
    def _emit(self, result: dict, urdf_xml: Optional[str]) -> None:
        """Publish one answer (called from the worker and from the subscription callbacks)."""
        with self._pub_lock:
            if urdf_xml is not None:
                self._pub_description.publish(String(data=urdf_xml))
                self._pub_meshes.publish(String(data=result_to_json(
                    {k: result.get(k) for k in ("id", "output_dir", "urdf_path", "mesh_paths")})))
                try:
                    self._pub_markers.publish(markers_from_urdf(urdf_xml))
                except Exception as err:   # markers are a courtesy; the result still goes out
                    self.get_logger().warning(f"no markers for {result.get('id')}: {err}")
            self._pub_result.publish(String(data=result_to_json(result)))
        if result.get("status") == "done":
            self.get_logger().info(f"request {result['id']} done in "
                                   f"{result['timings']['total']:.2f} s: {result['urdf_path']}")
        else:
            self.get_logger().warning(f"request {result.get('id')} {result.get('status')}: "
                                      f"{result.get('message')}")

    def flush(self, timeout: float = 1.0) -> None:
        """Wait (bounded) until reliable subscribers acknowledged the answers, so the last
        ones (e.g. the shutdown rejections) are not lost when the process ends right after.
        A subscriber that vanished without discovery noticing yet costs the full timeout."""
        from rclpy.duration import Duration

        try:
            self._pub_result.wait_for_all_acked(Duration(seconds=timeout))
        except Exception as err:   # best effort only
            self.get_logger().debug(f"flush: {err}")

    def _publish_status(self, state: str, message: str) -> None:
        with self._pub_lock:
            self._pub_status.publish(String(data=json.dumps(
                {"state": state, "message": message, "backend": self.settings.backend,
                 "node": self.get_fully_qualified_name()})))


def main(argv: Optional[list[str]] = None) -> int:
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format="[%(levelname)s] [%(name)s]: %(message)s")
    # Our own handlers: a signal only sets a flag; the main loop then shuts down in order.
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
        node = GeneratorNode()
    except (ParameterException, ValueError) as err:
        logging.getLogger("artformer_ros").error(f"invalid parameter: {err}")
        rclpy.try_shutdown()
        return 2
    except OSError as err:   # e.g. output_dir cannot be created
        logging.getLogger("artformer_ros").error(f"cannot start: {err}")
        rclpy.try_shutdown()
        return 1
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.2)
    finally:
        node.get_logger().info("shutting down: no new requests, queued ones rejected")
        clean = node.service.stop()
        node.flush()
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
    if not clean:
        # The worker is still inside the model's generate() (its result is discarded and
        # nothing was written) or the model is still loading. Leave without waiting: a native
        # call cannot be cut, and interpreter teardown under a running torch thread can crash.
        logging.getLogger("artformer_ros").info("abandoned the running model load / generation")
        logging.shutdown()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
