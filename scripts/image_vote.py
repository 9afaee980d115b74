"""Diagnostic: are an image model's structure misses uncertainty or confident misreadings?

For each held-out render (views 0-3) it decodes the greedy tree and K sampled trees at
temperature T, then scores three things against the object's structure: greedy; the
majority vote over the K + 1 trees (ties go to greedy); and whether any of them is right
(the ceiling any re-ranking of these samples could reach).

    python scripts/image_vote.py --checkpoint model/weights/image_small.pt --split val --k 8 --temperature 0.5
"""
from __future__ import annotations

import argparse
import collections
import json
import time

import torch

from model.articulation.evaluate import compare, record_structure
from model.imaging.evaluate import held_out_views
from model.imaging.model import load_image_model


def structure_key(summary: dict) -> str:
    return json.dumps([summary["category"], sorted(summary["counts"].items()),
                       sorted((k, sorted(v)) for k, v in summary["joint_types"].items())])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--checkpoint", default=None, help="image checkpoint (default: shipped)")
    ap.add_argument("--data", default="data/prepared/v1")
    ap.add_argument("--renders", default="data/renders/v1")
    ap.add_argument("--split", default="val")
    ap.add_argument("--views", type=int, default=4, help="views 0..N-1 of every object")
    ap.add_argument("--k", type=int, default=8, help="sampled trees per image")
    ap.add_argument("--temperature", type=float, default=0.5)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)

    im = load_image_model(args.checkpoint)
    _, jobs = held_out_views(args.data, args.renders, split=args.split,
                             views=list(range(args.views)))
    hits = collections.Counter()
    t0 = time.time()
    for n, (rec, _, _, path) in enumerate(jobs):
        tok, mask = im.encode([str(path)])
        with torch.inference_mode():
            greedy = im.am.decode(tok, mask, seed=0, temperature=0.0, modality="image")[0].summary()
            sampled = im.am.decode(tok.expand(args.k, -1, -1), mask.expand(args.k, -1), seed=n,
                                   temperature=args.temperature, modality="image")
        trees = [greedy] + [t.summary() for t in sampled]
        votes = collections.Counter(structure_key(s) for s in trees)
        voted = max(trees, key=lambda s: (votes[structure_key(s)], s is greedy))
        truth = record_structure(rec)
        right = [compare(s, truth)["all"] for s in trees]
        hits["greedy"] += right[0]
        hits["vote"] += compare(voted, truth)["all"]
        hits["any"] += any(right)
        hits["distinct"] += len(votes)
    n = max(len(jobs), 1)
    print(json.dumps({"checkpoint": args.checkpoint or "shipped", "split": args.split,
                      "images": len(jobs), "k": args.k, "temperature": args.temperature,
                      "greedy": hits["greedy"] / n, "vote": hits["vote"] / n,
                      "any_of_k_plus_1": hits["any"] / n,
                      "distinct_structures_per_image": hits["distinct"] / n,
                      "seconds": round(time.time() - t0, 1)}))


if __name__ == "__main__":
    main()
