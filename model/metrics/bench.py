"""`artformer bench`: per-stage generation speed and peak memory.

The measurement runs in a **fresh child process** (``python -m model.metrics.bench --child``),
so the peak resident set size (``resource.getrusage(RUSAGE_SELF).ru_maxrss``, the kernel's
high-water mark) is that of one generator serving N prompts, not of whatever ran before.

Stage timings are the pipeline's own (``GeneratedObject.timings``: stage → seconds, e.g. text
encoding, decoding, diffusion, meshing, export = URDF + meshes on disk, preview = the PNG
drawn after them) plus ``generate`` (wall time of generation), ``to_urdf`` (generate +
export: text in, URDF and meshes on disk — the speed target) and ``total`` (wall time
including the preview). Median, p95 and mean over the prompts, ``to_urdf`` also by part
count; the model load time is measured once.
"""
from __future__ import annotations

import json
import logging
import os
import platform
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable, Optional

import numpy as np

log = logging.getLogger(__name__)


@dataclass
class BenchConfig:
    n: int = 20
    checkpoint: Optional[str] = None     # None / "shipped" = packaged model
    seed: int = 0
    threads: int = 2
    steps: Optional[int] = None
    resolution: Optional[int] = None
    export: bool = True
    prompts_file: Optional[str] = None   # default: the fixed bench prompts (prompts_bench.txt)
    images: Optional[list] = None        # image files: time image requests instead of prompts
    warmup: int = 1                      # untimed generations first (lazy inits, allocator)


def _rss_mb() -> float:
    import resource
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss   # KiB on Linux
    return kb / 1024.0


def _current_rss_mb() -> float:
    from model.core.runtime import proc_memory_kb
    try:
        return proc_memory_kb()["VmRSS"] / 1024.0
    except (OSError, KeyError):
        return float("nan")


def _cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def stage_stats(timings: list[dict]) -> dict:
    """stage -> {median, p95, mean, n} over the prompts that report the stage."""
    stages: list[str] = []
    for t in timings:
        for k in t:
            if k not in stages:
                stages.append(k)
    out = {}
    for s in stages:
        v = np.array([t[s] for t in timings if s in t], dtype=np.float64)
        out[s] = {"median": float(np.median(v)), "p95": float(np.percentile(v, 95)),
                  "mean": float(v.mean()), "n": int(len(v))}
    return out


def run_child(cfg: BenchConfig, loader: Optional[Callable] = None) -> dict:
    """The measurement itself (meant to run in a fresh process; see module docstring)."""
    import torch
    torch.set_num_threads(max(1, cfg.threads))
    from model.core.runtime import release_free_memory, settle_after_load
    from model.pipeline.api import GenerationConfig
    from .reference import BENCH_PATH, freeform_prompts
    requests = list(cfg.images) if cfg.images else freeform_prompts(cfg.prompts_file or BENCH_PATH)

    def request(i: int, seed: int):
        r = requests[i % len(requests)]
        return (gen.generate(image=r, seed=seed, samples=1) if cfg.images
                else gen.generate(r, seed=seed, samples=1))
    if loader is None:
        from model.pipeline import Generator
        loader = Generator.load
    gcfg = GenerationConfig(checkpoint=None if cfg.checkpoint in (None, "", "shipped")
                            else cfg.checkpoint, threads=cfg.threads)
    if cfg.steps is not None:
        gcfg.steps = cfg.steps
    if cfg.resolution is not None:
        gcfg.resolution = cfg.resolution
    rss_before = _current_rss_mb()
    t0 = time.perf_counter()
    gen = loader(gcfg)
    load_s = time.perf_counter() - t0
    settle_after_load()                    # as the node does (model.core.runtime)
    rss_load = _current_rss_mb()
    timings, failures = [], []
    with tempfile.TemporaryDirectory(prefix="artformer-bench-") as tmp:
        for w in range(cfg.warmup):
            try:
                request(w, cfg.seed + 10_000 + w)
            except Exception as e:
                log.warning("warm-up failed: %s", e)
        for i in range(cfg.n):
            t1 = time.perf_counter()
            try:
                [g] = request(i, cfg.seed + i)
            except Exception as e:
                failures.append(f"{requests[i % len(requests)]!r}: {type(e).__name__}: {e}")
                continue
            t = {k: float(v) for k, v in g.timings.items()}
            t["generate"] = time.perf_counter() - t1
            if cfg.export:
                gen.export(g, os.path.join(tmp, f"{i:03d}"))   # URDF + meshes, then preview
                t["export"] = float(g.timings["export"])
                t["preview"] = float(g.timings.get("preview", 0.0))
            # the target figure: text (or image) in -> URDF and meshes on disk (the preview follows)
            t["to_urdf"] = t["generate"] + t.get("export", 0.0)
            t["total"] = time.perf_counter() - t1
            t["parts"] = float(len(g.obj.parts))
            timings.append(t)
            del g
            release_free_memory()          # as the node does after every request
    parts = [t.pop("parts") for t in timings]
    by_parts = {}
    for name, lo, hi in (("1-3", 1, 3), ("4-6", 4, 6), ("7-9", 7, 9), ("10+", 10, 10 ** 6)):
        sel = [t["to_urdf"] for t, n in zip(timings, parts) if lo <= n <= hi]
        if sel:
            by_parts[name] = {"n": len(sel), "to_urdf_median": float(np.median(sel))}
    return {"config": asdict(cfg), "checkpoint": cfg.checkpoint, "n": len(timings),
            "requests": "images" if cfg.images else "prompts",
            "threads": cfg.threads, "cpu": _cpu_name(), "python": sys.version.split()[0],
            "load_seconds": load_s, "stages": stage_stats(timings),
            "parts_median": float(np.median(parts)) if parts else None,
            "to_urdf_by_parts": by_parts,
            "peak_rss_mb": _rss_mb(), "rss_before_load_mb": rss_before,
            "mesh_workers": getattr(getattr(gen, "parts", None), "workers", 0),
            "helpers_peak_rss_mb": (gen.parts.peak_rss_mb() if hasattr(gen, "parts") else 0.0),
            "rss_after_load_mb": rss_load, "failures": failures, "per_prompt": timings}


def run_bench(cfg: BenchConfig, timeout: float = 3600) -> dict:
    """Run :func:`run_child` in a fresh interpreter and return its results."""
    with tempfile.TemporaryDirectory(prefix="artformer-bench-") as tmp:
        cfg_path, out_path = Path(tmp) / "cfg.json", Path(tmp) / "out.json"
        cfg_path.write_text(json.dumps(asdict(cfg)))
        cmd = [sys.executable, "-m", "model.metrics.bench", "--child", str(cfg_path),
               str(out_path)]
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
        if proc.returncode != 0 or not out_path.exists():
            raise RuntimeError(f"benchmark process failed (exit {proc.returncode}):\n"
                               f"{proc.stderr[-4000:]}")
        return json.loads(out_path.read_text())


def _child_main(argv: list[str]) -> int:
    cfg = BenchConfig(**json.loads(Path(argv[0]).read_text()))
    logging.basicConfig(level=logging.WARNING)
    res = run_child(cfg)
    Path(argv[1]).write_text(json.dumps(res))
    return 0


if __name__ == "__main__":
    if len(sys.argv) >= 4 and sys.argv[1] == "--child":
        raise SystemExit(_child_main(sys.argv[2:]))
    raise SystemExit("use `artformer bench` (this module's entry point is internal)")
