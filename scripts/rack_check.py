"""Oven racks as generated: how many span the cavity as the data's racks do, and how many of
the objects with racks pass the sim-ready audit (docs/refine.md, "Oven racks").

    python scripts/rack_check.py [--prompts model/metrics/prompts_racks.txt] [--seeds 4]
"""
import argparse
import tempfile

import numpy as np

from model.metrics.audit import audit_object
from model.pipeline import GenerationConfig, Generator


def spans_cavity(part, parent) -> bool:
    """Depth 80-92 % and width 88-95 % of the body, at most 2 cm thick (the data: 84-88 %,
    91-93 %, 6.5 mm)."""
    rel = np.asarray(part.bbox_size) / np.asarray(parent.bbox_size)
    return bool(0.8 <= rel[0] <= 0.92 and 0.88 <= rel[1] <= 0.95 and part.bbox_size[2] <= 0.02)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--prompts", default="model/metrics/prompts_racks.txt")
    ap.add_argument("--seeds", type=int, default=4)
    a = ap.parse_args()
    prompts = [ln.strip() for ln in open(a.prompts) if ln.strip()]
    gen = Generator.load(GenerationConfig())
    racks = spanning = objects = ready = 0
    for prompt in prompts:
        for seed in range(a.seeds):
            [res] = gen.generate(prompt, seed=seed)
            trays = [p for p in res.obj.parts if p.label == "tray"]
            if not trays:
                continue
            racks += len(trays)
            spanning += sum(spans_cavity(p, res.obj.parts[p.parent]) for p in trays)
            with tempfile.TemporaryDirectory() as d:
                out = gen.export(res, d)
                failures = audit_object(res.obj, urdf=out.urdf_path).failures
            objects += 1
            ready += not failures
            if failures:
                print(f"{prompt!r} seed {seed}: {failures[0]}")
    print(f"racks spanning the cavity as the data's do: {spanning} of {racks}")
    print(f"objects with racks sim-ready: {ready} of {objects}")


if __name__ == "__main__":
    main()
