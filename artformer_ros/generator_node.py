"""ROS 2 node ``artformer_generator``: text / image requests in, URDF + meshes out.

Topics (relative names, remappable):
  sub  text_request       std_msgs/String     plain text, or JSON {"text", "id"?, "seed"?,
                                               "structure"?, "size"?}
  sub  image_request      sensor_msgs/Image   rgb8 | bgr8 | rgba8 | bgra8 | mono8;
                                              request id = header.frame_id (else image-<n>);
                                              best effort: matches camera drivers and
                                              reliable publishers alike
  pub  robot_description  std_msgs/String     latest URDF (RELIABLE + TRANSIENT_LOCAL, depth 1)
  pub  mesh_paths         std_msgs/String     JSON {id, output_dir, urdf_path, mesh_paths} (latched)
  pub  markers            visualization_msgs/MarkerArray   the latest object's meshes in the
                                              fixed frame `frame_id`, posed at `openness` (latched)
  pub  joint_states       sensor_msgs/JointState  its movable joints at the same openness
  pub  generation_result  std_msgs/String     JSON per request: status done | error | rejected
  pub  status             std_msgs/String     JSON {state: loading|ready|failed|stopping} (latched)

The subscription callbacks only validate and queue (``GenerationService``); generation runs on
its worker thread. Requests that arrive during the model load wait in the queue. Every Python
log line (core and node) goes through the node's logger to /rosout. SIGINT / SIGTERM stop
the node cleanly with exit code 0.
"""
from __future__ import annotations

import json
import logging
import os
import signal
import sys
import threading
import time
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
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from artformer_ros.conversions import (MAX_ID_LENGTH, RequestError, decode_cdr_string,
                                       image_to_rgb, joint_state, markers_at, mesh_visuals,
                                       parse_text_request, result_to_json)
from artformer_ros.kinematics import ObjectPose, sweep
from artformer_ros.params import PARAMS, NodeSettings, ParamSpec, validate
from artformer_ros.rosout import route_python_logging
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
# Images: best effort (sensor-data QoS) so that camera drivers' best-effort streams match as
# well as reliable publishers; a lost image is a request never made, not a lost answer.
IMAGE_REQUESTS = QoSProfile(depth=16, history=HistoryPolicy.KEEP_LAST,
                            reliability=ReliabilityPolicy.BEST_EFFORT,
                            durability=DurabilityPolicy.VOLATILE)
# What our own clients publish images with (reliable: delivered unless the reader is gone).
IMAGE_PUBLISHER = QoSProfile(depth=16, history=HistoryPolicy.KEEP_LAST,
                             reliability=ReliabilityPolicy.RELIABLE)
# joint_state_publisher's convention, which robot_state_publisher subscribes with.
JOINT_STATES = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
# Parameters that change how the current object is shown.
_VIEW_PARAMS = ("frame_id", "openness", "animate", "animate_period")


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

    def __init__(self, load_backend: Optional[Callable] = None, *,
                 route_logging: bool = False, **node_kwargs):
        """``route_logging``: send every Python log record of the process through this
        node's logger to /rosout (what ``main`` does; undone by ``destroy_node``)."""
        super().__init__(NODE_NAME, **node_kwargs)
        self._pub_lock = threading.Lock()
        self._counters = {"text": 0, "image": 0}
        self._unroute_logging: Optional[Callable[[], None]] = None
        self._shown = None              # (ObjectPose, mesh visuals) of the latest object
        self._sweep_start = time.monotonic()
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
        self._pub_joints = self.create_publisher(JointState, "joint_states", JOINT_STATES)
        self._timer = self.create_timer(1.0 / self.settings.publish_rate, self._tick)

        if load_backend is None:
            from artformer_ros.backends import load_backend as default_loader
            load_backend = default_loader
        self.service = GenerationService(self.settings, partial(load_backend, self.settings),
                                         self._emit, self._publish_status)
        # raw: rclpy would decode invalid UTF-8 with replacement characters; we check it.
        self.create_subscription(String, "text_request", self._on_text, TEXT_REQUESTS, raw=True)
        self.create_subscription(Image, "image_request", self._on_image, IMAGE_REQUESTS)
        if route_logging:
            self._unroute_logging = route_python_logging(self)
        self.get_logger().info(
            f"backend={self.settings.backend} output_dir={self.settings.output_path} "
            f"queue_size={self.settings.queue_size} retention={self.settings.retention}")
        try:
            self.service.start()
        except Exception:
            self._restore_logging()
            raise

    def _restore_logging(self) -> None:
        if self._unroute_logging is not None:
            self._unroute_logging()
            self._unroute_logging = None

    def destroy_node(self) -> None:
        self._restore_logging()
        super().destroy_node()

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
        names = {p.name for p in params}
        if "publish_rate" in names:
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(1.0 / self.settings.publish_rate, self._tick)
        if "animate" in names and self.settings.animate:
            self._sweep_start = time.monotonic()     # a sweep starts closed
        if names & set(_VIEW_PARAMS):
            self._show(clear=False)

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
        self.service.submit(Job(req.request_id, "text", text=req.text, seed=req.seed,
                                structure=req.structure, size=req.size))

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
        shown = None
        if urdf_xml is not None:
            try:   # the core's kinematics of the URDF just written (no meshes loaded)
                shown = (ObjectPose.from_urdf(result["urdf_path"], urdf_xml),
                         mesh_visuals(urdf_xml))
            except Exception as err:   # markers are a courtesy; the result still goes out
                self.get_logger().warning(f"no markers / joint_states for {result.get('id')}: "
                                          f"{type(err).__name__}: {err}")
        with self._pub_lock:
            if urdf_xml is not None:
                self._pub_description.publish(String(data=urdf_xml))
                self._pub_meshes.publish(String(data=result_to_json(
                    {k: result.get(k) for k in ("id", "output_dir", "urdf_path", "mesh_paths")})))
                self._shown = shown
                self._show_locked(clear=True)
            self._pub_result.publish(String(data=result_to_json(result)))
        if result.get("status") == "done":
            self.get_logger().info(f"request {result['id']} done in "
                                   f"{result['timings']['total']:.2f} s: {result['urdf_path']}")
        else:
            self.get_logger().warning(f"request {result.get('id')} {result.get('status')}: "
                                      f"{result.get('message')}")

    # -- the object in RViz ---------------------------------------------------------------
    def current_openness(self) -> float:
        if self.settings.animate:
            return sweep(time.monotonic() - self._sweep_start, self.settings.animate_period)
        return self.settings.openness

    def _show(self, clear: bool) -> None:
        with self._pub_lock:
            self._show_locked(clear)

    def _show_locked(self, clear: bool, markers: bool = True) -> None:
        """Markers (unless ``markers`` is False) and joint_states of the latest object at the
        current openness; ``clear`` = a new object (its markers replace the old ones)."""
        if self._shown is None:
            if clear:   # the new object cannot be shown: take the old one off the screen
                self._pub_markers.publish(markers_at([], {}, frame_id=self.settings.frame_id))
            return
        pose, visuals = self._shown
        openness = self.current_openness()
        try:
            if markers:
                self._pub_markers.publish(markers_at(
                    visuals, pose.link_poses(openness), frame_id=self.settings.frame_id,
                    clear=clear))
            names, positions = pose.joint_positions(openness)
            self._pub_joints.publish(joint_state(names, positions,
                                                 self.get_clock().now().to_msg()))
        except Exception as err:   # never let the display cost an answer
            self.get_logger().warning(f"cannot show the object: {type(err).__name__}: {err}")
            self._shown = None
            if clear:
                self._pub_markers.publish(markers_at([], {}, frame_id=self.settings.frame_id))

    def _tick(self) -> None:
        """joint_states at publish_rate; markers too while animating."""
        with self._pub_lock:
            self._show_locked(clear=False, markers=self.settings.animate)

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
        node = GeneratorNode(route_logging=True)
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


def main_old_name() -> int:
    """``generator_node``: the executable's earlier name, kept for one more release."""
    print("generator_node is now artformer_generator_node; the old name goes in the next release",
          file=sys.stderr)
    return main()
