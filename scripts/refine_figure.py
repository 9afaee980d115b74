"""Raw model output beside the refined object, at rest and opened, for a few prompts:
docs/figures/raw_vs_refined.png.

    python scripts/refine_figure.py --out docs/figures/raw_vs_refined.png
"""
from __future__ import annotations

import argparse

import numpy as np

PROMPTS = ("a kitchen cabinet with three drawers and a door on the left",
           "an oven with four knobs and a door",
           "a safe with a keypad and a door",
           "a wardrobe with two doors")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="docs/figures/raw_vs_refined.png")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from model.export.render import render_views
    from model.pipeline import GenerationConfig, Generator
    gen = Generator.load(GenerationConfig())
    fig, axes = plt.subplots(len(PROMPTS), 2, figsize=(9, 2.3 * len(PROMPTS)), squeeze=False)
    for row, prompt in enumerate(PROMPTS):
        for col, refine in enumerate((False, True)):
            gen.config.refine = refine
            [res] = gen.generate(prompt, seed=a.seed)
            views = render_views(res.obj, (0.0, 0.7), 220, simplify=True)
            ax = axes[row, col]
            ax.imshow(np.concatenate(list(views), axis=1))
            ax.axis("off")
            ax.set_title(f"{'refined' if refine else 'raw model'}: {prompt}"[:70], fontsize=7)
    fig.tight_layout()
    fig.savefig(a.out, dpi=100)
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
