"""Bottles as solids of revolution: a screw cap and the body it turns on, rebuilt from the
profile their decoded meshes have about the cap's axis.

The shape prior decodes a bottle's thin features poorly: a screw cap's 1.5-3 mm skirt comes
out as a crown of slats with gaps between them, and the body's walls crumple (every body of
32 generated bottles had a regular octagon's eight-fold ripple, where the data's bottles are
60 % round). A cap that turns on a neck is a solid of revolution about its axis, or it
sweeps through the neck; the data's bodies are all round or regular prisms about the same
axis. So both are rebuilt: the mesh is cut at heights along the axis, rays from the axis at
``RAYS`` angles give where each enters and leaves the cut, and the profile runs from the
median entry to the median exit over the rays that meet the part (so a skirt of slats with
gaps closes and a ripple is averaged out); the profile is revolved.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from model.core import ArticulatedObject, JointType, meshops

from .meshes import VESSELS
from .sweeps import _z_to

RAYS = 96          # angles about the axis sampled at each height
CELL = 1 / 160     # profile grid step, as a share of the part's largest extent along or
                   # across the axis
PRESENT = 0.2      # a height is part of the profile where this share of the rays meets it
BRIDGE = 0.25      # the longest stretch of heights bridged, as a share of the part's length
WINDOW = 5         # heights of the running median that smooths the profile's radii
SEGMENTS = 96      # circular segments of the revolved mesh
KNOB_SEGMENTS = 32  # ... of a 3 cm knob pull (twelve of them had taken a 30,000-face budget's
                    # share from the carcass, which then overlapped a drawer)
SMOOTH = 0.5       # profile simplification tolerance, in grid steps
KEEP = (0.5, 3.0)  # the rebuilt volume's range, as a share of the decoded one; outside it
                   # the decoded part is not a solid of revolution about that axis


def _sections(V: np.ndarray, F: np.ndarray, heights: np.ndarray) -> list[np.ndarray]:
    """The mesh (vertices ``V`` in the axis frame, z along the axis) cut at each height:
    per height a (S, 2, 2) array of the cut's segments in the xy plane."""
    z = V[:, 2]
    tri_lo, tri_hi = z[F].min(1), z[F].max(1)
    edges = [(0, 1), (1, 2), (2, 0)]
    out = []
    for h in heights:
        idx = np.flatnonzero((tri_lo < h) & (tri_hi > h))
        if not len(idx):
            out.append(np.zeros((0, 2, 2)))
            continue
        f = F[idx]
        pts, hit = [], []
        for a, b in edges:
            za, zb = z[f[:, a]], z[f[:, b]]
            cross = (za - h) * (zb - h) < 0
            t = np.where(cross, (h - za) / np.where(cross, zb - za, 1.0), 0.0)
            pts.append(V[f[:, a], :2] + t[:, None] * (V[f[:, b], :2] - V[f[:, a], :2]))
            hit.append(cross)
        pts, hit = np.stack(pts, 1), np.stack(hit, 1)          # (T, 3, 2), (T, 3)
        two = hit.sum(1) == 2
        order = np.argsort(~hit[two], axis=1, kind="stable")[:, :2]
        seg = np.take_along_axis(pts[two], order[:, :, None], axis=1)
        out.append(seg)
    return out


def _radii(segments: np.ndarray, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per ray from the axis at ``angles``: where it first enters the closed cut
    ``segments`` (S, 2, 2) (0 where the axis is inside) and where it last leaves it; NaN
    for a ray that meets nothing."""
    nan = np.full(len(angles), np.nan)
    if not len(segments):
        return nan, nan
    d = np.stack([np.cos(angles), np.sin(angles)], 1)           # (A, 2)
    p, e = segments[:, 0], segments[:, 1] - segments[:, 0]      # (S, 2)
    den = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]   # cross(d, e)
    ok = np.abs(den) > 1e-15
    den = np.where(ok, den, 1.0)
    t = (p[None, :, 0] * e[None, :, 1] - p[None, :, 1] * e[None, :, 0]) / den
    s = (p[None, :, 0] * d[:, None, 1] - p[None, :, 1] * d[:, None, 0]) / den
    t = np.sort(np.where(ok & (s >= 0) & (s < 1) & (t > 0), t, np.inf), axis=1)
    n = np.isfinite(t).sum(1)
    rows = np.arange(len(angles))
    last = np.where(n > 0, t[rows, np.maximum(n - 1, 0)], np.nan)
    first = np.where(n % 2 == 1, 0.0, np.where(n > 0, t[:, 0], np.nan))
    return first, last


def _smoothed(r: np.ndarray) -> np.ndarray:
    """Running median of ``WINDOW`` heights (fewer at the ends)."""
    h = WINDOW // 2
    return np.array([np.median(r[max(0, j - h):j + h + 1]) for j in range(len(r))])


def _profile(V: np.ndarray, F: np.ndarray) -> tuple[list[np.ndarray], float]:
    """Closed (r, z) outlines of the mesh's profile (``V`` in the axis frame): at each
    height, from the median radius at which rays from the axis enter it to the median at
    which they leave it, over the rays that meet it, where at least ``PRESENT`` of them do;
    and the grid step."""
    rmax = float(np.linalg.norm(V[:, :2], axis=1).max())
    z0, z1 = float(V[:, 2].min()), float(V[:, 2].max())
    step = max(rmax, z1 - z0) * CELL
    nz = max(int(np.ceil((z1 - z0) / step)), 2)
    dz = (z1 - z0) / nz
    heights = z0 + (np.arange(nz) + 0.5) * dz
    angles = (np.arange(RAYS) + 0.37) * (2 * np.pi / RAYS)     # off the frame's axes
    inner, outer = np.full(nz, np.nan), np.full(nz, np.nan)
    for j, seg in enumerate(_sections(V, F, heights)):
        first, last = _radii(seg, angles)
        met = np.isfinite(last)
        if met.mean() >= PRESENT:
            inner[j], outer[j] = np.median(first[met]), np.median(last[met])
    keep = np.isfinite(outer) & (outer - inner > 0.5 * step)
    if not keep.any():
        return [], step
    # a short stretch that too few rays meet between two that they do (a cap's slats
    # short of its top) is bridged; the radii are smoothed along the axis
    idx = np.flatnonzero(keep)
    gap = ~keep & (np.arange(nz) > idx[0]) & (np.arange(nz) < idx[-1])
    for run in np.split(np.flatnonzero(gap), np.flatnonzero(np.diff(np.flatnonzero(gap)) > 1) + 1):
        if len(run) and len(run) <= BRIDGE * nz:
            inner[run] = np.interp(run, idx, inner[idx])
            outer[run] = np.interp(run, idx, outer[idx])
            keep[run] = True
    out = []
    for run in np.split(np.arange(nz), np.flatnonzero(np.diff(keep.astype(int))) + 1):
        if not keep[run[0]]:
            continue
        inner[run], outer[run] = _smoothed(inner[run]), _smoothed(outer[run])
        z = np.concatenate([[heights[run[0]] - dz / 2], heights[run], [heights[run[-1]] + dz / 2]])
        ro = np.concatenate([outer[run[:1]], outer[run], outer[run[-1:]]])
        ri = np.concatenate([inner[run[:1]], inner[run], inner[run[-1:]]])
        out.append(np.concatenate([np.stack([ro, z], 1), np.stack([ri, z], 1)[::-1]]))
    return out, step


def revolved(man, origin, axis, segments: int = SEGMENTS):
    """``man`` (a Manifold) rebuilt as the solid of revolution of its median profile
    (:func:`_profile`) about the line through ``origin`` along ``axis``; None where the
    profile is empty or the rebuilt volume leaves ``KEEP`` of the decoded one."""
    mf = meshops._mf()
    mesh = man.to_mesh()
    a = np.asarray(axis, dtype=np.float64)
    R = _z_to(a / max(float(np.linalg.norm(a)), 1e-12))        # axis frame: z along it
    o = np.asarray(origin, dtype=np.float64)
    V = (np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3] - o) @ R
    F = np.asarray(mesh.tri_verts, dtype=np.int64)
    if not len(F):
        return None
    contours, step = _profile(V, F)
    if not contours:
        return None
    z0, z1 = float(V[:, 2].min()), float(V[:, 2].max())
    half = mf.CrossSection.square((10 * (z1 - z0) + 1.0, 3 * (z1 - z0) + 1.0)) \
        .translate((0.0, z0 - (z1 - z0) - 0.5))
    cs = mf.CrossSection([np.ascontiguousarray(c) for c in contours], mf.FillRule.EvenOdd)
    cs = (cs ^ half).simplify(SMOOTH * step)
    if cs.is_empty():
        return None
    out = mf.Manifold.revolve(cs, circular_segments=segments).transform(
        np.hstack([R, o[:, None]]))
    vol, was = float(out.volume()), float(man.volume())
    if out.is_empty() or not KEEP[0] * was <= vol <= KEEP[1] * was:
        return None
    return out


def revolve_vessels(obj: ArticulatedObject, mans: dict) -> list[str]:
    """A bottle's screw caps and the body under them become solids of revolution about the
    cap's screw axis; a body under a flip lid one about the line through the body's centre
    along the lid's thinnest side. A cap with parts of its own keeps its mesh. Boxes, joints and
    collision pieces are left (the pipeline refits boxes to the meshes; the vessel step
    hulls the body's collision below the cap). Returns the parts rebuilt."""
    if obj.category not in VESSELS:
        return []
    axes: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for k in obj.movable_parts():
        p = obj.parts[k]
        if k not in mans or p.parent not in mans:
            continue
        if p.joint.type == JointType.SCREW:
            line = (np.asarray(p.joint.origin, float), np.asarray(p.joint.axis, float))
            axes.setdefault(k, line)
            axes.setdefault(p.parent, line)
        elif p.label == "lid" and p.joint.type.rotates:
            lo, hi = np.asarray(mans[p.parent].bounding_box(), dtype=np.float64).reshape(2, 3)
            line = ((lo + hi) / 2, np.eye(3)[int(np.argmin(p.bbox_size))])
            axes.setdefault(p.parent, line)
    done = []
    for i, (o, a) in sorted(axes.items()):
        if i in mans and not (obj.children(i) and obj.parts[i].parent >= 0):
            new = _safe_revolved(mans[i], o, a)
            if new is not None:
                mans[i] = new
                done.append(obj.parts[i].name)
    return done


def revolve_knobs(obj: ArticulatedObject, mans: dict) -> list[str]:
    """The knob pulls the layout made (``obj.metadata["knob_handles"]``,
    model.refine.hardware.knob_handles) become solids of revolution about their front's
    normal through their centre: a decoded bar squeezed into a knob's box is a lumpy block.
    Returns the parts rebuilt."""
    from .layout import face_of

    names = set(obj.metadata.get("knob_handles") or ())
    done = []
    for k, p in enumerate(obj.parts):
        if p.name not in names or k not in mans:
            continue
        face = face_of(obj, k)
        if face is None:
            continue
        lo, hi = np.asarray(mans[k].bounding_box(), dtype=np.float64).reshape(2, 3)
        new = _safe_revolved(mans[k], (lo + hi) / 2, np.eye(3)[face[0]], KNOB_SEGMENTS)
        if new is not None:
            mans[k] = new
            done.append(p.name)
    return done


def _safe_revolved(man, origin, axis, segments: int = SEGMENTS) -> Optional[object]:
    try:
        return revolved(man, origin, axis, segments)
    except (ValueError, RuntimeError):     # a degenerate cut or profile: keep the decoded part
        return None
