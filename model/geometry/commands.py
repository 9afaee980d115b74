"""`artformer train sdf|prior`, `artformer eval geometry`, `artformer bench geometry`.

argv keeps the route words, e.g. ['train', 'sdf', '--data', 'data/prepared/v1'].
"""
from __future__ import annotations

import argparse
import json
import logging
import sys


def _train_parser(kind: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=f"artformer train {kind}",
                                description=("train the tri-plane SDF auto-encoder" if kind == "sdf"
                                             else "train the codebook diffusion shape prior "
                                                  "(encodes every train part with --sdf first)"))
    p.add_argument("--data", required=True, help="prepared dataset folder (with manifest.json)")
    p.add_argument("--out", required=True, help="run folder: ckpt.pt, log.jsonl")
    p.add_argument("--preset", default="small",
                   help="tiny | small | small-fine | small-grid8 | paper (default small)")
    if kind == "prior":
        p.add_argument("--sdf", required=True, help="trained auto-encoder checkpoint")
        p.add_argument("--codebooks", type=int, help="number of codebooks C (preset: 4)")
        p.add_argument("--codebook-size", type=int, help="entries per codebook N (preset: 128)")
        p.add_argument("--codes-from", metavar="PRIOR",
                       help="adopt this prior's code space (codebooks and semantic encoder, "
                            "frozen) so the transformers trained for it run with the new "
                            "prior unchanged; needs --codes-sdf")
        p.add_argument("--codes-sdf", metavar="SDF",
                       help="with --codes-from: the auto-encoder that prior was trained on")
        p.add_argument("--distill-weight", type=float, default=1.0,
                       help="with --codes-from: weight of KL(that prior's codes || this one's)")
        p.add_argument("--bank-per-text", type=int, default=0, metavar="K",
                       help="with --export: keep at most K retrieval latents per label text "
                            "(a seeded draw; label code statistics stay those of all parts); "
                            "0 = all")
    p.add_argument("--steps", type=int, help="optimisation steps (default: the preset's)")
    p.add_argument("--epochs", type=float, help="alternative to --steps: passes over the parts")
    p.add_argument("--batch-size", type=int)
    p.add_argument("--lr", type=float)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, help="torch threads (split across torchrun ranks)")
    p.add_argument("--resume", action="store_true", help="continue from OUT/ckpt.pt")
    p.add_argument("--minutes", type=float, default=0.0,
                   help="wall-clock budget in minutes, counted over resumed runs (0 = none): "
                        "the run stops with its checkpoint written when it is spent")
    p.add_argument("--chunk-minutes", type=float, default=0.0,
                   help="stop this process after M minutes with its checkpoint written, schedule "
                        "untouched; the same command with --resume runs the next chunk")
    p.add_argument("--no-progress", action="store_true")
    if kind == "sdf":
        p.add_argument("--device", default="cpu", choices=("cpu", "cuda", "auto"),
                       help="where the auto-encoder trains (auto: CUDA when torch sees a GPU); "
                            "the weights load and run on the CPU either way, and the "
                            "checkpoint records the device")
    p.add_argument("--export", metavar="PATH",
                   help="also write a stripped fp16 copy of the final weights to PATH")
    return p


def _train(kind: str, argv: list[str]) -> int:
    from .train import RunArgs, export_weights, train_prior, train_sdf
    a = _train_parser(kind).parse_args(argv[2:])
    if a.minutes < 0 or a.chunk_minutes < 0:
        raise ValueError("--minutes and --chunk-minutes must be >= 0")
    args = RunArgs(data=a.data, out=a.out, preset=a.preset, steps=a.steps, epochs=a.epochs,
                   batch_size=a.batch_size, lr=a.lr, seed=a.seed, resume=a.resume,
                   threads=a.threads, progress=not a.no_progress,
                   sdf=getattr(a, "sdf", None), n_codebooks=getattr(a, "codebooks", None),
                   codebook_size=getattr(a, "codebook_size", None),
                   argv=tuple(["artformer", *argv]), minutes=a.minutes,
                   chunk_minutes=a.chunk_minutes, device=getattr(a, "device", "cpu"),
                   codes_from=getattr(a, "codes_from", None),
                   codes_sdf=getattr(a, "codes_sdf", None),
                   distill_weight=getattr(a, "distill_weight", 1.0))
    res = (train_sdf if kind == "sdf" else train_prior)(args)
    import os
    if int(os.environ.get("RANK", "0")) == 0:
        if a.export:
            res["exported_bytes"] = export_weights(res["out"], a.export, kind,
                                                   getattr(a, "bank_per_text", 0), a.seed)
            res["exported"] = a.export
        print(json.dumps(res, indent=1))
    return 0


def _load_shape(a, need_prior: bool):
    from .api import ShapeModel
    return ShapeModel.load(a.sdf, a.prior, need_prior=need_prior)


def _eval_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="artformer eval geometry",
                                description="per-label quality of the shape prior on held-out "
                                            "parts: F-score@1 %, Chamfer (mm), volume IoU, "
                                            "connected components and floaters of the "
                                            "auto-encoder's reconstructions and of prior samples")
    p.add_argument("--data", required=True)
    p.add_argument("--sdf", help="auto-encoder checkpoint (default: shipped)")
    p.add_argument("--prior", help="prior checkpoint (default: shipped)")
    p.add_argument("--split", default="test")
    p.add_argument("--max-parts", "--limit", type=int, default=300, dest="max_parts",
                   help="at most this many held-out parts (0 = all)")
    p.add_argument("--per-label", type=int, default=0,
                   help="at most this many parts per part label (0 = no cap)")
    p.add_argument("--resolution", type=int, default=64)
    p.add_argument("--labels", type=int, default=0,
                   help="prior: the N most frequent label texts (0 = every text in the selection)")
    p.add_argument("--samples-per-label", type=int, default=8, help="0 = skip the prior")
    p.add_argument("--steps", type=int, default=50)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--json", help="also write the results here")
    p.add_argument("--figures", metavar="DIR",
                   help="write geometry_worst_reconstructions.png and geometry_prior_samples.png "
                        "here")
    p.add_argument("--worst", type=int, default=12, help="reconstructions on the worst sheet")
    p.add_argument("--min-island", type=int, default=None,
                   help="meshing: remove inside islands of at most this many grid vertices "
                        "and fill enclosed voids (default: model.geometry.meshing.MIN_ISLAND; "
                        "0 keeps both)")
    p.add_argument("--diagnose", action="store_true",
                   help="instead: measure where thin walls are lost (resolution sweep, true SDF "
                        "meshed, decoder error vs distance, box vs iso frame, retrieval, "
                        "meshing remedies)")
    return p


def _eval(argv: list[str]) -> int:
    a = _eval_parser().parse_args(argv[2:])
    for name in ("max_parts", "per_label", "labels", "samples_per_label", "worst"):
        if getattr(a, name) < 0:
            raise ValueError(f"--{name.replace('_', '-')} must be >= 0")
    if a.min_island is not None and a.min_island < 0:
        raise ValueError("--min-island must be >= 0")
    mesh_kw = {} if a.min_island is None else {"min_island": a.min_island}
    if not 8 <= a.resolution <= 256:
        raise ValueError(f"--resolution must be in [8, 256], got {a.resolution}")
    import torch
    torch.set_num_threads(a.threads)
    from . import evaluate as ev
    if a.diagnose:
        return _diagnose(a)
    shape = _load_shape(a, need_prior=a.samples_per_label > 0)
    res = ev.evaluate(shape, a.data, split=a.split, max_parts=a.max_parts or None,
                      per_label_cap=a.per_label or None, resolution=a.resolution,
                      labels=a.labels or None, samples_per_label=a.samples_per_label,
                      steps=a.steps, seed=a.seed, keep_rows=True, mesh_kw=mesh_kw)
    rows = res.pop("rows")
    res["checkpoints"] = shape.info
    res["command"] = " ".join(["artformer", *argv])
    if a.figures:
        res["figures"] = _eval_figures(a.figures, rows, a.worst)
    res["parts_rows"] = {k: ev._json_rows(v) for k, v in rows.items()}
    print(ev.format_table(res))
    r, s = res["reconstruction"], res.get("prior", {})
    print(f"reconstruction: {r['parts']} parts, F@1% {r.get('fscore', float('nan')):.3f}, "
          f"true #components {r.get('true_components', float('nan')):.3f}, "
          f"mesh {r['mesh_ms_median']:.0f} ms/part (median)")
    if s:
        print(f"prior: {s['samples']} samples, watertight {s.get('watertight', 0):.3f}, "
              f"watertight without floaters {s['clean']:.3f}, diversity {s['diversity_mean']:.4f}")
    if a.json:
        from model.data.format import atomic_write_bytes
        atomic_write_bytes(a.json, json.dumps(res, indent=1, default=float).encode())
    return 0


def _diagnose(a) -> int:
    """`artformer eval geometry --diagnose`: the cause analysis, printed (and --json) as JSON."""
    from .evaluate import diagnose
    shape = _load_shape(a, need_prior=True)
    res = diagnose(shape, a.data, split=a.split, per_label_cap=a.per_label or 6,
                   max_parts=a.max_parts or None, seed=a.seed)
    res["checkpoints"] = shape.info
    text = json.dumps(res, indent=1)
    print(text)
    if a.json:
        from model.data.format import atomic_write_bytes
        atomic_write_bytes(a.json, text.encode())
    return 0


def _eval_figures(folder: str, rows: dict, worst: int) -> str:
    """The worst-reconstruction and prior-sample sheets into ``folder``; returns its path."""
    from pathlib import Path

    from .evaluate import samples_sheet, worst_sheet
    fig = Path(folder)
    fig.mkdir(parents=True, exist_ok=True)
    if rows["reconstruction"] and worst:
        worst_sheet(fig / "geometry_worst_reconstructions.png", rows["reconstruction"], k=worst)
    if rows["prior"]:
        samples_sheet(fig / "geometry_prior_samples.png", rows["prior"])
    return str(fig)


def _bench(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="artformer bench geometry",
                                description="ms per part mesh and DDIM time of the shape prior")
    p.add_argument("--sdf", help="auto-encoder checkpoint (default: shipped)")
    p.add_argument("--prior", help="prior checkpoint (default: shipped)")
    p.add_argument("--resolution", type=int, default=64)
    p.add_argument("--parts", type=int, default=8)
    p.add_argument("--steps", type=int, default=50)
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--threads", type=int, default=2, help="torch threads for meshing (2)")
    p.add_argument("--ddim-threads", type=int, default=1,
                   help="torch threads for DDIM (1, as the pipeline: model.core.runtime)")
    p.add_argument("--min-island", type=int, default=None,
                   help="meshing: inside islands removed up to this many grid vertices, "
                        "enclosed voids filled (default: model.geometry.meshing.MIN_ISLAND; "
                        "0 keeps both)")
    p.add_argument("--default-heap", action="store_true",
                   help="leave glibc's allocator thresholds alone (the pipeline keeps the "
                        "heap mapped: model.core.runtime.keep_heap_mapped)")
    a = p.parse_args(argv[2:])
    import torch
    torch.set_num_threads(a.threads)
    from model.core.runtime import keep_heap_mapped
    heap = False if a.default_heap else keep_heap_mapped()
    from .evaluate import benchmark
    shape = _load_shape(a, need_prior=True)
    if a.min_island is not None and a.min_island < 0:
        raise ValueError("--min-island must be >= 0")
    res = benchmark(shape, resolution=a.resolution, parts=a.parts, steps=a.steps,
                    repeats=a.repeats, ddim_threads=a.ddim_threads,
                    mesh_kw=None if a.min_island is None else {"min_island": a.min_island})
    res["heap_kept_mapped"] = heap
    for k, v in res.items():
        print(f"{k:<36} {v:.1f}" if isinstance(v, float) else f"{k:<36} {v}")
    return 0


def main(argv: list[str]) -> int:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    route = tuple(argv[:2])
    from .checkpoint import CheckpointError
    try:
        if route == ("train", "sdf"):
            return _train("sdf", argv)
        if route == ("train", "prior"):
            return _train("prior", argv)
        if route == ("eval", "geometry"):
            return _eval(argv)
        if route == ("bench", "geometry"):
            return _bench(argv)
    except (CheckpointError, FileNotFoundError, ValueError) as e:
        print(f"artformer {' '.join(route)}: error: {e}", file=sys.stderr)
        return 1
    print(f"model.geometry.commands: unknown route {' '.join(route)!r}", file=sys.stderr)
    return 2
