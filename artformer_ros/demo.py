"""One-command ROS demo: start the generator node, send one text request, print where the
URDF and meshes are, and stop the node (or keep it serving with ``--keep-serving``).

    python -m artformer_ros.demo ["a storage cabinet with two drawers"] [--keep-serving]
        [--backend model|example] [--output-dir out/ros] [-p name=value ...]

The node runs in its own process with localhost-only discovery; its log goes to
``<output-dir>/node.log``. With ``--keep-serving`` it stays up (Ctrl-C stops it) and other
terminals can send requests (``request --text ...``) on the same ROS_DOMAIN_ID.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from typing import Optional

DEFAULT_PROMPT = "a storage cabinet with two drawers and a door on the left"


def main(argv: Optional[list[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m artformer_ros.demo",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("text", nargs="?", default=DEFAULT_PROMPT)
    ap.add_argument("--backend", default="model", choices=["model", "example"])
    ap.add_argument("--output-dir", default="out/ros")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("-p", "--param", action="append", default=[], metavar="NAME=VALUE",
                    help="extra node parameter (repeatable)")
    ap.add_argument("--timeout", type=float, default=300.0)
    ap.add_argument("--keep-serving", action="store_true",
                    help="leave the node running after the demo request (Ctrl-C stops it)")
    args = ap.parse_args(argv)

    import rclpy

    from artformer_ros.bench import _parse_params
    from artformer_ros.client import GeneratorClient, start_node, stop_node

    out = os.path.abspath(args.output_dir)
    os.makedirs(out, exist_ok=True)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    params = {"backend": args.backend, "output_dir": os.path.join(out, "objects"),
              **_parse_params(args.param)}
    log = os.path.join(out, "node.log")
    proc = start_node(params, log_path=log)
    print(f"started generator node (pid {proc.pid}, backend {args.backend}, "
          f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')}); log: {log}")
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    client = GeneratorClient(context=ctx, watch_description=False)
    code = 0
    try:
        t0 = time.monotonic()
        if not client.wait_ready(args.timeout):
            print(f"demo: node not ready: {client.status}; see {log}", file=sys.stderr)
            return 1
        print(f"node ready after {time.monotonic() - t0:.1f} s; requesting: {args.text!r}")
        res = client.wait_result(client.send_text(args.text, seed=args.seed), args.timeout)
        if res is None or res.get("status") != "done":
            print(f"demo: request failed: {res and res.get('message')}", file=sys.stderr)
            code = 1
        else:
            print(f"done in {res['timings']['total']:.1f} s")
            print(f"URDF:   {res['urdf_path']}")
            print(f"meshes: {os.path.dirname(next(iter(res['mesh_paths'].values())))} "
                  f"({len(res['mesh_paths'])} parts)")
        if args.keep_serving and code == 0:
            print("node keeps serving (topics text_request / image_request -> "
                  "robot_description, generation_result); Ctrl-C to stop")
            stop = []
            signal.signal(signal.SIGINT, lambda *_: stop.append(1))
            signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
            while not stop and proc.poll() is None:
                client.spin_until(lambda: False, 0.5)
        return code
    finally:
        client.close()
        rc = stop_node(proc, 60)
        rclpy.try_shutdown(context=ctx)
        print(f"node stopped (exit code {rc})")


if __name__ == "__main__":
    sys.exit(main())
