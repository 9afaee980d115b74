"""`artformer data render`, `data partmaps`, `data features`, `artformer train image`,
`image-trunk` and `image-counts` (issue 8)."""
from __future__ import annotations

import argparse
import logging
import sys


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
    args = ap.parse_args(argv)
    from .renders import RenderSetError, render_dataset
    try:
        rep = render_dataset(args.data, args.out, views=args.views, seed=args.seed,
                             workers=args.workers, limit=args.limit,
                             splits=tuple(s for s in args.splits.split(",") if s), progress=True)
    except (RenderSetError, FileNotFoundError, ValueError) as e:
        print(f"artformer data render: {e}", file=sys.stderr)
        return 2
    print(f"rendered {rep.rendered} objects ({args.views} views each), {rep.skipped} already done, "
          f"{len(rep.failed)} failed, {rep.seconds:.1f} s -> {args.out}")
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
                    help="a fine-tuned trunk (`artformer train image-trunk` OUT/trunk.pt); default ImageNet's")
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
        from .train import cli_main
        return cli_main(argv[2:])
    if words == ("train", "image-trunk"):
        from .trunk import cli_main
        return cli_main(argv[2:])
    if words == ("train", "image-counts"):
        from .counts import cli_main
        return cli_main(argv[2:])
    print(f"model.imaging.commands: unknown command {' '.join(words)!r}", file=sys.stderr)
    return 2
