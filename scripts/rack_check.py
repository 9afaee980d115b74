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
    """The body's box is 6-10 cm deeper and 4-8 cm wider than the rack, which is at most 2 cm
    thick (the data's racks, 40 in synth-v4 ovens: 7.5-9 cm, 4.7-7.6 cm, 6.5 mm; fixed
    clearances, so a toaster-sized oven keeps them too)."""
    margin = np.asarray(parent.bbox_size) - np.asarray(part.bbox_size)
    return bool(0.06 <= margin[0] <= 0.10 and 0.04 <= margin[1] <= 0.08
                and part.bbox_size[2] <= 0.02)


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
