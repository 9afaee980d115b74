"""Category accuracy and structure alignment of an image checkpoint on held-out renders.

For every object of a split and every selected view, decode one tree from the rendered image
and compare it with the object's structure (category; count of every part label; joint types
of every label) exactly as the text model is scored (model.articulation.evaluate.compare).

    artformer train image --eval model/weights/image_small.pt --data data/prepared/v1 \
        --renders data/renders/v1 --split test

The same images through the whole generator (POR, validity): model.metrics.image_pipeline.
"""
from __future__ import annotations

import logging
from typing import Optional

import numpy as np

log = logging.getLogger(__name__)


def held_out_views(data_root: str, render_root: str, *, split: str = "test",
                   views: Optional[list[int]] = None, limit: int = 0) -> tuple[list[str], list[tuple]]:
    """The rendered objects of a split and one job per selected view:
    (ids, [(record, view index, openness, image path), ...])."""
    from model.data import format as fmt

    from .renders import rendered_ids, view_paths, view_specs
    ids = rendered_ids(render_root, fmt.split_ids(data_root, split))
    if limit:
        ids = ids[:limit]
    jobs = []
    for i in ids:
        rec = fmt.load_record(data_root, i)
        paths, specs = view_paths(render_root, i), view_specs(render_root, i)
        for k in (views if views is not None else range(len(paths))):
            if k < len(paths):
                jobs.append((rec, k, specs[k].openness, paths[k]))
    return ids, jobs


VISIBLE_PX = 16          # a part smaller than 4x4 pixels of a 224-px render is hard to count


def _part_pixels(data_root: str, render_root: str, rec, view: int, cache: dict) -> list:
    """[[label, visible pixels], ...] of every part of ``rec`` in its rendered view ``view``
    (``cache`` keeps the last object's meshes: its views come one after another)."""
    from .render import part_pixels
    from .renders import object_from_record, view_specs
    if rec.id not in cache:
        cache.clear()
        cache[rec.id] = object_from_record(data_root, rec)
    obj = cache[rec.id]
    px = part_pixels(obj, view_specs(render_root, rec.id)[view])
    return [[p.label, int(n)] for p, n in zip(obj.parts, px)]


def visibility_breakdown(rows: list[dict], visible_px: int = VISIBLE_PX) -> dict:
    """Structure alignment of the renders whose every part shows >= ``visible_px`` pixels,
    of those with a smaller (but seen) part and of those with a hidden part; and per label
    the share of parts under ``visible_px`` pixels."""
    groups = {f"every part >= {visible_px} px": lambda m: m >= visible_px,
              f"smallest part 1-{visible_px - 1} px": lambda m: 0 < m < visible_px,
              "a part hidden (0 px)": lambda m: m == 0}
    out = {}
    for name, test in groups.items():
        sel = [r for r in rows if test(min(n for _, n in r["part_pixels"]))]
        out[name] = {"renders": len(sel), "share": len(sel) / max(1, len(rows)),
                     "alignment": float(np.mean([r["all"] for r in sel])) if sel else float("nan")}
    small, total = {}, {}
    for r in rows:
        for lab, n in r["part_pixels"]:
            total[lab] = total.get(lab, 0) + 1
            small[lab] = small.get(lab, 0) + (n < visible_px)
    out["parts_under_threshold"] = {lab: small[lab] / total[lab] for lab in sorted(total)}
    return out


def farther_view(path, share: float) -> np.ndarray:
    """A render shown at ``share`` of a larger picture's side, the rest its border colour (the
    median of its outermost pixels): the same object seen from further away by a camera with
    more pixels, as a photo would be. (H/share, W/share, 3) float."""
    from model.encoders.framing import border_ring
    from model.encoders.image import to_rgb_float
    if not 0 < share <= 1:
        raise ValueError(f"share must be in (0, 1], got {share}")
    rgb = to_rgb_float(path)
    h, w = rgb.shape[:2]
    ring = border_ring(rgb, 1)
    H, W = int(round(h / share)), int(round(w / share))
    out = np.empty((H, W, 3), np.float32)
    out[:] = np.median(ring, axis=0)
    y0, x0 = (H - h) // 2, (W - w) // 2
    out[y0:y0 + h, x0:x0 + w] = rgb
    return out


def image_alignment_report(ckpt: str, data_root: str, render_root: str, *, split: str = "test",
                           views: Optional[list[int]] = None, limit: int = 0, seed: int = 0,
                           temperature: float = 1.0, batch: int = 32, progress: bool = True,
                           follow_plan: bool = False, count_plan: bool = True,
                           oracle_plan: bool = False, visibility: bool = False,
                           visible_px: int = VISIBLE_PX, frame: bool = False,
                           farther: float = 1.0, max_nodes: int = 32, max_depth: int = 4,
                           max_children: int = 16) -> dict:
    """``count_plan``: decode with END decisions held to the checkpoint's count head (if it
    has one); ``follow_plan``: otherwise to the transformer's START plan head;
    ``oracle_plan`` (a diagnostic): to the object's true part counts.
    ``visibility``: also measure how much of every part each render shows (a part-id render
    with the same camera) and report structure separately for the renders whose every part
    covers at least ``visible_px`` pixels and for the rest (``by_visibility``).
    ``farther`` < 1: every render is shown at that share of a larger picture (``farther_view``,
    a photo from further away); ``frame``: pictures are cropped around their object first,
    as the product does (model.encoders.framing)."""
    import torch

    from model.articulation.evaluate import compare, record_structure

    from .model import load_image_model

    im = load_image_model(ckpt)
    ids, jobs = held_out_views(data_root, render_root, split=split, views=views, limit=limit)
    rows, objects = [], {}
    rng = range(0, len(jobs), batch)
    if progress:
        from tqdm import tqdm
        rng = tqdm(rng, desc=f"decode {split} images", unit="batch")
    for s in rng:
        chunk = jobs[s:s + batch]
        images = [str(p) if farther == 1.0 else farther_view(p, farther) for *_, p in chunk]
        tok, mask, plan = im.condition(images, frame)
        if oracle_plan:
            from .counts import count_targets
            plan = count_targets([rec for rec, *_ in chunk], im.am.cfg.count_labels,
                                 im.am.cfg.plan_max_count)
        with torch.inference_mode():
            trees = im.am.decode(tok, mask, seed=seed + s, temperature=temperature, modality="image",
                                 max_nodes=max_nodes, max_depth=max_depth, max_children=max_children,
                                 follow_plan=follow_plan,
                                 plan=plan if count_plan or oracle_plan else None)
        for (rec, k, r, path), tree in zip(chunk, trees):
            truth = record_structure(rec)
            ok = compare(tree.summary(), truth)
            rows.append({"id": rec.id, "view": k, "openness": r, "image": str(path), **ok,
                         "decoded": tree.summary(), "truth": truth})
            if visibility:
                rows[-1]["part_pixels"] = _part_pixels(data_root, render_root, rec, k, objects)

    def share(rs, key="all"):
        return float(np.mean([r[key] for r in rs])) if rs else float("nan")

    cats = sorted({r["truth"]["category"] for r in rows})
    return {"checkpoint": str(ckpt), "data": str(data_root), "renders": str(render_root),
            "split": split, "objects": len(ids), "images": len(rows), "seed": seed,
            "temperature": temperature, "follow_plan": follow_plan, "frame": frame,
            "farther": farther,
            "count_plan": "oracle" if oracle_plan else bool(count_plan and im.counter is not None),
            "category": share(rows, "category"), "alignment": share(rows),
            "counts": share(rows, "counts"), "joint_types": share(rows, "joint_types"),
            "by_category": {c: {"category": share([r for r in rows if r["truth"]["category"] == c], "category"),
                                "alignment": share([r for r in rows if r["truth"]["category"] == c]),
                                "images": sum(r["truth"]["category"] == c for r in rows)}
                            for c in cats},
            **({"by_visibility": visibility_breakdown(rows, visible_px)} if visibility else {}),
            "by_openness": {name: share([r for r in rows if lo <= r["openness"] <= hi])
                            for name, (lo, hi) in {"closed(0)": (0, 0), "open(1)": (1, 1),
                                                   "between": (1e-6, 1 - 1e-6)}.items()},
            "rows": rows}
