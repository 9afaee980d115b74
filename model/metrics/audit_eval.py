"""`artformer eval audit`: the sim-ready audit as a row group — the procedural data floor,
the raw model (no refinement), the refined product, and refined part retrieval — on the
shipped free-form prompts plus everyday prompts, K seeds each.

    artformer eval audit --seeds 2 --out eval_audit                  # all four rows
    artformer eval audit --rows raw,refined --seeds 2                # a subset
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


ROWS = {"floor": "data floor", "raw": "raw model", "refined": "refined",
        "retrieval": "retrieval (refined)"}


def _rows(gen, prompts, seeds: int, out: Path, row: str, progress: bool):
    from model.metrics.audit import ObjectAudit, audit_object, visual_mesh_bytes
    gen.config.refine = row != "raw"
    gen.config.geometry = "retrieve" if row == "retrieval" else "generate"
    reps = []
    jobs = [(p, s) for p in prompts for s in range(seeds)]
    if progress:
        from tqdm import tqdm
        jobs = tqdm(jobs, desc=row, unit="obj")
    for n, (prompt, seed) in enumerate(jobs):
        try:
            [res] = gen.generate(prompt, seed=seed)
            exp = gen.export(res, out / row / f"{n:03d}", preview=False)
        except Exception as e:  # a failed generation is an object that is not sim-ready
            reps.append(ObjectAudit(name=f"{n:03d}", error=f"generation failed: {e}"))
            continue
        rep = audit_object(res.obj, urdf=exp.urdf_path,
                           mesh_bytes=visual_mesh_bytes(Path(exp.urdf_path)))
        rep.name = f"{n:03d}_{res.obj.name}"
        reps.append(rep)
    return reps


def _floor(n: int, out: Path, progress: bool):
    """As many procedural objects (seed 0, in order) as the other rows have, exported and
    audited the same way."""
    from model.data.synth import generate_object
    from model.export import export_object
    from model.metrics.audit import audit_object, visual_mesh_bytes
    idx = range(n)
    if progress:
        from tqdm import tqdm
        idx = tqdm(idx, desc="floor", unit="obj")
    reps = []
    for i in idx:
        obj = generate_object(0, i)
        exp = export_object(obj, out / "floor" / f"{i:03d}", preview=False)
        reps.append(audit_object(obj, urdf=exp.urdf_path,
                                 mesh_bytes=visual_mesh_bytes(Path(exp.urdf_path))))
    return reps


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="artformer eval audit", description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--out", default="eval_audit")
    p.add_argument("--checkpoint", default=None)
    p.add_argument("--freeform-file", default=None)
    p.add_argument("--no-everyday", action="store_true")
    p.add_argument("--rows", default="floor,raw,refined,retrieval",
                   help="comma-separated rows: floor, raw, refined, retrieval (default all)")
    p.add_argument("--no-sibling-room", dest="sibling_room", action="store_false",
                   help="decode without redrawing candidate boxes that cover a sibling "
                        "(GenerationConfig.sibling_room)")
    args = p.parse_args(argv[2:] if argv[:2] == ["eval", "audit"] else argv)
    from model.metrics.audit import audit_table, summarise, write_contact_sheet
    from model.metrics.reference import freeform_prompts
    from model.pipeline import GenerationConfig, Generator
    prompts = list(freeform_prompts(args.freeform_file)) + ([] if args.no_everyday else list(EVERYDAY))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    gen = Generator.load(GenerationConfig(checkpoint=args.checkpoint,
                                          sibling_room=args.sibling_room))
    t0 = time.time()
    results = {}
    rows = [r.strip() for r in args.rows.split(",") if r.strip()]
    bad = [r for r in rows if r not in ROWS]
    if bad:
        print(f"artformer eval audit: unknown rows {bad}; choose from {sorted(ROWS)}",
              file=sys.stderr)
        return 2
    for row in rows:
        if row == "floor":
            reps = _floor(len(prompts) * args.seeds, out, sys.stderr.isatty())
        else:
            reps = _rows(gen, prompts, args.seeds, out, row, sys.stderr.isatty())
        results[ROWS[row]] = {"summary": summarise(reps), "objects": [r.to_dict() for r in reps]}
        write_contact_sheet(reps, out / f"worst_{row}.png")
        print(f"## {ROWS[row]}\n{audit_table(reps).splitlines()[-1]}")
    (out / "audit.json").write_text(json.dumps(results, indent=1))
    print(f"wrote {out}/audit.json and worst_<row>.png in {time.time() - t0:.0f} s")
    return 0
