"""Metrics of one part mesh against its true held-out part, the choice of held-out parts, and
the aggregation of per-part metric rows (the building blocks of model.geometry.evaluate).

All distances are in the part's metric (object) frame unless a function says otherwise.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
import torch

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


def _mean(x) -> float:
    return float(np.mean(x)) if len(x) else float("nan")


def _median(x) -> float:
    x = [v for v in x if np.isfinite(v)]
    return float(np.median(x)) if len(x) else float("nan")
