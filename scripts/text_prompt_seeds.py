"""Decode each prompt of a file (one per line, '#' comments) with 8 seeds at the product's
structure decoding (END held to the plan head) and count the aligned trees (model.metrics
alignment), with the structures made.

    python scripts/text_prompt_seeds.py model/metrics/prompts_freeform.txt 0.3 model/weights/transformer_small.pt
"""
import argparse

import torch

from model.articulation.decode import ArticulationModel
from model.metrics.alignment import GeneratedStructure, check_alignment
from model.data.prompt_parse import parse_prompt

SHIPPED = "model/weights/transformer_small.pt"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("prompts", help="text file, one prompt per line")
    ap.add_argument("temperature", nargs="?", type=float, default=0.3)
    ap.add_argument("checkpoint", nargs="?", default=SHIPPED)
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    with open(args.prompts, encoding="utf-8") as f:
        prompts = [line.strip() for line in f if line.strip() and not line.startswith("#")]
    am = ArticulationModel.load(args.checkpoint)
    total = 0
    for prompt in prompts:
        expected = parse_prompt(prompt)
        tok, mask = am.encode_text([prompt])
        aligned, seen = 0, {}
        for seed in range(args.seeds):
            tree = am.decode(tok, mask, seed=seed, temperature=args.temperature, follow_plan=True)[0]
            got = GeneratedStructure.from_labels(tree.category or None, tree.labels, tree.joint_types)
            aligned += check_alignment(expected, got).aligned
            key = ",".join(f"{k}{v}" for k, v in sorted(tree.summary()["counts"].items()))
            seen[key] = seen.get(key, 0) + 1
        total += aligned
        print(f"{aligned}/{args.seeds}  {prompt!r}  parsed={expected}\n      {seen}")
    print("total", total, "/", args.seeds * len(prompts))


if __name__ == "__main__":
    main()
