"""Exact mesh booleans and volumes through manifold3d (DESIGN §7: POR; §3.1: collision checks).

All functions take ``trimesh.Trimesh`` (or an already converted ``manifold3d.Manifold``) and
return plain floats or trimesh meshes.

Watertightness
--------------
manifold3d only accepts closed, oriented 2-manifolds. :func:`to_manifold` first tries the mesh
as given, then a light repair (merge duplicate vertices, drop degenerate / duplicate faces, fix
winding, fill small holes). If the mesh is still not a closed manifold it raises
:class:`NotWatertightError` — unless ``fallback="hull"`` is given, in which case the convex hull
of the vertices is used (an over-estimate of the solid, logged as a warning). Callers that score
generated meshes (POR) should keep the default and count failures: a silent fallback would bias
the metric.

Example::

    from model.core import meshops
    iou = meshops.volume_iou(mesh_a, mesh_b)          # exact, milliseconds
    v = meshops.intersection_volume(mesh_a, mesh_b)   # m³
"""
from __future__ import annotations

import logging
from typing import Iterable, Sequence, Union

import numpy as np

log = logging.getLogger(__name__)

MeshLike = Union["trimesh.Trimesh", "manifold3d.Manifold"]  # noqa: F821


class NotWatertightError(ValueError):
    """The mesh is not a closed 2-manifold, even after a light repair."""


def _mf():
    import manifold3d
    return manifold3d


# ---------------------------------------------------------------------------------------------
# conversion
# ---------------------------------------------------------------------------------------------
def _manifold_from_arrays(vertices: np.ndarray, faces: np.ndarray):
    mf = _mf()
    mesh = mf.Mesh(vert_properties=np.ascontiguousarray(vertices, dtype=np.float32),
                   tri_verts=np.ascontiguousarray(faces, dtype=np.uint32))
    return mf.Manifold(mesh)


def _ok(man) -> bool:
    return man.status() == _mf().Error.NoError


def to_manifold(mesh: MeshLike, *, fallback: str = "error", repair: bool = True):
    """trimesh → manifold3d.Manifold.

    fallback: ``"error"`` (default) raises :class:`NotWatertightError` for meshes that are not
    closed manifolds after a light repair; ``"hull"`` uses the convex hull instead.
    repair: False skips the light repair (the mesh must be closed as given).
    An empty mesh gives an empty Manifold (volume 0).
    """
    mf = _mf()
    if isinstance(mesh, mf.Manifold):
        return mesh
    if fallback not in ("error", "hull"):
        raise ValueError(f"fallback must be 'error' or 'hull', got {fallback!r}")
    V = np.asarray(mesh.vertices, dtype=np.float64)
    F = np.asarray(mesh.faces, dtype=np.int64)
    if len(F) == 0:
        return mf.Manifold()
    if not np.all(np.isfinite(V)):
        raise NotWatertightError("mesh has non-finite vertices")
    man = _manifold_from_arrays(V, F)
    if _ok(man):
        return man
    repaired = _repair(mesh) if repair else None
    if repaired is not None:
        man = _manifold_from_arrays(repaired.vertices, repaired.faces)
        if _ok(man):
            return man
    if fallback == "hull":
        log.warning("mesh with %d faces is not watertight; using its convex hull", len(F))
        return hull(V)
    raise NotWatertightError(
        f"mesh with {len(V)} vertices / {len(F)} faces is not a closed 2-manifold "
        f"(manifold3d: {man.status().name}); make it watertight first "
        f"(e.g. model.data.preprocess.make_watertight) or pass fallback='hull'")


def _repair(mesh):
    """Merge vertices, drop degenerate/duplicate faces, fix winding, fill holes; None on failure."""
    try:
        import trimesh
        m = trimesh.Trimesh(vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces),
                            process=True, validate=True)
        m.merge_vertices()
        m.update_faces(m.unique_faces())
        m.update_faces(m.nondegenerate_faces())
        m.remove_unreferenced_vertices()
        trimesh.repair.fix_winding(m)
        trimesh.repair.fill_holes(m)
        trimesh.repair.fix_normals(m)
        return m
    except Exception as e:  # repair is best effort; the caller reports the failure
        log.debug("mesh repair failed: %s", e)
        return None


def hull(points: np.ndarray):
    """Convex hull of points as a Manifold."""
    return _mf().Manifold.hull_points(np.ascontiguousarray(points, dtype=np.float64))


def to_trimesh(man) -> "trimesh.Trimesh":  # noqa: F821
    """manifold3d.Manifold → trimesh.Trimesh (watertight by construction)."""
    import trimesh
    m = man.to_mesh()
    V = np.asarray(m.vert_properties, dtype=np.float64)[:, :3]  # (N, 3)
    F = np.asarray(m.tri_verts, dtype=np.int64)                  # (M, 3)
    return trimesh.Trimesh(vertices=V, faces=F, process=False)


def pack(man) -> tuple[np.ndarray, np.ndarray]:
    """A Manifold as plain arrays (float64 vertices (N, 3), uint64 triangles (M, 3)) that
    pickle between processes; :func:`unpack` rebuilds it with the same vertices."""
    m = man.to_mesh64()
    return (np.array(m.vert_properties, dtype=np.float64)[:, :3].copy(),
            np.array(m.tri_verts, dtype=np.uint64))


def unpack(packed: tuple[np.ndarray, np.ndarray]):
    """:func:`pack`'s arrays -> a Manifold (empty for no triangles)."""
    mf = _mf()
    V, F = packed
    if len(F) == 0:
        return mf.Manifold()
    man = mf.Manifold(mf.Mesh64(vert_properties=np.array(V, dtype=np.float64, order="C"),
                                tri_verts=np.array(F, dtype=np.uint64, order="C")))
    if not _ok(man):
        raise NotWatertightError(f"packed mesh is not a closed manifold ({man.status().name})")
    return man


def separate_coincident(mesh: "trimesh.Trimesh", eps: float = 2e-6) -> "trimesh.Trimesh":  # noqa: F821
    """``mesh`` (a closed manifold's triangles, unmerged) with every vertex that shares its
    exact position with an earlier one moved ``eps`` into the solid along its normal. A
    manifold's simplification or booleans can leave two sheets touching along a line or at
    a point, held apart only by vertex identity; a file keeps positions, not identity, so
    any reader that merges vertices (most do) would see edges of four faces and an open
    mesh. A couple of micrometres keeps them apart."""
    V = np.asarray(mesh.vertices, dtype=np.float64)
    _, first, inverse = np.unique(V, axis=0, return_index=True, return_inverse=True)
    dup = first[inverse.reshape(-1)] != np.arange(len(V))
    if not dup.any():
        return mesh
    out = mesh.copy()
    out.vertices[dup] = V[dup] - eps * np.asarray(mesh.vertex_normals)[dup]
    return out


def drop_degenerate(mesh: "trimesh.Trimesh", height: float = 1e-9) -> "trimesh.Trimesh":  # noqa: F821
    """``mesh`` without its zero-area slivers (faces under ``height`` tall, which exact
    booleans leave where cuts graze each other), coincident vertices merged. Such a face has
    no area and no neighbour across its collapsed edge, so mesh tools count it as a loose
    component and the mesh as open. Returned only when it stays closed where ``mesh`` was
    closed after merging; otherwise ``mesh`` itself."""
    m = mesh.copy()
    m.merge_vertices()
    keep = m.nondegenerate_faces(height=height)
    if keep.all():
        return mesh
    closed = m.is_watertight
    m.update_faces(keep)
    m.remove_unreferenced_vertices()
    return m if (m.is_watertight or not closed) else mesh


def edge_pieces(mesh) -> tuple[np.ndarray, np.ndarray]:
    """The pieces of a mesh whose faces share edges (what a reader sees as separate shells):
    (piece label per face, surface area per piece)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    F = len(mesh.faces)
    adj = np.asarray(mesh.face_adjacency)
    g = coo_matrix((np.ones(len(adj)), (adj[:, 0], adj[:, 1])), shape=(F, F)) if len(adj) \
        else coo_matrix((F, F))
    n, labels = connected_components(g, directed=False)
    return labels, np.bincount(labels, weights=np.asarray(mesh.area_faces), minlength=n)


# ---------------------------------------------------------------------------------------------
# measures
# ---------------------------------------------------------------------------------------------
def volume(mesh: MeshLike, *, fallback: str = "error") -> float:
    """Enclosed volume (m³) of a watertight mesh."""
    return float(to_manifold(mesh, fallback=fallback).volume())


def _bounds_overlap(a, b, pad: float = 0.0) -> bool:
    ba, bb = a.bounding_box(), b.bounding_box()
    return all(ba[i] - pad <= bb[i + 3] and bb[i] - pad <= ba[i + 3] for i in range(3))


def intersection(a: MeshLike, b: MeshLike, *, fallback: str = "error"):
    """Exact A ∩ B as a trimesh mesh (possibly empty)."""
    ma, mb = to_manifold(a, fallback=fallback), to_manifold(b, fallback=fallback)
    return to_trimesh(ma ^ mb)


def intersection_volume(a: MeshLike, b: MeshLike, *, fallback: str = "error") -> float:
    """Exact volume of A ∩ B (m³). Parts that only touch at faces give ~0."""
    ma, mb = to_manifold(a, fallback=fallback), to_manifold(b, fallback=fallback)
    if ma.is_empty() or mb.is_empty() or not _bounds_overlap(ma, mb):
        return 0.0
    return max(0.0, float((ma ^ mb).volume()))


def volume_iou(a: MeshLike, b: MeshLike, *, fallback: str = "error") -> float:
    """|A ∩ B| / |A ∪ B| of two watertight meshes; 0 when both are empty."""
    ma, mb = to_manifold(a, fallback=fallback), to_manifold(b, fallback=fallback)
    va, vb = float(ma.volume()), float(mb.volume())
    inter = 0.0
    if not (ma.is_empty() or mb.is_empty()) and _bounds_overlap(ma, mb):
        inter = max(0.0, float((ma ^ mb).volume()))
    uni = va + vb - inter
    return inter / uni if uni > 0 else 0.0


def union(meshes: Iterable[MeshLike], *, fallback: str = "error") -> "trimesh.Trimesh":  # noqa: F821
    """Exact union of several watertight meshes as one trimesh mesh."""
    mans = [to_manifold(m, fallback=fallback) for m in meshes]
    if not mans:
        return to_trimesh(_mf().Manifold())
    return to_trimesh(union_manifolds(mans))


def union_manifolds(mans: Sequence):
    mf = _mf()
    if len(mans) == 1:
        return mans[0]
    return mf.Manifold.batch_boolean(list(mans), mf.OpType.Add)


def difference(a: MeshLike, *others: MeshLike, fallback: str = "error") -> "trimesh.Trimesh":  # noqa: F821
    """Exact A minus every other mesh."""
    mf = _mf()
    mans = [to_manifold(a, fallback=fallback)] + [to_manifold(o, fallback=fallback) for o in others]
    return to_trimesh(mf.Manifold.batch_boolean(mans, mf.OpType.Subtract))


def pairwise_intersection_volumes(meshes: Sequence[MeshLike], *, fallback: str = "error",
                                  pad: float = 0.0) -> np.ndarray:
    """(N, N) symmetric matrix of exact intersection volumes (diagonal = own volume).

    Pairs whose bounding boxes (grown by ``pad``) do not overlap are skipped (0).
    """
    mans = [to_manifold(m, fallback=fallback) for m in meshes]
    n = len(mans)
    out = np.zeros((n, n))
    for i in range(n):
        out[i, i] = float(mans[i].volume())
        for j in range(i + 1, n):
            if mans[i].is_empty() or mans[j].is_empty() or not _bounds_overlap(mans[i], mans[j], pad):
                continue
            out[i, j] = out[j, i] = max(0.0, float((mans[i] ^ mans[j]).volume()))
    return out


def pairwise_iou(meshes: Sequence[MeshLike], *, fallback: str = "error") -> np.ndarray:
    """(N, N) volume IoU of every pair (diagonal 1 for non-empty meshes)."""
    inter = pairwise_intersection_volumes(meshes, fallback=fallback)
    vol = np.diag(inter).copy()
    uni = vol[:, None] + vol[None, :] - inter
    with np.errstate(divide="ignore", invalid="ignore"):
        iou = np.where(uni > 0, inter / np.where(uni > 0, uni, 1.0), 0.0)
    return iou


# ---------------------------------------------------------------------------------------------
# primitives (Manifold) used by the procedural generator
# ---------------------------------------------------------------------------------------------
def box(size: Sequence[float], center: Sequence[float] = (0.0, 0.0, 0.0)):
    """Axis-aligned box Manifold of ``size`` centred at ``center``."""
    return _mf().Manifold.cube([float(s) for s in size], True).translate([float(c) for c in center])


def cylinder(radius: float, height: float, center: Sequence[float] = (0.0, 0.0, 0.0),
             axis: str = "z", segments: int = 32, radius_top: float | None = None):
    """Cylinder (or frustum) Manifold along a principal axis, centred at ``center``."""
    mf = _mf()
    rt = radius if radius_top is None else radius_top
    c = mf.Manifold.cylinder(float(height), float(radius), float(rt), int(segments), True)
    if axis == "x":
        c = c.rotate([0.0, 90.0, 0.0])
    elif axis == "y":
        c = c.rotate([90.0, 0.0, 0.0])
    elif axis != "z":
        raise ValueError(f"axis must be x, y or z, got {axis!r}")
    return c.translate([float(v) for v in center])


def sphere(radius: float, center: Sequence[float] = (0.0, 0.0, 0.0), segments: int = 24):
    return _mf().Manifold.sphere(float(radius), int(segments)).translate([float(v) for v in center])


def affine34(T: np.ndarray) -> np.ndarray:
    """The 3x4 affine part of a 4x4 transform, as manifold3d's ``transform`` takes it."""
    return np.ascontiguousarray(np.asarray(T)[:3, :4], dtype=np.float64)


def axis_line(origin: Sequence[float], axis: Sequence[float], length: float):
    """A thin cylinder (radius 0.1 mm) along a joint axis line, centred on its origin."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    ref = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(a, ref)
    u /= np.linalg.norm(u)
    M = np.column_stack([u, np.cross(a, u), a, np.asarray(origin, dtype=np.float64)])
    return cylinder(1e-4, length, segments=8).transform(M)
