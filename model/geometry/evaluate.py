"""Quality and speed of the shape prior.

* ``evaluate``: reconstruction (encode the held-out parts' surface points, decode, mesh) —
  volume IoU (exact, manifold3d via model.core.meshops) and Chamfer distance against the true
  part meshes in the iso unit cube; prior samples per label — yield (non-empty, watertight)
  and diversity (mean pairwise Chamfer among the samples of one label).
* ``benchmark``: ms per part mesh at a given resolution, and DDIM time for a batch of parts.
"""
from __future__ import annotations

import logging
import statistics
import time
from typing import Optional

import numpy as np
import torch

from model.core.runtime import torch_threads

log = logging.getLogger(__name__)


def chamfer(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric Chamfer distance: mean nearest-neighbour distance a->b plus b->a, halved."""
    from scipy.spatial import cKDTree
    da, _ = cKDTree(b).query(a, k=1)
    db, _ = cKDTree(a).query(b, k=1)
    return float(0.5 * (da.mean() + db.mean()))


def _surface_points(mesh, n: int, seed: int) -> np.ndarray:
    import trimesh
    pts, _ = trimesh.sample.sample_surface(mesh, n, seed=seed)
    return np.asarray(pts)


def _true_mesh_iso(parts, i: int):
    """The prepared watertight part mesh moved into the iso unit cube (or None)."""
    import trimesh
    path = parts.mesh_path(i)
    if not path.exists():
        return None
    m = trimesh.load(path, force="mesh", process=True)
    m.apply_translation(-parts.center[i])
    m.apply_scale(float(parts.scale[i]))
    return m


def box_to_iso(mesh, c: np.ndarray, s: np.ndarray):
    """Box-frame mesh -> iso unit cube (inverse of model.geometry.data.box_frame)."""
    m = mesh.copy()
    if len(m.vertices):
        m.vertices = np.asarray(m.vertices) / s + c
    return m


def evaluate(shape, data: str, *, split: str = "test", max_parts: Optional[int] = 300,
             resolution: int = 64, labels: int = 12, samples_per_label: int = 8,
             steps: int = 50, seed: int = 0, batch: int = 16, progress: bool = True) -> dict:
    from model.core import meshops
    from .data import load_parts
    parts = load_parts(data, split, with_sdf=False)
    n = len(parts) if max_parts is None else min(len(parts), max_parts)
    order = torch.randperm(len(parts), generator=torch.Generator().manual_seed(seed))[:n]
    order = order.sort().values
    ious, chamfers, per_label, empty, iou_fail, no_mesh = [], [], {}, 0, 0, 0
    it = range(0, n, batch)
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc="reconstruct", unit="batch")
    gen = torch.Generator().manual_seed(seed)
    for s0 in it:
        idx = order[s0:s0 + batch]
        pts = parts.points[idx].float()                                   # (b, P, 3) box frame
        sel = torch.randint(0, pts.shape[1], (len(idx), min(1024, pts.shape[1])), generator=gen)
        z = shape.ae.encode(pts[torch.arange(len(idx)).unsqueeze(1), sel])
        for j, r in enumerate(shape.decode(z, resolution)):
            i = int(idx[j])
            c, s = parts.box_center[i].numpy(), parts.box_scale[i].numpy()
            if not r.ok:
                empty += 1
                ious.append(0.0)
                per_label.setdefault(parts.texts[i], []).append(0.0)
                continue
            pred = box_to_iso(r.mesh, c, s)
            true_pts = (parts.points[i].float().numpy() / s) + c
            chamfers.append(chamfer(_surface_points(pred, 4096, i), true_pts))
            true = _true_mesh_iso(parts, i)
            if true is None:
                no_mesh += 1
                continue
            try:
                iou = meshops.volume_iou(pred, true)
            except meshops.NotWatertightError:
                iou_fail += 1
                continue
            ious.append(iou)
            per_label.setdefault(parts.texts[i], []).append(iou)
    recon = {"parts": n, "split": split, "resolution": resolution,
             "iou_mean": _mean(ious), "iou_median": _median(ious),
             "chamfer_mean": _mean(chamfers), "empty": empty, "iou_failed": iou_fail,
             "without_true_mesh": no_mesh,
             "iou_per_label": {k: round(_mean(v), 4) for k, v in sorted(per_label.items())}}
    out = {"reconstruction": recon}
    if shape.prior is not None and samples_per_label > 0:
        out["prior"] = sample_quality(shape, parts, labels=labels, n=samples_per_label,
                                      steps=steps, seed=seed, resolution=resolution)
    return out


def sample_quality(shape, parts, *, labels: int, n: int, steps: int, seed: int,
                   resolution: int) -> dict:
    """Yield and diversity of prior samples for the most frequent label texts."""
    counts: dict[str, int] = {}
    for t in parts.texts:
        counts[t] = counts.get(t, 0) + 1
    texts = [t for t, _ in sorted(counts.items(), key=lambda kv: -kv[1])[:labels]]
    gen = torch.Generator().manual_seed(seed)
    total = good = 0
    div, per = [], {}
    for t in texts:
        z = shape.sample_for_labels([t] * n, steps=steps, generator=gen)
        res = shape.decode(z, resolution)
        ok = [r for r in res if r.ok and r.mesh.is_watertight]
        total += len(res)
        good += len(ok)
        clouds = [_surface_points(r.mesh, 2048, k) for k, r in enumerate(ok)]
        pair = [chamfer(clouds[a], clouds[b]) for a in range(len(clouds))
                for b in range(a + 1, len(clouds))]
        d = _mean(pair)
        div.append(d)
        per[t] = {"yield": len(ok) / len(res), "diversity": round(d, 4)}
    return {"samples": total, "yield": good / max(total, 1), "diversity_mean": _mean(div),
            "labels": per, "steps": steps}


def benchmark(shape, *, resolution: int = 64, parts: int = 8, steps: int = 50, repeats: int = 5,
              seed: int = 0, ddim_threads: int = 1) -> dict:
    """Median wall times (ms): each of ``parts`` parts meshed alone (median and max over the
    parts); all of them meshed in one call (per part); 50-step DDIM over all of them.

    Meshing runs on the current torch threads; DDIM on ``ddim_threads`` (the pipeline runs
    its token-sized networks on one thread, model.core.runtime)."""
    gen = torch.Generator().manual_seed(seed)
    lat = shape.bank.get("latents") if shape.bank else None
    if lat is not None:
        z = lat[torch.randint(0, lat.shape[0], (parts,), generator=gen)].float()
    else:
        z = torch.randn(parts, shape.ae.cfg.z_dim, generator=gen) * shape.ae.cfg.prior_std

    def timed(fn):
        fn()                                                    # warm-up
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            ts.append((time.perf_counter() - t0) * 1000)
        return statistics.median(ts)
    out = {"resolution": resolution, "threads": torch.get_num_threads()}
    # each part meshed alone (parts differ 3x in surface area, so one part is no measure)
    alone = [timed(lambda i=i: shape.decode(z[i:i + 1], resolution)) for i in range(parts)]
    out["mesh_one_part_ms"] = statistics.median(alone)
    out["mesh_one_part_max_ms"] = max(alone)
    out[f"mesh_{parts}_parts_ms_per_part"] = timed(lambda: shape.decode(z, resolution)) / parts
    if shape.prior is not None:
        P = shape.code_distribution(z).clamp_min(1e-8).log()
        cs = torch.randn(parts, shape.prior.cfg.cs_dim, generator=gen)
        out["ddim_threads"] = ddim_threads
        with torch_threads(ddim_threads):
            out[f"ddim_{parts}_parts_{steps}_steps_ms"] = timed(
                lambda: shape.sample_from_logits(P, cs, steps=steps,
                                                 generator=torch.Generator().manual_seed(0)))
            out[f"ddim_{parts}_parts_{steps}_steps_cfg_ms"] = timed(
                lambda: shape.sample_from_logits(P, cs, steps=steps, guidance=2.0,
                                                 generator=torch.Generator().manual_seed(0)))
    return out


def _mean(x) -> float:
    return float(np.mean(x)) if len(x) else float("nan")


def _median(x) -> float:
    return float(np.median(x)) if len(x) else float("nan")
