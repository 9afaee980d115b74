"""Bare object names ("a cabinet", "a dresser", "an oven"): the share of decoded objects with at
least one moving part, and the share whose doors and drawers all lie on the body's front
after the layout, per prompt and in all. Every training object of every category has a
moving part on its front, and a user who types only a name expects a working object; a text
model trained only on descriptions that list the parts can decode a bare name as an empty
carcass, or with its doors lying on the bottom ("a cabinet", 6 of 6 seeds, until the network
read the usual parts named). The text recipe's text-eval stage runs this for the candidate
and the shipped model, and scripts/compare_candidate.py holds the candidate to no fewer.

    python scripts/bare_names.py [--checkpoint DIR] [--seeds 3] [--json OUT]

Trees and their layouts (the product's decoding, prompt reader on; no shapes, no meshes):
about 15 s.
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

    from model.refine.layout import face_of

    gen = Generator.load(GenerationConfig(checkpoint=checkpoint, mesh_workers=0))
    try:
        rows, fronts = {}, {}
        for p in PROMPTS:
            trees = gen.decode_trees(p, seed=0, samples=seeds)[0]
            rows[p] = [int(sum(int(t) != int(JointType.FIXED) for t in tree.joint_types))
                       for tree in trees]
            fronts[p] = [_on_front(gen.layout(tree), face_of) for tree in trees]
    finally:
        gen.close()
    n = sum(len(v) for v in rows.values())
    moving = sum(m > 0 for v in rows.values() for m in v)
    front = sum(f for v in fronts.values() for f in v)
    return {"checkpoint": checkpoint or "shipped", "seeds": seeds, "objects": n,
            "with_moving_part": moving / max(n, 1), "fronts_on_front": front / max(n, 1),
            "moving_parts": rows, "on_front": fronts}


def _on_front(obj, face_of) -> bool:
    """Every door and drawer of the body on its front face (+x), or the object has none."""
    return all(face_of(obj, i) == (0, 1.0) for i, p in enumerate(obj.parts)
               if p.label in ("door", "drawer") and p.parent == obj.root)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--checkpoint", default=None, help="model folder (default: shipped)")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--json", default=None, help="write the result here")
    args = ap.parse_args(argv)
    out = bare_names(args.checkpoint, args.seeds)
    for p, v in out["moving_parts"].items():
        print(f"{p:22s} moving parts per seed: {v}")
    print(f"objects with a moving part: {out['with_moving_part']:.1%} of {out['objects']}; "
          f"doors and drawers all on the front: {out['fronts_on_front']:.1%}")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
