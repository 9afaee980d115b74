"""`artformer eval audit`: the sim-ready audit of generated objects, raw (no refinement)
beside refined, on the shipped free-form prompts plus everyday prompts, K seeds each.

    artformer eval audit --seeds 2 --out eval_audit      # table + JSON + contact sheets
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

EVERYDAY = (
    "a kitchen cabinet with three drawers and a door on the left",
    "a chest of four drawers",
    "a wardrobe with two doors",
    "a safe with a keypad and a door",
    "an oven with four knobs and a door",
    "a front-loading washing machine with a dial",
    "a bottle with a screw cap",
    "a usb stick with a cap",
    "a storage cabinet with two drawers and a door",
    "a nightstand with one drawer",
    "a microwave-sized safe with a turning knob",
    "a top-loading washing machine with a lid",
)


def _rows(gen, prompts, seeds: int, out: Path, refine: bool, progress: bool):
    from model.metrics.audit import audit_object
    gen.config.refine = refine
    reps = []
    jobs = [(p, s) for p in prompts for s in range(seeds)]
    if progress:
        from tqdm import tqdm
        jobs = tqdm(jobs, desc="refined" if refine else "raw", unit="obj")
    for n, (prompt, seed) in enumerate(jobs):
        try:
            [res] = gen.generate(prompt, seed=seed)
            exp = gen.export(res, out / ("refined" if refine else "raw") / f"{n:03d}", preview=False)
        except Exception as e:  # a failed generation is an object that is not sim-ready
            from model.metrics.audit import ObjectAudit
            reps.append(ObjectAudit(name=f"{n:03d}", error=f"generation failed: {e}"))
            continue
        rep = audit_object(res.obj, urdf=exp.urdf_path)
        rep.name = f"{n:03d}_{res.obj.name}"
        rep.seconds = res.timings.get("refine", 0.0)
        reps.append(rep)
    return reps


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="artformer eval audit", description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--out", default="eval_audit")
    p.add_argument("--checkpoint", default=None)
    p.add_argument("--freeform-file", default=None)
    p.add_argument("--no-everyday", action="store_true")
    args = p.parse_args(argv[2:] if argv[:2] == ["eval", "audit"] else argv)
    from model.metrics.audit import audit_table, summarise, write_contact_sheet
    from model.metrics.reference import freeform_prompts
    from model.pipeline import GenerationConfig, Generator
    prompts = list(freeform_prompts(args.freeform_file)) + ([] if args.no_everyday else list(EVERYDAY))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    gen = Generator.load(GenerationConfig(checkpoint=args.checkpoint))
    t0 = time.time()
    results = {}
    for refine in (False, True):
        name = "refined" if refine else "raw model"
        reps = _rows(gen, prompts, args.seeds, out, refine, sys.stderr.isatty())
        results[name] = {"summary": summarise(reps), "objects": [r.to_dict() for r in reps]}
        write_contact_sheet(reps, out / f"worst_{'refined' if refine else 'raw'}.png")
        print(f"## {name}\n{audit_table(reps).splitlines()[-1]}")
    (out / "audit.json").write_text(json.dumps(results, indent=1))
    print(f"wrote {out}/audit.json, worst_raw.png, worst_refined.png in {time.time() - t0:.0f} s")
    return 0
