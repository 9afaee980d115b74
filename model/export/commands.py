"""`artformer export`: write the built-in example objects as URDF folders.

    artformer export --out out/examples [--example cabinet|bottle|all] [--format obj|stl|glb]
                     [--mesh-uri file|package://pkg/prefix] [--no-preview] [--check]
"""
from __future__ import annotations

import argparse
import json
import sys
import time


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="artformer export",
                                description="Export the built-in example object(s) to URDF "
                                            "folders (URDF + meshes + metadata.json + preview.png).")
    p.add_argument("--out", required=True, help="output folder; one sub-folder per object")
    p.add_argument("--example", default="all", choices=["cabinet", "bottle", "all"])
    p.add_argument("--format", default="obj", choices=["obj", "stl", "glb"], help="mesh format")
    p.add_argument("--mesh-uri", default="file",
                   help="'file' (absolute file:// paths) or a package:// prefix that stands for "
                        "each object folder, e.g. package://artformer_ros/objects/cabinet "
                        "(the object name is appended)")
    p.add_argument("--density", type=float, default=600.0, help="kg/m^3 for the inertials")
    p.add_argument("--no-preview", action="store_true", help="skip preview.png")
    p.add_argument("--check", action="store_true",
                   help="load each URDF in yourdfpy, pybullet, MuJoCo and Pinocchio and "
                        "compare poses")
    return p


def main(argv: list[str]) -> int:
    args = _parser().parse_args(argv[1:] if argv and argv[0] == "export" else argv)
    from pathlib import Path

    from model.core.example import example_objects

    from .urdf import export_object

    objs = example_objects()
    names = list(objs) if args.example == "all" else [args.example]
    status = 0
    for name in names:
        t0 = time.perf_counter()
        uri = args.mesh_uri if args.mesh_uri == "file" else f"{args.mesh_uri.rstrip('/')}/{name}"
        res = export_object(objs[name], Path(args.out) / name, mesh_format=args.format,
                            density=args.density, mesh_uri=uri, preview=not args.no_preview,
                            provenance={"source": f"built-in example '{name}'"})
        print(f"{name}: {res.urdf_path}  ({time.perf_counter() - t0:.2f} s)")
        print(f"  meshes:   {Path(res.urdf_path).parent / 'meshes'} ({len(res.mesh_paths)} visual)")
        print(f"  metadata: {res.metadata_path}")
        if res.preview_path:
            print(f"  preview:  {res.preview_path}")
        if args.check:
            from .simcheck import check_urdf
            rep = check_urdf(res.urdf_path, objs[name])
            print("  " + rep.summary().replace("\n", "\n  "))
            if not rep.ok:
                status = 1
                print(json.dumps(rep.to_dict(), indent=1), file=sys.stderr)
    return status


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
