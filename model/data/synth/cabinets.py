"""Storage furniture, safes and ovens."""
from __future__ import annotations

import math

import numpy as np

from model.core import meshops

from .builder import (
    HANDLE_STYLES,
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
from .carcass import _carcass, _Cell, _door, _drawer, _split

DRAWER_ASPECT = 1.2   # a drawer front's height over its width, at most
DRAWER_BAND = 0.45    # m: a band of drawers at least this tall is split into rows


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
    queue = [(z0 + plinth, z1 + plinth, None) for z0, z1 in bands]
    bi = -1
    while queue:
        bz0, bz1, kind = queue.pop(0)
        bi += 1
        bh = bz1 - bz0
        kinds = ["drawers", "doors", "flip", "open"]
        p = np.array([0.45 if bh < 0.45 else 0.15, 0.25 if bh > 0.2 else 0.0,
                      0.15 if bh < 0.5 else 0.02, 0.08])
        kind = kind or _pick(rng, kinds, p / p.sum())
        if kind == "drawers" and bh >= DRAWER_BAND:
            # a tall band of drawers becomes rows of drawers (synth-6 drew 17 cm wide, 75 cm
            # tall "drawers" side by side): no front taller than DRAWER_ASPECT x its width
            rows = int(np.ceil(bh / DRAWER_BAND))
            queue[0:0] = [(bz0 - t + z0, bz0 - t + z1, "drawers")
                          for z0, z1 in _split(rng, bh + 2 * t, rows, t, 0.1, 0.15)]
            bi -= 1
            continue
        max_cols = int(np.clip(W / 0.22, 1, 4))
        if kind == "drawers":
            # columns whose average width is bh / DRAWER_ASPECT; _split's jitter (0.15) can
            # make one 15 % narrower than the average
            fit = int((W - t) // (1.2 * bh / DRAWER_ASPECT + t))
            n = int(rng.integers(1, int(np.clip(fit, 1, max_cols)) + 1))
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


