"""Bare object names ("a cabinet", "a dresser", "an oven"): the share of decoded objects with at
least one moving part, per prompt and in all. Every training object of every category has
one, and a user who types only a name expects a working object; a text model trained only on
descriptions that list the parts can decode a bare name as an empty carcass. The text
recipe's text-eval stage runs this for the candidate and the shipped model, and
scripts/compare_candidate.py holds the candidate to no fewer.

    python scripts/bare_names.py [--checkpoint DIR] [--seeds 3] [--json OUT]

Trees only (the product's decoding, prompt reader on; no shapes, no meshes): about 10 s.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

PROMPTS = ("a cabinet", "a kitchen cabinet", "a storage cabinet", "a dresser", "a wardrobe",
           "a nightstand", "a cupboard", "a safe", "an oven", "a microwave", "a washing machine",
           "a top loader", "a bottle", "a jar", "a usb stick", "a thumb drive")


def bare_names(checkpoint: str | None = None, seeds: int = 3) -> dict:
    from model.core import JointType
    from model.pipeline import GenerationConfig, Generator

    gen = Generator.load(GenerationConfig(checkpoint=checkpoint, mesh_workers=0))
    try:
        rows = {}
        for p in PROMPTS:
            trees = gen.decode_trees(p, seed=0, samples=seeds)[0]
            rows[p] = [int(sum(int(t) != int(JointType.FIXED) for t in tree.joint_types))
                       for tree in trees]
    finally:
        gen.close()
    n = sum(len(v) for v in rows.values())
    moving = sum(m > 0 for v in rows.values() for m in v)
    return {"checkpoint": checkpoint or "shipped", "seeds": seeds, "objects": n,
            "with_moving_part": moving / max(n, 1), "moving_parts": rows}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--checkpoint", default=None, help="model folder (default: shipped)")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--json", default=None, help="write the result here")
    args = ap.parse_args(argv)
    out = bare_names(args.checkpoint, args.seeds)
    for p, v in out["moving_parts"].items():
        print(f"{p:22s} moving parts per seed: {v}")
    print(f"objects with a moving part: {out['with_moving_part']:.1%} of {out['objects']}")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
