"""Python ``logging`` -> the node's ROS logger, so that the core's and the node's log lines
reach ``/rosout`` (and the ROS console) with their level.

A record of the Python logger ``model.pipeline.generator`` goes to the ROS logger
``<node logger>.model.pipeline.generator`` (an rclpy child logger, which publishes on the
node's ``/rosout``); DEBUG / INFO / WARNING / ERROR / CRITICAL map to DEBUG / INFO / WARN /
ERROR / FATAL. The Python root level follows the node logger's level (``--log-level``).
"""
from __future__ import annotations

import logging
import threading
from typing import Callable


class RosoutHandler(logging.Handler):
    """Forwards each record to a child of ``node_logger`` named like the Python logger."""

    def __init__(self, node_logger):
        super().__init__()
        self._base = node_logger
        self._children: dict = {}
        self._lock = threading.Lock()
        self.setFormatter(logging.Formatter("%(message)s"))   # + the traceback, if any

    def _logger(self, name: str):
        with self._lock:
            child = self._children.get(name)
            if child is None:
                child = self._children[name] = self._base.get_child(name)
            return child

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = self.format(record)
            ros = self._logger(record.name)
            # one call site per severity: rclpy refuses a call site whose severity changes
            if record.levelno >= logging.CRITICAL:
                ros.fatal(text)
            elif record.levelno >= logging.ERROR:
                ros.error(text)
            elif record.levelno >= logging.WARNING:
                ros.warning(text)
            elif record.levelno >= logging.INFO:
                ros.info(text)
            else:
                ros.debug(text)
        except Exception:
            self.handleError(record)


def route_python_logging(node) -> Callable[[], None]:
    """Send every Python log record of this process through ``node``'s logger (replacing the
    root logger's handlers: the ROS console prints them already). Returns the undo, which
    restores the previous handlers and level (call it before destroying the node)."""
    root = logging.getLogger()
    saved_handlers, saved_level = list(root.handlers), root.level
    handler = RosoutHandler(node.get_logger())
    for h in saved_handlers:
        root.removeHandler(h)
    root.addHandler(handler)
    # LoggingSeverity values are Python's (10 DEBUG ... 50 FATAL)
    root.setLevel(int(node.get_logger().get_effective_level()))

    def undo() -> None:
        root.removeHandler(handler)
        for h in saved_handlers:
            root.addHandler(h)
        root.setLevel(saved_level)

    return undo
