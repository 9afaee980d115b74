"""How much of the frame the object fills in rendered training views (the framing target of
model.encoders.framing.FRAME_FILL): the larger side of the box find_object finds, over the
frame side. Usage: python scripts/render_fill.py [--renders data/renders/v1] [--n 2000]"""
import argparse
from collections import Counter

import numpy as np

from model.data import format as fmt
from model.encoders.framing import find_object
from model.encoders.image import to_rgb_float
from model.imaging.renders import rendered_ids, view_paths


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default="data/prepared/v1")
    ap.add_argument("--renders", default="data/renders/v1")
    ap.add_argument("--split", default="train")
    ap.add_argument("--n", type=int, default=2000, help="renders (random objects and views)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    ids = rendered_ids(args.renders, fmt.split_ids(args.data, args.split))
    rng = np.random.default_rng(args.seed)
    fills, reasons = [], Counter()
    for i in rng.integers(0, len(ids), args.n):
        paths = view_paths(args.renders, ids[i])
        rgb = to_rgb_float(paths[rng.integers(0, len(paths))])
        f = find_object(rgb)
        reasons[f.reason] += 1
        if f.box is not None:
            y0, x0, y1, x1 = f.box
            fills.append(max(y1 - y0, x1 - x0) / max(rgb.shape[:2]))
    q = np.percentile(fills, [10, 25, 50, 75, 90])
    print(f"{args.n} {args.split} renders of {args.renders}: {dict(reasons)}")
    print("fill (object's larger side / frame side) percentiles 10/25/50/75/90: "
          + " / ".join(f"{v:.3f}" for v in q))


if __name__ == "__main__":
    main()
