"""Batch generation: many prompts x samples, several worker processes, a resumable manifest.

    artformer generate --prompts prompts.txt --samples 5 --workers 2 --out out/batch

    summary = run_batch(read_prompts("prompts.txt"), "out/batch", samples=5, workers=2)

The prompts file has one prompt per line; blank lines and lines starting with ``#`` are
skipped. Prompt ``i`` (0-based, counting prompts only) with sample ``k`` is the job
``<i:04d>_<k>``. It uses seed ``seed + k`` and writes the folder
``<i:04d>_<words of the prompt>_s<seed>/``, which holds the URDF, meshes, metadata and
preview, as ``artformer generate`` writes them.

``manifest.jsonl`` in the output folder has one JSON line per finished job, written by the
parent process only, flushed and fsynced line by line:

    {"id", "index", "sample", "prompt", "seed", "status": "ok" | "error",
     "out_dir", "urdf", "meshes", "preview"      (relative to the batch folder; null on error),
     "category", "parts", "timings_s" (stage -> s), "seconds" (wall time of the job),
     "worker" (pid), "audit" (null unless --audit; then {"sim_ready", "failures"}),
     "error" (null, or the message), "finished_utc"}

Resume: running the same command again skips every job that the manifest records (an "ok"
one whose URDF still exists, or an "error" one unless ``retry_failed``). An interrupted job
has no line and is redone; its folder is replaced atomically. A failing job is recorded with
its error and the batch goes on. A worker process that dies is replaced, and its job is
recorded as an error. At the end the manifest is rewritten with one line per job, in job
order.

Each worker process loads the model once; with one worker the jobs run in the calling
process. Torch threads per worker default to ``max(1, cpu_count // workers)``, and with
several workers each finishes its parts itself (no meshing helpers, ``mesh_workers`` 0).
"""
from __future__ import annotations

import datetime as _dt
import json
import logging
import os
import queue
import re
import shutil
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Callable, Optional, Sequence

log = logging.getLogger(__name__)

MANIFEST = "manifest.jsonl"


class BatchError(ValueError):
    """The batch cannot start (bad prompts file, options or a manifest from other prompts)."""


@dataclass
class Job:
    id: str
    index: int
    sample: int
    prompt: str
    seed: int
    folder: str                      # relative to the batch folder


@dataclass
class BatchSummary:
    out_dir: str
    manifest: str
    total: int                       # jobs in the batch
    skipped: int                     # already in the manifest at the start
    done: int = 0                    # finished ok in this run
    failed: int = 0                  # recorded as errors in this run
    seconds: float = 0.0             # wall time of this run, model loading included

    @property
    def per_minute(self) -> float:
        n = self.done + self.failed
        return 60.0 * n / self.seconds if self.seconds > 0 else 0.0


def read_prompts(path: os.PathLike) -> list[str]:
    """Prompts of a file, one per line (blank lines and ``#`` comments skipped)."""
    p = Path(path)
    if not p.is_file():
        raise BatchError(f"prompts file {p} does not exist")
    try:
        lines = p.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError as e:
        raise BatchError(f"prompts file {p} is not UTF-8 text ({e.reason})") from None
    prompts = [" ".join(ln.split()) for ln in lines]
    prompts = [x for x in prompts if x and not x.startswith("#")]
    if not prompts:
        raise BatchError(f"prompts file {p} has no prompts")
    return prompts


def _words(prompt: str, n: int = 40) -> str:
    s = re.sub(r"[^a-z0-9]+", "_", prompt.lower()).strip("_")
    return s[:n].rstrip("_") or "prompt"


def plan_jobs(prompts: Sequence[str], samples: int, seed: int) -> list[Job]:
    jobs = []
    for i, prompt in enumerate(prompts):
        for k in range(samples):
            s = seed + k
            jobs.append(Job(f"{i:04d}_{k}", i, k, prompt, s, f"{i:04d}_{_words(prompt)}_s{s}"))
    return jobs


def read_manifest(path: Path) -> dict[str, dict]:
    """id -> last entry; a torn last line (an interrupted write) is skipped."""
    out: dict[str, dict] = {}
    if not path.exists():
        return out
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        try:
            entry = json.loads(line)
            out[entry["id"]] = entry
        except (json.JSONDecodeError, KeyError, TypeError):
            log.warning("%s line %d is not a manifest entry (an interrupted write?); ignored",
                        path, n)
    return out


def _finished(entry: Optional[dict], root: Path, retry_failed: bool) -> bool:
    if entry is None:
        return False
    if entry.get("status") == "ok":
        return bool(entry.get("urdf")) and (root / entry["urdf"]).is_file()
    return entry.get("status") == "error" and not retry_failed


def _append(path: Path, entry: dict) -> None:
    with open(path, "a", encoding="utf-8") as f:
        f.write(json.dumps(entry, sort_keys=True) + "\n")
        f.flush()
        os.fsync(f.fileno())


def _compact(path: Path, jobs: Sequence[Job]) -> None:
    """One line per job, in job order (atomic replace)."""
    entries = read_manifest(path)
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        for j in jobs:
            if j.id in entries:
                f.write(json.dumps(entries[j.id], sort_keys=True) + "\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


# -- worker process ---------------------------------------------------------------------------


def _audit(obj, urdf: str):
    """{"sim_ready", "failures"} from model.export.simready, or an error note."""
    try:
        from model.export.simready import audit_object
    except ImportError as e:
        return {"error": f"audit not available: {e}"}
    try:
        rep = audit_object(obj, urdf=urdf)
        out = {"sim_ready": bool(rep.sim_ready), "failures": [str(f) for f in rep.failures]}
        if rep.error:
            out["error"] = rep.error
        return out
    except Exception as e:  # an audit crash is recorded, not a failed object
        return {"error": f"{type(e).__name__}: {e}"}


def _run_job(gen, job: Job, root: str, audit: bool, preview: bool, mesh_uri: str) -> dict:
    """Generate and export one job; any failure becomes an "error" entry."""
    import traceback

    from model.pipeline.api import GenerationError

    t0 = time.perf_counter()
    entry = {"id": job.id, "index": job.index, "sample": job.sample, "prompt": job.prompt,
             "seed": job.seed, "worker": os.getpid(), "audit": None, "error": None,
             "out_dir": None, "urdf": None, "meshes": None, "preview": None,
             "category": None, "parts": None, "timings_s": {}}
    try:
        [res] = gen.generate(job.prompt, seed=job.seed, samples=1)
        out = gen.export(res, Path(root) / job.folder, preview=preview, mesh_uri=mesh_uri)
        rel = lambda p: os.path.relpath(p, root) if p else None  # noqa: E731
        entry.update(status="ok", out_dir=job.folder, urdf=rel(out.urdf_path),
                     meshes=f"{job.folder}/meshes", preview=rel(out.preview_path),
                     category=res.obj.category, parts=len(res.obj.parts),
                     timings_s={k: round(v, 4) for k, v in res.timings.items()})
        if audit:
            t = time.perf_counter()
            entry["audit"] = _audit(res.obj, out.urdf_path)
            entry["timings_s"]["audit"] = round(time.perf_counter() - t, 4)
    except GenerationError as e:
        entry.update(status="error", error=str(e))
    except Exception as e:  # record any failure of one job and go on with the next
        entry.update(status="error", error=f"{type(e).__name__}: {e}")
        log.debug("job %s failed:\n%s", job.id, traceback.format_exc())
    entry["seconds"] = round(time.perf_counter() - t0, 4)
    entry["finished_utc"] = _now()
    return entry


def _worker(config_dict: dict, root: str, jobs, results, audit: bool, preview: bool,
            mesh_uri: str, parent_pid: int) -> None:
    """Load the model once, then take jobs until a None arrives or the parent is gone."""
    from model.pipeline.api import GenerationConfig
    from model.pipeline.generator import Generator

    pid = os.getpid()
    try:
        gen = Generator.load(GenerationConfig(**config_dict))
    except Exception as e:
        results.put({"kind": "load_failed", "worker": pid, "error": f"{type(e).__name__}: {e}"})
        return
    results.put({"kind": "ready", "worker": pid})
    while True:
        if os.getppid() != parent_pid:          # the batch was killed: stop too
            return
        try:
            job = jobs.get(timeout=1.0)
        except queue.Empty:
            continue
        if job is None:
            return
        job = Job(**job)
        results.put({"kind": "start", "worker": pid, "id": job.id})
        results.put({"kind": "done", "worker": pid,
                     "entry": _run_job(gen, job, root, audit, preview, mesh_uri)})


# -- parent ------------------------------------------------------------------------------------


def _clean_partial(root: Path) -> None:
    """Folders of exports cut short (``export_object`` builds ``.<name>.tmp-*`` beside its
    destination and renames it into place)."""
    for p in root.glob(".*.tmp-*"):
        if p.is_dir():
            shutil.rmtree(p, ignore_errors=True)
            log.info("removed the partial export %s", p)


def _end_with_newline(path: Path) -> None:
    """A write cut short leaves a torn last line; the next entry starts on a line of its own."""
    if path.exists() and path.stat().st_size:
        with open(path, "rb+") as f:
            f.seek(-1, os.SEEK_END)
            if f.read(1) != b"\n":
                f.write(b"\n")


def _record(manifest, entry: dict, summary, t0: float, progress) -> None:
    """Append a finished job to the manifest and count it."""
    _append(manifest, entry)
    if entry["status"] == "ok":
        summary.done += 1
    else:
        summary.failed += 1
    summary.seconds = time.perf_counter() - t0
    if progress:
        progress(entry, summary)


def _run_here(config, todo, root, manifest, summary, t0, audit, preview, mesh_uri, progress):
    from model.pipeline.generator import Generator
    gen = Generator.load(config)
    for job in todo:
        entry = _run_job(gen, job, str(root), audit, preview, mesh_uri)
        _record(manifest, entry, summary, t0, progress)


def run_batch(prompts: Sequence[str], out_dir: os.PathLike, *, samples: int = 1,
              workers: int = 1, seed: int = 0, config=None, audit: bool = False,
              preview: bool = True, mesh_uri: str = "file", retry_failed: bool = False,
              progress: Optional[Callable[[dict, BatchSummary], None]] = None) -> BatchSummary:
    """Generate every (prompt, sample) job not yet in ``out_dir/manifest.jsonl``.

    ``config``: a GenerationConfig (threads default to cpu_count // workers when left at
    the config's default). ``progress(entry, summary)`` is called after each job.
    Raises BatchError before starting when the options are bad or the manifest records
    other prompts for the same job ids.
    """
    from model.pipeline.api import GenerationConfig
    from model.pipeline.generator import validate_config

    if samples < 1:
        raise BatchError(f"samples must be >= 1, got {samples}")
    if workers < 1:
        raise BatchError(f"workers must be >= 1, got {workers}")
    if not prompts:
        raise BatchError("no prompts")
    config = config or GenerationConfig()
    validate_config(config)
    root = Path(out_dir).expanduser().resolve()
    root.mkdir(parents=True, exist_ok=True)
    manifest = root / MANIFEST
    jobs = plan_jobs(prompts, samples, seed)
    todo = _pending(jobs, manifest, root, retry_failed)
    summary = BatchSummary(str(root), str(manifest), total=len(jobs),
                           skipped=len(jobs) - len(todo))
    t0 = time.perf_counter()
    if todo:
        if config.threads == GenerationConfig().threads:   # left at the default: share the cores
            config = replace(config, threads=min(64, max(1, (os.cpu_count() or 1) // workers)))
        if workers > 1 and config.mesh_workers < 0:        # the workers already fill the cores
            config = replace(config, mesh_workers=0)
        _clean_partial(root)
        _end_with_newline(manifest)
        if workers == 1:                        # in this process: no spawn, no second import
            _run_here(config, todo, root, manifest, summary, t0, audit, preview, mesh_uri,
                      progress)
        else:
            _Pool(config, root, manifest, summary, t0, (audit, preview, mesh_uri), progress,
                  min(workers, len(todo))).run(todo)
    _compact(manifest, jobs)
    return summary


def _pending(jobs: list, manifest: Path, root: Path, retry_failed: bool) -> list:
    """The jobs the manifest does not record as finished; BatchError when it records other
    prompts or seeds under the same job ids."""
    seen = read_manifest(manifest)
    for j in jobs:
        e = seen.get(j.id)
        if e is not None and (e.get("prompt") != j.prompt or e.get("seed") != j.seed):
            raise BatchError(f"{manifest} records job {j.id} as prompt {e.get('prompt')!r} seed "
                             f"{e.get('seed')}, not {j.prompt!r} seed {j.seed}: resume with the "
                             f"same prompts file, --samples and --seed, or use another --out")
    return [j for j in jobs if not _finished(seen.get(j.id), root, retry_failed)]


class _Pool:
    """Worker processes (spawned) fed from one job queue; the parent alone writes the
    manifest. A worker that dies has its job recorded as failed and is replaced."""

    def __init__(self, config, root: Path, manifest: Path, summary: BatchSummary, t0: float,
                 export_opts: tuple, progress, n_workers: int):
        import multiprocessing as mp

        self.cfg, self.root, self.manifest = asdict(config), root, manifest
        self.summary, self.t0, self.export_opts = summary, t0, export_opts
        self.progress, self.n_workers = progress, n_workers
        self.ctx = mp.get_context("spawn")
        self.job_q, self.res_q = self.ctx.Queue(), self.ctx.Queue()
        self.procs: dict[int, object] = {}
        self.in_flight: dict[int, str] = {}          # worker pid -> job id

    def _start_worker(self) -> None:
        p = self.ctx.Process(target=_worker, args=(self.cfg, str(self.root), self.job_q,
                                                   self.res_q, *self.export_opts, os.getpid()),
                             daemon=True)
        p.start()
        self.procs[p.pid] = p

    def run(self, todo: list) -> None:
        for j in todo:
            self.job_q.put(asdict(j))
        for _ in range(self.n_workers):
            self._start_worker()
        self.by_id = {j.id: j for j in todo}
        self.remaining = set(self.by_id)
        load_failures = 0
        try:
            while self.remaining:
                try:
                    msg = self.res_q.get(timeout=1.0)
                except queue.Empty:
                    self._reap()
                    continue
                if msg["kind"] == "load_failed":
                    load_failures += 1
                    if load_failures >= self.n_workers:
                        raise BatchError(f"the model could not be loaded: {msg['error']}")
                elif msg["kind"] == "start":
                    self.in_flight[msg["worker"]] = msg["id"]
                elif msg["kind"] == "done":
                    entry = msg["entry"]
                    self.in_flight.pop(msg["worker"], None)
                    if entry["id"] in self.remaining:
                        self.remaining.discard(entry["id"])
                        _record(self.manifest, entry, self.summary, self.t0, self.progress)
        except BaseException:                   # interrupted or failed: stop the workers now
            for p in self.procs.values():
                p.terminate()
            raise
        finally:
            self._stop()

    def _reap(self) -> None:
        """Record the job of every worker that died as failed; start a replacement."""
        for pid, p in list(self.procs.items()):
            if p.is_alive():
                continue
            self.procs.pop(pid)
            jid = self.in_flight.pop(pid, None)
            if jid is not None and jid in self.remaining:
                j = self.by_id[jid]
                entry = {"id": j.id, "index": j.index, "sample": j.sample, "prompt": j.prompt,
                         "seed": j.seed, "status": "error",
                         "error": f"worker process {pid} died (exit code {p.exitcode})",
                         "worker": pid, "audit": None, "out_dir": None, "urdf": None,
                         "meshes": None, "preview": None, "category": None, "parts": None,
                         "timings_s": {}, "seconds": None, "finished_utc": _now()}
                _append(self.manifest, entry)
                self.remaining.discard(jid)
                self.summary.failed += 1
                if self.progress:
                    self.progress(entry, self.summary)
            if self.remaining and len(self.procs) < self.n_workers:
                log.warning("worker %s exited (code %s); starting another", pid, p.exitcode)
                self._start_worker()

    def _stop(self) -> None:
        for _ in self.procs:
            self.job_q.put(None)
        deadline = time.time() + 10
        for p in self.procs.values():
            p.join(timeout=max(0.1, deadline - time.time()))
            if p.is_alive():
                p.terminate()
                p.join(timeout=5)
        self.job_q.cancel_join_thread()
        self.summary.seconds = time.perf_counter() - self.t0
