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
"""
from __future__ import annotations

import logging
import statistics
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np
import torch

from model.core.runtime import torch_threads

log = logging.getLogger(__name__)

FSCORE_TAU = 0.01          # F-score threshold: 1 % of the part's largest side
N_SURFACE = 10_000         # surface samples per mesh for F-score / Chamfer


# -- geometry metrics -------------------------------------------------------------------------

def chamfer(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric Chamfer distance: mean nearest-neighbour distance a->b plus b->a, halved."""
    from scipy.spatial import cKDTree
    da, _ = cKDTree(b).query(a, k=1)
    db, _ = cKDTree(a).query(b, k=1)
    return float(0.5 * (da.mean() + db.mean()))


def point_mesh_distance(points: np.ndarray, mesh) -> np.ndarray:
    """Unsigned distance of each point to a mesh's surface (exact, libigl AABB tree)."""
    import igl
    d2 = igl.point_mesh_squared_distance(np.ascontiguousarray(points, dtype=np.float64),
                                         np.asarray(mesh.vertices, dtype=np.float64),
                                         np.asarray(mesh.faces, dtype=np.int64))[0]
    return np.sqrt(np.maximum(d2, 0.0))


def fscore_chamfer(pred_mesh, pred_pts: np.ndarray, true_mesh, true_pts: np.ndarray,
                   tau: float) -> tuple[float, float]:
    """(F-score at distance ``tau``, symmetric Chamfer) of two surfaces: precision from the
    predicted surface samples' distances to the true surface, recall from the true samples'
    distances to the predicted surface (point-to-surface, so the sampling density does not
    set a floor on either)."""
    dp = point_mesh_distance(pred_pts, true_mesh)
    dt = point_mesh_distance(true_pts, pred_mesh)
    p, r = float((dp < tau).mean()), float((dt < tau).mean())
    f = 2 * p * r / (p + r) if p + r > 0 else 0.0
    return f, float(0.5 * (dp.mean() + dt.mean()))


def _surface_points(mesh, n: int, seed: int) -> np.ndarray:
    import trimesh
    pts, _ = trimesh.sample.sample_surface(mesh, n, seed=seed)
    return np.asarray(pts)


def floater_faces(mesh, k: int) -> int:
    """Faces outside the ``k`` largest connected components (by surface area)."""
    from .meshing import components
    n, lab = components(mesh)
    if n <= k:
        return 0
    area = np.bincount(lab, weights=np.asarray(mesh.area_faces))
    keep = np.argsort(-area)[:max(k, 1)]
    return int((~np.isin(lab, keep)).sum())


@dataclass
class TruePart:
    """A held-out part's true mesh in its metric (object) frame, with cached statistics."""
    mesh: object
    points: np.ndarray            # (N_SURFACE, 3) surface samples
    size: float                   # largest side (m)
    components: int


def true_part(parts, i: int, seed: int = 0) -> Optional[TruePart]:
    """The prepared watertight mesh of part ``i`` (object frame) or None when missing."""
    import trimesh
    from .meshing import components
    path = parts.mesh_path(i)
    if not path.exists():
        return None
    m = trimesh.load(path, force="mesh", process=True)
    if m.is_empty:
        return None
    return TruePart(m, _surface_points(m, N_SURFACE, seed), float(np.max(m.extents)),
                    components(m)[0])


def box_to_iso(mesh, c: np.ndarray, s: np.ndarray):
    """Box-frame mesh -> iso unit cube (inverse of model.geometry.data.box_frame)."""
    m = mesh.copy()
    if len(m.vertices):
        m.vertices = np.asarray(m.vertices) / s + c
    return m


def box_to_metric(mesh, parts, i: int):
    """Box-frame mesh of part ``i`` -> its metric object frame (exact inverse of the data's
    normalisation: box frame -> iso unit cube -> object)."""
    m = box_to_iso(mesh, parts.box_center[i].numpy(), parts.box_scale[i].numpy())
    if len(m.vertices):
        m.vertices = np.asarray(m.vertices) / float(parts.scale[i]) + parts.center[i]
    return m


def compare(pred, true: TruePart, seed: int = 0, iou: bool = True) -> dict:
    """Metrics of a predicted mesh (metric frame) against a true part."""
    from model.core import meshops
    from .meshing import components
    out = {"faces": int(len(pred.faces)), "components": 0, "floater_faces": 0,
           "watertight": False, "fscore": 0.0, "chamfer": float("nan"),
           "iou": 0.0 if iou else float("nan")}
    if pred.is_empty or len(pred.faces) == 0:
        out["empty"] = True
        return out
    out["components"] = components(pred)[0]
    out["floater_faces"] = floater_faces(pred, true.components)
    out["watertight"] = bool(pred.is_watertight)
    f, c = fscore_chamfer(pred, _surface_points(pred, N_SURFACE, seed), true.mesh,
                          true.points, FSCORE_TAU * true.size)
    out["fscore"], out["chamfer"] = f, c
    if iou:
        try:
            out["iou"] = meshops.volume_iou(pred, true.mesh)
        except meshops.NotWatertightError:
            out["iou"] = float("nan")
            out["iou_failed"] = True
    return out


def part_label(text: str) -> str:
    """'storage furniture, drawer' -> 'drawer'."""
    return text.split(", ", 1)[-1]


def select_parts(parts, *, per_label: Optional[int], max_parts: Optional[int],
                 seed: int) -> list[int]:
    """Held-out part indices: a seeded shuffle, at most ``per_label`` per part label, at most
    ``max_parts`` in all; returned sorted."""
    order = torch.randperm(len(parts), generator=torch.Generator().manual_seed(seed)).tolist()
    taken: dict[str, int] = {}
    out = []
    for i in order:
        lab = part_label(parts.texts[i])
        if per_label is not None and taken.get(lab, 0) >= per_label:
            continue
        taken[lab] = taken.get(lab, 0) + 1
        out.append(i)
        if max_parts is not None and len(out) >= max_parts:
            break
    return sorted(out)


def encode_parts(shape, parts, idx: list[int], seed: int, n_points: int = 1024) -> torch.Tensor:
    """Posterior-mean latents of parts ``idx`` from a seeded subset of their surface points."""
    gen = torch.Generator().manual_seed(seed)
    zs = []
    for s0 in range(0, len(idx), 32):
        ii = torch.tensor(idx[s0:s0 + 32])
        pts = parts.points[ii].float()
        sel = torch.randint(0, pts.shape[1], (len(ii), min(n_points, pts.shape[1])), generator=gen)
        zs.append(shape.ae.encode(pts[torch.arange(len(ii)).unsqueeze(1), sel]))
    return torch.cat(zs)


# -- aggregation ------------------------------------------------------------------------------

def summarise(rows: list[dict]) -> dict:
    """Mean / share figures of a list of per-part metric rows."""
    if not rows:
        return {"n": 0}
    f = np.array([r["fscore"] for r in rows])
    iou = np.array([r["iou"] for r in rows], dtype=float)
    ch = np.array([r["chamfer"] for r in rows], dtype=float)
    out = {"n": len(rows), "fscore": float(f.mean()), "fscore_median": float(np.median(f)),
           "chamfer_mm": float(np.nanmean(ch) * 1000) if np.isfinite(ch).any() else float("nan"),
           "iou": float(np.nanmean(iou)) if np.isfinite(iou).any() else float("nan"),
           "components_mean": float(np.mean([r["components"] for r in rows])),
           "components_max": int(max(r["components"] for r in rows)),
           "with_floaters": float(np.mean([r["floater_faces"] > 0 for r in rows])),
           "watertight": float(np.mean([r["watertight"] for r in rows])),
           "empty": int(sum(bool(r.get("empty")) for r in rows))}
    if all("true_components" in r for r in rows):
        out["true_components"] = float(np.mean([r["components"] == r["true_components"]
                                                for r in rows]))
    return out


def per_label(rows: list[dict]) -> dict:
    groups: dict[str, list[dict]] = {}
    for r in rows:
        groups.setdefault(r["label"], []).append(r)
    return {k: summarise(v) for k, v in sorted(groups.items())}


# -- reconstruction and prior samples ---------------------------------------------------------

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
        if i not in truth:
            truth[i] = true_part(parts, i, seed)
        tp = truth[i]
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
            if i not in truth:
                truth[i] = true_part(parts, i, seed)
            tp = truth[i]
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


# -- contact sheets ---------------------------------------------------------------------------

def render_mesh(mesh, size: int = 160, azimuth: float = 35.0, elevation: float = 22.0,
                frame=None) -> np.ndarray:
    """(size, size, 3) uint8 image of one mesh; the largest component grey-blue, every other
    component red (so shredded parts show). ``frame``: bounds (lo, hi) to frame on."""
    from model.export.render import RenderOptions, _direction, _rasterise
    import math
    from .meshing import components
    opt = RenderOptions(azimuth=azimuth, elevation=elevation)
    img = np.ones((size, size, 3))
    if mesh is not None and len(mesh.faces):
        v, f = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
        lo, hi = frame if frame is not None else (v.min(0), v.max(0))
        centre = (np.asarray(lo) + np.asarray(hi)) / 2
        radius = max(float(np.linalg.norm(np.asarray(hi) - np.asarray(lo))) / 2, 1e-6) * 1.05
        eye = centre + radius / math.sin(math.radians(opt.fov) / 2) * _direction(azimuth, elevation)
        n, lab = components(mesh)
        cols = np.tile(np.array([0.55, 0.65, 0.85]), (len(f), 1))
        if n > 1:
            big = np.argmax(np.bincount(lab, weights=np.asarray(mesh.area_faces)))
            cols[lab != big] = (0.9, 0.25, 0.2)
        img = _rasterise(v[f], cols, np.zeros(len(f), dtype=bool), eye, centre, opt.fov,
                         size, size, opt)
    return np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)


def contact_sheet(path, tiles: list[list[np.ndarray]], row_titles: list[str],
                  title: str = "", tile_inches: float = 1.6) -> None:
    """Grid of images (rows of tiles), a title line above each row, written as a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows, cols = len(tiles), max(len(r) for r in tiles)
    head = 0.35 if title else 0.0
    fig = plt.figure(figsize=(tile_inches * cols, (tile_inches + 0.22) * rows + head))
    H = fig.get_figheight()
    for a in range(rows):
        top = 1 - (head + a * (tile_inches + 0.22)) / H
        fig.text(0.005, top - 0.02 / H, row_titles[a], fontsize=7, va="top", ha="left")
        for b, im in enumerate(tiles[a]):
            ax = fig.add_axes([b / cols, top - (0.22 + tile_inches) / H, 1 / cols,
                               tile_inches / H])
            ax.imshow(im)
            ax.axis("off")
    if title:
        fig.text(0.5, 1 - 0.05 / H, title, fontsize=9, ha="center", va="top")
    fig.savefig(path, dpi=100)
    plt.close(fig)


def worst_sheet(path, rows: list[dict], k: int = 12, size: int = 150) -> None:
    """True part | reconstruction for the ``k`` reconstructions with the lowest F-score,
    two pairs per sheet row."""
    worst = sorted(rows, key=lambda r: (r["fscore"], -r["components"]))[:k]
    tiles, titles = [], []
    for a in range(0, len(worst), 2):
        line, t = [], []
        for r in worst[a:a + 2]:
            tp = r["true"]
            fr = tp.mesh.bounds
            line += [render_mesh(tp.mesh, size, frame=fr), render_mesh(r["mesh"], size, frame=fr)]
            t.append(f"{r['text']} ({r['object']}): F {r['fscore']:.2f}, "
                     f"{r['components']} comp (true {r['true_components']})")
        tiles.append(line)
        titles.append(" | ".join(t))
    contact_sheet(path, tiles, titles,
                  title="worst reconstructions: true | reconstructed (red: extra components)")


def samples_sheet(path, rows: list[dict], per_row: int = 6, size: int = 130) -> None:
    """Prior samples, one sheet row per part label (box-frame meshes; a label with several
    category texts shows samples of each in turn)."""
    groups: dict[str, dict[str, list[dict]]] = {}
    for r in rows:
        groups.setdefault(r["label"], {}).setdefault(r["text"], []).append(r)
    tiles, titles = [], []
    for lab, by_text in sorted(groups.items()):
        seq = [r for k in range(max(len(v) for v in by_text.values()))
               for v in by_text.values() if k < len(v) for r in [v[k]]][:per_row]
        tiles.append([render_mesh(r.get("box_mesh", r["mesh"]), size) for r in seq])
        f = np.mean([r["fscore"] for r in seq])
        titles.append(f"{lab} ({', '.join(sorted({r['text'].split(', ')[0] for r in seq}))}): "
                      f"F {f:.2f} vs nearest true part, "
                      f"{np.mean([r['components'] for r in seq]):.1f} components on average")
    contact_sheet(path, tiles, titles,
                  title="prior samples per label (box frame; red: extra components)")


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


def _mean(x) -> float:
    return float(np.mean(x)) if len(x) else float("nan")


def _median(x) -> float:
    x = [v for v in x if np.isfinite(v)]
    return float(np.median(x)) if len(x) else float("nan")


# -- cause analysis ---------------------------------------------------------------------------

def _to_frame(tp: TruePart, parts, i: int, frame: str):
    """The true mesh in the part's box frame (``"box"``) or iso unit cube (``"iso"``, the
    part's longest side spans [-0.95, 0.95]), with the map back to metric."""
    m = tp.mesh.copy()
    v = (np.asarray(m.vertices) - parts.center[i]) * float(parts.scale[i])     # iso cube
    if frame == "box":
        c, s = parts.box_center[i].numpy(), parts.box_scale[i].numpy()
    else:
        lo, hi = v.min(0), v.max(0)
        c, s = (lo + hi) / 2, np.full(3, 0.95 / max(float(np.max(hi - lo)) / 2, 1e-9))
    m.vertices = (v - c) * s
    back = (lambda w, c=c, s=s: (np.asarray(w) / s + c) / float(parts.scale[i]) + parts.center[i])
    return m, back


def _igl_sdf(mesh):
    import igl
    V = np.asarray(mesh.vertices, dtype=np.float64)
    Fc = np.asarray(mesh.faces, dtype=np.int64)

    def fn(xyz: torch.Tensor) -> torch.Tensor:
        q = xyz.reshape(-1, 3).double().numpy()
        d = igl.signed_distance(q, V, Fc, sign_type=igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)[0]
        return torch.from_numpy(d).float().reshape(xyz.shape[:-1])
    return fn


def wall_thickness(mesh, n: int, seed: int, step: float, steps: int = 48,
                   sdf_fn=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local wall thickness at ``n`` surface points of a watertight mesh: march inwards along
    the face normal in ``step`` increments until the SDF turns positive (capped at
    ``steps`` x ``step``). -> (points, inward normals, thickness)."""
    import trimesh
    pts, fi = trimesh.sample.sample_surface(mesh, n, seed=seed)
    nrm = -np.asarray(mesh.face_normals)[fi]
    sdf_fn = sdf_fn or _igl_sdf(mesh)
    t = step * np.arange(1, steps + 1)
    probe = pts[:, None, :] + t[None, :, None] * nrm[:, None, :]            # (n, K, 3)
    d = sdf_fn(torch.from_numpy(probe.reshape(1, -1, 3)).float()).reshape(n, steps).numpy()
    out = d > 0
    first = np.where(out.any(1), out.argmax(1), steps)
    return np.asarray(pts), nrm, np.where(first < steps, t[np.minimum(first, steps - 1)],
                                          t[-1] + step)


def diagnose(shape, data: str, *, split: str = "test", per_label_cap: int = 6,
             max_parts: Optional[int] = 80, seed: int = 0,
             resolutions: tuple[int, ...] = (32, 64, 128), progress: bool = True) -> dict:
    """Measure where thin walls are lost (numbers per hypothesis; see docs/geometry.md).

    a) meshing resolution: the auto-encoder's reconstructions at each of ``resolutions``,
       and the TRUE SDF (exact, libigl) meshed the same way at 32 / 64 / 128 (the ceiling of
       meshing alone);
    b) the auto-encoder's field: SDF error and sign errors of the decoder against exact
       box-frame SDF samples, binned by distance to the surface (in 64^3 cells), and the
       share of wall mid-points (by wall thickness) that the decoder puts outside;
    c) the normalisation: wall thickness in cells of a 64^3 grid in the box frame vs the iso
       frame, and the true SDF meshed at 64^3 in both frames;
    d) prior vs auto-encoder: retrieval decodes (training latents) of the same label texts;
    e) meshing-time remedies on the same latents: iso-level offsets (dilation), keeping the
       largest component.

    Everything is meshed with ``min_island=0`` (no island removal), so every fragment the
    network makes is counted.
    """
    raw = {"min_island": 0}
    from .data import load_parts
    from .meshing import keep_largest_components, mesh_sdf_batch
    parts = load_parts(data, split, with_sdf=False)
    idx = select_parts(parts, per_label=per_label_cap, max_parts=max_parts, seed=seed)
    truth: dict = {i: true_part(parts, i, seed) for i in idx}
    idx = [i for i in idx if truth[i] is not None]
    z = encode_parts(shape, parts, idx, seed)
    out: dict = {"parts": len(idx), "split": split, "data_version": parts.data_version,
                 "labels": sorted({part_label(parts.texts[i]) for i in idx})}
    h64 = 2.0 / 64

    def brief(rows):
        s = summarise(rows)
        return {k: s.get(k) for k in ("n", "fscore", "chamfer_mm", "iou", "true_components",
                                      "with_floaters", "components_mean", "watertight")} | {
            "mesh_ms_median": _median([r.get("mesh_ms", float("nan")) for r in rows]),
            "body": {k: summarise([r for r in rows if r["label"] == "body"]).get(k)
                     for k in ("n", "fscore", "true_components")}}

    # a) resolution, auto-encoder
    res_rows = {}
    out["a_ae_resolution"] = {}
    for r in resolutions:
        rows = reconstruct(shape, parts, idx, resolution=r, seed=seed, truth=truth, z=z,
                           progress=progress, iou=False, mesh_kw=raw)
        res_rows[r] = rows
        out["a_ae_resolution"][str(r)] = brief(rows)
    # a) + c) the true SDF meshed in the box / iso frame
    out["a_true_sdf_box"], out["c_true_sdf_iso"] = {}, {}
    thick = {"box": [], "iso": []}
    mid_rows = []
    it = idx
    if progress:
        from tqdm import tqdm
        it = tqdm(idx, desc="true SDF / field", unit="part")
    true_rows: dict[str, list] = {}
    for j, i in zip(range(len(idx)), it):
        tp = truth[i]
        lab = part_label(parts.texts[i])
        for frame in ("box", "iso"):
            fm, back = _to_frame(tp, parts, i, frame)
            fn = _igl_sdf(fm)
            for r in ((32, 64, 128) if frame == "box" else (64,)):
                mr = mesh_sdf_batch(fn, 1, r, **raw)[0]
                m = mr.mesh.copy()
                if mr.ok:
                    m.vertices = back(m.vertices)
                row = compare(m, tp, seed, iou=False)
                row.update(label=lab, true_components=tp.components, index=i)
                true_rows.setdefault(f"{frame}{r}", []).append(row)
            # wall thickness in 64^3 cells of this frame
            _, _, t = wall_thickness(fm, 256, seed, step=h64 / 4, sdf_fn=fn)
            thick[frame].append((lab, t / h64))
            if frame == "box":
                # b) decoder error against exact samples, and wall mid-points
                from .data import sample_part
                _, _, smp = sample_part(fm, 16, 4096, np.random.default_rng(seed + i))
                planes = shape.ae.decode_planes(z[j:j + 1])
                q = torch.from_numpy(smp[:, :3]).float()[None]
                pred = shape.ae.query(planes, q)[0].numpy()
                mid_rows.append(("field", lab, smp[:, 3] / h64, pred / h64))
                p, nrm, t = wall_thickness(fm, 512, seed + 1, step=h64 / 4, sdf_fn=fn)
                midp = p + nrm * (t / 2)[:, None]
                pm = shape.ae.query(planes, torch.from_numpy(midp).float()[None])[0].numpy()
                mid_rows.append(("mid", lab, t / h64, pm / h64))
    for key, rows in true_rows.items():
        tgt = out["a_true_sdf_box"] if key.startswith("box") else out["c_true_sdf_iso"]
        tgt[key[3:]] = brief(rows)
    # b) field error by distance to the surface (cells of 64^3)
    bins = [0, 0.5, 1, 2, 4, 1e9]
    fld = [r for r in mid_rows if r[0] == "field"]
    d = np.concatenate([r[2] for r in fld])
    p = np.concatenate([r[3] for r in fld])
    is_body = np.concatenate([np.full(len(r[2]), r[1] == "body") for r in fld])
    b_err = []
    for lo, hi in zip(bins[:-1], bins[1:]):
        sel = (np.abs(d) >= lo) & (np.abs(d) < hi)
        b_err.append({"abs_distance_cells": f"{lo}-{hi if hi < 1e8 else 'inf'}",
                      "samples": int(sel.sum()),
                      "abs_error_cells": float(np.abs(p[sel] - d[sel]).mean()) if sel.any() else None,
                      "sign_errors": float((np.sign(p[sel]) != np.sign(d[sel])).mean()) if sel.any() else None,
                      "sign_errors_body": float((np.sign(p[sel & is_body]) != np.sign(d[sel & is_body])).mean()) if (sel & is_body).any() else None})
    out["b_field_error_by_distance"] = b_err
    mids = [r for r in mid_rows if r[0] == "mid"]
    t = np.concatenate([r[2] for r in mids])
    pm = np.concatenate([r[3] for r in mids])
    tb = [0, 1, 2, 4, 8, 1e9]
    out["b_wall_midpoints_outside"] = [
        {"wall_cells": f"{lo}-{hi if hi < 1e8 else 'inf'}", "points": int(sel.sum()),
         "decoded_outside": float((pm[sel] > 0).mean()) if sel.any() else None}
        for lo, hi in zip(tb[:-1], tb[1:]) for sel in [(t >= lo) & (t < hi)]]
    # c) wall thickness distributions, box vs iso frame
    out["c_wall_thickness_cells"] = {}
    for frame in ("box", "iso"):
        allt = np.concatenate([x[1] for x in thick[frame]])
        bod = [x[1] for x in thick[frame] if x[0] == "body"]
        bodt = np.concatenate(bod) if bod else np.zeros(0)
        out["c_wall_thickness_cells"][frame] = {
            "median": float(np.median(allt)), "under_1_cell": float((allt < 1).mean()),
            "under_2_cells": float((allt < 2).mean()),
            "body_median": float(np.median(bodt)) if len(bodt) else None,
            "body_under_2_cells": float((bodt < 2).mean()) if len(bodt) else None}
    # d) retrieval decodes of the same label texts (training latents through the AE)
    lat = shape.bank.get("latents") if shape.bank else None
    if lat is not None:
        gen = torch.Generator().manual_seed(seed)
        comps, wt, body_one = [], [], []
        texts = sorted({parts.texts[i] for i in idx})
        for tx in texts:
            if tx not in shape.bank["texts"]:
                continue
            sel = (shape.bank["text_ids"] == shape.bank["texts"].index(tx)).nonzero()[:, 0]
            pick = sel[torch.randperm(len(sel), generator=gen)[:per_label_cap]]
            for r in shape.decode(lat[pick].float(), 64, **raw):
                if not r.ok:
                    continue
                from .meshing import components
                comps.append(components(r.mesh)[0])
                wt.append(bool(r.mesh.is_watertight))
                if part_label(tx) == "body":
                    body_one.append(comps[-1] == 1)
        out["d_retrieval_64"] = {"n": len(comps), "single_component": float(np.mean(np.array(comps) == 1)),
                                 "components_mean": float(np.mean(comps)),
                                 "components_max": int(max(comps)) if comps else 0,
                                 "watertight": float(np.mean(wt)),
                                 "body_single_component": float(np.mean(body_one)) if body_one else None}
    out["d_reconstruction_64_single_component"] = float(np.mean([r["components"] == 1 for r in res_rows.get(64, [])])) if 64 in res_rows else None
    # e) meshing-time remedies on the same latents
    rem = {}
    for lv in (0.5, 1.0):
        rows = reconstruct(shape, parts, idx, resolution=64, seed=seed, truth=truth, z=z,
                           mesh_kw={"level": lv * h64, **raw}, iou=False)
        rem[f"level_+{lv}_cell"] = brief(rows)
    base = res_rows.get(64) or reconstruct(shape, parts, idx, resolution=64, seed=seed,
                                           truth=truth, z=z, iou=False, mesh_kw=raw)
    kept = []
    for r in base:
        if r.get("empty"):
            kept.append(r)
            continue
        m = keep_largest_components(r["mesh"], 1)
        row = compare(m, truth[r["index"]], seed, iou=False)
        row.update(label=r["label"], true_components=r["true_components"], index=r["index"])
        kept.append(row)
    rem["largest_component_only"] = brief(kept)
    out["e_remedies_64"] = rem
    return out
