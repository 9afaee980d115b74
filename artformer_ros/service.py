"""Serving core of the generator node, free of rclpy: background model load, a bounded
request queue, one worker thread, output folders with retention, clean stop.

Every request gets exactly one answer through ``emit(result, urdf_xml)``: ``result`` is the
dict sent as JSON on ``generation_result``; ``urdf_xml`` is the URDF text of a successful
request (the node latches it on ``robot_description``) and None otherwise.

Output folders: ``<output_dir>/<UTC time>_<n>_<request id>/`` holding ``result.json`` and one
exported object folder per sample, ``sample_<k>/`` (URDF, meshes/, metadata.json). A folder
is created with two marker files: ``.artformer_output`` (it is ours: only such folders are ever deleted) and
``.partial`` (removed last, when everything is written). Folders still marked partial are
not results: they are removed on abandon and at the next start. A shutdown never interrupts
an export, so after a clean stop no partial folder exists.

Requests that arrive while the model loads wait in the same bounded queue (full: 'rejected'
at once) and are served when it is ready; if the load fails, each gets the reason.

Every path in an answer exists when the answer is published (the folder just written is
never a retention victim). With the ``preview`` parameter, ``preview.png`` is drawn into each
sample folder after the answer is published, when no request is waiting, and put off again
(between its three views) when one arrives; the answer's ``preview_path`` is therefore null,
and ``result.json`` in the request folder names the picture once it is written (atomically).
A picture may never come: the node stops first, retention removes the folder, or a burst
pushes it out of the two newest pending pictures.
"""
from __future__ import annotations

import collections
import json
import logging
import os
import random
import shutil
import threading
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any, Callable, Optional, Protocol

import numpy as np

from artformer_ros.conversions import SEED_MAX, result_to_json, slug
from artformer_ros.params import NodeSettings
from model.core.runtime import release_free_memory

log = logging.getLogger("artformer_ros.service")

OWNER_MARKER = ".artformer_output"
PARTIAL_MARKER = ".partial"
RESULT_FILE = "result.json"

LOADING, READY, FAILED, STOPPING = "loading", "ready", "failed", "stopping"


class Backend(Protocol):
    """What the service needs from a generation backend (see ``artformer_ros.backends``)."""
    name: str

    def generate(self, *, text: Optional[str], image: Optional[np.ndarray], seed: int,
                 samples: int) -> list: ...
    # a request with a ``structure`` / ``size`` calls generate(..., structure=dict / size=
    # dict); a backend that cannot honour one raises GenerationError (an error result)

    def export(self, result: Any, out_dir: str) -> Any: ...


@dataclass
class Job:
    request_id: str
    kind: str                              # "text" | "image"
    text: Optional[str] = None             # the prompt of a text request
    image: Optional[np.ndarray] = None     # (H, W, 3) uint8 RGB of an image request
    seed: Optional[int] = None             # None: the node's seed policy
    structure: Optional[dict] = None       # parts to force (docs/ros.md), form already checked
    size: Optional[dict] = None            # the body's dimensions, m, form already checked
    received: float = field(default_factory=time.monotonic)

    @property
    def prompt(self) -> Optional[str]:
        if self.kind == "image" and self.image is not None:
            return f"<image {self.image.shape[1]}x{self.image.shape[0]}>"
        return self.text


def answer(job_or_id: Job | str, status: str, message: str, *, kind: str = "text",
           prompt: Optional[str] = None, **extra: Any) -> dict:
    """A non-success result (status 'error' or 'rejected') with a message."""
    if isinstance(job_or_id, Job):
        rid, kind, prompt = job_or_id.request_id, job_or_id.kind, job_or_id.prompt
    else:
        rid = job_or_id
    return {"id": rid, "status": status, "kind": kind, "prompt": prompt, "message": message,
            **extra}


def _existing(path: Optional[str]) -> Optional[str]:
    """``path`` if it names an existing file, else None (an answer names no missing file)."""
    return path if path and os.path.isfile(path) else None


def _write_atomic(path: str, text: str) -> None:
    tmp = os.path.join(os.path.dirname(path), f".{os.path.basename(path)}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def owned_folders(root: str) -> tuple[list[str], list[str]]:
    """(complete, partial) output folders under ``root`` that this node wrote, oldest first."""
    complete, partial = [], []
    try:
        names = sorted(os.listdir(root))
    except FileNotFoundError:
        return [], []
    for name in names:
        path = os.path.join(root, name)
        if os.path.isdir(path) and os.path.exists(os.path.join(path, OWNER_MARKER)):
            is_partial = os.path.exists(os.path.join(path, PARTIAL_MARKER))
            (partial if is_partial else complete).append(path)
    return complete, partial


MAX_PENDING_PREVIEWS = 2      # requests whose preview.png is still to be drawn


class GenerationService:
    """Bounded queue + one worker in front of a backend; see the module docstring."""

    def __init__(self, settings: NodeSettings, load_backend: Callable[[], Backend],
                 emit: Callable[[dict, Optional[str]], None],
                 on_state: Callable[[str, str], None] = lambda state, message: None):
        self.settings = settings          # live values (seed, samples, queue_size, retention)
        self._load_backend = load_backend
        self._emit = emit
        self._on_state = on_state
        self._backend: Optional[Backend] = None
        self._state, self._state_message = LOADING, "loading the model"
        self._queue: collections.deque[Job] = collections.deque()
        self._cond = threading.Condition()
        self._export_lock = threading.Lock()
        self._busy: Optional[Job] = None
        self._folder_counter = 0
        self._root = settings.output_path
        self._threads: list[threading.Thread] = []
        self._rng = random.Random()
        self._previews: list = []          # (generated, exported) to draw after publishing

    # -- lifecycle ------------------------------------------------------------------------
    @property
    def state(self) -> str:
        return self._state

    @property
    def state_message(self) -> str:
        return self._state_message

    @property
    def backend(self) -> Optional[Backend]:
        return self._backend

    def _set_state(self, state: str, message: str) -> None:
        with self._cond:
            if self._state == STOPPING and state != STOPPING:
                return
            self._state, self._state_message = state, message
            self._cond.notify_all()
        log.info("state %s: %s", state, message)
        self._on_state(state, message)

    def start(self) -> None:
        os.makedirs(self._root, exist_ok=True)
        _, stale = owned_folders(self._root)
        for path in stale:   # left by a crash or a kill -9 in the middle of an export
            log.warning("removing incomplete output folder %s", path)
            shutil.rmtree(path, ignore_errors=True)
        self._on_state(LOADING, self._state_message)
        for target, name in ((self._load, "artformer-load"), (self._work, "artformer-worker")):
            t = threading.Thread(target=target, name=name, daemon=True)
            t.start()
            self._threads.append(t)

    def _load(self) -> None:
        t0 = time.monotonic()
        log.info("loading the %s backend", self.settings.backend)
        try:
            backend = self._load_backend()
        except Exception as err:  # the node keeps answering: every request gets this reason
            message = f"model failed to load: {type(err).__name__}: {err}"
            with self._cond:
                if self._state == STOPPING:   # stop() already answered the queue
                    return
                self._state, self._state_message = FAILED, message
                waiting = list(self._queue)
                self._queue.clear()
                self._cond.notify_all()
            log.error("%s", message)
            self._on_state(FAILED, message)
            for job in waiting:
                self._safe_emit(answer(job, "error", message), None)
            return
        self._backend = backend
        self._set_state(READY, f"backend '{backend.name}' ready (loaded in "
                               f"{time.monotonic() - t0:.1f} s)")

    def wait_ready(self, timeout: Optional[float] = None) -> bool:
        with self._cond:
            self._cond.wait_for(lambda: self._state != LOADING, timeout)
            return self._state == READY

    def stop(self, timeout: Optional[float] = None) -> bool:
        """Stop accepting, answer the queued requests 'rejected', let a running export finish
        and abandon a running generation after ``timeout`` s (settings.shutdown_timeout).
        Returns True when the worker and the loader ended (False: one is still inside the
        backend — generate or the model load — and its result will be discarded)."""
        timeout = self.settings.shutdown_timeout if timeout is None else timeout
        with self._cond:
            was_stopping = self._state == STOPPING
            self._state, self._state_message = STOPPING, "shutting down"
            drained = list(self._queue)
            self._queue.clear()
            self._cond.notify_all()
        worker = self._threads[1] if len(self._threads) > 1 else None
        if was_stopping:
            return not any(t.is_alive() for t in self._threads)
        self._on_state(STOPPING, "shutting down")
        for job in drained:
            self._safe_emit(answer(job, "rejected", "rejected: node shutting down"), None)
        if worker is not None:
            worker.join(timeout)
        # Whatever the worker does now, it cannot start an export; an export under way ends.
        if not self._export_lock.acquire(timeout=max(60.0, timeout)):
            log.warning("an export is still running; its folder stays marked partial and is "
                        "removed at the next start")
            return False
        return not any(t.is_alive() for t in self._threads)

    # -- requests -------------------------------------------------------------------------
    def queue_length(self) -> int:
        with self._cond:
            return len(self._queue)

    def submit(self, job: Job) -> bool:
        """Queue a job; answer it at once (and return False) if it cannot be queued."""
        with self._cond:
            state, message = self._state, self._state_message
            if state in (READY, LOADING):     # while loading, requests wait for the model
                limit = self.settings.queue_size
                if len(self._queue) >= limit:
                    result = answer(job, "rejected", f"rejected: queue full ({limit} requests "
                                                     "waiting); try again later")
                else:
                    self._queue.append(job)
                    self._cond.notify_all()
                    if state == LOADING:
                        log.info("request %s waits for the model (%d queued)",
                                 job.request_id, len(self._queue))
                    return True
            elif state == FAILED:
                result = answer(job, "error", message)
            else:
                result = answer(job, "rejected", "rejected: node shutting down")
        self._safe_emit(result, None)
        return False

    def _safe_emit(self, result: dict, urdf_xml: Optional[str]) -> None:
        try:
            self._emit(result, urdf_xml)
        except Exception as err:  # a closed ROS context during shutdown must not kill the worker
            log.warning("could not publish the result of %s: %s", result.get("id"), err)

    # -- worker ---------------------------------------------------------------------------
    def _work(self) -> None:
        with self._cond:
            self._cond.wait_for(lambda: self._state != LOADING)
            if self._state != READY:   # failed load (queue answered by _load) or stopping
                return
        while True:
            with self._cond:
                # requests first; previews only when no request waits
                self._cond.wait_for(lambda: self._queue or self._previews
                                    or self._state == STOPPING)
                if self._state == STOPPING:
                    return
                job = self._queue.popleft() if self._queue else None
                self._busy = job
            if job is None:
                task = self._previews.pop(0)
                if not self._write_preview(*task):
                    self._previews.insert(0, task)       # a request came in: serve it first
                elif not self._previews:
                    release_free_memory()
                continue
            try:
                result, urdf = self._run(job)
            except Exception as err:  # never let one request end the worker
                log.exception("request %s failed", job.request_id)
                result, urdf = answer(job, "error", f"internal error: {type(err).__name__}: "
                                                    f"{err}"), None
            finally:
                with self._cond:
                    self._busy = None
            self._safe_emit(result, urdf)
            release_free_memory()

    def _write_preview(self, out, exp) -> bool:
        """preview.png of a published request, drawn when the queue is empty and interrupted
        (between its views) when a request arrives: the picture is for people and holds up a
        request by one view at most. Written atomically; skipped when stopping or when
        retention already removed the folder. False = interrupted, to be drawn later. Once
        written, the request's result.json names it."""
        with self._export_lock:
            if self._state == STOPPING or not os.path.isdir(exp.out_dir):
                return True
            try:
                done = self._backend.preview(
                    out, exp, interrupt=lambda: bool(self._queue) or self._state == STOPPING)
            except Exception as err:  # a picture must never cost the node
                log.warning("preview of %s failed: %s", exp.out_dir, err)
                return True
            if done is not None:
                self._record_preview(exp.out_dir, str(done))
            return done is not None or self._state == STOPPING

    def _record_preview(self, sample_dir: str, path: str) -> None:
        """Name a written preview in result.json (the answer itself went out without it)."""
        result_path = os.path.join(os.path.dirname(sample_dir), RESULT_FILE)
        try:
            with open(result_path, encoding="utf-8") as f:
                result = json.load(f)
            for k, sample in enumerate(result.get("samples", [])):
                if sample.get("output_dir") == sample_dir:
                    sample["preview_path"] = path
                    if k == 0:
                        result["preview_path"] = path
            _write_atomic(result_path, result_to_json(result))
        except (OSError, ValueError) as err:
            log.warning("could not record the preview %s in %s: %s", path, result_path, err)

    def _seed_for(self, job: Job) -> int:
        if job.seed is not None:
            return job.seed
        if self.settings.seed >= 0:
            return self.settings.seed
        return self._rng.randint(0, SEED_MAX)

    def _run(self, job: Job) -> tuple[dict, Optional[str]]:
        from model.pipeline.api import GenerationError  # lazy: keeps the node start light

        t_start = time.monotonic()
        seed, samples = self._seed_for(job), self.settings.samples
        base = {"seed": seed, "backend": self._backend.name}
        try:
            extra = {k: v for k, v in (("structure", job.structure), ("size", job.size))
                     if v is not None}
            outs = self._backend.generate(text=job.text, image=job.image, seed=seed,
                                          samples=samples, **extra)
        except GenerationError as err:
            return answer(job, "error", f"generation failed: {err}", **base), None
        t_gen = time.monotonic()
        if not outs:
            return answer(job, "error", "generation failed: the model returned no object",
                          **base), None
        if self._state == STOPPING:   # do not even queue up behind stop() for the lock
            return answer(job, "rejected", "abandoned: node shutting down before the result "
                                           "was written", **base), None
        with self._export_lock:
            if self._state == STOPPING:
                return answer(job, "rejected", "abandoned: node shutting down before the "
                                               "result was written", **base), None
            folder = self._new_folder(job)
            pending = len(self._previews)
            try:
                exports = []
                for k, out in enumerate(outs):
                    # the exporter replaces its target folder atomically: give it a subfolder
                    target = os.path.join(folder, f"sample_{k}")
                    exports.append(self._backend.export(out, target))
                    if self.settings.preview and hasattr(self._backend, "preview"):
                        self._previews.append((out, exports[-1]))   # drawn after the answer
                # under sustained load keep only the newest pending pictures: each holds its
                # object's meshes (tens of MB), and the node's memory must stay bounded
                del self._previews[:max(0, len(self._previews) - MAX_PENDING_PREVIEWS)]
                t_exp = time.monotonic()
                result = self._done_result(job, seed, folder, outs, exports,
                                           {"queue_wait": t_start - job.received,
                                            "generate": t_gen - t_start,
                                            "export": t_exp - t_gen,
                                            "total": t_exp - job.received})
                _write_atomic(os.path.join(folder, RESULT_FILE), result_to_json(result))
                with open(exports[0].urdf_path, encoding="utf-8") as f:
                    urdf = f.read()
                os.unlink(os.path.join(folder, PARTIAL_MARKER))
            except GenerationError as err:
                del self._previews[pending:]
                shutil.rmtree(folder, ignore_errors=True)
                return answer(job, "error", f"generation failed: {err}", **base), None
            except Exception:
                del self._previews[pending:]
                shutil.rmtree(folder, ignore_errors=True)
                raise
            self._apply_retention(keep=folder)
        return result, urdf

    def _new_folder(self, job: Job) -> str:
        self._folder_counter += 1
        stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%S.%f")[:-3]
        path = os.path.join(self._root, f"{stamp}Z_{self._folder_counter:05d}_"
                                        f"{slug(job.request_id)}")
        os.makedirs(self._root, exist_ok=True)
        os.makedirs(path)
        open(os.path.join(path, PARTIAL_MARKER), "w").close()
        with open(os.path.join(path, OWNER_MARKER), "w", encoding="utf-8") as f:
            json.dump({"id": job.request_id}, f)
        return path

    def _apply_retention(self, keep: str) -> None:
        """Delete the oldest complete folders beyond ``retention``; never ``keep`` (the one
        just written, whose answer is about to go out), even if its name sorts first (a
        clock set back)."""
        complete, _ = owned_folders(self._root)
        others = [p for p in complete if p != keep]
        for path in others[:max(0, len(others) + 1 - self.settings.retention)]:
            log.info("retention: removing %s", path)
            shutil.rmtree(path, ignore_errors=True)

    def _done_result(self, job: Job, seed: int, folder: str, outs: list, exports: list,
                     timings: dict) -> dict:
        samples = []
        for out, exp in zip(outs, exports):
            samples.append({"seed": getattr(out, "seed", seed), "output_dir": exp.out_dir,
                            "urdf_path": exp.urdf_path, "mesh_paths": dict(exp.mesh_paths),
                            "metadata_path": _existing(exp.metadata_path),
                            "preview_path": _existing(exp.preview_path),
                            "stage_timings": dict(getattr(out, "timings", {}) or {})})
        first = samples[0]
        return {"id": job.request_id, "status": "done", "kind": job.kind, "prompt": job.prompt,
                "seed": seed, "backend": self._backend.name, "message": "ok",
                **({"structure": job.structure} if job.structure is not None else {}),
                **({"size": job.size} if job.size is not None else {}),
                "output_dir": folder, "urdf_path": first["urdf_path"],
                "mesh_paths": first["mesh_paths"], "metadata_path": first["metadata_path"],
                "preview_path": first["preview_path"],
                "timings": {**timings, "stages": first["stage_timings"]},
                "samples": samples}
