"""Category accuracy and structure alignment of an image checkpoint on held-out renders.

For every object of a split and every selected view, decode one tree from the rendered image
and compare it with the object's structure (category; count of every part label; joint types
of every label) exactly as the text model is scored (model.articulation.evaluate.compare).

    artformer train image --eval model/weights/image_small.pt --data data/prepared/v1 \
        --renders data/renders/v1 --split test
"""
from __future__ import annotations

import logging
from typing import Optional

import numpy as np

log = logging.getLogger(__name__)


def image_alignment_report(ckpt: str, data_root: str, render_root: str, *, split: str = "test",
                           views: Optional[list[int]] = None, limit: int = 0, seed: int = 0,
                           temperature: float = 1.0, batch: int = 32, progress: bool = True,
                           follow_plan: bool = False,
                           max_nodes: int = 32, max_depth: int = 4, max_children: int = 16) -> dict:
    import torch

    from model.articulation.evaluate import compare, record_structure
    from model.data import format as fmt

    from .model import load_image_model
    from .renders import rendered_ids, view_paths, view_specs

    im = load_image_model(ckpt)
    ids = rendered_ids(render_root, fmt.split_ids(data_root, split))
    if limit:
        ids = ids[:limit]
    jobs = []    # (record, view index, openness, path)
    for i in ids:
        rec = fmt.load_record(data_root, i)
        paths, specs = view_paths(render_root, i), view_specs(render_root, i)
        for k in (views if views is not None else range(len(paths))):
            if k < len(paths):
                jobs.append((rec, k, specs[k].openness, paths[k]))
    rows = []
    rng = range(0, len(jobs), batch)
    if progress:
        from tqdm import tqdm
        rng = tqdm(rng, desc=f"decode {split} images", unit="batch")
    for s in rng:
        chunk = jobs[s:s + batch]
        tok, mask = im.encode([str(p) for *_, p in chunk])
        with torch.inference_mode():
            trees = im.am.decode(tok, mask, seed=seed + s, temperature=temperature, modality="image",
                                 max_nodes=max_nodes, max_depth=max_depth, max_children=max_children,
                                 follow_plan=follow_plan)
        for (rec, k, r, path), tree in zip(chunk, trees):
            truth = record_structure(rec)
            ok = compare(tree.summary(), truth)
            rows.append({"id": rec.id, "view": k, "openness": r, "image": str(path), **ok,
                         "decoded": tree.summary(), "truth": truth})

    def share(rs, key="all"):
        return float(np.mean([r[key] for r in rs])) if rs else float("nan")

    cats = sorted({r["truth"]["category"] for r in rows})
    return {"checkpoint": str(ckpt), "data": str(data_root), "renders": str(render_root),
            "split": split, "objects": len(ids), "images": len(rows), "seed": seed,
            "temperature": temperature, "follow_plan": follow_plan,
            "category": share(rows, "category"), "alignment": share(rows),
            "counts": share(rows, "counts"), "joint_types": share(rows, "joint_types"),
            "by_category": {c: {"category": share([r for r in rows if r["truth"]["category"] == c], "category"),
                                "alignment": share([r for r in rows if r["truth"]["category"] == c]),
                                "images": sum(r["truth"]["category"] == c for r in rows)}
                            for c in cats},
            "by_openness": {name: share([r for r in rows if lo <= r["openness"] <= hi])
                            for name, (lo, hi) in {"closed(0)": (0, 0), "open(1)": (1, 1),
                                                   "between": (1e-6, 1 - 1e-6)}.items()},
            "rows": rows}
