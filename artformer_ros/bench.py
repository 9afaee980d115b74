"""Benchmark of the generator node: request -> URDF-published latency and peak memory.

    python -m artformer_ros.bench [--backend model|example] [--n 20] [--out bench_ros.json]
                                  [-p resolution=64 -p steps=50 ...]

Starts the node in its own process (localhost discovery, a random ROS domain unless
ROS_DOMAIN_ID is set), waits until it is ready, sends one warm-up request, then ``--n`` text
requests one after the other. For each it measures the time from publishing the request to
receiving the new URDF on ``robot_description`` (and to the result message), and it reads the
node's resident memory from /proc throughout (peak = the kernel's VmHWM of the node process).
Prints median / p95 and saves everything as JSON.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import random
import statistics
import sys
import tempfile
import time
from typing import Optional

PROMPTS = [
    "a storage cabinet with two drawers and a door on the left",
    "a safe with a door hinged on the right and a knob",
    "an oven with a door that opens downwards and two knobs",
    "a washing machine with a round door",
    "a bottle with a screw cap",
    "a usb stick with a swivel cap",
    "a tall wardrobe with two doors",
    "a small cabinet with three drawers",
]


def percentile(values: list[float], q: float) -> float:
    """Linear-interpolated percentile (q in [0, 100])."""
    xs = sorted(values)
    if not xs:
        return float("nan")
    k = (len(xs) - 1) * q / 100.0
    lo, hi = int(k), min(int(k) + 1, len(xs) - 1)
    return xs[lo] + (xs[hi] - xs[lo]) * (k - lo)


def _parse_params(items: list[str]) -> dict:
    import yaml

    out = {}
    for item in items:
        if "=" not in item:
            raise SystemExit(f"bench: -p expects name=value, got {item!r}")
        k, v = item.split("=", 1)
        out[k] = yaml.safe_load(v)
    return out


def run(backend: str, n: int, params: dict, timeout: float, log_path: Optional[str]) -> dict:
    import rclpy

    from artformer_ros.client import GeneratorClient, proc_memory_kb, start_node, stop_node

    out_dir = tempfile.mkdtemp(prefix="artformer_bench_")
    node_params = {"backend": backend, "output_dir": out_dir, "retention": 3, "seed": 0,
                   **params}
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 100)))
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    t_start = time.monotonic()
    proc = start_node(node_params, log_path=log_path)
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    client = GeneratorClient(context=ctx)
    watch = _NodeWatch(client, proc, proc_memory_kb)
    try:
        if not client.wait_ready(timeout):
            raise RuntimeError(f"node not ready (waited up to {timeout:.0f} s): {client.status}")
        ready_s = time.monotonic() - t_start
        watch.sample_memory()
        ready_rss_mb = watch.rss[-1] / 1024.0
        # request 0 is the warm-up
        rows = [_timed_request(client, watch, i, timeout) for i in range(n + 1)]
        watch.sample_memory()
        mem = proc_memory_kb(proc.pid)
        client.close()
        rc = stop_node(proc, 60)
    finally:
        if proc.poll() is None:
            proc.kill()
        rclpy.try_shutdown(context=ctx)
    timed = [r for r in rows if not r["warmup"]]
    return {"backend": backend, "params": node_params, "n": len(timed), "ready_s": ready_s,
            **_latencies(timed), **_memory(timed, ready_rss_mb, mem, watch.rss),
            "node_exit_code": rc,
            "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                        "python": platform.python_version()},
            "requests": rows}


class _NodeWatch:
    """Spins the client while it waits on the node process, sampling the node's resident
    memory on every turn (the peak between samples is the kernel's VmHWM)."""

    def __init__(self, client, proc, memory_kb):
        self.client, self.proc, self._memory_kb = client, proc, memory_kb
        self.rss: list[int] = []                 # VmRSS samples (kB)

    def sample_memory(self) -> None:
        try:
            self.rss.append(self._memory_kb(self.proc.pid)["VmRSS"])
        except (FileNotFoundError, KeyError, ProcessLookupError):
            pass

    def wait(self, pred, limit) -> bool:
        end = time.monotonic() + limit
        while not pred():
            if time.monotonic() > end or self.proc.poll() is not None:
                return False
            self.client.spin_until(lambda: False, 0.05)
            self.sample_memory()
        return True


def _timed_request(client, watch: _NodeWatch, i: int, timeout: float) -> dict:
    """Send text request ``i`` and wait for its result and its URDF on robot_description:
    one row of the report (latencies from publishing the request)."""
    prompt = PROMPTS[i % len(PROMPTS)]
    n_desc = len(client.descriptions)
    t0 = time.monotonic()
    rid = client.send_text(prompt, request_id=f"bench{i}", seed=i)
    if not watch.wait(lambda: rid in client.results, timeout):
        raise RuntimeError(f"no answer to request {i} within {timeout} s")
    res = client.results[rid]
    if res["status"] != "done":
        raise RuntimeError(f"request {i} failed: {res['message']}")
    if not watch.wait(lambda: len(client.descriptions) > n_desc, 10):
        raise RuntimeError(f"request {i}: no URDF on robot_description")
    t_urdf = client.descriptions[n_desc][0]
    watch.sample_memory()
    return {"i": i, "prompt": prompt, "warmup": i == 0, "rss_mb": watch.rss[-1] / 1024.0,
            "urdf_latency_s": t_urdf - t0, "result_latency_s": res["_received"] - t0,
            "node_timings": res["timings"],
            "parts": len(res["mesh_paths"])}


def _latencies(timed: list[dict]) -> dict:
    """Latency and node-stage statistics (s) of the timed (not warm-up) requests' rows."""
    lat = [r["urdf_latency_s"] for r in timed]
    res_lat = [r["result_latency_s"] for r in timed]
    gen = [r["node_timings"]["generate"] for r in timed]
    exp = [r["node_timings"]["export"] for r in timed]
    return {
        "urdf_latency_s": {"median": statistics.median(lat), "p95": percentile(lat, 95),
                           "mean": statistics.fmean(lat), "min": min(lat), "max": max(lat)},
        "result_latency_s": {"median": statistics.median(res_lat),
                             "p95": percentile(res_lat, 95)},
        "node_generate_s": {"median": statistics.median(gen), "p95": percentile(gen, 95)},
        "node_export_s": {"median": statistics.median(exp), "p95": percentile(exp, 95)},
        "parts": {"median": statistics.median(r["parts"] for r in timed)}}


def _memory(timed: list[dict], ready_rss_mb: float, mem: dict, rss: list[int]) -> dict:
    """The node's resident memory (MB): when ready, after the first and the last timed
    request, the peak (VmHWM), the largest sample and at the end (``mem``: its /proc
    status after the last request)."""
    return {
        "ready_rss_mb": ready_rss_mb,
        "rss_after_first_timed_mb": timed[0]["rss_mb"],
        "rss_after_last_timed_mb": timed[-1]["rss_mb"],
        "peak_rss_mb": mem["VmHWM"] / 1024.0,
        "max_sampled_rss_mb": max(rss) / 1024.0 if rss else None,
        "final_rss_mb": mem["VmRSS"] / 1024.0}


def main(argv: Optional[list[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m artformer_ros.bench",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--backend", default="model", choices=["model", "example"])
    ap.add_argument("--n", type=int, default=20, help="timed requests (after 1 warm-up)")
    ap.add_argument("-p", "--param", action="append", default=[], metavar="NAME=VALUE",
                    help="extra node parameter (repeatable), e.g. -p resolution=48")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per wait")
    ap.add_argument("--out", default="bench_ros.json", help="JSON report path")
    ap.add_argument("--node-log", default=None, help="write the node's output here")
    args = ap.parse_args(argv)
    if args.n < 1:
        ap.error("--n must be >= 1")
    try:
        report = run(args.backend, args.n, _parse_params(args.param), args.timeout,
                     args.node_log)
    except RuntimeError as err:
        print(f"bench: {err}", file=sys.stderr)
        return 1
    report["command"] = "python -m artformer_ros.bench " + " ".join(
        sys.argv[1:] if argv is None else argv)
    with open(args.out, "w") as f:
        json.dump(report, f, indent=1)
    lat, res = report["urdf_latency_s"], report["result_latency_s"]
    print(f"backend {report['backend']}: {report['n']} requests, node ready after "
          f"{report['ready_s']:.1f} s")
    print(f"request -> URDF on robot_description: median {lat['median']:.3f} s, "
          f"p95 {lat['p95']:.3f} s (min {lat['min']:.3f}, max {lat['max']:.3f})")
    print(f"request -> result message:            median {res['median']:.3f} s, "
          f"p95 {res['p95']:.3f} s")
    print(f"inside the node: generate median {report['node_generate_s']['median']:.3f} s, "
          f"export median {report['node_export_s']['median']:.3f} s, "
          f"{report['parts']['median']:.0f} parts (median)")
    print(f"node RSS: {report['ready_rss_mb']:.0f} MB when ready, "
          f"{report['rss_after_first_timed_mb']:.0f} MB after the first timed request, "
          f"{report['rss_after_last_timed_mb']:.0f} MB after the last; "
          f"peak {report['peak_rss_mb']:.0f} MB (VmHWM)")
    print(f"saved {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
