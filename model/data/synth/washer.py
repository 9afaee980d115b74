"""Washing machines: front and top loaders with dials, buttons and a detergent drawer."""
from __future__ import annotations

import math

import numpy as np

from model.core import meshops

from .builder import (
    _Builder,
    _button_in_pocket,
    _cont,
    _handle,
    _knob,
    _pick,
    _pri,
    _rev,
    _u,
)
from .carcass import _Cell

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


