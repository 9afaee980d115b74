"""Fast meshing of SDFs: coarse-to-fine evaluation + marching cubes (DESIGN §4.3).

The SDF is evaluated on a coarse vertex grid over [-bound, bound]^3, then the resolution is
doubled level by level: the previous level is upsampled trilinearly and only the vertices
that the upsampled field puts near the surface (|sdf| < band x the cell diagonal) and that
were not evaluated before get the network's value; the others keep the interpolated value
(far from the surface only its sign matters). The finest level takes a narrower band and
closes it instead: every vertex at an end of a grid edge that changes sign gets its true
value, until none is left interpolated, so marching cubes only reads the network's values.
Network calls go in chunks of 32k points
(larger buffers measured 1.6x slower: page faults on every fresh allocation).
``skimage.measure.marching_cubes(level=0)`` then runs on the finest grid, padded with one
layer of "outside" so every surface is closed.

A part whose grid has no zero crossing gets an empty mesh and ``status`` "empty" (all
outside) or "full" (all inside): callers decide (the pipeline can fall back to its bbox).
"""
from __future__ import annotations

import logging
from typing import Callable, Optional

import numpy as np
import torch
import torch.nn.functional as F

from .surface import (MIN_ISLAND, MeshResult, SdfGrid, components,  # noqa: F401
                      fit_to_bbox, keep_largest_components, marching_cubes, mesh_grid,
                      remove_islands)

log = logging.getLogger(__name__)

SdfFn = Callable[[torch.Tensor], torch.Tensor]   # xyz (B, N, 3) -> sdf (B, N)

# The finest level's band, closed over sign-changing edges (evaluate_grid). On the 119 parts
# of the 20 bench prompts: 0.75 gives the same signs as evaluating every vertex (19.5 M) with
# 25 % fewer evaluations than band 1.5 unclosed (0.5: 2 signs differ).
FINAL_BAND = 0.75


def grid_levels(resolution: int, min_coarse: int = 16) -> list[int]:
    """Cells per side of each level, coarse to fine: 64 -> [16, 32, 64]."""
    levels = [int(resolution)]
    while levels[-1] % 2 == 0 and levels[-1] // 2 >= min_coarse:
        levels.append(levels[-1] // 2)
    return levels[::-1]


def _vertices(n: int, bound: float) -> torch.Tensor:
    return torch.linspace(-bound, bound, n + 1)


@torch.inference_mode()
def evaluate_grid(sdf_fn: SdfFn, batch: int, resolution: int = 64, *, bound: float = 1.0,
                  band: float = 1.5, min_coarse: int = 16, chunk: int = 32_768,
                  level: float = 0.0, final_band: Optional[float] = FINAL_BAND
                  ) -> tuple[torch.Tensor, torch.Tensor]:
    """SDF values on the (resolution+1)^3 vertex grid of ``batch`` parts, coarse to fine.

    ``level``: the iso-value that will be meshed (the refinement band is centred on it).
    ``final_band``: the finest level evaluates only this band (cell diagonals) and then
    closes it: every vertex of a grid edge whose ends differ in sign gets its true value,
    repeated until no such edge has an interpolated end, so marching cubes reads true
    values only; None uses ``band`` there too, without closing.
    Returns (values (B, n+1, n+1, n+1), evaluations per part (B,)).
    """
    levels = grid_levels(resolution, min_coarse)
    evals = torch.zeros(batch, dtype=torch.long)
    values = exact = None
    for li, n in enumerate(levels):
        ax = _vertices(n, bound)
        last = li == len(levels) - 1 and li > 0
        if li == 0:
            mask = torch.ones(batch, n + 1, n + 1, n + 1, dtype=torch.bool)
            values = torch.zeros(batch, n + 1, n + 1, n + 1)
        else:
            h = 2 * bound / n
            values = F.interpolate(values.unsqueeze(1), size=(n + 1,) * 3, mode="trilinear",
                                   align_corners=True).squeeze(1)
            # A vertex needs its true value when the upsampled field puts it within ``band``
            # cell diagonals of the surface; farther out only its sign matters, and the
            # interpolation has it right (measured on generated parts: band 1.5 gives the
            # same signs as evaluating all 65^3 vertices, band 1.0 misses 12 of 4.9 M).
            b = final_band if last and final_band is not None else band
            mask = (values - level).abs() < b * h * 3 ** 0.5
            ex = torch.zeros(batch, n + 1, n + 1, n + 1, dtype=torch.bool)
            ex[:, ::2, ::2, ::2] = exact
            mask &= ~ex
            exact = ex
        evals += _evaluate(sdf_fn, values, mask, ax, chunk)
        exact = mask if li == 0 else (exact | mask)
        while last and final_band is not None:
            mask = _sign_edge_ends(values < level) & ~exact
            if not mask.any():
                break
            evals += _evaluate(sdf_fn, values, mask, ax, chunk)
            exact |= mask
    return values, evals


def _sign_edge_ends(inside: torch.Tensor) -> torch.Tensor:
    """(B, n+1, n+1, n+1) bool -> the vertices at an end of a grid edge that changes sign."""
    out = torch.zeros_like(inside)
    for d in (1, 2, 3):
        n = inside.shape[d]
        ch = inside.narrow(d, 1, n - 1) != inside.narrow(d, 0, n - 1)
        out.narrow(d, 1, n - 1).logical_or_(ch)
        out.narrow(d, 0, n - 1).logical_or_(ch)
    return out


def _evaluate(sdf_fn: SdfFn, values: torch.Tensor, mask: torch.Tensor, ax: torch.Tensor,
              chunk: int) -> torch.Tensor:
    """The network's value at every ``mask`` vertex, written into ``values`` -> evaluations
    per part (B,)."""
    batch = values.shape[0]
    idx = mask.nonzero()                       # (M, 4), row-major order: grouped by part
    counts = torch.bincount(idx[:, 0], minlength=batch)                # (B,)
    if idx.shape[0]:
        maxc = int(counts.max())
        starts = torch.cumsum(counts, 0) - counts
        slot = torch.arange(idx.shape[0]) - starts[idx[:, 0]]          # (M,)
        xyz = torch.zeros(batch, maxc, 3)
        xyz[idx[:, 0], slot] = torch.stack([ax[idx[:, 1]], ax[idx[:, 2]], ax[idx[:, 3]]], -1)
        out = torch.empty(batch, maxc)
        step = max(1, chunk // max(batch, 1))
        for s in range(0, maxc, step):
            out[:, s:s + step] = sdf_fn(xyz[:, s:s + step]).float()
        values[idx[:, 0], idx[:, 1], idx[:, 2], idx[:, 3]] = out[idx[:, 0], slot]
    return counts


def evaluate_grids(sdf_fn: SdfFn, batch: int, resolution: int = 64, *, bound: float = 1.0,
                   band: float = 1.5, min_coarse: int = 16, level: float = 0.0,
                   final_band: Optional[float] = FINAL_BAND) -> list[SdfGrid]:
    """:func:`evaluate_grid` as one :class:`SdfGrid` per part (numpy, ready for meshing)."""
    values, evals = evaluate_grid(sdf_fn, batch, resolution, bound=bound, band=band,
                                  min_coarse=min_coarse, level=level, final_band=final_band)
    return [SdfGrid(values[b].numpy(), int(evals[b]), bound, level) for b in range(batch)]


def mesh_sdf_batch(sdf_fn: SdfFn, batch: int, resolution: int = 64, *, bound: float = 1.0,
                   band: float = 1.5, min_coarse: int = 16, level: float = 0.0,
                   min_island: int = MIN_ISLAND,
                   final_band: Optional[float] = FINAL_BAND) -> list[MeshResult]:
    """Mesh ``batch`` SDFs at once (one batched network call per level).

    ``level``: the iso-value meshed; ``min_island``: sign islands of at most this many
    vertices are removed first (:func:`remove_islands`; 0 keeps them)."""
    grids = evaluate_grids(sdf_fn, batch, resolution, bound=bound, band=band,
                           min_coarse=min_coarse, level=level, final_band=final_band)
    return [mesh_grid(g, min_island) for g in grids]
