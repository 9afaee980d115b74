"""Coarse-to-fine meshing on analytic SDFs, the no-surface case and bbox fitting."""
import math

import numpy as np
import pytest
import torch

from model.geometry.meshing import (evaluate_grid, fit_to_bbox, grid_levels, marching_cubes,
                                    mesh_sdf_batch)

torch.set_num_threads(1)


def sphere(r):
    return lambda x: x.norm(dim=-1) - r


def box(half):
    h = torch.tensor(half)

    def f(x):
        q = x.abs() - h
        return q.clamp_min(0).norm(dim=-1) + q.max(-1).values.clamp_max(0)
    return f


def test_levels():
    assert grid_levels(64) == [16, 32, 64]
    assert grid_levels(50) == [25, 50]


def test_sphere_area_and_volume():
    r = 0.7
    res = mesh_sdf_batch(sphere(r), 1, 64)[0]
    assert res.ok
    m = res.mesh
    assert m.is_watertight
    assert m.volume == pytest.approx(4 / 3 * math.pi * r ** 3, rel=0.01)
    assert m.area == pytest.approx(4 * math.pi * r ** 2, rel=0.01)
    assert res.evaluations < 0.4 * 65 ** 3          # coarse-to-fine skipped most of the grid


def test_coarse_to_fine_matches_dense_near_surface():
    # the unclosed band: every vertex within 1.5 cell diagonals holds the true value
    values, _ = evaluate_grid(sphere(0.5), 1, 32, final_band=None)
    ax = torch.linspace(-1, 1, 33)
    X, Y, Z = torch.meshgrid(ax, ax, ax, indexing="ij")
    dense = torch.stack([X, Y, Z], -1).norm(dim=-1) - 0.5
    near = dense.abs() < 0.1
    assert torch.allclose(values[0][near], dense[near], atol=1e-5)
    assert torch.equal(values[0] < 0, dense < 0)
    closed, _ = evaluate_grid(sphere(0.5), 1, 32)       # default: narrower, closed
    assert torch.equal(closed[0] < 0, dense < 0)


def test_thin_and_flat_boxes_are_watertight_and_batched():
    fns = [box([0.9, 0.5, 0.05]), box([0.9, 0.02, 0.3]), sphere(0.3)]

    def batched(x):   # (3, N, 3)
        return torch.stack([f(x[i]) for i, f in enumerate(fns)])
    res = mesh_sdf_batch(batched, 3, 64)
    expect = [8 * 0.9 * 0.5 * 0.05, 8 * 0.9 * 0.02 * 0.3, 4 / 3 * math.pi * 0.027]
    for r, v in zip(res, expect):
        assert r.ok and r.mesh.is_watertight
        assert r.mesh.volume == pytest.approx(v, rel=0.1)


def test_no_surface_is_reported():
    empty, full = mesh_sdf_batch(lambda x: torch.stack([x[0].norm(dim=-1) + 0.5,
                                                        -x[1].norm(dim=-1) - 2.0]), 2, 32)
    assert empty.status == "empty" and not empty.ok and len(empty.mesh.vertices) == 0
    assert full.status == "full" and len(full.mesh.faces) == 0


def test_fit_to_bbox():
    m = mesh_sdf_batch(sphere(0.8), 1, 32)[0].mesh
    out = fit_to_bbox(m, [1.0, 2.0, 3.0], [0.2, 0.4, 0.1])
    lo, hi = out.bounds
    assert np.allclose((lo + hi) / 2, [1, 2, 3], atol=1e-9)
    assert np.allclose(hi - lo, [0.2, 0.4, 0.1], atol=1e-9)
    assert np.allclose(m.bounds, mesh_sdf_batch(sphere(0.8), 1, 32)[0].mesh.bounds)  # input untouched


def test_remove_islands_specks_and_bubbles():
    from model.geometry.meshing import components, remove_islands
    x = torch.linspace(-1, 1, 33)
    X, Y, Z = torch.meshgrid(x, x, x, indexing="ij")
    v = (torch.stack([X, Y, Z]).abs().amax(0) - 0.5).numpy()        # a cube of side 1
    v[2, 2, 2] = -0.1                                                # a speck outside it
    v[16, 16, 16] = 0.1                                              # a bubble inside it
    v[16, 16, 17] = 0.1
    out, n = remove_islands(v)
    assert n == 2 and out[2, 2, 2] > 0 and out[16, 16, 16] < 0 and out[16, 16, 17] < 0
    assert np.array_equal(out < 0, (v < 0) ^ np.isin(np.arange(v.size).reshape(v.shape),
                                                     [np.ravel_multi_index(i, v.shape) for i in
                                                      ((2, 2, 2), (16, 16, 16), (16, 16, 17))]))
    plain, clean = marching_cubes(v).mesh, marching_cubes(out).mesh
    assert components(plain)[0] == 3 and components(clean)[0] == 1 and clean.is_watertight
    # through mesh_sdf_batch (default on): the speck next to a sphere is gone, and from the
    # inside grid that collision boxes are built from
    speck = lambda p: torch.minimum(p.norm(dim=-1) - 0.6,  # noqa: E731
                                    _grid_sdf(np.where(np.arange(33)[:, None, None] * 0 + (
                                        np.indices((33, 33, 33)) == 1).all(0), -0.05, 0.05), p))
    r0 = mesh_sdf_batch(speck, 1, 32, min_island=0, band=1e9, final_band=None)[0]
    r1 = mesh_sdf_batch(speck, 1, 32, band=1e9, final_band=None)[0]
    assert components(r0.mesh)[0] == 2 and components(r1.mesh)[0] == 1
    assert r0.inside[1, 1, 1] and not r1.inside[1, 1, 1]
    # a large separate piece is kept: islands are noise, fragments are damage
    w = v.copy()
    w[1:5, 1:5, 1:5] = -0.1
    assert remove_islands(w)[1] == 1 and (remove_islands(w)[0][1:5, 1:5, 1:5] < 0).all()
    # a void of any size inside the solid is filled (no part of the data encloses one); a
    # cavity open to the outside is kept
    cav = v.copy()
    cav[10:23, 10:23, 12:21] = 0.1                                  # 13 x 13 x 9 = 1,521 vertices
    filled, n = remove_islands(cav)
    assert n == 2 and (filled[9:24, 9:24, 9:24] < 0).all()              # and the speck
    assert components(marching_cubes(cav).mesh)[0] == 3                # part, void, speck
    assert components(marching_cubes(filled).mesh)[0] == 1
    cav[10:23, 10:23, 12:33] = 0.1                                  # the same pocket, opened at the top
    opened, n = remove_islands(cav)
    assert (opened[10:23, 10:23, 12:21] > 0).all() and components(marching_cubes(opened).mesh)[0] == 1
    assert remove_islands(cav, max_vertices=0)[1] == 0
    # a part that is only a tiny island keeps it
    t = np.full((9, 9, 9), 0.1)
    t[4, 4, 4] = -0.1
    assert remove_islands(t)[0][4, 4, 4] < 0


def test_marching_cubes_keeps_the_side_of_vertices_on_the_surface():
    """A vertex within 1e-4 of a cell of the level is moved off it (zero-area triangles) on
    its own side: one just inside a solid made a zero-size inverted shell of its own."""
    from model.geometry.meshing import components
    x = torch.linspace(-1, 1, 33)
    X, Y, Z = torch.meshgrid(x, x, x, indexing="ij")
    v = (torch.stack([X, Y, Z]).abs().amax(0) - 0.5).numpy()        # a cube of side 1
    cube = marching_cubes(v).mesh
    v[16, 16, 16] = -1e-7                                            # inside, on the level
    v[16, 16, 20] = 1e-7                                             # outside, on the level
    m = marching_cubes(v).mesh
    assert components(m)[0] == 2 and m.is_watertight                # the cube, the bubble
    assert abs(m.volume - cube.volume) < 1e-6


def _grid_sdf(v, p):
    """Nearest-vertex lookup of a 33^3 grid over [-1, 1]^3 (for meshing a hand-made field)."""
    n = v.shape[0] - 1
    ijk = ((p + 1) / 2 * n).round().long().clamp(0, n)
    return torch.from_numpy(v)[ijk[..., 0], ijk[..., 1], ijk[..., 2]].float()


def test_final_band_closure_reads_only_true_values_at_the_surface():
    # a thin slab and a small sphere: everything marching cubes reads (both ends of every
    # edge that changes sign) must be the SDF's own value, with fewer evaluations than the
    # unclosed 1.5 band
    from model.geometry.meshing import _sign_edge_ends

    def f(x):
        slab = (x[..., 2] - 0.1).abs() - 0.03
        ball = (x - torch.tensor([0.5, -0.4, -0.5])).norm(dim=-1) - 0.12
        return torch.minimum(slab.clamp_min(-0.5), ball)

    closed, n_closed = evaluate_grid(f, 1, 64)
    wide, n_wide = evaluate_grid(f, 1, 64, final_band=None)
    ax = torch.linspace(-1, 1, 65)
    true = f(torch.stack(torch.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(1, -1, 3))
    true = true.reshape(1, 65, 65, 65)
    assert torch.equal(closed < 0, true < 0)
    ends = _sign_edge_ends(closed < 0)
    assert ends.any()
    assert torch.allclose(closed[ends], true[ends], atol=1e-6)
    assert int(n_closed) < 0.9 * int(n_wide)
