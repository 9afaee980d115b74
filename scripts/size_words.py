"""Size words ("a tall cabinet", "a compact oven", "a narrow wardrobe"): the share of objects
whose body meets each word the prompt says of the object, as the network decodes it and as
the product lays it out. A word is met when the dimension it names is in the matching
quarter of the category's data (at or above the 75th percentile for tall / wide / deep /
long / large, at or below the 25th for short / narrow / shallow / small;
``model.data.prompt_size.SIZE_SPREAD``); "large" and "small" judge the body's overall size
(the geometric mean of its sides). The words each prompt says are written beside it here,
not read by the code under test.

    python scripts/size_words.py [--checkpoint DIR] [--seeds 4] [--json OUT]

Trees and layouts only (no shapes, no meshes): about 2 minutes on 2 cores.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

# prompt -> the words it says of the object: dimension + "+" (larger) or "-" (smaller)
PROMPTS = {
    "a tall cabinet with two doors": "height+",
    "a tall bathroom cabinet": "height+",
    "a short cabinet with two drawers": "height-",
    "a low sideboard with four drawers": "height-",
    "a wide dresser with six drawers": "width+",
    "a narrow cabinet with one door": "width-",
    "a small cabinet with a drawer and a door": "size-",
    "a large wardrobe with two doors": "size+",
    "a deep cabinet with two doors": "depth+",
    "a shallow cabinet with two doors": "depth-",
    "a tall, narrow cabinet with one door": "height+ width-",
    "The cabinet is tall and has three drawers.": "height+",
    "a big chest of drawers with five drawers": "size+",
    "a large safe with a door and a dial": "size+",
    "a tall safe with a door": "height+",
    "a compact lockbox with one door": "size-",
    "a large oven with four knobs": "size+",
    "a small oven with two knobs": "size-",
    "a wide range with six knobs": "width+",
    "a large washing machine with a door": "size+",
    "a compact washing machine with a round door": "size-",
    "a tall bottle with a cap": "height+",
    "a small bottle with a screw cap": "size-",
    "a big water bottle with a flip lid": "size+",
    "a short, wide jar with a lid": "height- width+",
    "a small usb stick with a cap": "size-",
    "a long usb drive with a cap": "length+",
    "a short usb stick with a swivel cap": "length-",
}
TOLERANCE = 1e-3        # m: a quartile reached up to rounding


def meets(category: str, dims: dict[str, float], words: str) -> bool:
    """Whether a body of ``dims`` (depth, width, height in m) meets every word of ``words``."""
    import numpy as np

    from model.data.prompt_size import SIZE_SPREAD

    for word in words.split():
        dim, sign = word[:-1], word[-1]
        if dim == "length":
            dim = max(dims, key=dims.get)
        value = float(np.exp(np.mean(np.log(list(dims.values()))))) if dim == "size" \
            else dims[dim]
        _, q1, q3, _ = SIZE_SPREAD[category][dim]
        if (sign == "+" and value < q3 - TOLERANCE) or (sign == "-" and value > q1 + TOLERANCE):
            return False
    return True


def size_words(checkpoint: str | None = None, seeds: int = 4) -> dict:
    from model.data.prompt_size import AXIS
    from model.pipeline import GenerationConfig, Generator

    gen = Generator.load(GenerationConfig(checkpoint=checkpoint, mesh_workers=0))
    rows = {}
    try:
        for prompt, words in PROMPTS.items():
            row = []
            for seed in range(seeds):
                [tree], *_ = gen.decode_trees(prompt, seed=seed)
                obj = gen.layout(tree, {})
                box = obj.parts[obj.root].bbox_size
                decoded = {d: float(tree.tokens[0, a]) for d, a in AXIS.items()}
                made = {d: float(box[a]) for d, a in AXIS.items()}
                row.append({"category": obj.category, "decoded": decoded, "made": made,
                            "decoded_met": meets(tree.category, decoded, words),
                            "made_met": meets(obj.category, made, words)})
            rows[prompt] = row
    finally:
        gen.close()
    n = sum(len(r) for r in rows.values())
    share = {k: sum(x[f"{k}_met"] for r in rows.values() for x in r) / max(n, 1)
             for k in ("decoded", "made")}
    return {"checkpoint": checkpoint or "shipped", "seeds": seeds, "objects": n,
            "met_as_decoded": share["decoded"], "met_as_made": share["made"], "rows": rows}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--checkpoint", default=None, help="model folder (default: shipped)")
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--json", default=None, help="write the result here")
    args = ap.parse_args(argv)
    out = size_words(args.checkpoint, args.seeds)
    for prompt, row in out["rows"].items():
        cells = " ".join(("ok " if x["made_met"] else "-- ") + "x".join(
            f"{x['made'][d]:.2f}" for d in ("width", "depth", "height")) for x in row)
        print(f"{prompt[:44]:44s} [{PROMPTS[prompt]}] w x d x h: {cells}")
    print(f"size words met as decoded: {out['met_as_decoded']:.1%}, as made: "
          f"{out['met_as_made']:.1%} of {out['objects']}")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
