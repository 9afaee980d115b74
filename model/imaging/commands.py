"""`artformer data render`, `data partmaps`, `data features`, `artformer train image`,
`image-trunk` and `image-counts` (issue 8)."""
from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path


def _render(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="artformer data render",
                                 description="Render every object of a prepared dataset from several "
                                             "viewpoints and openness states (cached, resumable).")
    ap.add_argument("--data", default="data/prepared/v1", help="prepared dataset folder")
    ap.add_argument("--out", default="data/renders/v1", help="render folder")
    ap.add_argument("--views", type=int, default=8, help="views per object (default 8)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    ap.add_argument("--limit", type=int, default=0, help="only the first N objects of each split")
    ap.add_argument("--splits", default="train,val,test")
    ap.add_argument("--reuse", default=None, metavar="RENDERS",
                    help="an earlier render folder (same settings, another data version): "
                         "objects whose record and meshes are unchanged take its views")
    args = ap.parse_args(argv)
    from .renders import RenderSetError, render_dataset
    try:
        rep = render_dataset(args.data, args.out, views=args.views, seed=args.seed,
                             workers=args.workers, limit=args.limit,
                             splits=tuple(s for s in args.splits.split(",") if s), progress=True,
                             reuse=args.reuse)
    except (RenderSetError, FileNotFoundError, ValueError) as e:
        print(f"artformer data render: {e}", file=sys.stderr)
        return 2
    reused = f"{rep.reused} taken from {args.reuse}, " if args.reuse else ""
    print(f"rendered {rep.rendered} objects ({args.views} views each), {rep.skipped} already done, "
          f"{reused}{len(rep.failed)} failed, {rep.seconds:.1f} s -> {args.out}")
    for oid, err in list(rep.failed.items())[:10]:
        print(f"  failed {oid}: {err}", file=sys.stderr)
    return 1 if rep.failed and not rep.rendered else 0


def _render_set_parser(name: str, description: str) -> argparse.ArgumentParser:
    """A `artformer data NAME` parser with the (--data, --renders) pair it works on."""
    ap = argparse.ArgumentParser(prog=f"artformer data {name}", description=description)
    ap.add_argument("--data", default="data/prepared/v1", help="prepared dataset folder")
    ap.add_argument("--renders", default="data/renders/v1", help="its render folder")
    return ap


def _partmaps(argv: list[str]) -> int:
    ap = _render_set_parser("partmaps", "Per-label part-centre maps (7x7) of every rendered view, "
                                        "for `artformer train image-trunk --centre-weight`.")
    ap.add_argument("--image", default=None,
                    help="image checkpoint whose count labels are mapped (default: the shipped one)")
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    args = ap.parse_args(argv)
    from .partmaps import build_partmaps, partmap_path
    from .trunk import count_labels_of
    try:
        labels = count_labels_of(args.image)
        pm = build_partmaps(args.data, args.renders, labels, workers=args.workers, progress=True)
    except (FileNotFoundError, ValueError) as e:
        print(f"artformer data partmaps: {e}", file=sys.stderr)
        return 2
    print(f"part maps of {len(pm['ids'])} objects ({len(pm['failed'])} failed) -> "
          f"{partmap_path(args.renders)}")
    return 1 if pm["failed"] else 0


def _features(argv: list[str]) -> int:
    ap = _render_set_parser("features", "Cache the encoder features of every rendered view of a "
                                        "dataset, as `artformer train image` does on first use "
                                        "(one process per render set runs the sets in parallel).")
    ap.add_argument("--trunk", default=None,
                    help="a fine-tuned trunk (`artformer train image-trunk` OUT/trunk.pt, or an "
                         "image checkpoint's); default ImageNet's")
    ap.add_argument("--image-size", type=int, default=224, help="encoder input size (a multiple of 224)")
    ap.add_argument("--splits", default="train,val,test", help="splits whose objects are cached")
    ap.add_argument("--multiscale", action="store_true",
                    help="also cache the block-10 map (14x14x112) that `train image --multiscale` reads")
    ap.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    args = ap.parse_args(argv)
    import time

    import torch

    from model.data import format as fmt
    from model.encoders.image import FINE_SPLIT, ImageEncoder, ImageEncoderConfig

    from .features import CACHE_SPLIT, IMAGENET, build_feature_cache, cache_path, encoder_cache_args
    from .trunk import TrunkError, load_trunk
    torch.set_num_threads(max(1, args.threads))
    t0 = time.time()
    try:
        ids = [i for s in args.splits.split(",") if s for i in fmt.split_ids(args.data, s)]
        enc = ImageEncoder(ImageEncoderConfig(image_size=args.image_size))
        trunk = load_trunk(args.trunk) if args.trunk else None
        if trunk is not None:
            enc.load_tail_state_dict(trunk["state_dict"])
        kw = encoder_cache_args(enc, IMAGENET if trunk is None else trunk["tag"])
        tag = kw.get("tag", IMAGENET)
        splits = [CACHE_SPLIT] + ([FINE_SPLIT] if args.multiscale else [])
        for split in splits:
            cache = build_feature_cache(args.renders, ids, progress=True, split=split, **kw)
            print(f"features of {len(cache['ids'])} objects ({tuple(cache['feats'].shape)}, "
                  f"tag {tag}) after {time.time() - t0:.0f} s -> "
                  f"{cache_path(args.renders, split, tag=tag)}")
    except (TrunkError, FileNotFoundError, KeyError, ValueError) as e:
        print(f"artformer data features: {e}", file=sys.stderr)
        return 2
    return 0


def _image_eval_args(ap: argparse.ArgumentParser) -> None:
    """The --eval options of `artformer train image`."""
    ap.add_argument("--eval", metavar="CKPT", help="category / structure accuracy of CKPT on --split")
    ap.add_argument("--split", default="test")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--eval-views", default="all", help="--eval: view indices (comma list) or 'all'")
    ap.add_argument("--eval-seed", type=int, default=0)
    ap.add_argument("--temperature", type=float, default=1.0)
    ap.add_argument("--follow-plan", action="store_true",
                    help="--eval: decode with END decisions held to the START plan head")
    ap.add_argument("--no-count-plan", action="store_true",
                    help="--eval: ignore the checkpoint's count head (decode END freely)")
    ap.add_argument("--oracle-plan", action="store_true",
                    help="--eval diagnostic: hold END decisions to each object's TRUE part "
                         "counts (how far count-guided decoding can go)")
    ap.add_argument("--visibility", action="store_true",
                    help="--eval: also measure every part's visible pixels in each render and "
                         "report structure by visibility (by_visibility)")
    ap.add_argument("--visible-px", type=int, default=16,
                    help="--visibility: pixels a part needs to count as visible (default 16)")
    ap.add_argument("--frame", action="store_true",
                    help="--eval: crop each picture around its object first, as the product "
                         "does for photos (model.encoders.framing)")
    ap.add_argument("--farther", type=float, default=1.0, metavar="S",
                    help="--eval: show each render at S (< 1) of the picture's side, in the "
                         "middle of a larger picture of its background colour: a photo taken "
                         "from further away (default 1: the render as it is)")


def image_parser():
    """The parser of `artformer train image` (model.app.train_image adds --pipeline)."""
    from model.articulation.commands import add_training_args
    ap = argparse.ArgumentParser(
        prog="artformer train image",
        description="Train the articulation transformer conditioned on rendered images "
                    "(EfficientNet-Lite0 tokens), or --eval an image checkpoint on held-out renders.")
    ap.add_argument("--data", default="data/prepared/v1")
    ap.add_argument("--renders", default="data/renders/v1")
    ap.add_argument("--prior", default="model/weights/prior_small.pt",
                    help="shape-prior checkpoint (P_gt / c_s targets); 'none' = stand-in targets")
    ap.add_argument("--sdf", default="model/weights/sdf_small.pt")
    ap.add_argument("--preset", default="small")
    ap.add_argument("--out", default="runs/image_small")
    ap.add_argument("--init", default="model/weights/transformer_small.pt",
                    help="text transformer checkpoint to start from ('none' = from scratch)")
    ap.add_argument("--trainable-blocks", type=int, default=0, choices=(0, 1),
                    help="0 = frozen encoder (default), 1 = fine-tune its last block + head")
    ap.add_argument("--tail-lr-mult", type=float, default=0.1)
    ap.add_argument("--trunk", metavar="TRUNK_PT",
                    help="read the features of this fine-tuned trunk (`artformer train "
                         "image-trunk` OUT/trunk.pt, or an image checkpoint's such as "
                         "model/weights/image_small.pt); default: the --init image "
                         "checkpoint's, else ImageNet's")
    ap.add_argument("--multiscale", action="store_true",
                    help="tokens also carry the 14x14 block-10 features (1728-d); from a "
                         "1280-d image checkpoint the projection is widened with zeros")
    ap.add_argument("--image-size", type=int, default=224, metavar="PX",
                    help="encoder input side, a multiple of 224 (448: the renders upsampled 2x so "
                         "small parts cover 4x the feature-map cells; the map entering the last "
                         "block is pooled back to 7x7); default 224")
    ap.add_argument("--count-tokens", metavar="TRUNK_PT",
                    help="add the count head of this trunk file (the run's own trunk) to the "
                         "condition: one token per label carrying its count distribution")
    ap.add_argument("--count-truth", type=float, default=0.0, metavar="SHARE",
                    help="with count tokens: share of training views whose tokens carry the "
                         "object's true counts instead of the head's (default 0)")
    ap.add_argument("--no-positions", action="store_true",
                    help="no 2-D position embedding of the 7x7 image tokens (the earlier model)")
    ap.add_argument("--extra-train", nargs=2, action="append", default=[],
                    metavar=("DATA", "RENDERS"),
                    help="more training objects: a prepared dataset with its own data version "
                         "and its render set (all its splits train; repeatable)")
    add_training_args(ap)
    ap.add_argument("--half", metavar="PATH", help="also write an fp16 copy (the shipped file)")
    _image_eval_args(ap)
    ap.add_argument("--json", metavar="PATH")
    return ap


def print_report(rep: dict, json_path) -> None:
    """An evaluation report on stdout without its rows; all of it to ``json_path`` if given."""
    print(json.dumps({k: v for k, v in rep.items() if k != "rows"}, indent=1))
    if json_path:
        Path(json_path).parent.mkdir(parents=True, exist_ok=True)
        Path(json_path).write_text(json.dumps(rep, indent=1))


def train_image_main(argv: list[str], args: argparse.Namespace | None = None) -> int:
    """`artformer train image` (training, or --eval on held-out renders); ``args``: ``argv``
    already parsed by a parser that extends ``image_parser()``."""
    import shlex
    args = args or image_parser().parse_args(argv)
    if args.eval:
        from .evaluate import image_alignment_report
        if not 0 < args.farther <= 1:
            print(f"artformer train image: --farther must be in (0, 1], got {args.farther}", flush=True)
            return 2
        views = None if args.eval_views == "all" else [int(v) for v in args.eval_views.split(",")]
        rep = image_alignment_report(args.eval, args.data, args.renders, split=args.split,
                                     views=views, limit=args.limit, seed=args.eval_seed,
                                     temperature=args.temperature, follow_plan=args.follow_plan,
                                     count_plan=not args.no_count_plan,
                                     oracle_plan=args.oracle_plan, visibility=args.visibility,
                                     visible_px=args.visible_px, frame=args.frame,
                                     farther=args.farther, progress=not args.no_progress)
        print_report(rep, args.json)
        return 0
    from model.articulation.commands import make_targets, training_overrides
    from model.encoders.image import check_image_size

    from .train import ImageRunConfig, ImageTrainConfig, train_image, write_half
    from model.articulation.config import preset
    net_cfg, tc = preset(args.preset, **training_overrides(args))
    targets = make_targets(args.prior, args.sdf, net_cfg)
    ic = ImageTrainConfig(trainable_blocks=args.trainable_blocks, tail_lr_mult=args.tail_lr_mult,
                          init=args.init, positions=not args.no_positions,
                          multiscale=args.multiscale, trunk=args.trunk or "",
                          image_size=args.image_size, count_tokens=args.count_tokens or "",
                          count_truth=args.count_truth)
    try:
        check_image_size(args.image_size)
    except ValueError as e:
        print(f"artformer train image: --image-size: {e}", flush=True)
        return 2
    if ic.init.lower() != "none" and not Path(ic.init).exists():
        print(f"artformer train image: --init {ic.init} does not exist; train the text model "
              f"first or pass --init none", flush=True)
        return 2
    command = "artformer train image " + " ".join(shlex.quote(a) for a in argv)
    path = train_image(ImageRunConfig(data=args.data, renders=args.renders, out=args.out,
                                      net=net_cfg, train=tc, image=ic, targets=targets,
                                      command=command, progress=not args.no_progress,
                                      resume=args.resume, chunk_minutes=args.chunk_minutes,
                                      extra=[tuple(x) for x in args.extra_train]))
    if args.half:
        write_half(path, Path(args.half))
        print(f"fp16 copy: {args.half}")
    print(f"checkpoint: {path}")
    return 0


def main(argv: list[str]) -> int:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    words = tuple(argv[:2])
    if words == ("data", "render"):
        return _render(argv[2:])
    if words == ("data", "partmaps"):
        return _partmaps(argv[2:])
    if words == ("data", "features"):
        return _features(argv[2:])
    if words == ("train", "image"):
        return train_image_main(argv[2:])
    if words == ("train", "image-trunk"):
        from .trunk import cli_main
        return cli_main(argv[2:])
    if words == ("train", "image-counts"):
        from .counts import cli_main
        return cli_main(argv[2:])
    print(f"model.imaging.commands: unknown command {' '.join(words)!r}", file=sys.stderr)
    return 2
