"""`artformer generate` and `artformer edit`."""
from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path


def _model_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--checkpoint", default=None,
                   help="folder with transformer*.pt, sdf*.pt, prior*.pt [, image*.pt] "
                        "(default: the shipped model in model/weights)")
    p.add_argument("--seed", type=int, default=0, help="sample i uses seed+i (default 0)")
    p.add_argument("--samples", type=int, default=1, help="objects to generate (default 1)")
    p.add_argument("--resolution", type=int, default=64,
                   help="marching-cubes cells per side of the largest parts (64)")
    p.add_argument("--mesh-cell", type=float, default=0.008,
                   help="m: small parts mesh at 16 or 32 cells when their cells stay under "
                        "this (default 0.008; 0 = every part at --resolution)")
    p.add_argument("--steps", type=int, default=50, help="DDIM steps of the shape prior (50)")
    p.add_argument("--guidance", type=float, default=1.0, help="classifier-free guidance (1 = off)")
    p.add_argument("--structure-temperature", type=float, default=0.3,
                   help="sampling temperature of the part tree (0 = greedy; default 0.3)")
    p.add_argument("--no-plan", dest="follow_plan", action="store_const", const=(),
                   default=("text",),
                   help="decode END from the END head alone (the paper's decoding), without "
                        "holding it to the START plan head")
    p.add_argument("--soft-plan", dest="hold_plan", action="store_false",
                   help="hold END to the START plan head without decoding again with its counts "
                        "as a structure (GenerationConfig.hold_plan)")
    p.add_argument("--no-prompt-structure", dest="prompt_structure", action="store_false",
                   help="decode a text with the network's own reading of it, without holding "
                        "the part counts, joint types and hinge sides the text states")
    p.add_argument("--no-sibling-room", dest="sibling_room", action="store_false",
                   help="keep every candidate box the network draws, also one that covers a "
                        "sibling part decoded before it")
    p.add_argument("--no-frame", dest="frame_images", action="store_false",
                   help="read an --image as it is, without cropping a plain background around "
                        "the object first")
    p.add_argument("--geometry", choices=("generate", "retrieve"), default="generate",
                   help="diffuse new part shapes, or retrieve the nearest training part")
    p.add_argument("--format", dest="mesh_format", choices=("obj", "stl", "glb"), default="obj")
    p.add_argument("--collision", choices=("auto", "cells", "vhacd", "hull", "none"),
                   default="auto", help="collision geometry per link (default auto)")
    p.add_argument("--no-refine", dest="refine", action="store_false",
                   help="export the raw model output (no layout / mesh refinement)")
    p.add_argument("--face-budget", type=int, default=30000,
                   help="visual faces per object, simplified to it with or without "
                        "refinement (default 30000; 0: all)")
    p.add_argument("--threads", type=int, default=2, help="torch CPU threads (2)")
    p.add_argument("--no-preview", action="store_true", help="skip preview.png")
    p.add_argument("--mesh-uri", default="file",
                   help="'file' (absolute file:// paths, for ROS), 'relative' (meshes/ beside "
                        "the URDF, for simulators) or a package:// prefix for mesh URIs")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("-v", "--verbose", action="store_true")


def _config(a):
    from model.pipeline.api import GenerationConfig
    return GenerationConfig(checkpoint=a.checkpoint, resolution=a.resolution,
                            mesh_cell=a.mesh_cell, steps=a.steps,
                            guidance=a.guidance, geometry=a.geometry, mesh_format=a.mesh_format,
                            collision=a.collision, threads=a.threads,
                            structure_temperature=a.structure_temperature,
                            follow_plan=a.follow_plan, refine=a.refine,
                            prompt_structure=getattr(a, "prompt_structure", True),
                            sibling_room=getattr(a, "sibling_room", True),
                            hold_plan=getattr(a, "hold_plan", True),
                            face_budget=a.face_budget,
                            frame_images=getattr(a, "frame_images", True))


def _report(outs, results, as_json: bool) -> None:
    rows = []
    for o, r in zip(outs, results):
        rows.append({"prompt": r.prompt, "seed": r.seed, "category": r.obj.category,
                     "parts": [f"{p.name}:{p.label}:{p.joint.type.name.lower()}" for p in r.obj.parts],
                     "urdf": o.urdf_path, "meshes": str(Path(o.out_dir) / "meshes"),
                     "preview": o.preview_path,
                     "timings_s": {k: round(v, 4) for k, v in r.timings.items()}})
    if as_json:
        print(json.dumps(rows if len(rows) > 1 else rows[0], indent=1))
        return
    for row in rows:
        total = sum(row["timings_s"].values())
        print(f"{row['category'] or 'object'} (seed {row['seed']}): {len(row['parts'])} parts, "
              f"{total:.2f} s")
        print(f"  URDF:    {row['urdf']}")
        print(f"  meshes:  {row['meshes']}")
        if row["preview"]:
            print(f"  preview: {row['preview']}")


def _generate(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="artformer generate",
                                description="Text (or an image) -> articulated object: URDF + meshes.")
    p.add_argument("text", nargs="?", help="description of the object")
    p.add_argument("--image", help="an image file instead of a text")
    p.add_argument("--structure", metavar="JSON",
                   help="force the parts, e.g. '{\"drawer\": 3, \"door\": {\"count\": 1, "
                        "\"hinge\": \"left\"}}' (labels, counts, joint types, hinge sides; "
                        "docs/articulation.md)")
    p.add_argument("--size", metavar="JSON",
                   help="the body's dimensions in metres, e.g. '{\"width\": 0.6, \"height\": "
                        "0.8}' (width, height, depth, length; over any the text states)")
    p.add_argument("--out", required=True, help="output folder (sample_<i>/ inside when --samples > 1)")
    b = p.add_argument_group("batch (model/pipeline/batch.py)")
    b.add_argument("--prompts", metavar="FILE",
                   help="one prompt per line: generate --samples objects per prompt into "
                        "OUT/<i>_<words>_s<seed>/ with OUT/manifest.jsonl; rerunning resumes")
    b.add_argument("--workers", type=int, default=1,
                   help="worker processes, each loading the model once (default 1)")
    b.add_argument("--audit", action="store_true",
                   help="record the sim-ready audit of each object in the manifest")
    b.add_argument("--retry-failed", action="store_true",
                   help="on resume, redo jobs the manifest records as errors")
    _model_args(p)
    a = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO if a.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if a.prompts is not None:
        if a.text is not None or a.image is not None:
            p.error("--prompts replaces TEXT / --image; give one of them")
        if a.structure is not None or a.size is not None:
            p.error("--structure and --size apply to one TEXT or --image, not to --prompts")
        return _batch(a)
    if (a.text is None) == (a.image is None):
        p.error("give a TEXT or --image (exactly one)")
    from model.pipeline.api import GenerationError
    from model.pipeline.generator import Generator
    try:
        structure = None
        if a.structure is not None:
            from model.pipeline.api import parse_structure
            structure = parse_structure(a.structure)    # bad JSON fails before the model loads
        size = None
        if a.size is not None:
            from model.pipeline.api import parse_size
            size = parse_size(a.size)                   # as the structure, before the load
        gen = Generator.load(_config(a))
        results = gen.generate(a.text, image=a.image, seed=a.seed, samples=a.samples,
                               structure=structure, size=size)
        outs = []
        for i, r in enumerate(results):
            d = Path(a.out) if len(results) == 1 else Path(a.out) / f"sample_{i}"
            outs.append(gen.export(r, d, preview=not a.no_preview, mesh_uri=a.mesh_uri))
    except GenerationError as e:
        print(f"artformer generate: {e}", file=sys.stderr)
        return 1
    _report(outs, results, a.json)
    return 0


def _batch(a) -> int:
    from model.pipeline.api import GenerationError
    from model.pipeline.batch import BatchError, read_prompts, run_batch

    config = _config(a)       # --threads left at its default: run_batch shares the cores

    def progress(entry, summary):
        n = summary.skipped + summary.done + summary.failed
        if entry["status"] == "ok":
            what = (f"ok    {entry['out_dir']}  {entry['category'] or 'object'}, "
                    f"{entry['parts']} parts")
        else:
            what = f"ERROR {entry['id']} {entry['prompt'][:40]!r}: {entry['error']}"
        secs = f"{entry['seconds']:.1f} s" if entry.get("seconds") is not None else ""
        print(f"[{n}/{summary.total}] {what}  {secs}", flush=True)

    import signal

    def _stop(signum, frame):   # SIGTERM (kill, a scheduler) stops the workers like Ctrl-C
        raise KeyboardInterrupt
    previous = signal.signal(signal.SIGTERM, _stop)
    try:
        prompts = read_prompts(a.prompts)
        summary = run_batch(prompts, a.out, samples=a.samples, workers=a.workers, seed=a.seed,
                            config=config, audit=a.audit, preview=not a.no_preview,
                            mesh_uri=a.mesh_uri, retry_failed=a.retry_failed,
                            progress=progress)
    except (BatchError, GenerationError) as e:
        print(f"artformer generate: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("artformer generate: interrupted; run the same command again to resume",
              file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGTERM, previous)
    ran = summary.done + summary.failed
    print(f"manifest: {summary.manifest}")
    print(f"{summary.total} jobs: {summary.skipped} already done, {summary.done} generated, "
          f"{summary.failed} failed in this run")
    if ran:
        print(f"throughput: {summary.per_minute:.2f} objects/min ({ran} in {summary.seconds:.1f} s "
              f"with {a.workers} worker(s), model loading included)")
    return 0 if summary.failed == 0 else 3


def _edit(argv: list[str]) -> int:
    p = argparse.ArgumentParser(
        prog="artformer edit",
        description="Remove parts (with their subtrees) from a URDF and regenerate the missing "
                    "parts from a text; kept parts keep their meshes and joints.")
    p.add_argument("urdf", help="input URDF (ours, or any URDF with meshes)")
    p.add_argument("--remove", nargs="+", default=[], metavar="LINK",
                   help="links to remove with their subtrees")
    p.add_argument("--text", required=True, help="what the edited object should be")
    p.add_argument("--out", required=True, help="output folder")
    _model_args(p)
    a = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO if a.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    from model.export import import_urdf
    from model.pipeline.api import GenerationError
    from model.pipeline.edit import remove_parts
    from model.pipeline.generator import Generator
    try:
        obj = import_urdf(a.urdf)
        kept = remove_parts(obj, a.remove)
        gen = Generator.load(_config(a))
        results = gen.generate(a.text, seed=a.seed, samples=a.samples, keep=kept)
        outs = []
        for i, r in enumerate(results):
            d = Path(a.out) if len(results) == 1 else Path(a.out) / f"sample_{i}"
            outs.append(gen.export(r, d, preview=not a.no_preview, mesh_uri=a.mesh_uri))
    except (GenerationError, ValueError, KeyError, FileNotFoundError) as e:
        print(f"artformer edit: {e}", file=sys.stderr)
        return 1
    _report(outs, results, a.json)
    return 0


def main(argv: list[str]) -> int:
    if argv[0] == "generate":
        return _generate(argv[1:])
    if argv[0] == "edit":
        return _edit(argv[1:])
    raise SystemExit(f"unknown command {argv[0]!r}")
