"""Views per second of the trunk-feature pass that ``build_feature_cache`` runs (decode +
resize + EfficientNet-Lite0 stem and blocks 0-14) at several batch sizes, on real renders.

    python scripts/bench_feature_batch.py --renders data/renders/v1 --threads 1 --size 224
"""
import argparse
import glob
import time

import torch

from model.core.runtime import keep_heap_mapped
from model.encoders.image import ImageEncoder, ImageEncoderConfig, preprocess


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--renders", default="data/renders/v1")
    ap.add_argument("--views", type=int, default=192, help="rendered views to encode per batch size")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--size", type=int, default=224, help="encoder input side (224 or 448)")
    ap.add_argument("--batches", default="2,4,8,16", help="comma list of batch sizes")
    args = ap.parse_args()
    keep_heap_mapped()
    torch.set_num_threads(args.threads)
    paths = sorted(glob.glob(f"{args.renders}/objects/*/*.png"))[:args.views]
    if not paths:
        raise SystemExit(f"no rendered views under {args.renders}/objects")
    enc = ImageEncoder(ImageEncoderConfig(image_size=args.size))
    enc.features_at(preprocess(paths[:4], args.size), 15)                  # warm-up
    for b in (int(x) for x in args.batches.split(",")):
        t = time.time()
        for s in range(0, len(paths), b):
            enc.features_at(preprocess(paths[s:s + b], args.size), 15)
        print(f"{args.size} px, {args.threads} thread(s), batch {b}: "
              f"{len(paths) / (time.time() - t):.1f} views/s", flush=True)


if __name__ == "__main__":
    main()
