"""Meshing lanes: a generated object's parts finished on several cores at once.

After the SDF network (torch, already on every core) each part still needs single-threaded
work: marching cubes, manifold construction, floater removal, simplification, collision
boxes (``model.pipeline.part_finish``). manifold3d and scikit-image hold the GIL, so
threads cannot share it; :class:`PartPool` keeps ``workers`` helper processes
(``python -m model.pipeline.part_pool``: numpy, scipy, scikit-image, trimesh and
manifold3d, no torch, ~0.6 s to start, ~100 MB each) and splits each object's parts
between them and the calling process by their cost (the SDF evaluations their surface
took), largest first.

The helpers are plain child processes speaking length-prefixed pickles over their
stdin/stdout; they never fork the caller (a ROS node's threads, torch's thread pool) and
never import its ``__main__``. A helper that dies, hangs past ``timeout`` seconds or
fails is stopped, its parts are finished in the calling process, and a fresh helper
starts on the next object: a request never fails because of a helper. The result does not
depend on the number of helpers (every part goes through the same arrays).
"""
from __future__ import annotations

import logging
import os
import pickle
import select
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Optional

from model.core.runtime import proc_memory_kb

from .part_finish import PartTask, finish_parts

log = logging.getLogger(__name__)

_ROOT = str(Path(__file__).resolve().parents[2])     # the folder that holds ``model``
_HEADER = 8


def default_workers() -> int:
    """One helper per core beyond the first, at most 3 (the parts of one object)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:          # not Linux
        cores = os.cpu_count() or 1
    return max(0, min(3, cores - 1))


class HelperError(RuntimeError):
    """A helper process died, hung or failed; its parts are finished by the caller."""


class _Helper:
    def __init__(self):
        env = dict(os.environ)
        env["PYTHONPATH"] = _ROOT + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            env[k] = "1"                 # one core each: the lanes are the parallelism
        self.proc = subprocess.Popen([sys.executable, "-m", "model.pipeline.part_pool"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env,
                                     cwd=_ROOT)

    def send(self, tasks: list) -> None:
        try:
            _write(self.proc.stdin, tasks)
        except (BrokenPipeError, OSError, ValueError) as e:
            raise HelperError(f"could not send parts to the meshing helper: {e}") from e

    def receive(self, timeout: float) -> list:
        status, payload = _read(self.proc.stdout, timeout)
        if status != "ok":
            raise HelperError(f"meshing helper failed:\n{payload}")
        return payload

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            pass
        for f in (self.proc.stdin, self.proc.stdout):
            try:
                f.close()
            except OSError:
                pass


class PartPool:
    """``finish(tasks)`` = ``finish_parts(tasks)``, spread over ``workers`` helpers and the
    calling process. ``workers`` 0 (or one part) runs everything in the caller."""

    def __init__(self, workers: int = 0, timeout: float = 120.0):
        self.workers = max(0, int(workers))
        self.timeout = float(timeout)
        self._helpers: list[Optional[_Helper]] = [None] * self.workers
        self._lock = threading.Lock()
        self.failures = 0

    def start(self) -> "PartPool":
        """Start the helpers now (they import for ~0.6 s) instead of on the first object."""
        with self._lock:
            for i in range(self.workers):
                self._helper(i)
        return self

    def _helper(self, i: int) -> _Helper:
        h = self._helpers[i]
        if h is None or not h.alive():
            if h is not None:
                h.stop()
            h = self._helpers[i] = _Helper()
        return h

    def finish(self, tasks: list) -> list:
        if self.workers == 0 or len(tasks) < 2 or not self._lock.acquire(blocking=False):
            return finish_parts(tasks)     # (another thread holds the helpers: no waiting)
        try:
            return self._finish(tasks)
        finally:
            self._lock.release()

    def _finish(self, tasks: list) -> list:
        lanes = split_by_cost(tasks, 1 + min(self.workers, len(tasks) - 1))
        sent = []
        for i, lane in enumerate(lanes[1:]):
            try:
                h = self._helper(i)
                h.send(lane)
                sent.append((h, i, lane))
            except (HelperError, OSError) as e:
                self._fail(i, e)
                lanes[0] = lanes[0] + lane
        try:
            done = finish_parts(lanes[0])
        except BaseException:
            for h, i, _ in sent:       # their answers must not be read as the next object's
                self._drop(i)
            raise
        deadline = time.monotonic() + self.timeout
        for h, i, lane in sent:
            try:
                done += h.receive(max(0.1, deadline - time.monotonic()))
            except (HelperError, OSError, EOFError, pickle.UnpicklingError) as e:
                self._fail(i, e)
                done += finish_parts(lane)
        by_index = {d.index: d for d in done}
        return [by_index[t.index] for t in tasks]

    def _fail(self, i: int, err: Exception) -> None:
        self.failures += 1
        log.warning("meshing helper %d: %s; its parts are finished here and a new helper "
                    "starts on the next object", i, err)
        self._drop(i)

    def _drop(self, i: int) -> None:
        h, self._helpers[i] = self._helpers[i], None
        if h is not None:
            h.stop()

    def peak_rss_mb(self) -> float:
        """The helpers' resident-set high-water marks, summed (MB; 0 without helpers)."""
        total = 0.0
        for h in self._helpers:
            if h is None or not h.alive():
                continue
            try:
                total += proc_memory_kb(h.proc.pid)["VmHWM"] / 1024.0
            except (OSError, KeyError):
                pass
        return total

    def close(self) -> None:
        with self._lock:
            for i, h in enumerate(self._helpers):
                if h is not None:
                    h.stop()
                self._helpers[i] = None

    def __del__(self):
        try:
            self.close()
        except Exception:  # interpreter shutdown: the children get EOF and exit anyway
            pass


def split_by_cost(tasks: list[PartTask], lanes: int) -> list[list[PartTask]]:
    """Largest first, each part to the lane with the least work so far (lane 0 is the
    caller's). Deterministic for given tasks."""
    out: list[list[PartTask]] = [[] for _ in range(max(1, lanes))]
    load = [0.0] * len(out)
    for t in sorted(tasks, key=lambda t: (-t.cost, t.index)):
        j = min(range(len(out)), key=lambda k: (load[k], k))
        out[j].append(t)
        load[j] += t.cost
    return out


# -- framing: 8-byte big-endian length + pickle -------------------------------------------------
def _write(f, obj) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    f.write(len(data).to_bytes(_HEADER, "big"))
    f.write(data)
    f.flush()


def _read_exact(f, n: int, deadline: Optional[float]) -> bytes:
    fd = f.fileno()
    buf = bytearray()
    while len(buf) < n:
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                raise HelperError("meshing helper did not answer in time")
        chunk = os.read(fd, min(n - len(buf), 1 << 20))
        if not chunk:
            raise EOFError("meshing helper exited")
        buf += chunk
    return bytes(buf)


def _read(f, timeout: Optional[float]):
    deadline = None if timeout is None else time.monotonic() + timeout
    n = int.from_bytes(_read_exact(f, _HEADER, deadline), "big")
    return pickle.loads(_read_exact(f, n, deadline))


def _serve() -> None:
    """The helper's loop: parts in, finished parts out, until stdin closes."""
    import traceback

    # what finishing a part needs, imported now (while the caller loads its model), not
    # during the first object
    import manifold3d  # noqa: F401
    import scipy.ndimage  # noqa: F401
    import skimage.measure  # noqa: F401
    import trimesh  # noqa: F401

    import model.export.collision  # noqa: F401
    import model.refine.prepare  # noqa: F401
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)                    # stray prints from libraries go to stderr, not the pipe
    inp = sys.stdin.buffer
    while True:
        try:
            tasks = _read(inp, None)
        except EOFError:
            return
        try:
            reply = ("ok", finish_parts(tasks))
        except Exception:            # the caller finishes these parts itself and reports
            reply = ("error", traceback.format_exc())
        _write(out, reply)


if __name__ == "__main__":
    _serve()
