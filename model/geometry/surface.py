"""The numpy half of meshing (no torch): marching cubes on a vertex grid, removal of
sub-resolution sign islands, fitting a unit-cube mesh into its box, connected components.

``model.geometry.meshing`` evaluates the SDF grids with the network and re-exports these
names; the pipeline's meshing helper process (``model.pipeline.part_pool``) imports only this
module, so it starts without torch.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np


@dataclass
class MeshResult:
    mesh: object            # trimesh.Trimesh (empty when status != "ok")
    status: str             # "ok" | "empty" (no inside) | "full" (no outside)
    evaluations: int        # SDF evaluations spent on this part
    inside: Optional[np.ndarray] = None   # (n+1, n+1, n+1) bool: grid vertices inside, over
                                          # [-bound, bound]^3 (collision boxes use it)
    bound: float = 1.0                    # the grid's half extent

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def marching_cubes(values: np.ndarray, bound: float = 1.0, level: float = 0.0) -> MeshResult:
    """One part's vertex grid (n+1)^3 over [-bound, bound]^3 -> closed mesh (or no surface).

    ``level`` > 0 meshes the surface ``level`` outside the decoded one (a dilation by that
    distance in the part's frame)."""
    import trimesh
    from skimage import measure
    n = values.shape[0] - 1
    if level:
        values = values - level
    if values.min() > 0:
        return MeshResult(trimesh.Trimesh(), "empty", 0)
    if values.max() < 0:
        return MeshResult(trimesh.Trimesh(), "full", 0)
    h = 2 * bound / n
    padded = np.pad(values.astype(np.float32), 1, constant_values=max(h, 1e-3))
    # a surface through a grid vertex makes zero-area triangles that break watertightness:
    # move such vertices off it, keeping their side (forcing them all outside turned a lone
    # vertex just inside a wall into a zero-size, inverted 8-face shell)
    t = 1e-4 * h
    near = np.abs(padded) < t
    padded[near] = np.where(padded[near] < 0, -t, t)
    verts, faces, _, _ = measure.marching_cubes(padded, level=0.0, spacing=(h, h, h),
                                                gradient_direction="descent")
    verts = verts - (bound + h)
    # skimage already shares vertices between faces; trimesh's processing (vertex merging)
    # would only cost time (~40-100 ms for a 45k-face part)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    return MeshResult(mesh, "ok", 0)


MIN_ISLAND = 8   # default: inside islands of <= 8 grid vertices (a 2x2x2 block) are removed


def remove_islands(values: np.ndarray, level: float = 0.0, max_vertices: int = MIN_ISLAND,
                   eps: Optional[float] = None) -> tuple[np.ndarray, int]:
    """Flip sign islands of a vertex grid: inside regions of at most ``max_vertices``
    vertices (connected through grid edges, the connectivity marching cubes keeps: vertices
    that only share a cell diagonal become separate shells) become outside, and every
    enclosed outside pocket (a void: outside vertices that do not reach the grid's boundary)
    becomes inside, whatever its size.

    Small islands are below what the grid resolves (a feature needs more than a 2x2x2 block of
    vertices to be meshed faithfully); in decoded fields they are the network's sign noise —
    isolated specks at box corners — and each one is a separate 8-to-48-face shell after
    marching cubes. Voids are sign errors: no part of the data encloses one (0 of 300
    held-out parts), while the decodes of 12 of them did, in a carcass's plinth or a cap's
    skirt (inside the true part's solid) and in door panels (docs/geometry.md). Larger
    inside fragments (a shredded wall) are kept: this removes noise and sealed pockets, it
    does not hide damage. Flipped vertices get ``level +- eps`` (default 1 % of the field's
    largest magnitude). ``max_vertices`` <= 0 removes nothing. -> (values, islands removed)."""
    from scipy import ndimage
    if max_vertices <= 0:
        return values, 0
    out = None
    removed = 0
    conn = ndimage.generate_binary_structure(3, 1)
    h = eps if eps is not None else float(np.abs(values - level).max()) * 0.01 + 1e-9
    for inside_side in (True, False):
        mask = values < level if inside_side else values >= level
        lab, n = ndimage.label(mask, structure=conn)
        if n <= 1:
            continue
        sizes = np.bincount(lab.ravel(), minlength=n + 1)
        # outside regions: every one that does not reach the boundary is a void
        small = sizes[1:] <= max_vertices if inside_side else np.ones(n, bool)
        small = np.concatenate([[False], small])
        if inside_side and small[1:].all():
            # every inside region is tiny: keep the largest (the part itself is tiny)
            small[int(np.argmax(sizes[1:])) + 1] = False
        if not inside_side:
            # outside regions touching the grid boundary are the part's exterior, never a bubble
            for face in (lab[[0, -1]], lab[:, [0, -1]], lab[:, :, [0, -1]]):
                small[np.unique(face)] = False
        if not small.any():
            continue
        if out is None:
            out = values.copy()
        out[small[lab]] = level + h if inside_side else level - h
        removed += int(small.sum())
    return (values if out is None else out), removed


@dataclass
class SdfGrid:
    """One part's SDF on the (n+1)^3 vertex grid over [-bound, bound]^3 (what the network's
    coarse-to-fine evaluation hands to marching cubes)."""
    values: np.ndarray      # (n+1, n+1, n+1) float32
    evaluations: int        # SDF evaluations spent on it
    bound: float = 1.0
    level: float = 0.0      # the iso-value to mesh


def mesh_grid(grid: SdfGrid, min_island: int = MIN_ISLAND) -> MeshResult:
    """Island removal (:func:`remove_islands`) and marching cubes of one evaluated grid."""
    n = grid.values.shape[0] - 1
    v, _ = remove_islands(grid.values, grid.level, min_island, eps=0.25 * 2 * grid.bound / n)
    r = marching_cubes(v, grid.bound, grid.level)
    r.evaluations = int(grid.evaluations)
    r.inside = v < grid.level
    r.bound = grid.bound
    return r


def fit_to_bbox(mesh, center, size, min_size: float = 1e-4):
    """Scale (per axis) and move a mesh so its bounds become the box (center, size).

    Returns a new mesh; an empty mesh comes back empty.
    """
    m = mesh.copy()
    if len(m.vertices) == 0:
        return m
    lo, hi = m.bounds
    ext = np.maximum(hi - lo, 1e-9)
    size = np.maximum(np.asarray(size, dtype=np.float64).reshape(3), min_size)
    center = np.asarray(center, dtype=np.float64).reshape(3)
    m.vertices = (np.asarray(m.vertices) - (lo + hi) / 2.0) * (size / ext) + center
    return m


def components(mesh) -> tuple[int, np.ndarray]:
    """Connected components of a mesh's faces (faces sharing a vertex are connected; marching
    cubes shares vertices between faces). -> (count, component id per face)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    f = np.asarray(mesh.faces)
    if len(f) == 0:
        return 0, np.zeros(0, dtype=np.int64)
    nv = len(mesh.vertices)
    a = np.concatenate([f[:, 0], f[:, 1]])
    b = np.concatenate([f[:, 1], f[:, 2]])
    g = coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(nv, nv))
    _, lab = connected_components(g, directed=False)
    fl = lab[f[:, 0]]
    uniq, inv = np.unique(fl, return_inverse=True)
    return len(uniq), inv


def keep_largest_components(mesh, k: int = 1):
    """The ``k`` components with the largest surface area (a new mesh; unused vertices
    dropped)."""
    import trimesh
    n, lab = components(mesh)
    if n <= k:
        return mesh.copy()
    keep = np.argsort(-np.bincount(lab, weights=np.asarray(mesh.area_faces)))[:k]
    faces = np.asarray(mesh.faces)[np.isin(lab, keep)]
    used, inv = np.unique(faces, return_inverse=True)
    return trimesh.Trimesh(np.asarray(mesh.vertices)[used], inv.reshape(-1, 3), process=False)
