"""Repeated parts and overlapping siblings of the layout refinement (model.refine.layout,
steps 3-5): align repeated parts on rows and columns, space small ones, cut overlapping
siblings apart, keep knobs, dials and buttons clear of the panels beside them."""
from __future__ import annotations

import numpy as np

from model.core import ArticulatedObject

from .layout import (CLEAR, GAP, MIN_KEEP, PANELS, SMALL, LayoutConfig, _attach, _lohi,
                     _move_subtree, _set, face_of)


def _clusters(values: np.ndarray, tol: float) -> list[list[int]]:
    order = np.argsort(values)
    groups: list[list[int]] = []
    for idx in order:
        if groups and values[idx] - values[groups[-1][-1]] <= tol:
            groups[-1].append(int(idx))
        else:
            groups.append([int(idx)])
    return groups


def _align(obj: ArticulatedObject, members: list[int], k: int) -> None:
    """Rows and columns of same-label siblings on the face with normal axis ``k``: members
    sharing a row get its mean coordinate and mean size across it."""
    parts = [obj.parts[i] for i in members]
    for d in (d for d in range(3) if d != k):
        cs = np.array([p.bbox_center[d] for p in parts])
        sizes = np.array([p.bbox_size[d] for p in parts])
        for g in _clusters(cs, 0.35 * float(np.median(sizes))):
            if len(g) < 2:
                continue
            c, size = float(cs[g].mean()), float(sizes[g].mean())
            for m in g:
                parts[m].bbox_center[d] = c
                parts[m].bbox_size[d] = size
    # same depth along the normal for the whole group
    for d in (k,):
        size = float(np.mean([p.bbox_size[d] for p in parts]))
        c = float(np.median([p.bbox_center[d] for p in parts]))
        for p in parts:
            p.bbox_size[d], p.bbox_center[d] = size, c


def _space_small(obj: ArticulatedObject, members: list[int], k: int) -> None:
    """Small parts that collide are spread evenly along the in-face axis of their largest
    spread, within their parent's face."""
    parts = [obj.parts[i] for i in members]
    if len(parts) < 2 or not any(_overlap(a, b) for n, a in enumerate(parts) for b in parts[n + 1:]):
        return
    ax = [d for d in range(3) if d != k]
    cs = np.array([p.bbox_center for p in parts])
    d = max(ax, key=lambda a: np.ptp(cs[:, a]))
    other = [a for a in ax if a != d][0]
    # a grid when the other axis has distinct rows: space within each row only
    rows = _clusters(cs[:, other], 0.5 * float(np.median([p.bbox_size[other] for p in parts])))
    plo, phi = _lohi(obj.parts[parts[0].parent])
    for row in rows:
        if len(row) < 2:
            continue
        row = sorted(row, key=lambda m: cs[m, d])
        size = max(parts[m].bbox_size[d] for m in row)
        pitch = max(size + GAP * 2, (cs[row[-1], d] - cs[row[0], d]) / (len(row) - 1))
        span = pitch * (len(row) - 1) + size
        room = phi[d] - plo[d]
        if span > room:                      # too many for the face: shrink to fit
            pitch = room / len(row)
            size = min(size, pitch - GAP)
            span = pitch * (len(row) - 1) + size
        mid = float(np.clip(cs[row, d].mean(), plo[d] + span / 2, phi[d] - span / 2))
        for n, m in enumerate(row):
            parts[m].bbox_center[d] = mid - pitch * (len(row) - 1) / 2 + n * pitch
            parts[m].bbox_size[d] = size


def _clear_panels(obj: ArticulatedObject, members: list[int], k: int) -> int:
    """Knobs, dials and buttons on a face keep ``CLEAR`` from the outline of a door or lid
    on that face: a panel swings its edge out past its closed outline by up to its
    thickness, and the collision pieces of both stand a few millimetres proud of their
    meshes (an oven door stalled on the knob 3 mm above it). A small part closer than that
    moves away along the axis it stands beside the panel on, or, when it stands in front of
    the panel, off its outline the shortest way, within its parent's face; where it cannot
    move, the panel gives way on that side. Returns how many moved."""
    panels = [obj.parts[c] for c in members if obj.parts[c].label in PANELS]
    plo, phi = _lohi(obj.parts[obj.parts[members[0]].parent])
    moved = 0
    for c in members:
        q = obj.parts[c]
        if q.label not in ("knob", "dial", "button"):
            continue
        for panel in panels:
            lo, hi = _lohi(panel)
            qlo, qhi = _lohi(q)
            ins = [d for d in range(3) if d != k]
            gaps = [max(lo[d] - qhi[d], qlo[d] - hi[d]) for d in ins]   # < 0: extents overlap
            if max(gaps) >= CLEAR:
                continue
            # beside the panel: away along that axis; in front of it (a knob on a door's
            # outline, which the door hits when it opens): off it the shortest way that fits
            order = [int(np.argmax(gaps))] if max(gaps) >= 0 else list(np.argsort(gaps)[::-1])
            for n in order:
                d = ins[n]
                up = q.bbox_center[d] > panel.bbox_center[d]
                new = q.bbox_center[d] + (CLEAR - gaps[n]) * (1.0 if up else -1.0)
                if plo[d] + q.bbox_size[d] / 2 <= new <= phi[d] - q.bbox_size[d] / 2:
                    q.bbox_center[d] = new
                    moved += 1
                    break
            else:                # no room to move it: the panel gives way on that side
                n = order[0]
                d, up = ins[n], q.bbox_center[ins[n]] > panel.bbox_center[ins[n]]
                keep = MIN_KEEP * (hi[d] - lo[d])
                if up:
                    hi[d] = max(min(hi[d], qlo[d] - CLEAR), lo[d] + keep)
                else:
                    lo[d] = min(max(lo[d], qhi[d] + CLEAR), hi[d] - keep)
                _set(panel, lo, hi)
                moved += 1
    return moved


def _overlap(a, b, pad: float = 0.0) -> bool:
    alo, ahi = _lohi(a)
    blo, bhi = _lohi(b)
    return bool(np.all(alo < bhi - pad) and np.all(blo < ahi - pad))


def _union(parts) -> tuple[np.ndarray, np.ndarray]:
    return (np.min([_lohi(p)[0] for p in parts], axis=0),
            np.max([_lohi(p)[1] for p in parts], axis=0))


def _separate(first_group: list, second_group: list, k: int) -> bool:
    """Cut two groups of sibling boxes apart in the face plane (normal axis ``k``) along the
    in-face axis where their union boxes already stand furthest apart (centre distance over
    mean size): stacked drawers split vertically, a door beside a drawer column sideways.
    Each box keeps at least MIN_KEEP of its size. Returns whether they overlapped."""
    alo, ahi = _union(first_group)
    blo, bhi = _union(second_group)
    if not (np.all(alo < bhi - GAP / 4) and np.all(blo < ahi - GAP / 4)):
        return False
    ac, bc = (alo + ahi) / 2, (blo + bhi) / 2
    d = max((d for d in range(3) if d != k),
            key=lambda d: abs(ac[d] - bc[d]) / max((ahi[d] - alo[d] + bhi[d] - blo[d]) / 2, 1e-9))
    low, high = (first_group, second_group) if ac[d] <= bc[d] else (second_group, first_group)
    cut = (max(alo[d], blo[d]) + min(ahi[d], bhi[d])) / 2
    for p in low:
        lo, hi = _lohi(p)
        hi[d] = min(hi[d], max(cut - GAP / 2, lo[d] + MIN_KEEP * (hi[d] - lo[d])))
        _set(p, lo, hi)
    for p in high:
        lo, hi = _lohi(p)
        lo[d] = max(lo[d], min(cut + GAP / 2, hi[d] - MIN_KEEP * (hi[d] - lo[d])))
        _set(p, lo, hi)
    return True


def _separate_all(obj: ArticulatedObject, members: list[int], k: int) -> int:
    """Repeated parts among themselves first (a stack splits into rows), then each label's
    group against each other's, then any pair left."""
    by_label: dict[str, list] = {}
    for c in members:
        by_label.setdefault(obj.parts[c].label, []).append(obj.parts[c])
    groups = list(by_label.values())
    n = 0
    for _ in range(3):
        hit = 0
        for g in groups:
            for a_i, a in enumerate(g):
                for b in g[a_i + 1:]:
                    hit += _separate([a], [b], k)
        for a_i, a in enumerate(groups):
            for b in groups[a_i + 1:]:
                hit += _separate(a, b, k)
        parts = [obj.parts[c] for c in members]
        for a_i, a in enumerate(parts):
            for b in parts[a_i + 1:]:
                hit += _separate([a], [b], k)
        n += hit
        if not hit:
            break
    return n


FRONTS = PANELS + ("drawer",)
FRAME = 0.023      # m of carcass around a storage front (the data's median at the sides and top)


def _fill(obj: ArticulatedObject, parent: int, members: list[int], k: int) -> int:
    """The doors and drawers on one face of a piece of storage furniture grow to tile it: a
    decoded front often leaves drawers as small boxes in a wide empty face, where the data's
    fronts cover 93 % (median) of the rectangle they span, and that rectangle reaches to
    ``FRAME`` of the carcass's sides and top (its bottom varies with the plinth, so it stays
    where the fronts put it). Vertical extents first, then horizontal; a part grows towards
    a front wholly beyond it only to the middle of the gap between them (``GAP`` apart), so
    every front above, below, left or right of another stays so; nothing shrinks. Children
    move with their part's centre. -> the number of parts grown."""
    fronts = [i for i in members if obj.parts[i].label in FRONTS]
    if not fronts:
        return 0
    R0, R1 = _union([obj.parts[i] for i in fronts])
    P0, P1 = _lohi(obj.parts[parent])
    for d in range(3):
        if d != k:
            R1[d] = max(R1[d], P1[d] - FRAME)
            if d != 2:
                R0[d] = min(R0[d], P0[d] + FRAME)
    start = {i: obj.parts[i].bbox_center.copy() for i in fronts}
    axes = sorted((d for d in range(3) if d != k), key=lambda d: d != 2)   # z first
    for d in axes:
        box = {i: _lohi(obj.parts[i]) for i in fronts}
        new = {}
        for i in fronts:
            lo, hi = box[i][0].copy(), box[i][1].copy()
            up, down = R1[d], R0[d]
            for j in fronts:      # any front wholly beyond i along d stays beyond it, so
                jl, jh = box[j]     # what is above, below, left or right of what keeps so
                if j == i:
                    continue
                if jl[d] >= hi[d] - 1e-6:
                    up = min(up, (hi[d] + jl[d]) / 2 - GAP / 2)
                elif jh[d] <= lo[d] + 1e-6:
                    down = max(down, (lo[d] + jh[d]) / 2 + GAP / 2)
            lo[d], hi[d] = min(lo[d], down), max(hi[d], up)
            new[i] = (lo, hi)
        for i, (lo, hi) in new.items():
            _set(obj.parts[i], lo, hi)
    grown = 0
    for i in fronts:
        move = obj.parts[i].bbox_center - start[i]
        if np.abs(move).max() > 1e-6:
            grown += 1
            for c in obj.children(i):
                _move_subtree(obj, c, move)
    return grown


def siblings(obj: ArticulatedObject, cfg: LayoutConfig, report: dict) -> None:
    """Align repeated parts and cut overlapping siblings apart, parent by parent; children
    of a changed part are re-attached to it afterwards."""
    for par in obj.topological_order():
        faces: dict[tuple, list[int]] = {}
        for c in obj.children(par):
            f = face_of(obj, c)
            if f is not None:
                faces.setdefault(f, []).append(c)
        for (k, s), members in faces.items():
            if cfg.align:
                by_label: dict[str, list[int]] = {}
                for c in members:
                    by_label.setdefault(obj.parts[c].label, []).append(c)
                for label, same in by_label.items():
                    if len(same) >= 2:
                        _align(obj, same, k)
                        if label in SMALL:
                            _space_small(obj, same, k)
                        report["aligned_groups"] += 1
            if cfg.separate:
                report["separated"] += _separate_all(obj, members, k)
                report["cleared"] = report.get("cleared", 0) + _clear_panels(obj, members, k)
            if cfg.fill and obj.category == "StorageFurniture":
                report["filled"] = report.get("filled", 0) + _fill(obj, par, members, k)
            if cfg.attach:
                for c in members:
                    for g in obj.children(c):
                        f = face_of(obj, g)
                        if f is not None:
                            _attach(obj, g, f)


__all__ = ["LayoutConfig", "refine_layout", "face_of"]
