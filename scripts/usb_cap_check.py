"""USB slide caps of generated sticks: how many come out in pieces or without a sleeve wall.

    python scripts/usb_cap_check.py                 # 5 slide-cap prompts x seeds 0-7, refined
    python scripts/usb_cap_check.py --no-refine     # the raw model output

A slide cap is a sleeve in the data (model/data/synth/handheld.py): four walls along the
slide and an end wall away from the stick. A wall counts as there when the cap's outer 3 mm
covers at least 90 % of its box face (model.refine.meshes.sleeve_covers), as the
refinement's ``close_slide_caps`` decides.
"""
from __future__ import annotations

import argparse

PROMPTS = ("a usb stick with a cap", "a usb drive with a cap that slides off",
           "a thumb drive with a cap", "a usb flash drive with a removable cap",
           "a usb drive with a keyring loop")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--no-refine", action="store_true")
    args = ap.parse_args()

    from model.core import meshops
    from model.pipeline.api import GenerationConfig
    from model.pipeline.generator import Generator
    from model.refine.layout import _principal
    from model.refine.meshes import SLEEVE_COVER, sleeve_covers

    gen = Generator.load(GenerationConfig(refine=not args.no_refine))
    caps = pieces = open_walls = 0
    for prompt in PROMPTS:
        for seed in range(args.seeds):
            [res] = gen.generate(prompt, seed=seed)
            obj = res.obj
            for p in obj.parts:
                if p.label != "cap" or p.joint.type.rotates or p.mesh is None:
                    continue
                m = meshops.to_manifold(p.mesh)
                body = meshops.to_manifold(obj.parts[p.parent].mesh)
                covers = sleeve_covers(m, body, _principal(p.joint.axis)[0])
                bare = [f for f, c in covers.items() if c < SLEEVE_COVER]
                n = len(m.decompose())
                caps += 1
                pieces += n > 1
                open_walls += bool(bare)
                print(f"{prompt!r} seed {seed}: {n} piece(s), {len(bare)} wall(s) missing")
    print(f"slide caps: {caps}; in pieces: {pieces}; with a wall missing: {open_walls}")


if __name__ == "__main__":
    main()
