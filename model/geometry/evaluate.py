"""Quality and speed of the shape prior.

* ``evaluate``: per part label, on held-out parts, for the auto-encoder's reconstructions
  (encode the part's surface points, decode, mesh) and for prior samples:

  - F-score at 1 % of the part's largest side and Chamfer distance (metres) against the
    TRUE watertight part mesh, both in the part's metric frame (object units);
  - volume IoU (exact, manifold3d via model.core.meshops);
  - connected components against the true part's (share of parts with the true count) and
    floater faces (faces outside the k largest components, k = the true part's count);
  - watertightness (prior samples).

  A prior sample has no true part: it is compared to the nearest true part of its label
  (Chamfer in the box frame), fitted into that part's box as the pipeline fits parts.
* ``diagnose``: where thin walls are lost (meshing resolution, auto-encoder field error vs
  distance to the surface, box-frame vs iso-frame normalisation, prior vs auto-encoder,
  and meshing-time remedies).
* ``contact_sheet``: PNGs of the worst reconstructions and of prior samples per label.
* ``benchmark``: ms per part mesh at a given resolution, and DDIM time for a batch of parts.

Modules: the metrics of one mesh, the choice of held-out parts and the aggregation of rows in
eval_metrics.py; reconstructions and prior samples in eval_samples.py; the contact sheets in
eval_sheets.py; the cause analysis in eval_diagnose.py (their names are importable from here
too); here, the evaluation itself, its table and the benchmark.
"""
from __future__ import annotations

import statistics
import time
from typing import Optional

import numpy as np
import torch

from model.core.runtime import torch_threads

# the building blocks, re-exported: model.geometry.evaluate stays the one import of callers
from .eval_diagnose import _igl_sdf, _to_frame, diagnose, wall_thickness  # noqa: F401
from .eval_metrics import (FSCORE_TAU, N_SURFACE, TruePart, _mean, _median,  # noqa: F401
                           _surface_points, box_to_iso, box_to_metric, chamfer, compare,
                           encode_parts, floater_faces, fscore_chamfer, part_label, per_label,
                           point_mesh_distance, select_parts, summarise, true_part)
from .eval_samples import diversity, prior_samples, reconstruct  # noqa: F401
from .eval_sheets import contact_sheet, render_mesh, samples_sheet, worst_sheet  # noqa: F401


def evaluate(shape, data: str, *, split: str = "test", max_parts: Optional[int] = 300,
             per_label_cap: Optional[int] = None, resolution: int = 64,
             labels: Optional[int] = None, samples_per_label: int = 8, steps: int = 50,
             seed: int = 0, progress: bool = True, keep_rows: bool = False,
             mesh_kw: Optional[dict] = None) -> dict:
    """Per-label reconstruction and prior-sample quality on held-out parts (see module doc).

    ``labels``: number of most frequent label texts to sample from the prior (None = all).
    With ``keep_rows`` the per-part rows (with meshes) come back under ``"rows"``.
    """
    from .data import load_parts
    parts = load_parts(data, split, with_sdf=False)
    idx = select_parts(parts, per_label=per_label_cap, max_parts=max_parts, seed=seed)
    truth: dict = {}
    rows = reconstruct(shape, parts, idx, resolution=resolution, seed=seed, progress=progress,
                       truth=truth, mesh_kw=mesh_kw)
    allsum = summarise(rows)
    recon = {"parts": len(idx), "split": split, "resolution": resolution,
             "data_version": parts.data_version, **allsum,
             "iou_mean": allsum.get("iou", float("nan")),
             "iou_median": _median([r["iou"] for r in rows]),
             "empty": allsum.get("empty", 0),
             "iou_failed": int(sum(bool(r.get("iou_failed")) for r in rows)),
             "without_true_mesh": len(idx) - len(rows),
             "labels": per_label(rows),
             "mesh_ms_median": _median([r["mesh_ms"] for r in rows])}
    out = {"reconstruction": recon}
    srows: list[dict] = []
    if shape.prior is not None and samples_per_label > 0:
        counts: dict[str, int] = {}
        for i in idx:
            counts[parts.texts[i]] = counts.get(parts.texts[i], 0) + 1
        texts = [t for t, _ in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))]
        if labels is not None:
            texts = texts[:labels]
        srows = prior_samples(shape, parts, n=samples_per_label, steps=steps, seed=seed,
                              resolution=resolution, texts=texts, truth=truth,
                              mesh_kw=mesh_kw)
        ssum = summarise(srows)
        div = diversity(srows)
        ok = [r for r in srows if r.get("watertight") and not r.get("empty")]
        out["prior"] = {"samples": len(srows), "steps": steps, **ssum,
                        "yield": len(ok) / max(len(srows), 1),
                        "clean": float(np.mean([r.get("watertight", False)
                                                and r.get("floater_faces", 0) == 0
                                                for r in srows])) if srows else float("nan"),
                        "diversity_mean": _mean(list(div.values())),
                        "diversity": {k: round(v, 4) for k, v in sorted(div.items())},
                        "labels": per_label(srows)}
    if keep_rows:
        out["rows"] = {"reconstruction": rows, "prior": srows}
    return out


# -- the printed table ------------------------------------------------------------------------

def format_table(res: dict) -> str:
    """Markdown table: per label, reconstruction and prior-sample columns."""
    rec = res["reconstruction"]["labels"]
    pri = res.get("prior", {}).get("labels", {})
    head = ("| label | parts | F@1% | CD (mm) | IoU | true #comp | floaters | "
            "samples | F@1% | CD (mm) | IoU | watertight | floaters |")
    lines = [head, "|" + "---|" * 13]

    def fmt(x, p=3):
        return "–" if x is None or (isinstance(x, float) and not np.isfinite(x)) else f"{x:.{p}f}"

    def row(name, r, s):
        return (f"| {name} | {r.get('n', 0)} | {fmt(r.get('fscore'))} | "
                f"{fmt(r.get('chamfer_mm'), 1)} | {fmt(r.get('iou'))} | "
                f"{fmt(r.get('true_components'), 2)} | {fmt(r.get('with_floaters'), 2)} | "
                f"{s.get('n', 0)} | {fmt(s.get('fscore'))} | {fmt(s.get('chamfer_mm'), 1)} | "
                f"{fmt(s.get('iou'))} | {fmt(s.get('watertight'), 2)} | "
                f"{fmt(s.get('with_floaters'), 2)} |")
    for lab in sorted(set(rec) | set(pri)):
        lines.append(row(lab, rec.get(lab, {}), pri.get(lab, {})))
    lines.append(row("**all**", res["reconstruction"], res.get("prior", {})))
    return "\n".join(lines)


def _json_rows(rows: list[dict]) -> list[dict]:
    skip = {"mesh", "box_mesh", "true"}
    return [{k: v for k, v in r.items() if k not in skip} for r in rows]


# -- benchmark ---------------------------------------------------------------------------------

def benchmark(shape, *, resolution: int = 64, parts: int = 8, steps: int = 50, repeats: int = 5,
              seed: int = 0, ddim_threads: int = 1, mesh_kw: Optional[dict] = None) -> dict:
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
    kw = mesh_kw or {}
    alone = [timed(lambda i=i: shape.decode(z[i:i + 1], resolution, **kw)) for i in range(parts)]
    out["mesh_one_part_ms"] = statistics.median(alone)
    out["mesh_one_part_max_ms"] = max(alone)
    out[f"mesh_{parts}_parts_ms_per_part"] = timed(lambda: shape.decode(z, resolution, **kw)) / parts
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
