"""Procedural articulated objects in the paper's six categories (DESIGN §3.1).

Every part is a closed 2-manifold built from exact manifold3d booleans of boxes and
cylinders: bodies are hollow carcasses with real openings, drawers are open boxes with a
front, doors / lids / caps fit their openings with a clearance gap. Handles are separate
fixed child parts of the drawer / door / lid they belong to (the PartNet-Mobility convention,
where handles are their own segmented parts).

Frames (DESIGN §2): metres, x forward, y left, z up; base on z = 0, centred on the z axis,
front facing +x. Side words ("left", "right") are as seen by a viewer standing in front of
the object, who looks towards -x: the viewer's left is -y, right is +y.

Hinge convention: a door / lid turns about the outer edge of its outer face, and its joint
axis is chosen so that positive angles open it; every joint's rest value is 0 and its range
starts at 0 (closed) and ends fully open.

Every object is verified with :func:`check_object` (exact intersection volumes of all part
pairs at 10 openness states, and the distance of every moving part to its parent); the
generator shrinks offending joint ranges a few times and otherwise draws a new object.

    obj = generate_object(seed=0, index=12)                  # one object
    for obj in generate_objects(n=100, seed=0): ...           # deterministic stream
"""
from __future__ import annotations

import logging
import math
from pathlib import Path
from dataclasses import dataclass, field
from typing import Callable, Iterator, Optional

import numpy as np

from model.core import meshops
from model.core.objects import ArticulatedObject, Joint, JointType, Part

log = logging.getLogger(__name__)

CATEGORY_WEIGHTS: dict[str, float] = {"StorageFurniture": 0.34, "Safe": 0.12, "Oven": 0.14,
                                      "WashingMachine": 0.14, "Bottle": 0.13, "USB": 0.13}
# synth-2: strict overlap test (≤ 1 mm³ and ≤ 0.2 mm thick); synth-3: legs and top overhangs on
# storage furniture, shaker (recessed-panel) doors, side-hinged oven doors; synth-4: every
# object also passes the geometric checks of the sim-ready audit (model.metrics.audit:
# interpenetration over the per-joint sweeps, hinges, drawer axes, mesh health) or is redrawn.
GENERATOR_VERSION = "synth-4"


@dataclass
class SynthConfig:
    seed: int = 0
    categories: dict[str, float] = field(default_factory=lambda: dict(CATEGORY_WEIGHTS))
    states: int = 10                 # openness states of the collision check
    max_shrinks: int = 4             # joint-range shrink rounds before redrawing an object
    max_redraws: int = 30
    attach_distance: float = 0.004  # a moving part must stay within this of its parent (m)
    collision_abs_tol: float = 1e-9  # m³ (1 mm³) of intersection tolerated between two parts...
    collision_depth_tol: float = 2e-4  # ... and if its mean thickness 2V/A is below this (m)
    audit: bool = True               # redraw objects the audit's geometric checks fail (synth-4)
    audit_physics: bool = False      # ... and its MuJoCo check (exports every draw: slow)


class GenerationRejected(RuntimeError):
    """No valid object could be drawn for a seed (should not happen in practice)."""


# =============================================================================================
# builder
# =============================================================================================
class _Builder:
    """Collects parts as manifolds; names are ``<label>_<k>``."""

    def __init__(self, category: str):
        self.category = category
        self.parts: list[dict] = []
        self.meta: dict = {}

    def add(self, label: str, man, parent: int = -1, joint: Optional[Joint] = None, **info) -> int:
        k = sum(1 for p in self.parts if p["label"] == label)
        self.parts.append({"name": f"{label}_{k}", "label": label, "parent": parent,
                           "joint": joint or Joint(), "man": man, "info": info})
        return len(self.parts) - 1

    def build(self, name: str) -> ArticulatedObject:
        parts = []
        for p in self.parts:
            mesh = meshops.to_trimesh(p["man"])
            part = Part(name=p["name"], label=p["label"], parent=p["parent"], joint=p["joint"],
                        mesh=mesh)
            part.fit_bbox_to_mesh()
            parts.append(part)
        meta = dict(self.meta)
        meta["parts"] = {p["name"]: p["info"] for p in self.parts}
        meta["generator"] = GENERATOR_VERSION
        return ArticulatedObject(parts=parts, category=self.category, name=name, metadata=meta)


def _rev(origin, axis, hi: float, lo: float = 0.0) -> Joint:
    return Joint(JointType.REVOLUTE, origin, axis, r_range=(lo, hi), effort=20.0, velocity=1.5)


def _pri(origin, axis, hi: float, lo: float = 0.0) -> Joint:
    return Joint(JointType.PRISMATIC, origin, axis, t_range=(lo, hi), effort=50.0, velocity=0.3)


def _cont(origin, axis) -> Joint:
    # Continuous joints have no limits in a URDF; the range is what openness sweeps.
    return Joint(JointType.CONTINUOUS, origin, axis, r_range=(0.0, 2 * math.pi), effort=2.0,
                 velocity=3.0)


def _u(rng, lo, hi) -> float:
    return float(rng.uniform(lo, hi))


def _pick(rng, items, p=None):
    return items[int(rng.choice(len(items), p=p))]


# =============================================================================================
# small shapes
# =============================================================================================
def _handle(rng, style: str, face_x: float, center_yz, along: str, length: float, scale: float = 1.0):
    """A handle on the plane x = face_x, protruding to +x, touching the plane.

    along: "y" (horizontal) or "z" (vertical) — the direction of its long side.
    """
    cy, cz = float(center_yz[0]), float(center_yz[1])
    r = 0.006 * scale * _u(rng, 0.8, 1.3)
    proud = 0.025 * scale * _u(rng, 0.8, 1.3)
    if style == "knob":
        r1 = r * 1.2
        r2 = r * _u(rng, 2.0, 3.0)
        stem = meshops.cylinder(r1, proud * 0.7, (face_x + proud * 0.35, cy, cz), axis="x", segments=20)
        cap = meshops.cylinder(r2, proud * 0.4, (face_x + proud * 0.7 + proud * 0.2 - 1e-4, cy, cz),
                               axis="x", segments=28)
        return meshops.union_manifolds([stem, cap])
    half = length / 2.0
    if style == "edge":  # a lip pull: one flat bar standing out of the face
        h = r * 1.6
        size = [proud * 0.8, length, h] if along == "y" else [proud * 0.8, h, length]
        return meshops.box(size, (face_x + size[0] / 2, cy, cz))
    # bar / square (D-shaped) handles: two posts and a grip
    offs = [(-half + r, 0.0), (half - r, 0.0)] if along == "y" else [(0.0, -half + r), (0.0, half - r)]
    pieces = []
    for dy, dz in offs:
        if style == "bar":
            pieces.append(meshops.cylinder(r * 0.8, proud, (face_x + proud / 2, cy + dy, cz + dz),
                                           axis="x", segments=16))
        else:
            pieces.append(meshops.box([proud, 2 * r * 0.8, 2 * r * 0.8], (face_x + proud / 2, cy + dy, cz + dz)))
    gx = face_x + proud - r * 0.5
    if style == "bar":
        pieces.append(meshops.cylinder(r, length, (gx, cy, cz), axis=along, segments=20))
    else:
        size = [2 * r, length, 2 * r] if along == "y" else [2 * r, 2 * r, length]
        pieces.append(meshops.box(size, (gx, cy, cz)))
    return meshops.union_manifolds(pieces)


HANDLE_STYLES = ("bar", "square", "knob", "edge")


def _knob(rng, face_x: float, cy: float, cz: float, radius: float, gap: float = 0.0008,
          style: Optional[str] = None):
    """A control knob / dial on the plane x = face_x (with a small gap), axis +x; a pointer
    ridge on its front face shows that it turns."""
    style = style or _pick(rng, ["round", "fluted", "pointer"])
    depth = radius * _u(rng, 0.6, 1.1)
    x0 = face_x + gap
    segs = 8 if style == "fluted" else 32
    body = meshops.cylinder(radius, depth, (x0 + depth / 2, cy, cz), axis="x", segments=segs)
    ridge = meshops.box([depth * 0.4, radius * 0.3, radius * 1.6],
                        (x0 + depth + depth * 0.2 - 1e-4, cy, cz + radius * 0.1))
    if style == "pointer":
        ridge = meshops.box([depth * 0.5, radius * 0.35, radius * 1.9],
                            (x0 + depth + depth * 0.25 - 1e-4, cy, cz + radius * 0.2))
    return meshops.union_manifolds([body, ridge]), style


def _button_in_pocket(face_x: float, cy: float, cz: float, w: float, h: float, travel: float,
                      gap: float = 0.0008, proud: float = 0.004):
    """A push button and the pocket to cut into its parent.

    The pocket is (travel + 3 mm) deep; the button stands ``proud`` out of the face and
    ``travel`` can push it in without touching the pocket floor.
    Returns (button, pocket) manifolds; the joint moves the button along -x.
    """
    depth = travel + 0.003
    pocket = meshops.box([depth + 0.002, w + 2 * gap, h + 2 * gap], (face_x - depth / 2 + 0.001, cy, cz))
    bx0 = face_x - depth + travel + 0.001      # rear face of the button at rest
    bx1 = face_x + proud
    button = meshops.box([bx1 - bx0, w, h], ((bx0 + bx1) / 2, cy, cz))
    return button, pocket


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


def _gen_storage(rng, b: _Builder) -> None:
    W = _u(rng, 0.4, 1.6)
    D = _u(rng, 0.35, 0.6)
    H = _u(rng, 0.4, 1.9)
    t = _u(rng, 0.015, 0.025)
    back = t
    plinth = _u(rng, 0.0, 0.08) if rng.random() < 0.5 else 0.0
    g = _u(rng, 0.002, 0.004)
    handle_style = _pick(rng, list(HANDLE_STYLES))
    max_bands = int(np.clip(round(H / 0.22), 1, 6))
    n_bands = int(rng.integers(1, max_bands + 1))
    bands = _split(rng, H - plinth, n_bands, t, 0.12)
    cells: list[_Cell] = []
    for bi, (bz0, bz1) in enumerate(bands):
        bz0, bz1 = bz0 + plinth, bz1 + plinth
        bh = bz1 - bz0
        kinds = ["drawers", "doors", "flip", "open"]
        p = np.array([0.45 if bh < 0.45 else 0.15, 0.25 if bh > 0.2 else 0.0,
                      0.15 if bh < 0.5 else 0.02, 0.08])
        kind = _pick(rng, kinds, p / p.sum())
        max_cols = int(np.clip(W / 0.22, 1, 4))
        if kind == "drawers":
            n = int(rng.integers(1, max_cols + 1))
            for ci, (y0, y1) in enumerate(_split(rng, W, n, t, 0.12, 0.15)):
                cells.append(_Cell(y0 - W / 2, y1 - W / 2, bz0, bz1, "drawer", band=bi, col=ci))
        elif kind == "doors":
            n = int(rng.integers(1, min(max_cols, 3) + 1))
            double = n == 1 and W > 0.5 and rng.random() < 0.6
            for ci, (y0, y1) in enumerate(_split(rng, W, n, t, 0.15, 0.1)):
                y0, y1 = y0 - W / 2, y1 - W / 2
                if double:
                    m = (y0 + y1) / 2
                    cells.append(_Cell(y0, m, bz0, bz1, "door", "left", bi, 0))
                    cells.append(_Cell(m, y1, bz0, bz1, "door", "right", bi, 1))
                else:
                    side = _pick(rng, ["left", "right"])
                    cells.append(_Cell(y0, y1, bz0, bz1, "door", side, bi, ci))
        elif kind == "flip":
            for ci, (y0, y1) in enumerate(_split(rng, W, int(rng.integers(1, min(max_cols, 2) + 1)), t, 0.15, 0.1)):
                side = _pick(rng, ["top", "bottom"])
                cells.append(_Cell(y0 - W / 2, y1 - W / 2, bz0, bz1, "door", side, bi, ci))
        else:
            cells.append(_Cell(t - W / 2, W / 2 - t, bz0, bz1, "open", band=bi))
    if all(c.kind == "open" for c in cells):   # at least one moving part
        c = cells[int(rng.integers(len(cells)))]
        c.kind, c.side = ("drawer", "") if c.z1 - c.z0 < 0.45 else ("door", _pick(rng, ["left", "right"]))
        c.y0, c.y1 = -W / 2 + t, W / 2 - t
    # Double doors share one cavity: merge their cells for the carcass.
    cav: list[_Cell] = []
    for c in cells:
        if cav and c.kind == "door" and c.side == "right" and cav[-1].kind == "door" and \
                cav[-1].side == "left" and cav[-1].band == c.band and abs(cav[-1].y1 - c.y0) < 1e-9:
            prev = cav.pop()
            cav.append(_Cell(prev.y0, c.y1, c.z0, c.z1, "door", "double", c.band))
        else:
            cav.append(c)
    body_man = _carcass(W, D, H, t, cav, back, plinth)
    base = "plinth" if plinth > 0 else "flush"
    if plinth > 0.03 and rng.random() < 0.5:      # four corner legs instead of a solid plinth
        lw = min(_u(rng, 0.03, 0.06), W / 4, D / 4)
        body_man = body_man - meshops.union_manifolds([
            meshops.box([D - 2 * lw, W + 0.02, plinth + 0.01], (0.0, 0.0, plinth / 2 - 0.005)),
            meshops.box([D + 0.02, W - 2 * lw, plinth + 0.01], (0.0, 0.0, plinth / 2 - 0.005))])
        base = "legs"
    top = "flush"
    if rng.random() < 0.4:                         # a top slab overhanging the sides and back
        os_, ob, tt = _u(rng, 0.005, 0.03), _u(rng, 0.0, 0.02), _u(rng, 0.015, 0.03)
        body_man = body_man + meshops.box([D + ob, W + 2 * os_, tt], (-ob / 2, 0.0, H + tt / 2 - 1e-4))
        top = "overhang"
    body = b.add("body", body_man)
    door_style = _pick(rng, ["flat", "shaker"])
    n_moving = 0
    for c in cells:
        if n_moving >= 16:
            break
        if c.kind == "drawer":
            _drawer(rng, b, body, c, D, back, handle_style, g)
            n_moving += 1
        elif c.kind == "door":
            double = any(x.side == "double" and x.band == c.band for x in cav)
            if c.side in ("left", "right"):
                limit = math.radians(_u(rng, 75, 90) if double else _u(rng, 80, 110))
            elif c.side == "bottom":
                limit = math.radians(_u(rng, 60, 90))
            else:
                limit = math.radians(_u(rng, 60, 95))
            _door(rng, b, body, c, D, handle_style, g, limit, style=door_style)
            n_moving += 1
    b.meta.update(size=[D, W, H], layout=[c.kind for c in cells], handle_style=handle_style,
                  shelves=sum(c.kind == "open" for c in cells), base=base, top=top, door_style=door_style)


def _gen_safe(rng, b: _Builder) -> None:
    W = _u(rng, 0.3, 0.7)
    D = _u(rng, 0.3, 0.6)
    H = _u(rng, 0.25, 0.9)
    t = _u(rng, 0.03, 0.06)
    g = _u(rng, 0.002, 0.003)
    n_doors = 2 if H > 0.55 and rng.random() < 0.35 else 1
    side = _pick(rng, ["left", "right"])
    cells = [_Cell(y0 - W / 2, y1 - W / 2, z0, z1, "door", side, bi) for bi, (z0, z1) in
             enumerate(_split(rng, H, n_doors, t, 0.15, 0.2)) for (y0, y1) in [(t, W - t)]]
    body = b.add("body", _carcass(W, D, H, t, cells, t))
    td = _u(rng, 0.03, 0.05)
    features = []
    for c in cells:
        lever = rng.random() < 0.5
        style = None if lever else _pick(rng, ["bar", "square", "knob"])
        d = _door(rng, b, body, c, D, style, g, math.radians(_u(rng, 80, 110)), thickness=td)
        w, h = c.y1 - c.y0 - 2 * g, c.z1 - c.z0 - 2 * g
        cy, cz = (c.y0 + c.y1) / 2, (c.z0 + c.z1) / 2
        fx = D / 2
        # keep controls out of the hinge strip and the handle strip
        free_sign = 1 if side == "left" else -1
        ctrl_y = cy + free_sign * w * 0.1
        door_man = b.parts[d]["man"]
        n_ctrl = 0
        if lever:
            hub_r = min(w, h) * 0.05
            hy = cy + free_sign * w * 0.32
            hub = meshops.cylinder(hub_r, 0.015, (fx + 0.0008 + 0.0075, hy, cz), axis="x", segments=24)
            arm_len = min(h * 0.3, w * 0.3)
            arm = meshops.box([0.012, hub_r * 0.8, arm_len], (fx + 0.0008 + 0.015 + 0.006 - 1e-4, hy, cz - arm_len / 2 + hub_r * 0.4))
            b.add("handle", meshops.union_manifolds([hub, arm]), d,
                  _rev([fx, hy, cz], [1, 0, 0], math.radians(_u(rng, 45, 90))), style="lever", on="door")
            n_ctrl += 1
        if rng.random() < 0.75:
            r = min(w, h) * _u(rng, 0.07, 0.11)
            dz = cz + h * 0.2
            kman, kstyle = _knob(rng, fx, ctrl_y, dz, r)
            b.add("dial", kman, d, _cont([fx, ctrl_y, dz], [1, 0, 0]), style=kstyle, on="door")
            n_ctrl += 1
        if rng.random() < 0.6:
            rows, cols = _pick(rng, [(2, 2), (3, 3), (4, 3), (2, 3), (1, 3)])
            bw = min(w * 0.3 / cols, 0.022)
            pitch = bw * 1.6
            pockets = []
            kz0 = cz - h * 0.12
            for i in range(rows):
                for j in range(cols):
                    by = ctrl_y + (j - (cols - 1) / 2) * pitch
                    bz = kz0 - i * pitch
                    bman, pocket = _button_in_pocket(fx, by, bz, bw, bw, travel=0.003)
                    pockets.append(pocket)
                    b.add("button", bman, d, _pri([fx, by, bz], [-1, 0, 0], 0.003), style="keypad", on="door")
            door_man = door_man - meshops.union_manifolds(pockets)
            features.append(f"keypad{rows}x{cols}")
        b.parts[d]["man"] = door_man
    b.meta.update(size=[D, W, H], hinge=side, features=features)


def _gen_oven(rng, b: _Builder) -> None:
    W = _u(rng, 0.5, 0.9)
    D = _u(rng, 0.5, 0.65)
    H = _u(rng, 0.45, 0.95)
    t = _u(rng, 0.02, 0.035)
    g = _u(rng, 0.002, 0.003)
    panel_h = _u(rng, 0.07, 0.14)
    drawer = H > 0.7 and rng.random() < 0.5
    drawer_h = _u(rng, 0.1, 0.16) if drawer else 0.0
    z_cav0 = t + (drawer_h + t if drawer else 0.0)
    z_cav1 = H - panel_h
    side_hinged = rng.random() < 0.25              # wall-oven style door on a vertical hinge
    cells = [_Cell(-W / 2 + t, W / 2 - t, z_cav0, z_cav1, "door",
                   _pick(rng, ["left", "right"]) if side_hinged else "bottom", 1)]
    if drawer:
        cells.append(_Cell(-W / 2 + t, W / 2 - t, t, t + drawer_h, "drawer", band=0))
    body_man = _carcass(W, D, H, t, cells, t)
    fx = D / 2
    # tray ledges on the cavity walls, and the trays on them
    n_trays = int(rng.choice([0, 1, 1, 2])) if not side_hinged else 0
    cav_h = z_cav1 - z_cav0
    tray_specs = []
    for k in range(n_trays):
        zl = z_cav0 + cav_h * (0.3 + 0.35 * k) * _u(rng, 0.9, 1.1)
        ledge_w = 0.01
        for s in (-1, 1):
            yl = s * (W / 2 - t - ledge_w / 2 + 0.0005)
            body_man = body_man + meshops.box([D - 2 * t - 0.03, ledge_w + 0.001, 0.006],
                                              (t / 2 - 0.015 + 0.0, yl, zl - 0.003))
        tray_specs.append(zl)
    # knobs on the control panel, plus optional buttons (pockets in the panel)
    n_knobs = int(rng.integers(2, 7))
    n_buttons = int(rng.choice([0, 0, 1, 2, 3]))
    slots = n_knobs + n_buttons
    pz = H - panel_h / 2
    ys = np.linspace(-W / 2 + W / (slots + 1), W / 2 - W / (slots + 1), slots) if slots > 1 else np.array([0.0])
    order = rng.permutation(slots)
    knob_r = min(panel_h * 0.32, W / (slots + 1) * 0.35)
    pockets = []
    btn_specs = []
    for k, slot in enumerate(order):
        y = float(ys[slot])
        if k < n_knobs:
            continue
        bw = min(knob_r * 1.2, 0.02)
        bman, pocket = _button_in_pocket(fx, y, pz, bw, bw * 0.7, travel=0.003)
        pockets.append(pocket)
        btn_specs.append((bman, y))
    if pockets:
        body_man = body_man - meshops.union_manifolds(pockets)
    body = b.add("body", body_man)
    knob_style = _pick(rng, ["round", "fluted", "pointer"])
    for k, slot in enumerate(order[:n_knobs]):
        y = float(ys[slot])
        kman, _ = _knob(rng, fx, y, pz, knob_r, style=knob_style)
        jt = _cont([fx, y, pz], [1, 0, 0]) if rng.random() < 0.5 else \
            _rev([fx, y, pz], [1, 0, 0], math.radians(_u(rng, 180, 300)))
        b.add("knob", kman, body, jt, style=knob_style)
    for bman, y in btn_specs:
        b.add("button", bman, body, _pri([fx, y, pz], [-1, 0, 0], 0.003), style="push")
    handle_style = _pick(rng, ["bar", "square", "edge"])
    if side_hinged:
        _door(rng, b, body, cells[0], D, handle_style, g, math.radians(_u(rng, 80, 110)),
              thickness=_u(rng, 0.025, 0.04))
    else:
        door = _door(rng, b, body, cells[0], D, None, g, math.radians(_u(rng, 70, 90)),
                     thickness=_u(rng, 0.025, 0.04))
        dz1 = z_cav1 - g
        hman = _handle(rng, handle_style, fx, (0.0, dz1 - 0.035), "y", (W - 2 * t) * _u(rng, 0.6, 0.85))
        b.add("handle", hman, door, None, style=handle_style, on="door")
    if drawer:
        _drawer(rng, b, body, cells[1], D, t, handle_style, g)
    # trays: a frame of bars sitting on the ledges, sliding out
    for zl in tray_specs:
        tw_y = W - 2 * t - 2 * 0.003
        tx0, tx1 = -D / 2 + t + 0.01, D / 2 - 0.045
        depth = tx1 - tx0
        bar = 0.006
        pieces = [meshops.box([depth, bar, bar], ((tx0 + tx1) / 2, s * (tw_y / 2 - bar / 2), zl + 0.0005 + bar / 2))
                  for s in (-1, 1)]
        pieces += [meshops.box([bar, tw_y, bar], (x, 0.0, zl + 0.0005 + bar / 2)) for x in (tx0 + bar / 2, tx1 - bar / 2)]
        n_wires = int(rng.integers(4, 10))
        for yk in np.linspace(-tw_y / 2 + 0.03, tw_y / 2 - 0.03, n_wires):
            pieces.append(meshops.box([depth - 0.002, 0.003, 0.003], ((tx0 + tx1) / 2, float(yk), zl + 0.0005 + bar / 2)))
        height_above_hinge = zl - z_cav0
        travel = min(depth * _u(rng, 0.4, 0.6), max(0.03, height_above_hinge * 1.1))
        b.add("tray", meshops.union_manifolds(pieces), body,
              _pri([tx1, 0.0, zl], [1, 0, 0], travel), style="rack")
    b.meta.update(size=[D, W, H], knobs=n_knobs, buttons=n_buttons, has_drawer=drawer,
                  knob_style=knob_style)


def _gen_washer(rng, b: _Builder) -> None:
    W = _u(rng, 0.55, 0.7)
    D = _u(rng, 0.5, 0.65)
    H = _u(rng, 0.8, 0.95)
    t = _u(rng, 0.02, 0.03)
    fx = D / 2
    top_loader = rng.random() < 0.3
    body_man = meshops.box([D, W, H], (0.0, 0.0, H / 2))
    n_dials = int(rng.integers(1, 3))
    n_buttons = int(rng.choice([0, 1, 2, 3, 4, 5]))
    if not top_loader:
        panel_h = _u(rng, 0.1, 0.16)
        Ro = min(W * 0.36, (H - panel_h) * 0.36)
        zc = (H - panel_h) * _u(rng, 0.48, 0.55)
        drum = meshops.cylinder(Ro, D - t + 0.01, (t / 2 + 0.005, 0.0, zc), axis="x", segments=48)
        body_man = body_man - drum
        det = rng.random() < 0.5
        pz = H - panel_h / 2
        pockets, specs = [], []
        y_left = -W / 2
        if det:
            dw, dh = W * 0.3, panel_h * 0.6
            dy0, dy1 = -W / 2 + t, -W / 2 + t + dw
            cell = _Cell(dy0, dy1, pz - dh / 2, pz + dh / 2, "drawer", band=0)
            pocket = meshops.box([D * 0.5 + 0.01, dw, dh], (fx - D * 0.25 + 0.005, (dy0 + dy1) / 2, pz))
            body_man = body_man - pocket
            specs.append(("det", cell))
            y_left = dy1 + 0.01
        slots = n_dials + n_buttons
        ys = np.linspace(y_left + 0.02, W / 2 - 0.02, slots + 2)[1:-1]
        pitch = (W / 2 - y_left - 0.04) / (slots + 1)
        dial_r = min(panel_h * 0.38, pitch * 0.4)
        for k in range(slots):
            y = float(ys[k])
            if k < n_dials:
                specs.append(("dial", y))
            else:
                bw = min(dial_r * 0.8, 0.02)
                bman, pocket = _button_in_pocket(fx, y, pz, bw, bw * 0.7, travel=0.003)
                pockets.append(pocket)
                specs.append(("button", bman, y))
        if pockets:
            body_man = body_man - meshops.union_manifolds(pockets)
        body = b.add("body", body_man)
        c = _u(rng, 0.002, 0.003)
        Rd = min(Ro + _u(rng, 0.02, 0.05), W / 2 - 0.01)
        td = _u(rng, 0.03, 0.06)
        x0 = fx + c
        ring = meshops.cylinder(Rd, td, (x0 + td / 2, 0.0, zc), axis="x", segments=48)
        glass = meshops.cylinder(Ro * 0.85, td * 0.5, (x0 + td - td * 0.25 + 0.001, 0.0, zc), axis="x", segments=48)
        side = _pick(rng, ["left", "right"])
        sgn = -1 if side == "left" else 1
        origin = [x0, sgn * Rd, zc]   # hinge on the back face's outer edge, next to the body
        axis = [0, 0, -1] if side == "left" else [0, 0, 1]
        door = b.add("door", ring - glass, body, _rev(origin, axis, math.radians(_u(rng, 90, 120))),
                     side=side, shape="round")
        hy = -sgn * (Rd - 0.03)
        hman = meshops.box([0.02, 0.025, 0.07], (x0 + td + 0.01, hy, zc))
        b.add("handle", hman, door, None, style="grip", on="door")
        for s in specs:
            if s[0] == "det":
                _washer_det_drawer(rng, b, body, s[1], fx, D)
            elif s[0] == "dial":
                kman, kstyle = _knob(rng, fx, s[1], pz, dial_r, style=_pick(rng, ["round", "pointer"]))
                b.add("dial", kman, body, _cont([fx, s[1], pz], [1, 0, 0]), style=kstyle)
            else:
                b.add("button", s[1], body, _pri([fx, s[2], pz], [-1, 0, 0], 0.003), style="push")
        b.meta.update(loading="front", door_side=side)
    else:
        console_d = _u(rng, 0.08, 0.14)
        console_h = _u(rng, 0.08, 0.15)
        xb = -D / 2 + console_d                  # console front face
        Rt = min(W, D - console_d) * 0.38
        xc = (xb + D / 2) / 2
        tub = meshops.cylinder(Rt, H - t, (xc, 0.0, t + (H - t) / 2 + 0.005), axis="z", segments=48)
        console = meshops.box([console_d, W, console_h], (-D / 2 + console_d / 2, 0.0, H + console_h / 2 - 0.001))
        body_man = (body_man - tub) + console
        slots = n_dials + n_buttons
        ys = np.linspace(-W / 2, W / 2, slots + 2)[1:-1]
        dial_r = min(console_h * 0.35, W / (slots + 1) * 0.35)
        pz = H + console_h / 2
        pockets, btns = [], []
        for k in range(n_dials, slots):
            bw = min(dial_r, 0.018)
            bman, pocket = _button_in_pocket(xb, float(ys[k]), pz, bw, bw * 0.7, travel=0.003)
            pockets.append(pocket)
            btns.append((bman, float(ys[k])))
        if pockets:
            body_man = body_man - meshops.union_manifolds(pockets)
        body = b.add("body", body_man)
        c = 0.003
        tl = _u(rng, 0.02, 0.035)
        proud = dial_r * 1.7 + 0.01 + tl
        xh = xb + proud                             # lid hinge line, clear of the dials
        lid = meshops.box([D / 2 - 0.005 - xh, W - 0.02, tl], ((xh + D / 2 - 0.005) / 2, 0.0, H + c + tl / 2))
        # hinge on the lid's lower back edge, next to the body top
        lid_i = b.add("lid", lid, body, _rev([xh, 0.0, H + c], [0, -1, 0], math.radians(_u(rng, 75, 90))),
                      side="back")
        hman = _handle(rng, "edge", D / 2 - 0.005, (0.0, H + c + tl / 2), "y", W * 0.3)
        b.add("handle", hman, lid_i, None, style="edge", on="lid")
        for k in range(n_dials):
            kman, kstyle = _knob(rng, xb, float(ys[k]), pz, dial_r)
            b.add("dial", kman, body, _cont([xb, float(ys[k]), pz], [1, 0, 0]), style=kstyle)
        for bman, y in btns:
            b.add("button", bman, body, _pri([xb, y, pz], [-1, 0, 0], 0.003), style="push")
        b.meta.update(loading="top")
    b.meta.update(size=[D, W, H], dials=n_dials, buttons=n_buttons)


def _washer_det_drawer(rng, b: _Builder, body: int, c: _Cell, fx: float, D: float) -> int:
    """Detergent drawer in a pocket (D/2 deep) of the control panel."""
    g = 0.003
    y0, y1, z0, z1 = c.y0 + g, c.y1 - g, c.z0 + g, c.z1 - g
    w, h = y1 - y0, z1 - z0
    dd = D * 0.5 - 2 * g
    tf = 0.012
    front = meshops.box([tf, w, h], (fx - tf / 2, (y0 + y1) / 2, (z0 + z1) / 2))
    box = meshops.box([dd - tf + 0.001, w - 0.002, h * 0.8], (fx - tf - (dd - tf) / 2 + 0.0005, (y0 + y1) / 2, z0 + h * 0.4))
    inner = meshops.box([dd - tf - 0.012, w - 0.014, h], (fx - tf - (dd - tf) / 2, (y0 + y1) / 2, z0 + 0.006 + h / 2))
    man = meshops.union_manifolds([front, box - inner])
    d = b.add("drawer", man, body, _pri([fx, (y0 + y1) / 2, (z0 + z1) / 2], [1, 0, 0], dd * _u(rng, 0.5, 0.8)),
              role="detergent")
    hman = _handle(rng, "edge", fx, ((y0 + y1) / 2, z0 + h * 0.25), "y", w * 0.5, scale=0.6)
    b.add("handle", hman, d, None, style="edge", on="drawer")
    return d


def _gen_bottle(rng, b: _Builder) -> None:
    Rb = _u(rng, 0.025, 0.06)
    hb = _u(rng, 0.08, 0.25)
    segs = int(_pick(rng, [48, 48, 48, 6, 8]))
    Rn = Rb * _u(rng, 0.3, 0.6)
    hs = _u(rng, 0.01, 0.05)
    hn = _u(rng, 0.015, 0.035)
    w = _u(rng, 0.0015, 0.003)
    outer = meshops.union_manifolds([
        meshops.cylinder(Rb, hb, (0, 0, hb / 2), segments=segs),
        meshops.cylinder(Rb, hs, (0, 0, hb + hs / 2 - 1e-5), segments=segs, radius_top=Rn)
        if segs > 10 else meshops.cylinder(Rb * 0.98, hs, (0, 0, hb + hs / 2 - 1e-5), segments=48, radius_top=Rn),
        meshops.cylinder(Rn, hn + 0.001, (0, 0, hb + hs + hn / 2 - 0.0005), segments=48)])
    ztop = hb + hs + hn
    ri = Rb - w if segs > 10 else Rb * 0.8
    inner = meshops.union_manifolds([
        meshops.cylinder(ri, hb - w, (0, 0, w + (hb - w) / 2 + 1e-4), segments=48),
        meshops.cylinder(ri, hs, (0, 0, hb + hs / 2), segments=48, radius_top=Rn - w),
        meshops.cylinder(Rn - w, hn + 0.01, (0, 0, hb + hs + hn / 2 + 0.004), segments=48)])
    body_man = outer - inner
    kind = "screw" if rng.random() < 0.65 else "flip"
    if kind == "screw":
        body = b.add("body", body_man)
        c = 0.0008
        wc = _u(rng, 0.0015, 0.003)
        skirt = min(hn * _u(rng, 0.6, 0.95), hn - 0.002)
        hc = skirt + wc
        z0 = ztop + c - skirt                      # cap skirt bottom
        cap = meshops.cylinder(Rn + c + wc, hc, (0, 0, z0 + hc / 2), segments=48) - \
            meshops.cylinder(Rn + c, skirt + 0.001, (0, 0, z0 + skirt / 2 - 0.0005), segments=48)
        if rng.random() < 0.5:   # knurled ribs
            ribs = [meshops.box([0.0015, 0.0015, hc * 0.9], ((Rn + c + wc) * math.cos(a), (Rn + c + wc) * math.sin(a), z0 + hc / 2))
                    .rotate([0, 0, 0]) for a in np.linspace(0, 2 * math.pi, 16, endpoint=False)]
            cap = meshops.union_manifolds([cap] + ribs)
        turns = _u(rng, 1.0, 3.0)
        lift = min(skirt - 0.002, _u(rng, 0.004, 0.012))
        j = Joint(JointType.SCREW, [0, 0, ztop], [0, 0, 1], t_range=(0.0, lift),
                  r_range=(0.0, 2 * math.pi * turns), effort=2.0, velocity=2.0)
        b.add("cap", cap, body, j, style="screw")
    else:
        Rc = Rn + _u(rng, 0.003, 0.008)
        hcol = _u(rng, 0.006, 0.012)
        collar = meshops.cylinder(Rc, hcol, (0, 0, ztop - hcol / 2), segments=48) - \
            meshops.cylinder(Rn - w, hcol + 0.01, (0, 0, ztop - hcol / 2), segments=48)
        body = b.add("body", body_man + collar)
        c = 0.0008
        tl = _u(rng, 0.004, 0.008)
        lid = meshops.cylinder(Rc, tl, (0, 0, ztop + c + tl / 2), segments=48)
        tab = meshops.box([0.006, 0.01, tl * 0.6], (Rc + 0.003 - 0.0005, 0, ztop + c + tl * 0.7))
        b.add("lid", meshops.union_manifolds([lid, tab]), body,
              _rev([-Rc, 0.0, ztop + c], [0, -1, 0], math.radians(_u(rng, 100, 160))), style="flip")
    b.meta.update(size=[2 * Rb, 2 * Rb, ztop], cap=kind, faceted=segs < 10)


def _gen_usb(rng, b: _Builder) -> None:
    L = _u(rng, 0.03, 0.06)
    Wd = _u(rng, 0.014, 0.024)
    T = _u(rng, 0.006, 0.011)
    lc = _u(rng, 0.011, 0.013)
    wc, tc = 0.012, 0.0045
    kind = "swivel" if rng.random() < 0.5 else "slide"
    c = 0.001
    tp = _u(rng, 0.0008, 0.0015)
    z_body = tp + c                              # the cap's lower plate rests on z = 0
    zc = z_body + T / 2
    x0 = -L / 2
    casing = meshops.box([L, Wd, T], (0.0, 0.0, zc))
    if rng.random() < 0.4:                       # lanyard hole
        casing = casing - meshops.cylinder(0.0022, T + 0.01, (x0 + 0.005, 0.0, zc), axis="z", segments=20)
    plug = meshops.box([lc + 0.001, wc, tc], (L / 2 + lc / 2 - 0.0005, 0.0, zc))
    body = b.add("body", meshops.union_manifolds([casing, plug]))
    tip = L / 2 + lc
    if kind == "swivel":
        xp = x0 + Wd / 2
        pw = Wd + 0.002
        reach = tip + c + tp - xp
        plates = []
        for zz in (tp / 2, z_body + T + c + tp / 2):
            plate = meshops.box([reach + pw / 2, pw, tp], (xp + (reach - pw / 2) / 2, 0.0, zz))
            plate = plate + meshops.cylinder(pw / 2, tp, (xp, 0.0, zz), segments=32)
            plates.append(plate)
        end = meshops.box([tp, pw, 2 * tp + 2 * c + T], (tip + c + tp / 2, 0.0, (2 * tp + 2 * c + T) / 2))
        cap = meshops.union_manifolds(plates + [end])
        b.add("cap", cap, body, _rev([xp, 0.0, zc], [0, 0, 1], math.radians(_u(rng, 160, 200))), style="swivel")
    else:
        lo = _u(rng, 0.004, 0.012)
        te = _u(rng, 0.001, 0.002)
        ts = tp
        outer_len = lc + lo + c + te
        xs0 = L / 2 - lo
        outer = meshops.box([outer_len, Wd + 2 * c + 2 * ts, T + 2 * c + 2 * ts],
                            (xs0 + outer_len / 2, 0.0, zc))
        inner = meshops.box([lc + lo + c + 0.001, Wd + 2 * c, T + 2 * c], (xs0 + (lc + lo + c) / 2 - 0.0005, 0.0, zc))
        b.add("cap", outer - inner, body, _pri([tip, 0.0, zc], [1, 0, 0], lc + lo - 0.002), style="slide")
    b.meta.update(size=[L + lc, Wd, T], cap=kind)


GENERATORS: dict[str, Callable] = {
    "StorageFurniture": _gen_storage, "Safe": _gen_safe, "Oven": _gen_oven,
    "WashingMachine": _gen_washer, "Bottle": _gen_bottle, "USB": _gen_usb,
}


# =============================================================================================
# verification
# =============================================================================================
@dataclass
class CheckReport:
    collisions: list[tuple[str, str, float, float]] = field(default_factory=list)  # a, b, ratio, m³
    detached: list[tuple[str, float, float]] = field(default_factory=list)         # part, ratio, gap

    @property
    def ok(self) -> bool:
        return not self.collisions and not self.detached


def check_object(obj: ArticulatedObject, states: int = 10, *, attach_distance: float = 0.004,
                 abs_tol: float = 1e-9, depth_tol: float = 2e-4, manifolds: Optional[dict] = None,
                 stop_early: bool = False) -> CheckReport:
    """Exact pairwise intersection volumes of all parts at ``states`` openness ratios, and the
    distance of every moving part to its parent.

    A pair collides when their intersection exceeds ``abs_tol`` m³, or when it is non-empty
    (> 1e-12 m³) and its mean thickness 2·volume / area exceeds ``depth_tol`` (a real
    interpenetration, however small). Parts touching at faces pass (float32 noise only)."""
    names = [p.name for p in obj.parts]
    mans = manifolds or {p.name: meshops.to_manifold(p.mesh) for p in obj.parts}
    rep = CheckReport()
    moving = set(names[i] for i in obj.movable_parts())
    for r in np.linspace(0.0, 1.0, states):
        T = obj.link_transforms(ratio=float(r))
        posed = {n: mans[n].transform(meshops.affine34(T[n])) for n in names}
        boxes = {n: np.asarray(posed[n].bounding_box()) for n in names}
        for i in range(len(names)):
            a = names[i]
            for j in range(i + 1, len(names)):
                bn = names[j]
                ba, bb = boxes[a], boxes[bn]
                if np.any(ba[:3] >= bb[3:]) or np.any(bb[:3] >= ba[3:]):
                    continue
                x = posed[a] ^ posed[bn]
                v = float(x.volume())
                if v <= 1e-12:
                    continue
                # mean thickness of the overlap: a contact sheet (float noise of touching faces,
                # at any orientation) is ~0 thick; a real interpenetration is not
                thick = 2.0 * v / max(float(x.surface_area()), 1e-18)
                if v > abs_tol or thick > depth_tol:
                    rep.collisions.append((a, bn, float(r), v))
                    if stop_early:
                        return rep
        for p in obj.parts:
            if p.name in moving and p.parent >= 0 and p.joint.type.translates:
                gap = posed[p.name].min_gap(posed[names[p.parent]], attach_distance * 3)
                if gap > attach_distance:
                    rep.detached.append((p.name, float(r), float(gap)))
                    if stop_early:
                        return rep
    # A rotating joint keeps its axis line fixed in both frames: it is attached when that line
    # passes within attach_distance of the part and of its parent (checked at rest).
    extent = float(np.max([np.ptp(np.asarray(mans[n].bounding_box()).reshape(2, 3), axis=0).max()
                           for n in names]))
    for p in obj.parts:
        if p.name in moving and p.parent >= 0 and not p.joint.type.translates:
            line = meshops.axis_line(p.joint.origin, p.joint.axis, 2.5 * extent)
            for other in (p.name, names[p.parent]):
                gap = line.min_gap(mans[other], attach_distance * 3)
                if gap > attach_distance:
                    rep.detached.append((p.name, 0.0, float(gap)))
                    if stop_early:
                        return rep
    return rep
    return rep


def _audit_failures(obj: ArticulatedObject, physics: bool) -> list[str]:
    """What the sim-ready audit finds wrong with a drawn object."""
    from model.metrics.audit import AuditConfig, audit_object
    rep = audit_object(obj, config=AuditConfig(physics=physics))
    return ([rep.error] if rep.error else []) + rep.failures


def _moving_ancestor(obj: ArticulatedObject, name: str) -> Optional[int]:
    i = obj.index_of(name)
    while i >= 0:
        if obj.parts[i].joint.type != JointType.FIXED:
            return i
        i = obj.parts[i].parent
    return None


def _shrink(joint: Joint, factor: float) -> None:
    if joint.type.translates:
        joint.t_range = (joint.t_range[0], joint.t_range[0] + (joint.t_range[1] - joint.t_range[0]) * factor)
    if joint.type.rotates and joint.type != JointType.CONTINUOUS:
        joint.r_range = (joint.r_range[0], joint.r_range[0] + (joint.r_range[1] - joint.r_range[0]) * factor)


# =============================================================================================
# public API
# =============================================================================================
def object_rng(seed: int, index: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), int(index)])


def pick_category(rng: np.random.Generator, weights: dict[str, float]) -> str:
    cats = list(weights)
    p = np.array([weights[c] for c in cats], dtype=np.float64)
    return cats[int(rng.choice(len(cats), p=p / p.sum()))]


def generate_object(seed: int = 0, index: int = 0, config: Optional[SynthConfig] = None,
                    category: Optional[str] = None) -> ArticulatedObject:
    """One verified object, a pure function of (seed, index, category)."""
    cfg = config or SynthConfig(seed=seed)
    rng = object_rng(seed, index)
    cat = category or pick_category(rng, cfg.categories)
    if cat not in GENERATORS:
        raise ValueError(f"unknown category {cat!r}; choose from {sorted(GENERATORS)}")
    last: Optional[CheckReport] = None
    for attempt in range(cfg.max_redraws):
        b = _Builder(cat)
        GENERATORS[cat](rng, b)
        obj = b.build(f"{cat.lower()}_{seed}_{index:05d}")
        obj.metadata.update(seed=int(seed), index=int(index), attempt=attempt)
        mans = {p["name"]: p["man"] for p in b.parts}
        for _ in range(cfg.max_shrinks + 1):
            rep = check_object(obj, cfg.states, attach_distance=cfg.attach_distance,
                               abs_tol=cfg.collision_abs_tol, depth_tol=cfg.collision_depth_tol,
                               manifolds=mans, stop_early=True)
            if rep.ok:
                obj.validate()
                failures = _audit_failures(obj, cfg.audit_physics) if cfg.audit else []
                if not failures:
                    return obj
                log.debug("%s seed %d index %d attempt %d fails the audit: %s", cat, seed,
                          index, attempt, failures)
                break
            last = rep
            if rep.detached:
                break           # shrinking does not re-attach a part: redraw
            a, bn = rep.collisions[0][:2]
            movers = {k for k in (_moving_ancestor(obj, a), _moving_ancestor(obj, bn)) if k is not None}
            if not movers:
                break           # two static parts overlap: a construction fault, redraw
            for k in movers:
                _shrink(obj.parts[k].joint, 0.7)
        log.debug("%s seed %d index %d attempt %d rejected: %s", cat, seed, index, attempt, last)
    raise GenerationRejected(f"no valid {cat} for seed {seed} index {index}: {last}")


def generate_objects(n: int, seed: int = 0, config: Optional[SynthConfig] = None,
                     start: int = 0) -> Iterator[ArticulatedObject]:
    for i in range(start, start + n):
        yield generate_object(seed, i, config)


# =============================================================================================
# dataset on disk
# =============================================================================================
def _synth_one(args) -> dict:
    out, seed, index, cfg = args
    from model.data.describe import describe
    from model.data.partnet import write_partnet
    folder = Path(out) / f"{index:06d}"
    if (folder / "descriptions.json").exists():
        return {"index": index, "skipped": True}
    try:
        obj = generate_object(seed, index, cfg)
    except GenerationRejected as e:
        return {"index": index, "error": str(e)}
    texts = describe(obj, np.random.default_rng([seed, index, 7]))
    # descriptions.json is written last by write_partnet: it marks the folder complete
    write_partnet(obj, folder, descriptions=texts, extra_meta={"seed": seed, "index": index})
    return {"index": index, "category": obj.category, "parts": len(obj.parts),
            "movable": len(obj.movable_parts())}


def synthesize_dataset(out: str, n: int, seed: int = 0, workers: int = 2, config: Optional[SynthConfig] = None,
                       progress: bool = True) -> dict:
    """Write objects 0..n-1 of ``seed`` as PartNet-Mobility folders ``out/<index:06d>``.

    Resumable (complete folders are skipped), parallel over objects; writes ``out/synth.json``.
    """
    import time
    cfg = config or SynthConfig(seed=seed)
    Path(out).mkdir(parents=True, exist_ok=True)
    jobs = [(out, seed, i, cfg) for i in range(n)]
    t0 = time.time()
    results = []
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=n, desc="synth", unit="obj")
    if workers > 1 and n > 1:
        import multiprocessing as mp
        with mp.get_context("fork").Pool(workers) as pool:
            for r in pool.imap_unordered(_synth_one, jobs, chunksize=4):
                results.append(r)
                if bar:
                    bar.update(1)
    else:
        for j in jobs:
            results.append(_synth_one(j))
            if bar:
                bar.update(1)
    if bar:
        bar.close()
    errors = {r["index"]: r["error"] for r in results if "error" in r}
    info = {"generator": GENERATOR_VERSION, "seed": seed, "n": n, "errors": errors,
            "seconds_last_run": round(time.time() - t0, 1), "config": {
                "states": cfg.states, "attach_distance": cfg.attach_distance,
                "collision_abs_tol": cfg.collision_abs_tol, "collision_depth_tol": cfg.collision_depth_tol,
                "categories": cfg.categories}}
    from model.data.format import atomic_write_json
    atomic_write_json(Path(out) / "synth.json", info)
    return info
