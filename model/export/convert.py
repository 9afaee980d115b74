"""`artformer convert`: an exported object folder (URDF + meshes) to another format.

    artformer convert out/cabinet --to mjcf                   # out/cabinet/mjcf/
    artformer convert out/cabinet --to mjcf --out sim/cabinet --floating --check
    artformer convert out/cabinet --to usd                    # out/cabinet/usd/<name>.usd
    artformer convert out/cabinet --to ros-package --name cabinet   # .../ros/cabinet_description

Python: ``model.export.convert.convert(folder, "mjcf")`` (or the per-format functions
``model.export.mjcf.export_mjcf`` ...).
"""
from __future__ import annotations

import argparse
import logging
import os
import sys
from pathlib import Path
from typing import Optional

FORMATS = ("mjcf", "usd", "ros-package")


def convert(folder: os.PathLike, to: str, out: Optional[os.PathLike] = None, **options):
    """Convert the object folder ``folder`` to format ``to``; returns that format's result
    object. ``options`` go to the format's function. Raises ConvertError on bad input."""
    from .urdfmodel import ConvertError
    if to == "mjcf":
        from .mjcf import export_mjcf
        return export_mjcf(folder, out, **options)
    if to == "usd":
        from .usd import export_usd
        return export_usd(folder, out, **options)
    if to == "ros-package":
        from .rospackage import export_ros_package
        return export_ros_package(folder, out, **options)
    raise ConvertError(f"unknown format {to!r}; choose one of {', '.join(FORMATS)}")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="artformer convert",
        description="Convert an object folder written by `artformer export` / `artformer "
                    "generate` (URDF + meshes) to MJCF, USD or a ROS 2 description "
                    "package.")
    p.add_argument("folder", help="object folder (or its .urdf file)")
    p.add_argument("--to", required=True, choices=FORMATS, help="target format")
    p.add_argument("--out", help="mjcf: output folder (default FOLDER/mjcf); usd: output file "
                                 ".usd/.usda/.usdc (default FOLDER/usd/<name>.usd); "
                                 "ros-package: the package folder (default "
                                 "FOLDER/ros/NAME_description)")
    p.add_argument("--floating", action="store_true",
                   help="mjcf, usd: do not fix the root link to the world (MJCF: free joint)")
    g = p.add_argument_group("mjcf")
    g.add_argument("--kp-hz", type=float, default=4.0,
                   help="natural frequency of every position actuator at rest (default 4 Hz)")
    g = p.add_argument_group("ros-package")
    g.add_argument("--name", help="package NAME_description (default: from the robot name)")
    p.add_argument("--check", action="store_true",
                   help="load the result in its consumer and move every joint (exit 1 on failure)")
    p.add_argument("-v", "--verbose", action="store_true")
    return p


def _print_mjcf(res, check: bool) -> int:
    print(f"model:     {res.model_xml}")
    print(f"scene:     {res.scene_xml}")
    print(f"joints:    {len(res.joints)}  actuators: {len(res.actuators)}"
          f"{'  screw couplings: ' + str(len(res.couplings)) if res.couplings else ''}")
    if res.dropped_meshes:
        print(f"left out ({len(res.dropped_meshes)} meshes MuJoCo cannot compile): "
              f"{', '.join(res.dropped_meshes[:5])}{' ...' if len(res.dropped_meshes) > 5 else ''}")
    if not check:
        return 0
    from .mjcf import drive_check
    rep = drive_check(res.scene_xml, res.joints)
    worst = min(rep.reached.values()) if rep.reached else 1.0
    print(f"check:     {'ok' if rep.ok else 'FAIL'} loaded={rep.loaded} finite={rep.finite} "
          f"within_limits={rep.within_limits} worst travel reached={worst:.2f}"
          f"{' missing joints: ' + str(rep.missing_joints) if rep.missing_joints else ''}"
          f"{' error: ' + rep.error if rep.error else ''}")
    for name, share in rep.reached.items():
        if share < 0.9:
            print(f"  actuator {name} reached {share:.2f} of its commanded travel")
    return 0 if rep.ok else 1


def _print_usd(res, check: bool, folder) -> int:
    print(f"stage:     {res.path}")
    print(f"root:      {res.root}  links: {len(res.links)}  moving joints: {len(res.joints)}")
    if not check:
        return 0
    from .usd import check_usd
    problems = check_usd(res.path, folder)
    print(f"check:     {'ok' if not problems else 'FAIL'}"
          + "".join(f"\n  {p}" for p in problems))
    return 0 if not problems else 1


def _print_ros(res, check: bool) -> int:
    print(f"package:   {res.package}  ({res.out_dir})")
    print(f"urdf:      {res.urdf}  ({len(res.meshes)} meshes)")
    print(f"build:     colcon build --base-paths {Path(res.out_dir).parent} && "
          f"source install/setup.bash")
    print(f"installed: share/{res.share_urdf}")
    if check:
        print("check:     --check is not available for ros-package (build it with colcon)")
    return 0


def main(argv: list[str]) -> int:
    args = _parser().parse_args(argv[1:] if argv and argv[0] == "convert" else argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    from .urdfmodel import ConvertError
    options = {}
    if args.to == "mjcf":
        options = {"floating": args.floating, "kp_hz": args.kp_hz}
    elif args.to == "usd":
        options = {"floating": args.floating}
    else:
        options = {"name": args.name}
    try:
        res = convert(args.folder, args.to, Path(args.out) if args.out else None, **options)
    except ConvertError as e:
        print(f"artformer convert: {e}", file=sys.stderr)
        return 1
    if args.to == "usd":
        return _print_usd(res, args.check, args.folder)
    if args.to == "ros-package":
        return _print_ros(res, args.check)
    return _print_mjcf(res, args.check)


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
