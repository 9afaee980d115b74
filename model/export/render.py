"""Offscreen rendering without a display: a vectorised numpy z-buffer rasteriser.

    imgs = render_views(obj, ratios=(0, 0.5, 1), size=224)            # (3, 224, 224, 3) uint8
    imgs = render_views(obj, (0.3,), 224, seed=7)                      # random view / light / colours
    write_preview(obj, "out/preview.png")                              # openness 0 | 0.5 | 1

Flat-shaded triangles (Lambert + ambient + Blinn specular, two-sided so open meshes render),
perspective camera looking at the object's centre. Every pixel candidate of every triangle's
screen bounding box is generated at once with ``np.repeat``, tested with edge functions and
resolved with a ``np.minimum.at`` z-buffer, so the cost is proportional to covered pixels, not to a
Python loop over triangles. Deterministic: the same object, options and seed give the same
image bit for bit.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from typing import Optional, Sequence

import numpy as np

_MAX_CANDIDATES = 400_000        # pixel candidates per chunk (bounds memory: ~20 arrays of it)


@dataclass
class RenderOptions:
    """Camera, lighting and colours. Angles in degrees; azimuth 0 looks at the front (+x)."""
    azimuth: float = 35.0           # camera around z, from +x towards +y
    elevation: float = 22.0         # camera above the horizon
    fov: float = 30.0               # vertical field of view
    margin: float = 1.08            # bounding sphere scale in the frame
    light_azimuth: float = 60.0     # light direction (from the object towards the light)
    light_elevation: float = 55.0
    ambient: float = 0.35
    diffuse: float = 0.65
    specular: float = 0.12
    shininess: float = 24.0
    background: tuple = (1.0, 1.0, 1.0)
    colour_mode: str = "label"      # "label": a colour per part label; "random": per part (seed)
    supersample: int = 2            # render at k× and box-filter down (anti-aliasing)


def random_options(seed: int, base: Optional[RenderOptions] = None) -> RenderOptions:
    """Viewpoint, lighting, background and part colours varied deterministically by ``seed``
    (for image-conditioning datasets)."""
    rng = np.random.default_rng(seed)
    base = base or RenderOptions()
    bg = float(rng.uniform(0.75, 1.0))
    return replace(base,
                   azimuth=float(rng.uniform(-70.0, 70.0)),
                   elevation=float(rng.uniform(5.0, 40.0)),
                   fov=float(rng.uniform(25.0, 40.0)),
                   light_azimuth=float(rng.uniform(-120.0, 120.0)),
                   light_elevation=float(rng.uniform(20.0, 80.0)),
                   ambient=float(rng.uniform(0.2, 0.5)),
                   diffuse=float(rng.uniform(0.5, 0.8)),
                   specular=float(rng.uniform(0.0, 0.25)),
                   background=tuple(np.clip(bg + rng.normal(0, 0.03, 3), 0, 1).tolist()),
                   colour_mode="random")


def _part_colours(obj, mode: str, seed: Optional[int]) -> list[np.ndarray]:
    from .urdf import DEFAULT_COLOUR, LABEL_COLOURS
    if mode == "label":
        return [np.array(LABEL_COLOURS.get(p.label, DEFAULT_COLOUR)) for p in obj.parts]
    if mode == "random":
        rng = np.random.default_rng(0 if seed is None else seed + 1)
        out = []
        for _ in obj.parts:
            h, s, v = rng.uniform(0, 1), rng.uniform(0.2, 0.7), rng.uniform(0.45, 0.95)
            out.append(_hsv_to_rgb(h, s, v))
        return out
    raise ValueError(f"colour_mode must be 'label' or 'random', got {mode!r}")


def _hsv_to_rgb(h, s, v) -> np.ndarray:
    i = int(h * 6.0) % 6
    f = h * 6.0 - int(h * 6.0)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    return np.array([(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)][i])


def _direction(azimuth: float, elevation: float) -> np.ndarray:
    a, e = math.radians(azimuth), math.radians(elevation)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def cluster_vertices(v: np.ndarray, f: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertex-clustering simplification: vertices in one ``cell``-sized grid cube merge into
    their mean; faces that collapse disappear. At pixel-sized cells the picture does not
    change, and a 70k-face marching-cubes handle a few pixels wide becomes a few hundred."""
    if cell <= 0 or len(f) == 0:
        return v, f
    _, inv = np.unique(np.floor(v / cell).astype(np.int64), axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    n = int(inv.max()) + 1
    cnt = np.bincount(inv, minlength=n).astype(np.float64)
    nv = np.stack([np.bincount(inv, weights=v[:, k], minlength=n) for k in range(3)], 1) / cnt[:, None]
    nf = inv[f]
    keep = (nf[:, 0] != nf[:, 1]) & (nf[:, 1] != nf[:, 2]) & (nf[:, 0] != nf[:, 2])
    return nv, nf[keep]


def _part_geometry(obj, cell: float = 0.0) -> list:
    """Per part (vertices, faces, closed) at rest; ``cell`` > 0 simplifies by vertex
    clustering. Faces of watertight, outward-wound meshes may be back-face culled."""
    out = []
    for p in obj.parts:
        if p.mesh is None or len(p.mesh.faces) == 0:
            out.append(None)
            continue
        try:
            is_closed = bool(p.mesh.is_watertight and p.mesh.volume > 0)
        except Exception:  # broken meshes: draw both sides
            is_closed = False
        v, f = np.asarray(p.mesh.vertices, dtype=np.float64), np.asarray(p.mesh.faces)
        if cell > 0:
            v, f = cluster_vertices(v, f, cell)
        out.append((v, f, is_closed))
    return out


def _scene(obj, ratio: float, colours, geometry: Optional[list] = None, dtype=np.float64
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Triangles (T, 3, 3), base colours (T, 3) and a closed-surface flag (T,) of the object
    posed at ``ratio`` (``geometry``: from ``_part_geometry``, default the full meshes)."""
    T = obj.link_transforms(ratio=ratio)
    geometry = _part_geometry(obj) if geometry is None else geometry
    tris, cols, closed = [], [], []
    for p, c, g in zip(obj.parts, colours, geometry):
        if g is None:
            continue
        v, f, is_closed = g
        v = v @ T[p.name][:3, :3].T + T[p.name][:3, 3]
        tris.append(v[f].astype(dtype, copy=False))                  # (F, 3, 3)
        cols.append(np.broadcast_to(c, (len(f), 3)))
        closed.append(np.full(len(f), is_closed))
    if not tris:
        return np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0, dtype=bool)
    return np.concatenate(tris), np.concatenate(cols), np.concatenate(closed)


def _rasterise(tris: np.ndarray, cols: np.ndarray, closed: np.ndarray, eye: np.ndarray,
               target: np.ndarray, fov: float, H: int, W: int, opt: RenderOptions,
               with_index: bool = False):
    """Flat-shaded z-buffer render; returns (H, W, 3) float in [0, 1], and with
    ``with_index`` also (H, W) int64: the triangle seen at each pixel (-1: background)."""
    img = np.empty((H, W, 3))
    img[:] = np.asarray(opt.background, dtype=np.float64)
    tbuf = np.full(H * W, -1, dtype=np.int64) if with_index else None
    if len(tris) == 0:
        return (img, tbuf.reshape(H, W)) if with_index else img
    fwd, right, cam_up = _camera_axes(eye, target)
    # per-triangle arithmetic in the triangles' precision (float32 for previews)
    eye, fwd, right, cam_up = (a.astype(tris.dtype) for a in (eye, fwd, right, cam_up))
    rel = tris - eye                                                 # (T, 3, 3)
    x, y, z = rel @ right, rel @ cam_up, rel @ fwd                   # (T, 3) each
    keep, shade = _cull_and_shade(tris, cols, closed, z, eye, opt)
    kept = np.nonzero(keep)[0]                                       # (K,) input triangle ids
    x, y, z = x[keep], y[keep], z[keep]
    f = 0.5 * H / math.tan(math.radians(fov) / 2.0)
    u = f * x / z + W / 2.0                                          # (K, 3) pixel coords
    v = H / 2.0 - f * y / z
    cbuf = img.reshape(-1, 3)
    _draw(u, v, z, shade, kept, cbuf, tbuf, H, W)
    img = np.clip(cbuf.reshape(H, W, 3), 0.0, 1.0)
    return (img, tbuf.reshape(H, W)) if with_index else img


def _camera_axes(eye: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit forward, right and up vectors (3,) of a camera at ``eye`` looking at ``target``
    with world +z up."""
    fwd = target - eye
    fwd /= np.linalg.norm(fwd)
    up = np.array([0.0, 0.0, 1.0])
    right = np.cross(fwd, up)
    if np.linalg.norm(right) < 1e-9:            # looking straight down / up
        right = np.array([0.0, -1.0, 0.0])
    right /= np.linalg.norm(right)
    cam_up = np.cross(right, fwd)
    return fwd, right, cam_up


def _cull_and_shade(tris: np.ndarray, cols: np.ndarray, closed: np.ndarray, z: np.ndarray,
                    eye: np.ndarray, opt: RenderOptions) -> tuple[np.ndarray, np.ndarray]:
    """Which of the triangles (T, 3, 3) are drawn (T,) bool: in front of the camera (view
    depths ``z`` (T, 3)), not degenerate, not the back face of a closed surface; and the
    flat colour (K, 3) of each drawn one."""
    near = 1e-3
    keep = np.all(z > near, axis=1)
    # Shading per triangle (world frame, two-sided).
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])  # (T, 3)
    nn = np.linalg.norm(n, axis=1)
    keep &= nn > 1e-15
    # Back faces of closed surfaces are hidden anyway: culling them halves the raster work.
    keep &= ~(closed & (np.sum(n * (eye - tris.mean(axis=1)), axis=1) < 0))
    tris_c = (tris[keep].mean(axis=1))                               # (K, 3)
    n = n[keep] / nn[keep, None]
    view = eye - tris_c
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    n *= np.sign(np.sum(n * view, axis=1, keepdims=True) + 1e-12)   # face the camera
    light = _direction(opt.light_azimuth, opt.light_elevation)
    lam = np.clip(n @ light, 0.0, 1.0)
    half = light[None, :] + view
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    spec = np.clip(np.sum(n * half, axis=1), 0.0, 1.0) ** opt.shininess
    shade = (cols[keep] * (opt.ambient + opt.diffuse * lam)[:, None]
             + opt.specular * spec[:, None])                         # (K, 3)
    return keep, shade


def _draw(u: np.ndarray, v: np.ndarray, z: np.ndarray, shade: np.ndarray, kept: np.ndarray,
          cbuf: np.ndarray, tbuf: Optional[np.ndarray], H: int, W: int) -> None:
    """Z-buffer the K projected triangles (pixel coords ``u``, ``v`` and view depths ``z``,
    (K, 3) each) into ``cbuf`` (H * W, 3) with their colours ``shade`` (K, 3), and into
    ``tbuf`` (H * W,) when given, their input triangle ids ``kept`` (K,)."""
    area = (u[:, 1] - u[:, 0]) * (v[:, 2] - v[:, 0]) - (u[:, 2] - u[:, 0]) * (v[:, 1] - v[:, 0])
    ok = np.abs(area) > 1e-12
    x0 = np.clip(np.floor(u.min(axis=1) - 0.5), 0, W).astype(np.int64)
    x1 = np.clip(np.ceil(u.max(axis=1) - 0.5), -1, W - 1).astype(np.int64)
    y0 = np.clip(np.floor(v.min(axis=1) - 0.5), 0, H).astype(np.int64)
    y1 = np.clip(np.ceil(v.max(axis=1) - 0.5), -1, H - 1).astype(np.int64)
    bw, bh = x1 - x0 + 1, y1 - y0 + 1
    cnt = np.where(ok & (bw > 0) & (bh > 0), bw * bh, 0)
    zbuf = np.full(H * W, np.inf)
    invz = 1.0 / z                                                   # (K, 3)
    start = 0
    K = len(cnt)
    while start < K:  # chunks of triangles bounded by their candidate count
        csum = np.cumsum(cnt[start:])
        stop = start + max(1, int(np.searchsorted(csum, _MAX_CANDIDATES, side="right")))
        c = cnt[start:stop]
        tot = int(c.sum())
        if tot:
            ti = np.repeat(np.arange(start, stop), c)                # (N,) triangle index
            local = np.arange(tot) - np.repeat(np.cumsum(c) - c, c)
            px = x0[ti] + local % bw[ti]
            py = y0[ti] + local // bw[ti]
            sx, sy = px + 0.5, py + 0.5
            uu, vv = u[ti], v[ti]                                    # (N, 3)
            w0 = (uu[:, 2] - uu[:, 1]) * (sy - vv[:, 1]) - (vv[:, 2] - vv[:, 1]) * (sx - uu[:, 1])
            w1 = (uu[:, 0] - uu[:, 2]) * (sy - vv[:, 2]) - (vv[:, 0] - vv[:, 2]) * (sx - uu[:, 2])
            w2 = (uu[:, 1] - uu[:, 0]) * (sy - vv[:, 0]) - (vv[:, 1] - vv[:, 0]) * (sx - uu[:, 0])
            a = area[ti]
            inside = (w0 * a >= 0) & (w1 * a >= 0) & (w2 * a >= 0)
            ti, px, py = ti[inside], px[inside], py[inside]
            b = np.stack([w0[inside], w1[inside], w2[inside]], axis=1) / a[inside, None]
            depth = 1.0 / np.sum(b * invz[ti], axis=1)               # perspective-correct
            pid = py * W + px
            # z-buffer: per-pixel minimum (ufunc.at is ~50x faster than a sort here), then
            # the candidates that reach it write their colour.
            np.minimum.at(zbuf, pid, depth)
            win = depth == zbuf[pid]
            cbuf[pid[win]] = shade[ti[win]]
            if tbuf is not None:
                tbuf[pid[win]] = kept[ti[win]]
        start = stop


def _camera(obj, ratios: Sequence[float], geometry: list, options: RenderOptions, H: int, W: int
            ) -> tuple[np.ndarray, np.ndarray]:
    """(eye, target) of one camera framed on the union of the object posed at ``ratios``
    (bounds of the posed vertices); the scenes themselves are built one at a time (a 19-part
    object is ~1M triangles)."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for r in ratios:
        T = obj.link_transforms(ratio=float(r))
        for p, g in zip(obj.parts, geometry):
            if g is not None and len(g[1]):
                v = g[0][np.unique(g[1])] @ T[p.name][:3, :3].T + T[p.name][:3, 3]
                lo, hi = np.minimum(lo, v.min(axis=0)), np.maximum(hi, v.max(axis=0))
    if not np.all(np.isfinite(lo)):
        lo, hi = -np.ones(3) * 0.5, np.ones(3) * 0.5
    centre = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-3) * options.margin
    half_fov = math.radians(min(options.fov, options.fov * W / H)) / 2.0
    dist = radius / math.sin(half_fov)
    return centre + dist * _direction(options.azimuth, options.elevation), centre


def render_views(obj, ratios: Sequence[float] = (0.0, 0.5, 1.0), size=224, *,
                 options: Optional[RenderOptions] = None, seed: Optional[int] = None,
                 simplify: bool = False, interrupt=None) -> Optional[np.ndarray]:
    """Render ``obj`` at each openness ratio; returns (len(ratios), H, W, 3) uint8.

    ``size``: int (square) or (H, W). ``options`` fixes camera / lighting / colours; with
    ``seed`` and no ``options`` they are drawn by ``random_options(seed)``. All views of one
    call share a camera framed on the union of the posed objects, so they are comparable.
    ``simplify``: cluster mesh vertices at half a (supersampled) pixel of the object's rest
    size first (previews of dense marching-cubes meshes; the dataset renders keep every face).
    ``interrupt``: a callable asked before each view; when it returns True the rendering
    stops and None is returned (a server yields to a waiting request).
    """
    H, W = (size, size) if np.ndim(size) == 0 else (int(size[0]), int(size[1]))
    if options is None:
        options = random_options(seed) if seed is not None else RenderOptions()
    ss = max(1, int(options.supersample))
    colours = _part_colours(obj, options.colour_mode, seed)
    cell = 0.0
    if simplify:
        b = [p.mesh.bounds for p in obj.parts if p.mesh is not None and len(p.mesh.faces)]
        if b:
            ext = float(np.max(np.max([x[1] for x in b], 0) - np.min([x[0] for x in b], 0)))
            cell = 0.5 * ext * options.margin / (min(H, W) * ss)
    geometry = _part_geometry(obj, cell)
    eye, centre = _camera(obj, ratios, geometry, options, H, W)
    out = np.empty((len(ratios), H, W, 3), dtype=np.uint8)
    for k, r in enumerate(ratios):
        if interrupt is not None and interrupt():
            return None
        # previews: single precision halves the per-triangle arrays (sub-pixel differences)
        tris, cols, closed = _scene(obj, float(r), colours, geometry,
                                    np.float32 if simplify else np.float64)
        img = _rasterise(tris, cols, closed, eye, centre, options.fov, H * ss, W * ss, options)
        del tris, cols, closed
        if ss > 1:
            img = img.reshape(H, ss, W, ss, 3).mean(axis=(1, 3))
        out[k] = np.round(img * 255.0).astype(np.uint8)
    return out


def render_part_ids(obj, ratio: float, size=224, *, options: Optional[RenderOptions] = None
                    ) -> np.ndarray:
    """Which part is seen at every pixel of the view ``render_views(obj, (ratio,), size,
    options=options)`` renders (same camera, same z-buffer, one sample at each pixel centre,
    no supersampling): (H, W) int64, the index into ``obj.parts``, -1 for the background."""
    H, W = (size, size) if np.ndim(size) == 0 else (int(size[0]), int(size[1]))
    options = options or RenderOptions()
    geometry = _part_geometry(obj)
    eye, centre = _camera(obj, (ratio,), geometry, options, H, W)
    tris, cols, closed = _scene(obj, float(ratio), [np.zeros(3)] * len(obj.parts), geometry)
    if len(tris) == 0:
        return np.full((H, W), -1, dtype=np.int64)
    part_of = np.concatenate([np.full(len(g[1]), k, dtype=np.int64)
                              for k, g in enumerate(geometry) if g is not None])
    _, tri = _rasterise(tris, cols, closed, eye, centre, options.fov, H, W, options, with_index=True)
    return np.where(tri >= 0, part_of[np.maximum(tri, 0)], -1)


def write_preview(obj, path, *, ratios: Sequence[float] = (0.0, 0.5, 1.0), size: int = 320,
                  options: Optional[RenderOptions] = None, interrupt=None) -> Optional[str]:
    """PNG of the object at each ratio side by side (written atomically); returns the path,
    or None when ``interrupt`` (see ``render_views``) stopped it before anything was written."""
    import io

    from PIL import Image

    from model.core.files import atomic_write_bytes
    views = render_views(obj, ratios, size, options=options, simplify=True,
                         interrupt=interrupt)                       # (V, S, S, 3)
    if views is None:
        return None
    gap = 4
    strip = np.full((size, len(views) * size + (len(views) - 1) * gap, 3), 255, dtype=np.uint8)
    for k, im in enumerate(views):
        strip[:, k * (size + gap):k * (size + gap) + size] = im
    buf = io.BytesIO()
    Image.fromarray(strip).save(buf, format="PNG")
    atomic_write_bytes(path, buf.getvalue())
    os.chmod(path, 0o644)      # the atomic temp file is created 0600
    return str(path)
