"""Cabinets: a carcass with a grid of cells, and the drawers and doors that fill them
(storage furniture, safes and ovens share it)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from model.core import meshops

from .builder import _Builder, _handle, _pri, _rev, _u

# =============================================================================================
# cabinets: a carcass with a grid of cells (storage furniture, safes, ovens share it)
# =============================================================================================
@dataclass
class _Cell:
    y0: float
    y1: float
    z0: float
    z1: float
    kind: str            # drawer | door | flip | open | oven_door | panel
    side: str = ""       # hinge side for doors: left / right / top / bottom
    band: int = 0
    col: int = 0


def _split(rng, total: float, n: int, t: float, min_size: float, jitter: float = 0.35) -> list[tuple[float, float]]:
    """Split [0, total] into n cells separated (and bordered) by walls of thickness t."""
    inner = total - (n + 1) * t
    w = rng.uniform(1 - jitter, 1 + jitter, n)
    w = w / w.sum() * inner
    w = np.maximum(w, min_size)
    w = w / w.sum() * inner
    out, pos = [], t
    for x in w:
        out.append((pos, pos + float(x)))
        pos += float(x) + t
    return out


def _carcass(W: float, D: float, H: float, t: float, cells: list[_Cell], back: float, plinth: float = 0.0):
    """Outer box minus one cavity per cell (open to the front); returns the body manifold."""
    body = meshops.box([D, W, H], (0.0, 0.0, H / 2))
    cavities = []
    for c in cells:
        if c.kind == "panel":
            continue
        x0, x1 = -D / 2 + back, D / 2 + 0.01
        cavities.append(meshops.box([x1 - x0, c.y1 - c.y0, c.z1 - c.z0],
                                    ((x0 + x1) / 2, (c.y0 + c.y1) / 2, (c.z0 + c.z1) / 2)))
    if cavities:
        body = body - meshops.union_manifolds(cavities)
    return body


def _drawer(rng, b: _Builder, body: int, c: _Cell, D: float, back: float, handle_style: str,
            g: float) -> int:
    """Open box with a flush front, sliding +x; its handle is a fixed child."""
    fx = D / 2
    y0, y1, z0, z1 = c.y0 + g, c.y1 - g, c.z0 + g, c.z1 - g
    w, h = y1 - y0, z1 - z0
    avail = D - back - 2 * g
    dd = avail * _u(rng, 0.75, 0.97)
    tf = min(_u(rng, 0.014, 0.022), dd * 0.2)
    tw = _u(rng, 0.006, 0.012)
    hb = h * _u(rng, 0.6, 0.92)
    front = meshops.box([tf, w, h], (fx - tf / 2, (y0 + y1) / 2, (z0 + z1) / 2))
    bx0, bx1 = fx - dd, fx - tf + 0.001
    box = meshops.box([bx1 - bx0, w - 0.002, hb], ((bx0 + bx1) / 2, (y0 + y1) / 2, z0 + hb / 2))
    inner = meshops.box([bx1 - bx0 - 2 * tw, w - 0.002 - 2 * tw, hb],
                        ((bx0 + bx1) / 2, (y0 + y1) / 2, z0 + tw + hb / 2 + 0.001))
    man = meshops.union_manifolds([front, box - inner])
    ext = min(dd * _u(rng, 0.6, 0.85), dd - 0.03)
    d = b.add("drawer", man, body, _pri([fx, (y0 + y1) / 2, (z0 + z1) / 2], [1, 0, 0], ext),
              band=c.band, col=c.col)
    along = "y" if w >= h * 0.8 or handle_style == "edge" else "z"
    L = min(w, h if along == "z" else w) * _u(rng, 0.3, 0.6)
    hz = (z0 + z1) / 2 if rng.random() < 0.6 else z1 - min(0.04, h * 0.25)
    hman = _handle(rng, handle_style, fx, ((y0 + y1) / 2, hz), along, max(L, 0.04))
    b.add("handle", hman, d, None, style=handle_style, on="drawer")
    return d


def _door(rng, b: _Builder, body: int, c: _Cell, D: float, handle_style: Optional[str], g: float,
          max_angle: float, thickness: Optional[float] = None, label: str = "door",
          style: str = "flat") -> int:
    """Inset panel flush with the front, hinged on c.side; handle on the free edge.

    style "shaker": a shallow recess in the front face inside a frame wide enough to carry
    the handle (the envelope, hence the motion check, is unchanged)."""
    fx = D / 2
    y0, y1, z0, z1 = c.y0 + g, c.y1 - g, c.z0 + g, c.z1 - g
    td = thickness or _u(rng, 0.015, 0.025)
    # The free edge's back corner sweeps out to sqrt(L² + td²) from the hinge: widen that
    # gap so thick doors do not bind against the far side of the opening.
    if c.side in ("left", "right"):
        extra = 1.3 * td * td / (2 * (y1 - y0))
        y0, y1 = (y0, y1 - extra) if c.side == "left" else (y0 + extra, y1)
    else:
        extra = 1.3 * td * td / (2 * (z1 - z0))
        z0, z1 = (z0, z1 - extra) if c.side == "bottom" else (z0 + extra, z1)
    w, h = y1 - y0, z1 - z0
    man = meshops.box([td, w, h], (fx - td / 2, (y0 + y1) / 2, (z0 + z1) / 2))
    cy, cz = (y0 + y1) / 2, (z0 + z1) / 2
    if style == "shaker":
        edge = min(0.04, (w if c.side in ("left", "right") else h) * 0.15)
        m = edge + 0.025                       # frame width: the handle stays on the frame
        if w - 2 * m > 0.05 and h - 2 * m > 0.05:
            depth = td * 0.35
            man = man - meshops.box([depth + 0.002, w - 2 * m, h - 2 * m], (fx - depth / 2 + 0.001, cy, cz))
        else:
            style = "flat"
    if c.side == "left":      # viewer's left = -y edge
        origin, axis, hpos, along = [fx, y0, cz], [0, 0, -1], (y1 - min(0.04, w * 0.15), cz), "z"
    elif c.side == "right":
        origin, axis, hpos, along = [fx, y1, cz], [0, 0, 1], (y0 + min(0.04, w * 0.15), cz), "z"
    elif c.side == "bottom":
        origin, axis, hpos, along = [fx, cy, z0], [0, 1, 0], (cy, z1 - min(0.04, h * 0.15)), "y"
    else:  # top
        origin, axis, hpos, along = [fx, cy, z1], [0, -1, 0], (cy, z0 + min(0.04, h * 0.15)), "y"
    d = b.add(label, man, body, _rev(origin, axis, max_angle), side=c.side, band=c.band, col=c.col,
              panel=style)
    if handle_style:
        span = h if along == "z" else w
        L = max(0.04, span * _u(rng, 0.2, 0.45))
        hman = _handle(rng, handle_style, fx, hpos, along, L)
        b.add("handle", hman, d, None, style=handle_style, on=label)
    return d


