"""``request`` — demo client of the generator node.

    request --text "a cabinet with two drawers" [--seed 3] [--timeout 300]
    request --image photo.png [--timeout 300]

Waits for the node to be ready, sends one request, waits for its answer and prints the URDF
path and the mesh folder. Exit codes: 0 done, 1 the node answered with an error or a
rejection, 2 bad arguments, 3 timeout (no ready node or no answer in time).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Optional


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="request", description=__doc__.split("\n\n")[0])
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--text", help="text description of the object")
    what.add_argument("--image", help="image file (png, jpg, ...) of the object")
    p.add_argument("--seed", type=int, default=None, help="seed (text requests)")
    p.add_argument("--id", default=None, help="request id (default: a fresh uuid)")
    p.add_argument("--namespace", default="", help="namespace of the generator node's topics")
    p.add_argument("--timeout", type=float, default=300.0,
                   help="seconds to wait for a ready node and then for the answer")
    p.add_argument("--json", action="store_true", help="print the whole result as JSON")
    return p


def main(argv: Optional[list[str]] = None) -> int:
    import rclpy
    from rclpy.utilities import remove_ros_args

    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(remove_ros_args(["request", *argv])[1:])
    image = None
    if args.image:
        from artformer_ros.client import load_rgb
        try:
            image = load_rgb(args.image)
        except (OSError, ValueError) as err:
            print(f"request: cannot read image {args.image!r}: {err}", file=sys.stderr)
            return 2
    from artformer_ros.client import GeneratorClient

    context = rclpy.Context()
    rclpy.init(args=["request", *argv], context=context)
    client = GeneratorClient(context=context, namespace=args.namespace,
                             watch_description=False)
    try:
        t0 = time.monotonic()
        if not client.wait_ready(args.timeout):
            state = client.status or {}
            if state.get("state") == "failed":
                print(f"request: the generator failed to load: {state.get('message')}",
                      file=sys.stderr)
                return 1
            print(f"request: no ready generator node within {args.timeout:.0f} s "
                  f"(status: {state.get('state', 'none seen')})", file=sys.stderr)
            return 3
        if image is not None:
            rid = client.send_image(image, request_id=args.id)
        else:
            rid = client.send_text(args.text, request_id=args.id, seed=args.seed)
        left = max(1.0, args.timeout - (time.monotonic() - t0))
        result = client.wait_result(rid, left)
        if result is None:
            print(f"request: no answer to request {rid} within {args.timeout:.0f} s",
                  file=sys.stderr)
            return 3
        result.pop("_received", None)
        if args.json:
            print(json.dumps(result, indent=1))
        if result.get("status") != "done":
            print(f"request {rid}: {result.get('status')}: {result.get('message')}",
                  file=sys.stderr)
            return 1
        if not args.json:
            print(f"request {rid} done in {result['timings']['total']:.1f} s "
                  f"(seed {result['seed']})")
            print(f"URDF:   {result['urdf_path']}")
            meshes = sorted({os.path.dirname(p) for p in result["mesh_paths"].values()})
            print(f"meshes: {', '.join(meshes)} ({len(result['mesh_paths'])} parts)")
            print(f"folder: {result['output_dir']}")
        return 0
    except KeyboardInterrupt:
        return 130
    finally:
        client.close()
        rclpy.try_shutdown(context=context)


if __name__ == "__main__":
    sys.exit(main())


def main_old_name() -> int:
    """``request``: the executable's earlier name, kept for one more release."""
    print("request is now artformer_request; the old name goes in the next release",
          file=sys.stderr)
    return main()
