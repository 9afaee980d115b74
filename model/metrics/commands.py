"""`artformer eval ...` and `artformer bench ...` (``eval geometry`` / ``bench geometry`` are
routed to the geometry package by model/cli.py)."""
from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

# Eval sizes. `tiny` is the CI smoke run (minutes on a laptop CPU); `full` the DESIGN §7 one.
EVAL_PRESETS: dict[str, dict] = {
    "tiny": dict(n=3, n_freeform=3, points=256, poses=3, por_states=3, diversity_prompts=1,
                 diversity_samples=2, steps=5, resolution=24, collision="hull"),
    "full": dict(),
}


def _eval_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="artformer eval",
        description="Generate for the test prompts and free-form prompts, then score POR, "
                    "MMD/COV/1-NNA (Instantiation Distance), alignment, diversity and validity "
                    "against baselines (retrieval, the training set's floor, ablations). "
                    "Writes results.json, results.md and PNG figures to --out.")
    p.add_argument("--checkpoint", default="shipped",
                   help="folder of the stage checkpoints, or 'shipped' (default)")
    p.add_argument("--data", default=None,
                   help="prepared dataset root (default: the pipeline's default dataset)")
    p.add_argument("--split", default="test")
    p.add_argument("--n", type=int, default=None, help="test prompts (records); default 20")
    p.add_argument("--freeform", type=int, default=None, dest="n_freeform",
                   help="how many free-form prompts (default: all shipped ones)")
    p.add_argument("--freeform-file", default=None)
    p.add_argument("--freeform-only", action="store_true",
                   help="only the free-form set's structure alignment (decoding + layout "
                        "refinement, no shapes, no dataset needed): the table by category, by "
                        "asked-for part count and by spatial fact")
    p.add_argument("--seeds", type=int, default=1,
                   help="--freeform-only: seeds per prompt (seed, seed+1, ...)")
    p.add_argument("--json", default=None, help="--freeform-only: write every row here")
    p.add_argument("--preset", choices=sorted(EVAL_PRESETS), default="full",
                   help="eval sizes: tiny = CI smoke run, full = DESIGN §7 sizes")
    p.add_argument("--out", default="eval_out")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--points", type=int, default=None, help="ID points per posed object (4096)")
    p.add_argument("--poses", type=int, default=None, help="ID instantiations per object (10)")
    p.add_argument("--por-states", type=int, default=None, help="POR openness states (10)")
    p.add_argument("--diversity-prompts", type=int, default=None)
    p.add_argument("--diversity-samples", type=int, default=None)
    p.add_argument("--ablation", action="append", default=[], metavar="NAME=DIR",
                   help="extra checkpoint scored as its own row (repeatable)")
    p.add_argument("--baselines-only", action="store_true",
                   help="skip generation with --checkpoint; score retrieval / floor / GT only")
    p.add_argument("--no-retrieval", action="store_true")
    p.add_argument("--no-part-retrieval", action="store_true",
                   help="skip the 'model (part retrieval)' row (paper: Ours-PR)")
    p.add_argument("--no-floor", action="store_true")
    p.add_argument("--no-validity", action="store_true")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--workers", type=int, default=1, help="KD-tree query threads")
    p.add_argument("--collision", default=None,
                   choices=["pipeline", "auto", "hull", "vhacd", "none"],
                   help="URDF collision geometry for validity (default: the generator's own "
                        "export; tiny preset: hull)")
    p.add_argument("--steps", type=int, default=None, help="DDIM steps override")
    p.add_argument("--resolution", type=int, default=None, help="meshing resolution override")
    p.add_argument("--structure-temperature", type=float, default=None,
                   help="tree decoding temperature override (product default 0.3)")
    p.add_argument("--no-plan", dest="follow_plan", action="store_const", const=False,
                   default=None, help="the paper's END decoding (no plan head guidance)")
    p.add_argument("--no-prompt-structure", dest="prompt_structure", action="store_false",
                   help="--freeform-only: decode with the network's own reading of each "
                        "prompt, without holding the parts it states")
    p.add_argument("-v", "--verbose", action="store_true")
    return p


def _default_data() -> str | None:
    """The newest prepared dataset under ./data/prepared or the repository's data/prepared
    (where `artformer data prepare` writes by default), when none matches the model's."""
    roots = [Path.cwd() / "data" / "prepared",
             Path(__file__).resolve().parents[2] / "data" / "prepared"]
    found = [m.parent for r in roots if r.is_dir() for m in r.glob("*/manifest.json")]
    found += [r for r in roots if (r / "manifest.json").exists()]
    if not found:
        return None
    return str(max(found, key=lambda p: (p / "manifest.json").stat().st_mtime))


def _model_data(checkpoint: str) -> str | None:
    """The prepared dataset the evaluated transformer was trained on (its data_version), if
    it is on this machine: its held-out splits are the ones to score."""
    from model.articulation.checkpoint import read_checkpoint
    from model.pipeline.generator import find_checkpoints

    from .diversity import _matching_data
    try:
        paths = find_checkpoints(None if checkpoint == "shipped" else checkpoint)
        return _matching_data(read_checkpoint(paths["transformer"]).get("data_version"))
    except Exception:  # noqa: BLE001 - a bad checkpoint is reported when it is loaded
        return None


def eval_main(argv: list[str]) -> int:
    args = _eval_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if args.freeform_only:
        return _freeform_main(args)
    from .evaluate import EvalConfig, freeform_table, run_eval
    data = args.data or _model_data(args.checkpoint) or _default_data()
    if not data:
        print("artformer eval: give --data DIR (a prepared dataset, `artformer data prepare`)",
              file=sys.stderr)
        return 2
    ablations = {}
    for a in args.ablation:
        if "=" not in a:
            print(f"artformer eval: --ablation wants NAME=DIR, got {a!r}", file=sys.stderr)
            return 2
        k, v = a.split("=", 1)
        ablations[k] = v
    kw = dict(EVAL_PRESETS[args.preset])
    for name in ("n", "n_freeform", "points", "poses", "por_states", "diversity_prompts",
                 "diversity_samples", "steps", "resolution", "collision",
                 "structure_temperature", "follow_plan"):
        v = getattr(args, name)
        if v is not None:
            kw[name] = v
    cfg = EvalConfig(data=data, out=args.out, checkpoint=args.checkpoint, split=args.split,
                     freeform_file=args.freeform_file, seed=args.seed, ablations=ablations,
                     model=not args.baselines_only, retrieval=not args.no_retrieval,
                     part_retrieval=not args.no_part_retrieval, train_floor=not args.no_floor,
                     validity=not args.no_validity, workers=args.workers,
                     plots=not args.no_plots, progress=True, **kw)
    results = run_eval(cfg)
    print((Path(cfg.out) / "results.md").read_text())
    for row in results["rows"]:
        if row.get("alignment_freeform_breakdown"):
            print(f"\nFree-form alignment of {row['name']}:\n")
            print(freeform_table(row["alignment_freeform_breakdown"]))
    print(f"wrote {cfg.out}/results.json, results.md"
          + (", " + ", ".join(Path(f).name for f in results.get("figures", [])) if results.get("figures") else "")
          + f" in {results['seconds']:.0f} s")
    return 0


def _freeform_main(args) -> int:
    from .evaluate import FreeformConfig, freeform_alignment
    cfg = FreeformConfig(checkpoint=args.checkpoint, prompts_file=args.freeform_file,
                         seeds=args.seeds, seed=args.seed, limit=args.n_freeform,
                         structure_temperature=args.structure_temperature,
                         follow_plan=args.follow_plan, progress=sys.stderr.isatty(),
                         prompt_structure=args.prompt_structure)
    try:
        res = freeform_alignment(cfg)
    except (ValueError, FileNotFoundError) as e:
        print(f"artformer eval: {e}", file=sys.stderr)
        return 2
    print(f"Free-form structure alignment: {res['n_prompts']} prompts x {cfg.seeds} seed(s), "
          f"{res['checkpoint']}, T = {res['structure_temperature']}, "
          f"plan {'on' if res['follow_plan'] else 'off'} ({res['seconds']:.0f} s)\n")
    print(res["table"])
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(res, indent=1))
        print(f"wrote {args.json}")
    return 0


def _bench_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="artformer bench",
        description="Per-stage generation timings (median / p95 over N prompts), model load "
                    "time and peak memory (RSS high-water mark of a fresh process).")
    p.add_argument("--n", type=int, default=20)
    p.add_argument("--checkpoint", default="shipped")
    p.add_argument("--out", default="bench.json")
    p.add_argument("--md", default=None, help="also write the markdown table here")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--steps", type=int, default=None)
    p.add_argument("--resolution", type=int, default=None)
    p.add_argument("--no-export", action="store_true")
    p.add_argument("--warmup", type=int, default=1)
    p.add_argument("--prompts-file", default=None)
    p.add_argument("--images", nargs="+", default=None, metavar="IMAGE",
                   help="time image requests on these files (cycled) instead of text prompts")
    return p


def bench_main(argv: list[str]) -> int:
    args = _bench_parser().parse_args(argv)
    from .bench import BenchConfig, run_bench
    from .report import bench_markdown
    cfg = BenchConfig(n=args.n, checkpoint=args.checkpoint, seed=args.seed, threads=args.threads,
                      steps=args.steps, resolution=args.resolution, export=not args.no_export,
                      prompts_file=args.prompts_file, warmup=args.warmup,
                      images=[str(Path(f).resolve()) for f in args.images] if args.images else None)
    missing = [f for f in cfg.images or [] if not Path(f).is_file()]
    if missing:
        print(f"artformer bench: no such image file(s): {missing[:3]}", file=sys.stderr)
        return 2
    print(f"benchmarking {cfg.n} {'images' if cfg.images else 'prompts'} in a fresh process ...",
          file=sys.stderr)
    res = run_bench(cfg)
    md = bench_markdown(res)
    print(md)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(res, indent=1))
    if args.md:
        Path(args.md).write_text(md)
    if res["failures"]:
        print(f"{len(res['failures'])} prompt(s) failed: {res['failures'][:3]}", file=sys.stderr)
    print(f"wrote {args.out}")
    return 0


def audit_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(
        prog="artformer audit",
        description="Physical audit of URDF folders (ours, the dataset's, anyone's): "
                    "interpenetration over joint sweeps, attachment, hinge and drawer axes, "
                    "mesh health, MuJoCo physics; a sim-ready verdict per object.")
    p.add_argument("paths", nargs="+", help="URDF files or folders (searched recursively)")
    p.add_argument("--json", default=None, help="write every object's audit here")
    p.add_argument("--sheet", default=None, help="contact-sheet PNG of the worst objects")
    p.add_argument("--worst", type=int, default=8, help="objects on the contact sheet")
    p.add_argument("--no-physics", action="store_true", help="skip the MuJoCo check")
    p.add_argument("--face-budget", type=int, default=None,
                   help="faces per object (default 30000; 0: not checked)")
    p.add_argument("--states", type=int, default=None, help="openness states of the sweeps (10)")
    args = p.parse_args(argv)
    from .audit import AuditConfig, audit_paths, audit_table, summarise, write_contact_sheet
    cfg = AuditConfig(physics=not args.no_physics)
    if args.face_budget is not None:
        cfg.face_budget = args.face_budget
    if args.states is not None:
        cfg.states = args.states
    try:
        reps = audit_paths(args.paths, cfg, progress=sys.stderr.isatty())
    except FileNotFoundError as e:
        print(f"artformer audit: {e}", file=sys.stderr)
        return 2
    if not reps:
        print("artformer audit: no .urdf file under " + " ".join(args.paths), file=sys.stderr)
        return 2
    print(audit_table(reps, cfg))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps({"summary": summarise(reps, cfg),
                                               "objects": [r.to_dict() for r in reps]}, indent=1))
        print(f"wrote {args.json}")
    if args.sheet:
        print(f"wrote {write_contact_sheet(reps, args.sheet, worst=args.worst)}")
    return 0


def main(argv: list[str]) -> int:
    if not argv:
        print("usage: artformer eval|bench|audit [...]", file=sys.stderr)
        return 2
    if argv[:2] == ["eval", "diversity"]:
        from .diversity import main as diversity_main
        return diversity_main(argv[2:])
    if argv[:2] == ["eval", "layout"]:
        from .layout_precision import main as layout_main
        return layout_main(argv[2:])
    if argv[0] == "eval":
        return eval_main(argv[1:])
    if argv[0] == "bench":
        return bench_main(argv[1:])
    if argv[0] == "audit":
        return audit_main(argv[1:])
    print(f"model.metrics.commands: unknown command {argv[0]!r}", file=sys.stderr)
    return 2
