"""Door handles as generated: how many sit on the hinge half of their door or lid, and how
many are bars across the swing (docs/refine.md, "Handles to the free edge").

    python scripts/handle_check.py [--prompts model/metrics/prompts_bench.txt] [--seeds 2]
"""
import argparse

import numpy as np

from model.core import JointType
from model.pipeline import GenerationConfig, Generator


def handle_places(obj) -> list[tuple[float, bool]]:
    """(distance of the handle's centre from the hinge line over the panel's width, whether
    it is a bar across the swing wider than half the panel) for every handle on a hinged
    door or lid."""
    out = []
    for i, d in enumerate(obj.parts):
        if d.label not in ("door", "lid") or d.joint.type != JointType.REVOLUTE:
            continue
        a, k = int(np.argmax(np.abs(d.joint.axis))), int(np.argmin(d.bbox_size))
        if a == k:
            continue
        u = 3 - a - k
        w = d.bbox_size[u]
        for c in obj.children(i):
            h = obj.parts[c]
            if h.label == "handle":
                across = h.bbox_size[u] > 0.5 * w and h.bbox_size[u] > h.bbox_size[a]
                out.append((abs(h.bbox_center[u] - d.joint.origin[u]) / w, bool(across)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--prompts", default="model/metrics/prompts_bench.txt")
    ap.add_argument("--seeds", type=int, default=2)
    a = ap.parse_args()
    prompts = [ln.strip() for ln in open(a.prompts) if ln.strip() and not ln.startswith("#")]
    gen = Generator.load(GenerationConfig())
    places = []
    for prompt in prompts:
        for seed in range(a.seeds):
            [res] = gen.generate(prompt, seed=seed)
            places += handle_places(res.obj)
    print(f"handles on hinged doors and lids: {len(places)}; on the hinge half: "
          f"{sum(d < 0.5 for d, _ in places)}; bars across the swing: "
          f"{sum(x for _, x in places)}")


if __name__ == "__main__":
    main()
