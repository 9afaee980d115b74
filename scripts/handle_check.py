"""Door handles as generated: how many sit on the hinge half of their door or lid, and how
many are bars across the swing (docs/refine.md, "Handles to the free edge"); and knobs and
dials out of the data's round shape (docs/refine.md, "Round controls").

    python scripts/handle_check.py [--prompts model/metrics/prompts_bench.txt] [--seeds 2]
"""
import argparse

import numpy as np

from model.pipeline import GenerationConfig, Generator
from model.refine.layout import swing_axes


def handle_places(obj) -> list[tuple[float, bool]]:
    """(distance of the handle's centre from the hinge line over the panel's width, whether
    it is a bar across the swing wider than half the panel) for every handle on a hinged
    door or lid."""
    out = []
    for i, d in enumerate(obj.parts):
        axes = swing_axes(d)
        if axes is None:
            continue
        a, _, u = axes
        w = d.bbox_size[u]
        for c in obj.children(i):
            h = obj.parts[c]
            if h.label == "handle":
                across = h.bbox_size[u] > 0.5 * w and h.bbox_size[u] > h.bbox_size[a]
                out.append((abs(h.bbox_center[u] - d.joint.origin[u]) / w, bool(across)))
    return out


def odd_controls(obj) -> tuple[int, int]:
    """(knobs and dials, those whose footprint is over 1.25 times longer one way than the
    other or that stand out further than they are wide: the data's are round, ~0.7 of their
    diameter deep)."""
    n = odd = 0
    for p in obj.parts:
        if p.label not in ("knob", "dial") or not p.joint.type.rotates:
            continue
        k = int(np.argmax(np.abs(p.joint.axis)))
        u, v = [d for d in range(3) if d != k]
        a, b = sorted((p.bbox_size[u], p.bbox_size[v]))
        n += 1
        odd += bool(b > 1.25 * a or p.bbox_size[k] > b * (1 + 1e-6))
    return n, odd


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--prompts", default="model/metrics/prompts_bench.txt")
    ap.add_argument("--seeds", type=int, default=2)
    a = ap.parse_args()
    prompts = [ln.strip() for ln in open(a.prompts) if ln.strip() and not ln.startswith("#")]
    gen = Generator.load(GenerationConfig())
    places, controls, odd = [], 0, 0
    for prompt in prompts:
        for seed in range(a.seeds):
            [res] = gen.generate(prompt, seed=seed)
            places += handle_places(res.obj)
            n, bad = odd_controls(res.obj)
            controls, odd = controls + n, odd + bad
    print(f"handles on hinged doors and lids: {len(places)}; on the hinge half: "
          f"{sum(d < 0.5 for d, _ in places)}; bars across the swing: "
          f"{sum(x for _, x in places)}")
    print(f"knobs and dials: {controls}; out of the data's round shape: {odd}")


if __name__ == "__main__":
    main()
