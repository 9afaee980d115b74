"""Short user-style prompts built from held-out objects, naming only the moving part kinds
("a cabinet with four drawers and two doors", no handles): how many the text model aligns
with the product's decoding (T = 0.3, END held to the plan head).

    python scripts/text_short_prompts.py data/prepared/v1 test model/weights/transformer_small.pt
"""
import argparse
from collections import Counter

import torch

from model.articulation.decode import ArticulationModel
from model.data import format as fmt
from model.data.vocab import CATEGORY_SYNONYMS, number_word, plural
from model.metrics.alignment import GeneratedStructure, check_alignment
from model.data.prompt_parse import parse_prompt


def short_prompts(root: str, split: str) -> list[str]:
    """One prompt per object of the split that has a part other than body and handles."""
    prompts = []
    for i in fmt.load_manifest(root)["splits"][split]:
        rec = fmt.load_record(root, i)
        counts = Counter(label for label in rec.labels if label not in ("body", "handle"))
        if not counts:
            continue
        parts = [f"a {lab}" if n == 1 else f"{number_word(n)} {plural(lab)}"
                 for lab, n in sorted(counts.items())]
        prompts.append(f"a {CATEGORY_SYNONYMS[rec.category][0]} with " + " and ".join(parts))
    return prompts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", help="prepared dataset folder")
    ap.add_argument("split", help="train | val | test")
    ap.add_argument("checkpoint", help="text transformer checkpoint")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    am = ArticulationModel.load(args.checkpoint)
    prompts = short_prompts(args.data, args.split)
    aligned, misses = 0, []
    for s in range(0, len(prompts), 32):
        chunk = prompts[s:s + 32]
        tok, mask = am.encode_text(chunk)
        trees = am.decode(tok, mask, seed=s, temperature=0.3, follow_plan=True)
        for prompt, tree in zip(chunk, trees):
            got = GeneratedStructure.from_labels(tree.category or None, tree.labels, tree.joint_types)
            if check_alignment(parse_prompt(prompt), got).aligned:
                aligned += 1
            else:
                misses.append((prompt, dict(Counter(tree.labels))))
    print(f"{aligned}/{len(prompts)} aligned")
    for miss in misses[:40]:
        print("  ", miss)


if __name__ == "__main__":
    main()
