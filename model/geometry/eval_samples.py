"""Reconstructions (encode, decode, mesh) and prior samples of held-out parts, one metric row
per mesh (model.geometry.eval_metrics), and the diversity of prior samples."""
from __future__ import annotations

import time
from typing import Optional

import numpy as np
import torch

from .eval_metrics import (TruePart, _mean, _surface_points, box_to_metric, chamfer,
                           compare, encode_parts, part_label, true_part)


def _true_part_cached(truth: dict, parts, i: int, seed: int) -> Optional[TruePart]:
    """The true part ``i`` (None when its mesh is missing), loaded once into ``truth``."""
    if i not in truth:
        truth[i] = true_part(parts, i, seed)
    return truth[i]


def reconstruct(shape, parts, idx: list[int], *, resolution: int = 64, seed: int = 0,
                progress: bool = False, truth: Optional[dict] = None, mesh_kw=None,
                z: Optional[torch.Tensor] = None, iou: bool = True) -> list[dict]:
    """Encode, decode and mesh parts ``idx``; one metric row per part (``mesh`` kept, metric
    frame). ``truth`` caches TruePart per index across calls."""
    truth = {} if truth is None else truth
    if z is None:
        z = encode_parts(shape, parts, idx, seed)
    rows = []
    it = range(len(idx))
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc=f"reconstruct {resolution}", unit="part")
    for j in it:
        i = idx[j]
        tp = _true_part_cached(truth, parts, i, seed)
        if tp is None:
            continue
        t0 = time.perf_counter()
        r = shape.decode(z[j:j + 1], resolution, **(mesh_kw or {}))[0]
        ms = (time.perf_counter() - t0) * 1000
        pred = box_to_metric(r.mesh, parts, i) if r.ok else r.mesh
        row = compare(pred, tp, seed, iou=iou)
        row.update(index=i, label=part_label(parts.texts[i]), text=parts.texts[i],
                   object=parts.object_ids[i], true_components=tp.components,
                   size_m=tp.size, mesh_ms=ms, status=r.status, mesh=pred, true=tp)
        rows.append(row)
    return rows


def prior_samples(shape, parts, *, n: int, steps: int, seed: int, resolution: int,
                  texts: Optional[list[str]] = None, candidates: int = 48,
                  truth: Optional[dict] = None, mesh_kw=None) -> list[dict]:
    """``n`` prior samples per label text, each compared to the nearest true held-out part
    of its text (Chamfer in the box frame over at most ``candidates`` parts), after fitting
    the sample into that part's metric bbox as the pipeline does."""
    from .meshing import fit_to_bbox
    truth = {} if truth is None else truth
    by_text: dict[str, list[int]] = {}
    for i, t in enumerate(parts.texts):
        by_text.setdefault(t, []).append(i)
    if texts is None:
        texts = sorted(by_text)
    gen = torch.Generator().manual_seed(seed)
    rows = []
    for t in texts:
        pool = by_text.get(t, [])
        if not pool:
            continue
        pick = torch.randperm(len(pool), generator=torch.Generator().manual_seed(seed))
        pool = [pool[k] for k in pick[:candidates].tolist()]
        clouds = [parts.points[i].float().numpy() for i in pool]
        z = shape.sample_for_labels([t] * n, steps=steps, generator=gen)
        for k, r in enumerate(shape.decode(z, resolution, **(mesh_kw or {}))):
            row = {"label": part_label(t), "text": t, "sample": k, "status": r.status}
            if not r.ok:
                row.update(fscore=0.0, chamfer=float("nan"), iou=0.0, components=0,
                           floater_faces=0, watertight=False, empty=True, mesh=r.mesh)
                rows.append(row)
                continue
            cloud = _surface_points(r.mesh, 1024, k)
            best = int(np.argmin([chamfer(cloud, c[:1024]) for c in clouds]))
            i = pool[best]
            tp = _true_part_cached(truth, parts, i, seed)
            if tp is None:
                continue
            lo, hi = tp.mesh.bounds
            pred = fit_to_bbox(r.mesh, (lo + hi) / 2, hi - lo)
            row.update(compare(pred, tp, seed))
            row.update(nearest=i, true_components=tp.components, mesh=pred,
                       box_mesh=r.mesh)
            rows.append(row)
    return rows


def diversity(rows: list[dict]) -> dict[str, float]:
    """Mean pairwise Chamfer (box frame) among the non-empty samples of each label text."""
    out = {}
    groups: dict[str, list] = {}
    for r in rows:
        if "box_mesh" in r:
            groups.setdefault(r["text"], []).append(r["box_mesh"])
    for t, ms in groups.items():
        clouds = [_surface_points(m, 2048, k) for k, m in enumerate(ms)]
        pair = [chamfer(clouds[a], clouds[b]) for a in range(len(clouds))
                for b in range(a + 1, len(clouds))]
        out[t] = _mean(pair)
    return out
