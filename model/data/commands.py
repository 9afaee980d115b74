"""`artformer data synth | prepare | stats` (argv keeps the route words: ['data', 'synth', ...])."""
from __future__ import annotations

import argparse
import logging
import sys
import time


def _synth(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="artformer data synth",
                                 description="write N procedural articulated objects as PartNet-Mobility folders")
    ap.add_argument("--n", type=int, required=True, help="number of objects")
    ap.add_argument("--out", required=True, help="output folder (one sub-folder per object)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--categories", default="",
                    help="comma-separated subset, e.g. Bottle,USB (default: all six with the standard weights)")
    args = ap.parse_args(argv)
    from model.data.synth import CATEGORY_WEIGHTS, SynthConfig, synthesize_dataset
    cfg = SynthConfig(seed=args.seed)
    if args.categories:
        cats = [c.strip() for c in args.categories.split(",") if c.strip()]
        unknown = [c for c in cats if c not in CATEGORY_WEIGHTS]
        if unknown:
            print(f"unknown categories {unknown}; choose from {sorted(CATEGORY_WEIGHTS)}", file=sys.stderr)
            return 2
        cfg.categories = {c: CATEGORY_WEIGHTS[c] for c in cats}
    t0 = time.time()
    info = synthesize_dataset(args.out, args.n, args.seed, args.workers, config=cfg)
    print(f"synth: {args.n} objects in {args.out} ({time.time() - t0:.1f} s, "
          f"{len(info['errors'])} failed)")
    return 1 if info["errors"] else 0


def _prepare(argv: list[str]) -> int:
    from model.data.preprocess import PrepareConfig
    d = PrepareConfig()
    ap = argparse.ArgumentParser(prog="artformer data prepare",
                                 description="preprocess PartNet-Mobility-format folders (synthetic or real) "
                                             "into the prepared training format (resumable)")
    ap.add_argument("--src", required=True, help="a PartNet-Mobility object folder or a dataset folder")
    ap.add_argument("--out", required=True, help="prepared dataset folder (one per data version)")
    ap.add_argument("--workers", type=int, default=d.workers)
    ap.add_argument("--points", type=int, default=d.points, help="surface points per part")
    ap.add_argument("--samples", type=int, default=d.samples, help="SDF samples per part")
    ap.add_argument("--seed", type=int, default=d.seed, help="split and sampling seed")
    ap.add_argument("--up-axis", choices=["auto", "y", "z"], default="auto",
                    help="auto: meta.json's up_axis, else y (real PartNet-Mobility)")
    ap.add_argument("--version", default="", help="data_version string for the manifest")
    ap.add_argument("--limit", type=int, default=0, help="only the first N objects")
    ap.add_argument("--no-meshes", action="store_true", help="do not keep the watertight part meshes")
    args = ap.parse_args(argv)
    from model.data.preprocess import prepare_dataset
    cfg = PrepareConfig(src=args.src, out=args.out, workers=args.workers, points=args.points,
                        samples=args.samples, seed=args.seed, up_axis=args.up_axis,
                        data_version=args.version, limit=args.limit, write_meshes=not args.no_meshes)
    t0 = time.time()
    m = prepare_dataset(cfg)
    n = {k: len(v) for k, v in m["splits"].items()}
    print(f"prepare: {sum(n.values())} objects ({n}) in {args.out}, version {m['data_version']!r}, "
          f"{time.time() - t0:.1f} s, {len(m['errors'])} failed")
    for k, v in list(m["errors"].items())[:10]:
        print(f"  failed {k}: {v}", file=sys.stderr)
    return 1 if m["errors"] and not any(n.values()) else 0


def _stats(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="artformer data stats",
                                 description="table and plot of a prepared dataset (or a synth folder)")
    ap.add_argument("dir", help="prepared dataset folder (with manifest.json) or PartNet-Mobility folders")
    ap.add_argument("--plot", default="", help="PNG path (default: DIR/stats.png)")
    ap.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    ap.add_argument("--audit", default="", metavar="SRC",
                    help="also audit the PartNet-Mobility folders SRC: exact part overlaps (POR) "
                         "over 10 openness states and the number of distinct objects")
    args = ap.parse_args(argv)
    from model.data.stats import compute_stats, format_table, save_plot
    st = compute_stats(args.dir)
    print(format_table(st, markdown=args.markdown))
    from pathlib import Path
    png = args.plot or str(Path(args.dir) / "stats.png")
    save_plot(st, png)
    print(f"plot: {png}")
    if args.audit:
        from model.data.stats import audit_objects
        a = audit_objects(args.audit)
        print(f"audit {args.audit}: {a['objects']} objects, {a['distinct']} distinct; "
              f"POR mean {a['por_mean']:.3g}, worst state {a['por_max_state']:.3g}; "
              f"largest pairwise intersection {a['max_intersection_m3']:.3g} m³ ({a['worst']}); "
              f"{len(a['overlapping'])} objects with a real overlap {a['overlapping'][:20]}")
    return 0


def main(argv: list[str]) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    words = list(argv)
    if words and words[0] == "data":
        words = words[1:]
    sub = {"synth": _synth, "prepare": _prepare, "stats": _stats}
    if not words or words[0] in ("-h", "--help") or words[0] not in sub:
        print("usage: artformer data {synth,prepare,stats} [...]\n\n"
              "  synth    write N procedural objects as PartNet-Mobility folders\n"
              "  prepare  preprocess folders into the prepared training format\n"
              "  stats    per-category counts, parts histogram, joint types, description lengths",
              file=sys.stderr if words and words[0] not in ("-h", "--help") else sys.stdout)
        return 0 if not words or words[0] in ("-h", "--help") else 2
    return sub[words[0]](words[1:])
