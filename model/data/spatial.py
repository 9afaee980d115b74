"""Spatial facts of an articulated object, read from the geometry and joints (never from
generator metadata, so they hold for generated and real objects too): hinge sides, opening
directions, arrangements in rows and columns, places on the body, one group above another.
"left" / "right" are the viewer's (``vocab.SIDE_DIRECTIONS``).

The descriptions (model.data.describe) state them and the alignment metric
(model.metrics.alignment) checks a prompt's against them:

    spatial_summary(obj)   # {"door": {"hinge": ["left"], "opens": ["sideways"], "layout": "row", ...}}
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from model.core.objects import ArticulatedObject, JointType
from model.data import vocab

SPATIAL_LABELS = ("drawer", "door", "lid", "tray", "knob", "dial", "button")   # arranged groups
HINGED_LABELS = ("door", "lid")                                                # hinge / opening
HPOS_MARGIN = 0.2   # |offset| from the body's centre, in half-widths, that counts as left/right
VPOS_MARGIN = 0.2   # ... in half-heights, that counts as top/bottom


def body_box(obj: ArticulatedObject) -> tuple[np.ndarray, np.ndarray]:
    """(centre, size) of the root part's box (the object's carcass)."""
    r = obj.parts[obj.root]
    size = np.maximum(np.abs(r.bbox_size), 1e-6)
    return np.asarray(r.bbox_center, float), size


def hinge_side(obj: ArticulatedObject, i: int) -> Optional[str]:
    """Side of the part's box its rotation axis runs along ("left", "right", "top", "bottom",
    "back", "front"), or None when the part does not rotate about an edge (a knob's own axis)."""
    p = obj.parts[i]
    if p.joint.type not in (JointType.REVOLUTE, JointType.CONTINUOUS):
        return None
    a = p.joint.axis / max(np.linalg.norm(p.joint.axis), 1e-12)
    c = np.asarray(p.bbox_center, float)
    d = p.joint.origin - c
    d = d - (d @ a) * a                      # centre -> axis line, perpendicular to the axis
    n = float(np.linalg.norm(d))
    # an edge hinge sits about half the box's extent (along d) from the centre; an axis
    # through the part (a knob's) much nearer
    half = 0.5 * float(np.abs(p.bbox_size) @ np.abs(d / max(n, 1e-12)))
    if n < 0.5 * max(half, 1e-6):
        return None
    return vocab.side_of(d)


def opening_direction(obj: ArticulatedObject, i: int) -> Optional[str]:
    """Where a hinged part's free edge goes when it opens: "down", "up" or "sideways". The
    free edge is the one opposite the hinge in the panel's plane, at the hinge's depth (a
    thick flip lid hinged on its underside's back edge lifts its front edge; its top front
    corner swings mostly backwards)."""
    p = obj.parts[i]
    if hinge_side(obj, i) is None:
        return None
    j = p.joint
    a = j.axis / max(np.linalg.norm(j.axis), 1e-12)
    lo, hi = j.r_range
    ang = hi if abs(hi) >= abs(lo) else lo
    ang = float(np.clip(ang, -math.pi / 2, math.pi / 2))
    if abs(ang) < 1e-3:
        return None
    c = np.asarray(p.bbox_center, float)
    d = c - j.origin
    d = d - (d @ a) * a
    thin = int(np.argmin(np.abs(p.bbox_size)))
    if abs(a[thin]) < 0.5:                         # the panel's plane holds the axis
        d[thin] = 0.0
    free = j.origin + 2 * d                        # the edge opposite the hinge
    T = j.transform(0.0, ang)
    moved = T[:3, :3] @ free + T[:3, 3]
    delta = moved - free
    n = float(np.linalg.norm(delta))
    if n < 1e-9:
        return None
    if delta[2] < -0.35 * n:
        return "down"
    if delta[2] > 0.35 * n:
        return "up"
    return "sideways"


def part_position(obj: ArticulatedObject, i: int) -> tuple[str, str]:
    """(horizontal, vertical) place of a part on the body: left/middle/right (the viewer's),
    top/middle/bottom."""
    bc, bs = body_box(obj)
    c = np.asarray(obj.parts[i].bbox_center, float)
    u = (c[1] - bc[1]) / (bs[1] / 2)
    v = (c[2] - bc[2]) / (bs[2] / 2)
    h = vocab.side_of((0.0, u, 0.0)) if abs(u) > HPOS_MARGIN else "middle"
    w = vocab.side_of((0.0, 0.0, v)) if abs(v) > VPOS_MARGIN else "middle"
    return h, w


def _clusters(centres: np.ndarray, sizes: np.ndarray) -> list[list[int]]:
    """Group 1-D positions: a part joins a cluster when its centre is within half the smaller
    extent of the cluster's mean. Clusters sorted by position, members by index."""
    order = np.argsort(centres, kind="stable")
    out: list[list[int]] = []
    for k in order:
        if out:
            cl = out[-1]
            m = float(np.mean(centres[cl]))
            if abs(centres[k] - m) < 0.5 * min(float(sizes[k]), float(np.min(sizes[cl]))):
                cl.append(int(k))
                continue
        out.append([int(k)])
    return [sorted(c) for c in out]


def arrangement(obj: ArticulatedObject, idx: list[int]) -> dict:
    """Rows and columns of a group of parts seen from the front.

    ``layout``: "single" (one part), "row" (one row), "column" (one above the other), "grid"
    (every row and every column equally full), "irregular" (rows of different lengths);
    ``rows``; ``columns`` (None for "irregular"); ``per_row``: parts per row, top row first.
    """
    n = len(idx)
    if n == 0:
        return {}
    if n == 1:
        return {"layout": "single", "rows": 1, "columns": 1, "per_row": [1]}
    cen = np.array([obj.parts[i].bbox_center for i in idx], float)
    siz = np.array([np.abs(obj.parts[i].bbox_size) for i in idx], float)
    rows = _clusters(-cen[:, 2], np.maximum(siz[:, 2], 1e-6))        # top row first
    cols = _clusters(cen[:, 1], np.maximum(siz[:, 1], 1e-6))         # viewer's left first
    R, C = len(rows), len(cols)
    per_row = [len(r) for r in rows]
    if R == 1:
        layout = "row"
    elif C == 1:
        layout = "column"
    elif R * C == n and all(len(r) == C for r in rows) and all(len(c) == R for c in cols):
        layout = "grid"
    else:
        layout, C = "irregular", None
    return {"layout": layout, "rows": R, "columns": C, "per_row": per_row}


def spatial_summary(obj: ArticulatedObject) -> dict[str, dict]:
    """Spatial facts per countable part label present (sets as sorted lists):

    ``hinge`` (doors, lids): sides their hinges are on; ``opens``: where they open (down, up,
    sideways); ``layout`` / ``rows`` / ``columns`` / ``per_row`` (see :func:`arrangement`);
    ``hpos`` / ``vpos``: where the parts sit on the body; ``z``: [lowest bottom, highest top]
    of the group's boxes (for "above" / "below" between groups); ``y``: the same across the
    front (for "beside").
    """
    out: dict[str, dict] = {}
    for label in vocab.COUNTABLE_LABELS:
        idx = [i for i, p in enumerate(obj.parts) if p.label == label]
        if not idx:
            continue
        f: dict = {}
        if label in HINGED_LABELS:
            hs = {hinge_side(obj, i) for i in idx}
            op = {opening_direction(obj, i) for i in idx}
            f["hinge"] = sorted(h for h in hs if h)
            f["opens"] = sorted(o for o in op if o)
        if label in SPATIAL_LABELS:
            f.update(arrangement(obj, idx))
        pos = [part_position(obj, i) for i in idx]
        f["hpos"] = sorted({h for h, _ in pos})
        f["vpos"] = sorted({v for _, v in pos})
        lo = [float(obj.parts[i].bbox_center[2] - abs(obj.parts[i].bbox_size[2]) / 2) for i in idx]
        hi = [float(obj.parts[i].bbox_center[2] + abs(obj.parts[i].bbox_size[2]) / 2) for i in idx]
        f["z"] = [min(lo), max(hi)]
        f["y"] = [min(float(obj.parts[i].bbox_center[1] - abs(obj.parts[i].bbox_size[1]) / 2)
                      for i in idx),
                  max(float(obj.parts[i].bbox_center[1] + abs(obj.parts[i].bbox_size[1]) / 2)
                      for i in idx)]
        f["z_centres"] = [min(float(obj.parts[i].bbox_center[2]) for i in idx),
                          max(float(obj.parts[i].bbox_center[2]) for i in idx)]
        out[label] = f
    return out


def is_above(spatial: dict, a: str, b: str) -> Optional[bool]:
    """Every part of group ``a`` sits above every part of group ``b``: the lowest ``a`` box
    bottom is no more than 1 cm below the highest ``b`` box top (parts *on* a door are not
    above or below it). None when either group is missing."""
    if a not in spatial or b not in spatial:
        return None
    return spatial[a]["z"][0] > spatial[b]["z"][1] - 0.01


def is_beside(spatial: dict, a: str, b: str) -> Optional[bool]:
    """Group ``a`` and group ``b`` side by side, either way round: every part of one is left
    of every part of the other (boxes overlapping across the front by at most 1 cm), and
    their heights overlap. None when either group is missing."""
    if a not in spatial or b not in spatial:
        return None
    (ay0, ay1), (by0, by1) = spatial[a]["y"], spatial[b]["y"]
    (az0, az1), (bz0, bz1) = spatial[a]["z"], spatial[b]["z"]
    apart = ay1 < by0 + 0.01 or by1 < ay0 + 0.01
    return apart and min(az1, bz1) > max(az0, bz0)
