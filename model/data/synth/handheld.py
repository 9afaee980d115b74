"""Bottles and USB sticks."""
from __future__ import annotations

import math

import numpy as np

from model.core import meshops
from model.core.objects import Joint, JointType

from .builder import _Builder, _pick, _pri, _rev, _u

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
    # a solid body with an open mouth: the neck bore, 0.6 of the neck deep, its wall twice the
    # body's wall (synth-8; the hollow 1.5-3 mm shell of synth-1..7 is about one cell of the
    # shape prior's 64-cell box frame and decoded shredded)
    rm, depth = Rn - 2 * w, 0.6 * hn
    body_man = outer - meshops.cylinder(rm, depth + 0.01, (0, 0, ztop - depth + (depth + 0.01) / 2),
                                        segments=48)
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
            meshops.cylinder(rm, hcol + 0.01, (0, 0, ztop - hcol / 2), segments=48)
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


