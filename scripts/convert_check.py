"""Convert object folders to MJCF, USD and ROS description packages and count how many load
in their consumers (MuJoCo, pxr, colcon build + the installed URDF in yourdfpy / pybullet /
MuJoCo / Pinocchio).

    python scripts/convert_check.py out/batch            # a batch folder (its manifest.jsonl)
    python scripts/convert_check.py out/a out/b --work /tmp/conv --json figures.json

Figures printed per consumer:
  mjcf  loads      MuJoCo compiles scene.xml and every URDF moving joint is a MuJoCo joint
  mjcf  driven     ... and each position actuator moves its joint >= 90 % of the way to both
                   ends of its range within 1.5 s, the state stays finite and within limits
  usd   ok         pxr opens the stage and check_usd finds nothing (joint set, limits, bodies,
                   articulation root, joint frames agree at rest)
  ros   built      colcon build installed the package (share/<pkg>/urdf + meshes)
  ros   loads      the installed URDF (package:// through the ament index) loads and moves in
                   the four URDF loaders
  physics          (--physics) the audit's MuJoCo check (model.export.physics) passes on the
                   URDF and on the MJCF object model
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def object_folders(paths: list[str]) -> list[Path]:
    """Object folders: a batch folder gives its manifest's ok entries, a folder holding a
    .urdf is one object, any other folder gives its sub-folders that hold one."""
    out = []
    for p in map(Path, paths):
        manifest = p / "manifest.jsonl"
        if manifest.is_file():
            for line in manifest.read_text().splitlines():
                if line.strip():
                    e = json.loads(line)
                    if e.get("status") == "ok":
                        out.append(p / e["out_dir"])
        elif list(p.glob("*.urdf")):
            out.append(p)
        else:
            out.extend(sorted(d for d in p.iterdir() if d.is_dir() and list(d.glob("*.urdf"))))
    return out


def _mjcf(folder: Path, out: Path, counts: dict, failures: list, physics: bool) -> None:
    from model.export.mjcf import drive_check, export_mjcf

    res = export_mjcf(folder, out)
    rep = drive_check(res.scene_xml, res.joints)
    if rep.loaded and not rep.missing_joints:
        counts["mjcf_loads"] += 1
    if rep.ok:
        counts["mjcf_driven"] += 1
    else:
        stuck = {n: round(v, 2) for n, v in rep.reached.items() if v < 0.9}
        failures.append(f"mjcf {folder}: finite={rep.finite} within_limits="
                        f"{rep.within_limits} stuck={stuck} {rep.error}")
    if physics:
        from model.export.physics import physics_check

        for kind, path in (("urdf", next(folder.glob("*.urdf"))), ("mjcf", res.model_xml)):
            ph = physics_check(path)
            counts[f"{kind}_physics"] += int(ph.ok)
            if not ph.ok:
                failures.append(f"{kind} physics {folder}: {ph.failures[:2]}")


def _usd(folder: Path, out: Path, counts: dict, failures: list) -> None:
    from model.export.usd import check_usd, export_usd

    res = export_usd(folder, out)
    problems = check_usd(res.path, folder)
    if problems:
        failures.append(f"usd {folder}: {problems[:3]}")
    else:
        counts["usd_ok"] += 1


def _ros(packages: dict, work: Path, counts: dict, failures: list, seconds: dict) -> None:
    """One colcon build of every package, then the installed URDFs in the four loaders."""
    from model.export.simcheck import check_urdf

    colcon = Path(sys.executable).parent / "colcon"
    colcon = str(colcon) if colcon.exists() else shutil.which("colcon") or "colcon"
    t = time.perf_counter()
    build = subprocess.run([colcon, "--log-base", str(work / "log"), "build",
                            "--base-paths", str(work / "ws" / "src"),
                            "--build-base", str(work / "build"),
                            "--install-base", str(work / "install")],
                           capture_output=True, text=True, cwd=work)
    seconds["colcon_build"] = time.perf_counter() - t
    prefixes = []
    for pkg, (folder, r) in packages.items():
        share = work / "install" / pkg / "share" / r.share_urdf
        if f"Finished <<< {pkg}" in build.stdout and share.is_file():
            counts["ros_built"] += 1
            prefixes.append(str(work / "install" / pkg))
        else:
            failures.append(f"ros {folder}: colcon did not install {pkg}")
    os.environ["AMENT_PREFIX_PATH"] = os.pathsep.join(
        prefixes + [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p])
    t = time.perf_counter()
    for pkg, (folder, r) in packages.items():
        share = work / "install" / pkg / "share" / r.share_urdf
        if not share.is_file():
            continue
        rep = check_urdf(share)
        if rep.ok:
            counts["ros_loads"] += 1
        else:
            failures.append(f"ros {folder}: installed URDF: {rep.summary()}")
    seconds["ros_check"] = time.perf_counter() - t


def _timed(seconds: dict, key: str, failures: list, label: str, fn, *args) -> None:
    t = time.perf_counter()
    try:
        fn(*args)
    except Exception as e:
        failures.append(f"{label}: {type(e).__name__}: {e}")
    seconds[key] = seconds.get(key, 0.0) + time.perf_counter() - t


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("paths", nargs="+", help="object folders, batch folders or their parents")
    ap.add_argument("--work", help="folder for the converted files (default: a temp folder)")
    ap.add_argument("--no-ros", action="store_true", help="skip the colcon build")
    ap.add_argument("--physics", action="store_true",
                    help="also run the audit's MuJoCo physics check on each URDF and its MJCF")
    ap.add_argument("--json", help="also write the figures to this file")
    a = ap.parse_args(argv)

    from model.export.rospackage import export_ros_package

    folders = object_folders(a.paths)
    if not folders:
        print("no object folders found", file=sys.stderr)
        return 1
    work = Path(a.work or tempfile.mkdtemp(prefix="convert_check_"))
    work.mkdir(parents=True, exist_ok=True)
    counts = {"objects": len(folders), "mjcf_loads": 0, "mjcf_driven": 0, "usd_ok": 0,
              "ros_built": 0, "ros_loads": 0, "urdf_physics": 0, "mjcf_physics": 0}
    seconds: dict = {}
    failures: list[str] = []
    packages = {}

    def package(k, folder):
        r = export_ros_package(folder, work / "ws" / "src" / f"obj{k:03d}_description",
                               name=f"obj{k:03d}")
        packages[r.package] = (folder, r)

    for k, folder in enumerate(folders):
        tag = f"{k:03d}_{folder.name}"
        _timed(seconds, "mjcf", failures, f"mjcf {folder}", _mjcf, folder,
               work / "mjcf" / tag, counts, failures, a.physics)
        _timed(seconds, "usd", failures, f"usd {folder}", _usd, folder,
               work / "usd" / f"{tag}.usd", counts, failures)
        if not a.no_ros:
            _timed(seconds, "ros", failures, f"ros {folder}", package, k, folder)
    if packages:
        _ros(packages, work, counts, failures, seconds)

    n = counts["objects"]
    print(f"{n} objects, converted under {work}")
    print(f"  MuJoCo loads the MJCF with every joint:        {counts['mjcf_loads']}/{n}")
    print(f"  MuJoCo: every actuator drives its joint:       {counts['mjcf_driven']}/{n}")
    if a.physics:
        print(f"  audit physics check passes, URDF:              {counts['urdf_physics']}/{n}")
        print(f"  audit physics check passes, MJCF:              {counts['mjcf_physics']}/{n}")
    print(f"  pxr opens the USD, joints + limits match URDF: {counts['usd_ok']}/{n}")
    if not a.no_ros:
        print(f"  colcon build installs the ROS package:         {counts['ros_built']}/{n}")
        print(f"  installed URDF loads in the 4 URDF loaders:    {counts['ros_loads']}/{n}")
    print("  seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in seconds.items()))
    for f in failures:
        print("  - " + f)
    if a.json:
        Path(a.json).write_text(json.dumps({"counts": counts, "seconds": seconds,
                                            "failures": failures}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
