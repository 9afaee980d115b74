"""Instantiation Distance (ID, from NAP; DESIGN §7) and the point clouds it is built from.

ID(A, B): pose each object ``n_poses`` times, every joint at its own ratio drawn from U(0, 1);
sample ``n_points`` surface points of the whole posed object; D is the (n_poses, n_poses)
matrix of Chamfer distances between A's and B's posed clouds; ID = mean of the row minima +
mean of the column minima. ID is symmetric, and 0 for two identical objects.

Chamfer distance (the usual point-cloud form, as in PointFlow / pytorch3d's default):
``CD(X, Y) = mean_x min_y |x - y|² + mean_y min_x |x - y|²`` (squared metres, no normalisation
of the objects: both sets live in the same metric frame, REP-103, base on z = 0).

Sampling is seeded with the *same* seed for every object, so identical objects get identical
clouds and an identical set gives MMD 0 exactly. Surface points are drawn area-weighted over
the rest-pose meshes and moved with their part: rigid motions keep areas, so this is the same
distribution as sampling the posed mesh, at a fraction of the cost.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from model.core import ArticulatedObject

log = logging.getLogger(__name__)

N_POSES = 10
N_POINTS = 4096


@dataclass
class PosedClouds:
    """The ``n_poses`` posed surface clouds of one object and their KD-trees."""
    points: np.ndarray          # (n_poses, n_points, 3) float64
    trees: list                 # n_poses scipy cKDTree

    @property
    def n_poses(self) -> int:
        return int(self.points.shape[0])


def _part_meshes(obj: ArticulatedObject):
    """(part index, trimesh) for every part; a part without mesh uses its bbox as a box."""
    import trimesh
    out = []
    for i, p in enumerate(obj.parts):
        m = p.mesh
        if m is None or len(m.faces) == 0:
            if np.all(p.bbox_size > 0):
                m = trimesh.creation.box(extents=p.bbox_size)
                m.apply_translation(p.bbox_center)
                log.debug("ID: part %r has no mesh; using its bbox", p.name)
            else:
                continue
        out.append((i, m))
    if not out:
        raise ValueError(f"object {obj.name!r} has no part geometry to sample")
    return out


def _sample_rest(obj: ArticulatedObject, n_points: int, rng: np.random.Generator):
    """Area-weighted surface samples at rest: points (n, 3) and their part index (n,)."""
    parts = _part_meshes(obj)
    tris = [np.asarray(m.triangles, dtype=np.float64) for _, m in parts]   # each (F_k, 3, 3)
    owner = np.concatenate([np.full(len(t), i) for (i, _), t in zip(parts, tris)])  # (F,)
    tri = np.concatenate(tris)                                             # (F, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    total = area.sum()
    if not np.isfinite(total) or total <= 0:
        raise ValueError(f"object {obj.name!r} has zero surface area")
    face = rng.choice(len(tri), size=n_points, p=area / total)             # (n,)
    u, v = rng.random(n_points), rng.random(n_points)
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    t = tri[face]                                                          # (n, 3, 3)
    pts = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
    return pts, owner[face]


def posed_clouds(obj: ArticulatedObject, n_poses: int = N_POSES, n_points: int = N_POINTS,
                 seed: int = 0) -> PosedClouds:
    """Sample the object's ``n_poses`` random instantiations (each joint its own U(0,1) ratio)."""
    from scipy.spatial import cKDTree
    rng = np.random.default_rng(seed)
    names = [p.name for p in obj.parts]
    clouds = np.empty((n_poses, n_points, 3))
    for k in range(n_poses):
        ratios = {nm: float(x) for nm, x in zip(names, rng.random(len(names)))}
        T = obj.link_transforms(ratio=ratios)
        pts, owner = _sample_rest(obj, n_points, rng)
        for i in np.unique(owner):
            sel = owner == i
            M = T[names[i]]
            clouds[k, sel] = pts[sel] @ M[:3, :3].T + M[:3, 3]
    return PosedClouds(clouds, [cKDTree(c) for c in clouds])


def chamfer_matrix(a: PosedClouds, b: PosedClouds, workers: int = 1) -> np.ndarray:
    """(a.n_poses, b.n_poses) Chamfer distances between every posed cloud of a and of b."""
    na, nb = a.n_poses, b.n_poses
    n_a = a.points.shape[1]
    # One query per tree over all clouds of the other object: (na * n_a,) distances at once.
    a_to_b = np.stack([t.query(a.points.reshape(-1, 3), workers=workers)[0] for t in b.trees])
    a_to_b = (a_to_b ** 2).reshape(nb, na, n_a).mean(-1).T                # (na, nb)
    n_b = b.points.shape[1]
    b_to_a = np.stack([t.query(b.points.reshape(-1, 3), workers=workers)[0] for t in a.trees])
    b_to_a = (b_to_a ** 2).reshape(na, nb, n_b).mean(-1)                  # (na, nb)
    return a_to_b + b_to_a


def id_from_chamfer(D: np.ndarray) -> float:
    """ID = mean of row minima + mean of column minima of the Chamfer matrix D."""
    return float(D.min(axis=1).mean() + D.min(axis=0).mean())


def instantiation_distance(a, b, *, n_poses: int = N_POSES, n_points: int = N_POINTS,
                           seed: int = 0, workers: int = 1) -> float:
    """ID between two objects (ArticulatedObject or precomputed :class:`PosedClouds`)."""
    ca = a if isinstance(a, PosedClouds) else posed_clouds(a, n_poses, n_points, seed)
    cb = b if isinstance(b, PosedClouds) else posed_clouds(b, n_poses, n_points, seed)
    return id_from_chamfer(chamfer_matrix(ca, cb, workers))


def id_matrix(rows: list[PosedClouds], cols: list[PosedClouds] | None = None, *,
              workers: int = 1, progress: bool = False) -> np.ndarray:
    """(len(rows), len(cols)) ID matrix. ``cols=None``: the symmetric matrix of ``rows`` with
    itself (each pair computed once, diagonal 0)."""
    symmetric = cols is None
    cols = rows if symmetric else cols
    M = np.zeros((len(rows), len(cols)))
    pairs = [(i, j) for i in range(len(rows)) for j in range(len(cols))
             if not symmetric or j > i]
    it = pairs
    if progress:
        from tqdm import tqdm
        it = tqdm(pairs, desc="instantiation distance", leave=False)
    for i, j in it:
        M[i, j] = id_from_chamfer(chamfer_matrix(rows[i], cols[j], workers))
        if symmetric:
            M[j, i] = M[i, j]
    return M


def diversity(samples: list[PosedClouds], workers: int = 1) -> float:
    """Mean pairwise ID among the samples of one prompt (0 for fewer than two)."""
    if len(samples) < 2:
        return 0.0
    M = id_matrix(samples, workers=workers)
    iu = np.triu_indices(len(samples), k=1)
    return float(M[iu].mean())
