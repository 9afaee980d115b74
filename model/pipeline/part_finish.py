"""What happens to one part between the SDF network and refinement, in any process.

The network's half of meshing (``ShapeModel.decode_grids``) runs on torch in the main
process; everything after it needs only this part's grid and box: island removal and
marching cubes, fitting into the predicted box, collision boxes from the grid's occupancy,
and the refinement's per-part preparation (closed manifold, floaters, first simplification
step). :func:`finish_part` does that from a :class:`PartTask`, imports no torch, and
returns plain arrays, so ``model.pipeline.part_pool`` can run it in a helper process.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from model.geometry.surface import MIN_ISLAND, SdfGrid, fit_to_bbox, mesh_grid


@dataclass
class PartTask:
    index: int                   # the part's index in its object
    grid: SdfGrid
    center: np.ndarray           # (3,) the part's box in the object frame
    size: np.ndarray             # (3,)
    min_island: int = MIN_ISLAND
    prepare: bool = True         # also prepare the refinement's mesh (model.refine.prepare)
    floaters: bool = True        # ... dropping floaters
    simplify: bool = True        # ... and taking the first simplification steps

    @property
    def cost(self) -> float:     # work after the network follows the surface it evaluated
        return float(self.grid.evaluations)


@dataclass
class PartDone:
    index: int
    status: str                            # "ok" | "empty" | "full" (no surface)
    evaluations: int
    vertices: Optional[np.ndarray] = None  # the fitted mesh (object frame)
    faces: Optional[np.ndarray] = None
    boxes: Optional[list] = None           # collision boxes: (extents (3,), transform (4, 4))
    prepared: Optional[object] = None      # model.refine.prepare.PreparedMesh

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def moved(self, index: int, offset) -> "PartDone":
        """This result for part ``index``, an identical box ``offset`` (m) away."""
        d = np.asarray(offset, dtype=np.float64)
        if not self.ok:
            return PartDone(index, self.status, 0)

        def shift(T):
            T = np.array(T, dtype=np.float64)
            T[:3, 3] += d
            return T
        return PartDone(index, self.status, 0, self.vertices + d, self.faces,
                        None if self.boxes is None else [(e, shift(T)) for e, T in self.boxes],
                        None if self.prepared is None else self.prepared.moved(d))

    def mesh(self):
        import trimesh
        return trimesh.Trimesh(self.vertices, self.faces, process=False)

    def collision(self) -> Optional[list]:
        import trimesh
        if self.boxes is None:
            return None
        return [trimesh.primitives.Box(extents=e, transform=T) for e, T in self.boxes]


def finish_part(task: PartTask) -> PartDone:
    r = mesh_grid(task.grid, task.min_island)
    if not r.ok:
        return PartDone(task.index, r.status, r.evaluations)
    fitted = fit_to_bbox(r.mesh, task.center, task.size)
    boxes = collision_boxes(r, fitted)
    prepared = None
    if task.prepare:
        from model.refine.prepare import STEPS_AHEAD, prepare_mesh
        prepared = prepare_mesh(fitted, task.floaters, STEPS_AHEAD if task.simplify else 0)
    return PartDone(task.index, r.status, r.evaluations,
                    np.asarray(fitted.vertices, dtype=np.float64),
                    np.asarray(fitted.faces, dtype=np.int64),
                    None if boxes is None else [(np.array(b.primitive.extents),
                                                 np.array(b.primitive.transform))
                                                for b in boxes],
                    prepared)


def finish_parts(tasks: list) -> list:
    return [finish_part(t) for t in tasks]


def collision_boxes(r, fitted, max_boxes: int = 32, min_coverage: float = 0.0,
                    layer_fill: float = 0.8):
    """Collision boxes of a generated part from its SDF cell occupancy (``r.inside`` over the
    meshing cube), mapped by the same per-axis scale and shift that fitted the mesh to its
    box. Box-like parts (panels, carcasses, drawers) come out as a few exact boxes in
    milliseconds; when ``max_boxes`` cannot cover ``min_coverage`` of the solid (round
    shapes), None leaves the choice to the exporter (hull if convex, else V-HACD)."""
    from model.export.collision import occupancy_boxes

    if r.inside is None or not r.inside.any():
        return None
    lo_m, hi_m = np.asarray(r.mesh.bounds, dtype=np.float64)
    lo_f, hi_f = np.asarray(fitted.bounds, dtype=np.float64)
    scale = (hi_f - lo_f) / np.maximum(hi_m - lo_m, 1e-9)
    bound = r.bound
    # vertex v of the (n+1)^3 grid owns the cell [v - h/2, v + h/2]^3 (its dual cell)
    half = bound + bound / (r.inside.shape[0] - 1)
    lo = (-half - (lo_m + hi_m) / 2.0) * scale + (lo_f + hi_f) / 2.0
    hi = (half - (lo_m + hi_m) / 2.0) * scale + (lo_f + hi_f) / 2.0
    boxes, covered = occupancy_boxes(r.inside, lo, hi, max_boxes=max_boxes, layer_fill=layer_fill)
    if not boxes or covered < min_coverage:
        return None
    return [b for b in (_clipped(b, lo_f, hi_f) for b in boxes) if b is not None]


def _clipped(box, lo, hi):
    """An axis-aligned collision box cut to the part's mesh bounds: a surface cell's dual
    cell reaches half a cell past the mesh, and two doors meshed 2 mm apart then touch in
    the simulator and hold each other shut. None when nothing is left."""
    import trimesh
    c = np.asarray(box.primitive.transform, dtype=np.float64)[:3, 3]
    e = np.asarray(box.primitive.extents, dtype=np.float64)
    blo, bhi = np.maximum(c - e / 2, lo), np.minimum(c + e / 2, hi)
    if np.any(bhi - blo <= 1e-6):
        return None
    T = np.eye(4)
    T[:3, 3] = (blo + bhi) / 2
    return trimesh.primitives.Box(extents=bhi - blo, transform=T)
