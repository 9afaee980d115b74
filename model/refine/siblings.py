"""Repeated parts and overlapping siblings of the layout refinement (model.refine.layout,
steps 3-5): align repeated parts on rows and columns, space small ones, cut overlapping
siblings apart, keep knobs, dials and buttons clear of the panels beside them."""
from __future__ import annotations

from types import SimpleNamespace
from typing import Optional

import numpy as np

from model.core import ArticulatedObject
from model.data.expected_structure import ARRANGEMENT_KEYS, POSITION_KEYS

from .layout import (CLEAR, CONTROLS, GAP, MIN_KEEP, MIN_SIDE, PANELS, SLIDERS, SMALL,
                     LayoutConfig, _attach, _lohi, _move_subtree, _principal, _set, _union,
                     face_of)

CLEAR_SWING = 0.02   # m between a knob, dial or button and a panel edge that swings out


def _clusters(values: np.ndarray, tol: float) -> list[list[int]]:
    order = np.argsort(values)
    groups: list[list[int]] = []
    for idx in order:
        if groups and values[idx] - values[groups[-1][-1]] <= tol:
            groups[-1].append(int(idx))
        else:
            groups.append([int(idx)])
    return groups


ALIGN_SPAN = 1.35   # a member this many times its row's median size across it is not of it


def _align(obj: ArticulatedObject, members: list[int], k: int, s: float) -> None:
    """Rows and columns of same-label siblings on the face with normal axis ``k`` (outwards
    along ``s``): members sharing a row get its mean coordinate and mean size across it,
    except one over ``ALIGN_SPAN`` times the row's median size ("a cabinet with seven
    drawers": a wide drawer under a column of three was narrowed to the column, holes
    either side of it); the whole group gets its mean depth with its outer sides at their
    median (a drawer stack stays flush with the face it was attached to)."""
    parts = [obj.parts[i] for i in members]
    for d in (d for d in range(3) if d != k):
        cs = np.array([p.bbox_center[d] for p in parts])
        sizes = np.array([p.bbox_size[d] for p in parts])
        for g in _clusters(cs, 0.35 * float(np.median(sizes))):
            mid = float(np.median(sizes[g]))
            g = [m for m in g if sizes[m] <= ALIGN_SPAN * mid]   # a front wider than its
            if len(g) < 2:                                      # column spans more of them
                continue
            c, size = float(cs[g].mean()), float(sizes[g].mean())
            for m in g:
                parts[m].bbox_center[d] = c
                parts[m].bbox_size[d] = size
    # same depth along the normal for the whole group, outer sides where most of them are
    size = float(np.mean([p.bbox_size[k] for p in parts]))
    outer = float(np.median([p.bbox_center[k] + s * p.bbox_size[k] / 2 for p in parts]))
    for p in parts:
        p.bbox_size[k], p.bbox_center[k] = size, outer - s * size / 2


HEAPS = ("drawer", "door")   # fronts whose heaps become grids
HEAP = 0.3                   # of the smaller front's face covered by another: a heap


def _face_areas(a: tuple, b: tuple, k: int) -> tuple[float, float, float]:
    """Boxes ``a`` and ``b`` as (lo, hi) seen on a face of normal axis ``k``: (area of their
    overlap, area of a, area of b)."""
    ax = [d for d in range(3) if d != k]
    (alo, ahi), (blo, bhi) = a, b
    inter = np.prod(np.clip(np.minimum(ahi, bhi)[ax] - np.maximum(alo, blo)[ax], 0, None))
    return float(inter), float(np.prod((ahi - alo)[ax])), float(np.prod((bhi - blo)[ax]))


def _heaped(obj: ArticulatedObject, members: list[int], k: int) -> bool:
    """Whether two of ``members`` cover more than ``HEAP`` of the smaller one's face (the
    in-face axes of normal ``k``) — the decoder's guess at a group it could not place."""
    boxes = [_lohi(obj.parts[i]) for i in members]
    for n, a in enumerate(boxes):
        for b in boxes[n + 1:]:
            inter, area_a, area_b = _face_areas(a, b, k)
            if inter > HEAP * min(area_a, area_b):
                return True
    return False


def _alone(obj: ArticulatedObject, group: list[int], members: list[int], k: int) -> bool:
    """Whether no other door or drawer on the face covers more than ``HEAP`` of its own face
    inside ``group``'s rectangle (a front where two groups heap over each other is left to
    the separation, which splits the groups apart first)."""
    rect = _union([obj.parts[i] for i in group])
    for i in members:
        if i in group or obj.parts[i].label not in HEAPS:
            continue
        inter, _, own = _face_areas(rect, _lohi(obj.parts[i]), k)
        if inter > HEAP * own:
            return False
    return True


def _unheap(obj: ArticulatedObject, members: list[int]) -> list[int]:
    """A heap of same-label fronts on a front face becomes rows of equal cells over the
    rectangle it covers (``arrange._lay_out``, top row first). The columns are the heap's
    own: its members' horizontal centres chained within half their median width (the
    decoder stacks a chest's drawers with the right vertical order but boxes too tall to
    fit); the rows follow from the count. -> parts per row."""
    from .arrange import H, _lay_out

    parts = [obj.parts[i] for i in members]
    width = float(np.median([p.bbox_size[H] for p in parts]))
    cols = len(_clusters(np.array([p.bbox_center[H] for p in parts]), 0.5 * width))
    rows = -(-len(members) // cols)
    per = [cols] * (rows - 1) + [len(members) - cols * (rows - 1)]
    _lay_out(obj, members, per)
    return per


EVEN_WIDTH = 1.5    # fronts of one label within this ratio of widths: one column size


def _uneven(obj: ArticulatedObject, members: list[int], stated: Optional[dict]) -> bool:
    """Whether ``members`` (five or more storage drawers or doors of one label on the front,
    no arrangement or place stated for them) are columns of one width holding different
    numbers of fronts: "a cabinet with ten drawers", seed 2, came out as columns of 4, 3 and
    3 drawers at staggered heights, with holes between them. A front of the data repeats one
    cell; a layout of wide and narrow fronts ("two small drawers over three wide ones") is
    left as decoded."""
    from .arrange import H

    parts = [obj.parts[i] for i in members]
    if obj.category != "StorageFurniture" or len(members) < 5 or parts[0].label not in HEAPS \
            or set((stated or {}).get(parts[0].label) or {}) & PLACED:
        return False
    widths = [p.bbox_size[H] for p in parts]
    if max(widths) > EVEN_WIDTH * min(widths):
        return False
    cols = _clusters(np.array([p.bbox_center[H] for p in parts]), 0.5 * float(np.median(widths)))
    return len({len(c) for c in cols}) > 1


TALL_DRAWER = 1.5   # a drawer front this many times as tall as wide is no drawer furniture has


def _restack(obj: ArticulatedObject, drawers: list[int], facts: dict) -> int:
    """Drawers decoded side by side as tall narrow fronts (the synth-6 data had them; synth-7
    does not) are stacked over the rectangle they cover, one per row, unless the prompt
    states their arrangement (or drawers on both sides). -> rows restacked."""
    from .arrange import H, V, _lay_out

    if facts.keys() & ARRANGED or len(facts.get("hpos") or []) > 1:
        return 0
    parts = [obj.parts[i] for i in drawers]
    height = float(np.median([p.bbox_size[V] for p in parts]))
    done = 0
    for row in _clusters(np.array([p.bbox_center[V] for p in parts]), 0.25 * height):
        fronts = [parts[j] for j in row]
        if len(row) >= 2 and all(p.bbox_size[V] > TALL_DRAWER * p.bbox_size[H]
                                 for p in fronts):
            _lay_out(obj, [drawers[j] for j in row], [1] * len(row))
            done += 1
    return done


SLIVER = 0.06       # m: a storage front narrower or lower than this is no door or drawer
PLACED = ARRANGEMENT_KEYS | POSITION_KEYS   # stated facts that keep a face's own layout


def _retile(obj: ArticulatedObject, members: list[int], stated: dict,
            tall: bool = False) -> int:
    """Doors and drawers that the cuts left as slivers (a front under ``SLIVER`` across: the
    network had decoded them on top of each other) are laid out again; with ``tall`` (after
    the restack) so are fronts that still overlap or a drawer still over ``TALL_DRAWER``
    times as tall as wide (five drawers heaped beside a door came out as 8 cm wide, 36 cm
    tall strips, two of them overlapping; the data's drawers are at most 1.16 times as tall
    as wide). Laid out again over the rectangle the face's fronts cover: the drawers one
    stack, the doors side by side, the two blocks next to each other in the order of their
    centres, each as wide as its share of the columns (a column per door, one for the
    stack), ``GAP`` apart. Not where the prompt states their arrangement or places, or other
    parts than fronts share the face.
    -> 1 if laid out again."""
    from .arrange import FRONT, H, V, _lay_out, _place

    fronts = [i for i in members if obj.parts[i].label in HEAPS]
    if not fronts or len(fronts) < len(members) \
            or any(set(stated.get(lab) or {}) & PLACED for lab in HEAPS):
        return 0
    parts = [obj.parts[i] for i in fronts]
    if all(min(p.bbox_size[H], p.bbox_size[V]) >= SLIVER for p in parts) and not (tall and (
            any(p.label == "drawer" and p.bbox_size[V] > TALL_DRAWER * p.bbox_size[H]
                for p in parts)
            or any(_overlap(a, b, GAP / 4) for n, a in enumerate(parts) for b in parts[n + 1:]))):
        return 0
    lo, hi = _union([obj.parts[i] for i in fronts])
    blocks = [[i for i in fronts if obj.parts[i].label == lab] for lab in HEAPS]
    blocks = sorted((b for b in blocks if b),
                    key=lambda b: np.mean([obj.parts[i].bbox_center[H] for i in b]))
    stack = [obj.parts[b[0]].label == "drawer" for b in blocks]
    cols = [1 if st else len(b) for b, st in zip(blocks, stack)]
    step = (hi[H] - lo[H]) / sum(cols)
    left = lo[H]
    for block, n, st in zip(blocks, cols, stack):
        right = left + n * step
        centre, size = (lo + hi) / 2, hi - lo
        centre[H], size[H] = (left + right) / 2, right - left - GAP
        for i in block:                  # the block's rectangle (depth kept), then its cells
            c, z = centre.copy(), size.copy()
            c[FRONT], z[FRONT] = obj.parts[i].bbox_center[FRONT], obj.parts[i].bbox_size[FRONT]
            _place(obj, i, c, z)
        _lay_out(obj, block, [1] * len(block) if st else [len(block)], gap=GAP)
        left = right
    return 1


def _groups(obj: ArticulatedObject, members: list[int]) -> list[list[int]]:
    """The drawers and the doors among ``members``, by label, two or more each."""
    out = [[i for i in members if obj.parts[i].label == label] for label in HEAPS]
    return [g for g in out if len(g) >= 2]


def _regular(obj: ArticulatedObject, members: list[int], group: list[int]) -> int:
    """Drawers or doors of one label that fill a grid — centres within half the median
    width one column, within half the median height one row, one part in every cell — get equal
    cells of that grid over the rectangle they cover, ``GAP`` apart, as built furniture
    repeats one drawer or door; not where another part on the face reaches into that
    rectangle. -> 1 if laid out."""
    from .arrange import H, V, _place

    parts = [obj.parts[i] for i in group]
    cell = {}
    for ax in (H, V):
        lines = _clusters(np.array([p.bbox_center[ax] for p in parts]),
                          0.5 * float(np.median([p.bbox_size[ax] for p in parts])))
        for n, line in enumerate(lines):
            for m in line:
                cell.setdefault(m, []).append((n, len(lines)))
    (_, cols), (_, rows) = cell[0]
    if len({tuple(c[0] for c in v) for v in cell.values()}) < len(group) \
            or rows * cols != len(group) or _crossed(obj, members, group):
        return 0
    lo, hi = _union(parts)
    lo, hi = lo - GAP / 2, hi + GAP / 2
    for m, ((c, cols), (r, rows)) in cell.items():
        centre, size = parts[m].bbox_center.copy(), parts[m].bbox_size.copy()
        for ax, n, count in ((H, c, cols), (V, r, rows)):
            step = (hi[ax] - lo[ax]) / count
            centre[ax], size[ax] = lo[ax] + (n + 0.5) * step, step - GAP
        _place(obj, group[m], centre, size)
    return 1


def _crossed(obj: ArticulatedObject, members: list[int], group: list[int]) -> bool:
    """Whether a part of the face outside ``group`` reaches into the rectangle it covers."""
    lo, hi = _union([obj.parts[i] for i in group])
    return any(np.all(_lohi(obj.parts[i])[0] < hi) and np.all(_lohi(obj.parts[i])[1] > lo)
               for i in members if i not in group)


def _relay(obj: ArticulatedObject, members: list[int], group: list[int], per: list[int]) -> None:
    """A heap's grid (``per`` parts per row) laid out again in equal cells ``GAP`` apart
    over the rectangle the fill grew it to, unless another part reaches into it."""
    from .arrange import _lay_out

    if not _crossed(obj, members, group):
        _lay_out(obj, group, per, gap=GAP)


def _drawer_handles(obj: ArticulatedObject, drawers: list[int]) -> int:
    """Drawers on a front, each with one child of a single label (its handle or knob): the
    child is centred across its drawer, as the data's always are, and kept within a quarter
    of the drawer's height of its middle (the data's are at the middle or near the top);
    where the drawers' boxes are equal (within 1 mm) the children also share their median
    size and height on the front. -> children moved."""
    from .arrange import H, V

    kids = [obj.children(i) for i in drawers]
    if any(len(c) != 1 for c in kids) or len({obj.parts[c[0]].label for c in kids}) != 1:
        return 0
    kids = [c[0] for c in kids]
    sizes = np.array([obj.parts[i].bbox_size for i in drawers])
    same = len(drawers) > 1 and np.ptp(sizes, axis=0).max() <= 1e-3
    offsets = np.array([obj.parts[c].bbox_center - obj.parts[i].bbox_center
                        for i, c in zip(drawers, kids)])
    size = np.median([obj.parts[c].bbox_size for c in kids], axis=0)
    for n, (i, c) in enumerate(zip(drawers, kids)):
        off = offsets[n].copy()
        off[H] = 0.0
        if same:
            off[V] = float(np.median(offsets[:, V]))
            obj.parts[c].bbox_size = size.copy()
        reach = obj.parts[i].bbox_size[V] / 4        # the data's: centred, or near the top
        off[V] = float(np.clip(off[V], -reach, reach))
        _move_subtree(obj, c, obj.parts[i].bbox_center + off - obj.parts[c].bbox_center)
    return len(kids)


ROW_OVERLAP = 0.9   # of the median size across a row: centres closer than this share a row
ARRANGED = ARRANGEMENT_KEYS   # stated facts whose rows model.refine.arrange laid


def _space_small(obj: ArticulatedObject, members: list[int], k: int,
                 stated_rows: bool = False) -> None:
    """Small parts that collide are spread evenly along the in-face axis of their largest
    spread, within their parent's face, row by row. Parts whose boxes overlap across the
    row (centres within ``ROW_OVERLAP`` of the median size: a stove's knobs decoded as two
    interleaved, overlapping rows) form one row at their mean height; a keypad's rows,
    a pitch apart, stay rows, as do rows the prompt states (``stated_rows``: laid out by
    model.refine.arrange, rows half a size apart)."""
    parts = [obj.parts[i] for i in members]
    if len(parts) < 2 or not any(_overlap(a, b) for n, a in enumerate(parts)
                                 for b in parts[n + 1:]):
        return
    ax = [d for d in range(3) if d != k]
    cs = np.array([p.bbox_center for p in parts])
    d = max(ax, key=lambda a: np.ptp(cs[:, a]))
    other = [a for a in ax if a != d][0]
    # a grid when the other axis has distinct rows: space within each row only
    tol = 0.5 if stated_rows else ROW_OVERLAP
    rows = _clusters(cs[:, other], tol * float(np.median([p.bbox_size[other] for p in parts])))
    plo, phi = _lohi(obj.parts[parts[0].parent])
    for row in rows:
        if len(row) < 2:
            continue
        if not stated_rows:
            for m in row:
                parts[m].bbox_center[other] = float(cs[row, other].mean())
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


ROUND = ("knob", "dial")   # round in the data (model/data/synth: _knob's radius)


def _round_controls(obj: ArticulatedObject, members: list[int], k: int, s: float) -> int:
    """Knobs and dials on the face of normal axis ``k`` (outwards along ``s``) get a square
    footprint in the face, their shorter side, about their centre, and stand out from the
    face no more than that side: every knob and dial of the data is round and about 0.7 of
    its diameter deep, and a decoded knob cut apart from its neighbours can be left 20 cm
    wide, 1.5 cm tall and 10 cm deep. -> parts changed."""
    changed = 0
    u, v = [d for d in range(3) if d != k]
    for c in members:
        p = obj.parts[c]
        if p.label not in ROUND:
            continue
        lo, hi = _lohi(p)
        side = float(min(hi[u] - lo[u], hi[v] - lo[v]))
        if max(hi[u] - lo[u], hi[v] - lo[v], hi[k] - lo[k]) <= side * (1 + 1e-6):
            continue
        for d in (u, v):
            mid = (lo[d] + hi[d]) / 2
            lo[d], hi[d] = mid - side / 2, mid + side / 2
        if hi[k] - lo[k] > side:         # the side on the face stays where it is
            if s > 0:
                hi[k] = lo[k] + side
            else:
                lo[k] = hi[k] - side
        _set(p, lo, hi)
        changed += 1
    return changed


def _clearance(front, d: int) -> float:
    """How far a knob, dial or button beside ``front`` along axis ``d`` stays from it:
    ``CLEAR_SWING`` beside a door's or lid's edges that swing out (across its hinge axis),
    else ``CLEAR``."""
    if front.label in PANELS and _principal(front.joint.axis)[0] != d:
        return CLEAR_SWING
    return CLEAR


def _clear_panels(obj: ArticulatedObject, members: list[int], k: int) -> int:
    """Knobs, dials and buttons on a face keep ``CLEAR`` from the outline of a door or lid
    on that face: a panel swings its edge out past its closed outline by up to its
    thickness, and the collision pieces of both stand a few millimetres proud of their
    meshes (an oven door stalled on the knob 3 mm above it). A small part closer than that
    moves away along the axis it stands beside the panel on, or, when it stands in front of
    the panel, off its outline the shortest way, within its parent's face; where it cannot
    move, or the move would bring it onto another control (a row of knobs above the one it
    belongs to), the panel gives way on that side. Beside the edges that swing out (across
    the hinge axis: the top edge of a drop-down door, the free edge of a side-hinged one) the
    panel then gives way to ``CLEAR_SWING``: the collision pieces are cells of the part's
    meshing grid (a centimetre on a 70 cm door), and a drop-down door's top edge clipped
    knobs 1.2 cm above it; the knobs stay, so rows of them keep their places. Returns how
    many moved or gave way."""
    panels = [obj.parts[c] for c in members if obj.parts[c].label in PANELS]
    plo, phi = _lohi(obj.parts[obj.parts[members[0]].parent])
    moved = 0
    ins = [d for d in range(3) if d != k]
    controls = [obj.parts[c] for c in members if obj.parts[c].label in CONTROLS]

    def give_way(panel, q, n: int, clear: float) -> None:
        lo, hi = _lohi(panel)
        qlo, qhi = _lohi(q)
        d, up = ins[n], q.bbox_center[ins[n]] > panel.bbox_center[ins[n]]
        keep = MIN_KEEP * (hi[d] - lo[d])
        if up:
            hi[d] = max(min(hi[d], qlo[d] - clear), lo[d] + keep)
        else:
            lo[d] = min(max(lo[d], qhi[d] + clear), hi[d] - keep)
        _set(panel, lo, hi)

    def gaps_of(panel, q) -> list[float]:
        (lo, hi), (qlo, qhi) = _lohi(panel), _lohi(q)
        return [max(lo[d] - qhi[d], qlo[d] - hi[d]) for d in ins]   # < 0: extents overlap

    for c in members:
        q = obj.parts[c]
        if q.label not in CONTROLS:
            continue
        for panel in panels:
            gaps = gaps_of(panel, q)
            if max(gaps) < CLEAR:
                # beside the panel: away along that axis; in front of it (a knob on a door's
                # outline, which the door hits when it opens): off it the shortest way
                order = [int(np.argmax(gaps))] if max(gaps) >= 0 else \
                    list(np.argsort(gaps)[::-1])
                for n in order:
                    d = ins[n]
                    up = q.bbox_center[d] > panel.bbox_center[d]
                    new = q.bbox_center[d] + (CLEAR - gaps[n]) * (1.0 if up else -1.0)
                    if plo[d] + q.bbox_size[d] / 2 <= new <= phi[d] - q.bbox_size[d] / 2:
                        if _onto_controls(q, d, new, controls):   # its row stays: the panel
                            give_way(panel, q, n, CLEAR)           # gives way instead
                        else:
                            q.bbox_center[d] = new
                        break
                else:            # no room to move it: the panel gives way on that side
                    give_way(panel, q, order[0], CLEAR)
                moved += 1
    for c in members:            # then the swinging edges give way, the parts staying put
        q = obj.parts[c]
        if q.label not in CONTROLS:
            continue
        for panel in panels:
            gaps = gaps_of(panel, q)
            n = int(np.argmax(gaps))
            need = _clearance(panel, ins[n])
            if gaps[n] < need and all(g < 0 for m, g in enumerate(gaps) if m != n):
                give_way(panel, q, n, need)
                moved += 1
    return moved


def _onto_controls(q, d: int, centre: float, controls: list) -> bool:
    """Whether moving control ``q``'s centre to ``centre`` along axis ``d`` brings it within
    GAP of another control it stands clear of now (the lower row of "six knobs, 2 rows of
    3" lifted off an oven door into the upper row), or into one it is within GAP of but
    does not overlap now (a column of knobs 1 mm apart: the lowest, lifted 1.7 cm off a
    toaster oven's door, had gone half into the one above it)."""
    moved = SimpleNamespace(bbox_center=q.bbox_center.copy(), bbox_size=q.bbox_size)
    moved.bbox_center[d] = centre
    return any(o is not q and ((not _overlap(q, o, -GAP) and _overlap(moved, o, -GAP))
                               or (not _overlap(q, o) and _overlap(moved, o)))
               for o in controls)


def _overlap(a, b, pad: float = 0.0) -> bool:
    alo, ahi = _lohi(a)
    blo, bhi = _lohi(b)
    return bool(np.all(alo < bhi - pad) and np.all(blo < ahi - pad))


def _separate(first_group: list, second_group: list, k: int) -> bool:
    """Cut two groups of sibling boxes apart in the face plane (normal axis ``k``) along the
    in-face axis where their union boxes already stand furthest apart (centre distance over
    mean size): stacked drawers split vertically, a door beside a drawer column sideways.
    Each box keeps at least MIN_KEEP of its size, and MIN_SIDE. Returns whether they
    overlapped."""
    alo, ahi = _union(first_group)
    blo, bhi = _union(second_group)
    if not (np.all(alo < bhi - GAP / 4) and np.all(blo < ahi - GAP / 4)):
        return False
    ac, bc = (alo + ahi) / 2, (blo + bhi) / 2
    d = max((d for d in range(3) if d != k),
            key=lambda d: abs(ac[d] - bc[d]) / max((ahi[d] - alo[d] + bhi[d] - blo[d]) / 2, 1e-9))
    low, high = (first_group, second_group) if ac[d] <= bc[d] else (second_group, first_group)
    cut = (max(alo[d], blo[d]) + min(ahi[d], bhi[d])) / 2

    def keep(lo, hi) -> float:      # cut after cut, never below MIN_SIDE (a drawer cut to
        size = hi[d] - lo[d]         # 0.5 mm meshed as a 65,000-face sheet)
        return max(MIN_KEEP * size, min(MIN_SIDE, size))

    for p in low:
        lo, hi = _lohi(p)
        hi[d] = min(hi[d], max(cut - GAP / 2, lo[d] + keep(lo, hi)))
        _set(p, lo, hi)
    for p in high:
        lo, hi = _lohi(p)
        lo[d] = max(lo[d], min(cut + GAP / 2, hi[d] - keep(lo, hi)))
        _set(p, lo, hi)
    return True


def _separate_all(obj: ArticulatedObject, members: list[int], k: int,
                  stated: Optional[dict] = None) -> int:
    """Repeated parts among themselves first (a stack splits into rows), then each label's
    group against each other's, then any pair left. Two groups the prompt puts one either
    side of the other (``stated``, ``arrange._flanks``: doors left and right of a drawer
    stack) are cut apart only where two of their members overlap: their unions do."""
    from .arrange import _flanks

    flanked = {frozenset(pair) for pair in _flanks(stated)}
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
                if frozenset((a[0].label, b[0].label)) not in flanked \
                        or any(_overlap(p, q, GAP / 4) for p in a for q in b):
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
BEYOND = 0.1       # of the smaller front's side: an overlap that still leaves it beyond
KEEP_SIDE = 0.25   # half-faces off the middle a front stated on one side keeps (the alignment
                   # check's margin is 0.2, model.data.spatial.HPOS_MARGIN)
# m of carcass left around the fronts a face's fill grows, per category, and whether the
# bottom is held too (the data's medians, model/data/synth: a cabinet's sides and top, its
# bottom varying with the plinth; an oven's walls around its door and drawer, the control
# panel above them; a safe's walls). Washers keep their round doors as decoded.
FILL_FRAME = {"StorageFurniture": (0.023, False), "Oven": (0.03, True), "Safe": (0.05, True)}
# of the body's height: an open band under a storage face's fronts at least this tall stays
# open, a narrower one is filled. The data leaves a band of a tenth of the height or more
# under 15 % of its fronts, most of them a quarter of it (a cell left open), the rest a
# plinth (median 3.4 %); the decoder left one of a tenth or more under 41 % (80 free-form
# prompts x 2 seeds), most of them under a fifth of the height; with this, 14 %.
OPEN_CELL = 0.18


def _stated_down_to_bottom(stated: dict, labels: set) -> bool:
    """Whether the prompt lays out the fronts of ``labels`` from top to bottom: a front at the
    bottom or lower than another ("a lower door", "drawers at the bottom", "a drawer above
    two doors"), in rows ("two upper and two lower doors", "in a column"), or on one side
    with nothing said of its height ("a door on the left": a column of the front; the
    README's example had been left with a quarter of its height open under its door and
    drawers with 5 of 8 seeds). The fill then grows the lowest fronts down to the frame: a
    storage front may leave an open band below its fronts (as 15 % of the data's do by a
    tenth of the height or more, ``OPEN_CELL``), but not one whose lower fronts the user
    named."""
    for label in labels:
        facts = stated.get(label) or {}
        if "bottom" in (facts.get("vpos") or []) or facts.get("above") or facts.get("below") \
                or facts.get("layout") in ("column", "grid") or (facts.get("rows") or 0) > 1 \
                or len(facts.get("per_row") or []) > 1 \
                or (set(facts.get("hpos") or []) & {"left", "right"} and not facts.get("vpos")):
            return True
    return False


def _kept_side(stated: dict, label: str, d: int) -> Optional[float]:
    """-1 / +1 when the prompt puts ``label`` on one side along axis ``d`` (y: "on the left" /
    "on the right"; z: "at the bottom" / "on top"), else None."""
    want = (stated.get(label) or {}).get("hpos" if d == 1 else "vpos") or []
    sides = {"left": -1.0, "right": 1.0} if d == 1 else {"bottom": -1.0, "top": 1.0}
    return sides.get(want[0]) if len(want) == 1 else None


def _recess(obj: ArticulatedObject, parent: int, fronts: list[int], deep: list[int],
            k: int) -> None:
    """A tray the network put at the depth of a front that now covers it (an oven rack level
    with the door) moves back into its parent, ``GAP`` behind the front, as the data's racks
    sit in the cavity behind the door."""
    pc = obj.parts[parent].bbox_center[k]
    for j in deep:
        for i in fronts:
            (lo, hi), (jl, jh) = _lohi(obj.parts[i]), _lohi(obj.parts[j])
            if not np.all((jl < hi - 1e-6) & (lo < jh - 1e-6)):
                continue
            s = 1.0 if obj.parts[i].bbox_center[k] >= pc else -1.0
            move = np.zeros(3)
            move[k] = (lo[k] - GAP - jh[k]) if s > 0 else (hi[k] + GAP - jl[k])
            _move_subtree(obj, j, move)


def _fill(obj: ArticulatedObject, parent: int, members: list[int], k: int,
          stated: Optional[dict] = None) -> int:
    """The doors and drawers on one face grow to tile it: a decoded front often leaves
    drawers as small boxes in a wide empty face, or an oven's door in a corner of its
    front, where the data's fronts cover 93 % (storage, median) of the rectangle they span,
    and that rectangle reaches to the category's frame (``FILL_FRAME``) of the carcass
    (a storage front's bottom only where the prompt lays it out, ``_stated_down_to_bottom``).
    Vertical extents first, then horizontal (past the parts above or below it at its new
    height); a part grows towards a front wholly beyond it only to the middle of the gap
    between them (``GAP`` apart), and towards a knob, dial, button or handle on its face
    only to ``_clearance`` of it, so every front above, below, left or right of another stays
    so, and every small part beside it; nothing shrinks. A tray it now covers goes in behind it
    (``_recess``). A front the prompt puts on one side
    (``stated``: "a door on the left") keeps its centre there, at least ``KEEP_SIDE`` of the
    half-face off the middle; one it puts at the top or bottom, or on one side where its
    kind is all the face holds ("three drawers on the right"), grows only towards that edge.
    A drawer's children move with its centre; a door's stay where they are (on the door,
    which only grew: a dial stated in the middle stays there).
    -> the number of parts grown."""
    frame, bottom = FILL_FRAME[obj.category]
    fronts = [i for i in members if obj.parts[i].label in FRONTS]
    bottom = bottom or _stated_down_to_bottom(stated or {}, {obj.parts[i].label for i in fronts})
    fixed = [i for i in members if obj.parts[i].label in SMALL]
    deep = [i for i in members if obj.parts[i].label not in FRONTS + SMALL]   # trays
    if not fronts:
        return 0
    R0, R1 = _union([obj.parts[i] for i in fronts])
    P0, P1 = _lohi(obj.parts[parent])
    if not bottom and R0[2] - P0[2] < OPEN_CELL * (P1[2] - P0[2]):
        bottom = True          # a band under the fronts narrower than the data's open cells
    for d in range(3):
        if d != k:
            R1[d] = max(R1[d], P1[d] - frame)
            if d != 2 or bottom:
                R0[d] = min(R0[d], P0[d] + frame)
    start = {i: obj.parts[i].bbox_center.copy() for i in fronts}
    alone = len({obj.parts[i].label for i in fronts}) == 1 and not fixed  # all the face holds
    axes = sorted((d for d in range(3) if d != k), key=lambda d: d != 2)   # z first
    for n, d in enumerate(axes):
        box = {i: _lohi(obj.parts[i]) for i in fronts + fixed}
        new = {}
        for i in fronts:
            lo, hi = box[i][0].copy(), box[i][1].copy()
            up, down = R1[d], R0[d]
            clear = _clearance(obj.parts[i], d)
            for j in fronts + fixed:   # any part wholly beyond i along d stays beyond it, so
                jl, jh = box[j]         # what is above, below, left or right of what keeps so
                if j == i or n and not _beside(box[i], box[j], axes[0]):
                    continue
                # touching within a tenth of the smaller side still counts as beyond
                tol = BEYOND * min(hi[d] - lo[d], jh[d] - jl[d]) + 1e-6
                front = j in start          # a front: the middle of the gap; else CLEAR
                if jl[d] >= hi[d] - tol:
                    up = min(up, (hi[d] + jl[d] - GAP) / 2 if front else jl[d] - clear)
                elif jh[d] <= lo[d] + tol:
                    down = max(down, (lo[d] + jh[d] + GAP) / 2 if front else jh[d] + clear)
            lo0, hi0 = lo[d], hi[d]
            lo[d], hi[d] = min(lo[d], down), max(hi[d], up)
            side = _kept_side(stated or {}, obj.parts[i].label, d)
            if side is not None and (d == 2 or alone):   # "at the bottom" / "on top", or
                if side < 0:           # the face's only fronts "on the right": it grows to
                    hi[d] = hi0        # that edge only, the rest of the face left open ("a
                else:                  # bookcase with two doors at the bottom" had its doors
                    lo[d] = lo0        # grown to 80 % of its height; "a desk with three
                                       # drawers on the right" to three quarters of its width)
            elif side is not None:   # the centre stays off the middle on its stated side
                mid, half = (P0[d] + P1[d]) / 2, (P1[d] - P0[d]) / 2
                off = min(side * (start[i][d] - mid) / half, KEEP_SIDE)
                if off > 0:
                    edge = 2 * (mid + side * off * half)      # = lo + hi at the limit
                    if side < 0:
                        hi[d] = max(min(hi[d], edge - lo[d]), hi0)
                    else:
                        lo[d] = min(max(lo[d], edge - hi[d]), lo0)
            new[i] = (lo, hi)
        for i, (lo, hi) in new.items():
            _set(obj.parts[i], lo, hi)
    _recess(obj, parent, fronts, deep, k)
    grown = 0
    for i in fronts:
        move = obj.parts[i].bbox_center - start[i]
        if np.abs(move).max() > 1e-6:
            grown += 1
            if obj.parts[i].label in SLIDERS:      # a drawer's handle stays centred on it
                for c in obj.children(i):
                    _move_subtree(obj, c, move)
    return grown


# An oven's front in the data (model/data/synth/cabinets.py, every object of the category):
# its knobs and buttons in one row, evenly spaced across the width, on a control panel 7-14 cm
# tall at the top; a knob at most 0.64 of the panel's height and 0.7 of its slot; the door
# below, over the cavity's width (and a drawer under the door in tall ovens)
PANEL_TALL = (0.07, 0.14)    # m
PANEL_KNOB = 0.64            # a control's side at most this share of the panel's height
SLOT_KNOB = 0.7              # ... and of its slot's width
PANEL_SHARE = 0.25           # of the body's height, the most the panel takes
SMALL_DOOR = 0.3             # of the face's height or width: a door this small is a sliver
HANDLE_DROP = 0.035          # m from a drop-down door's top edge to its handle's centre


def _oven_panel(obj: ArticulatedObject, par: int, members: list[int], k: int,
                stated: Optional[dict] = None) -> int:
    """An oven's front laid out as the data's are (``PANEL_TALL``) where the cuts and the
    fill left its one door blocked by its own controls: a control still on the door's
    rectangle of the face, a door under ``SMALL_DOOR`` of the face's height or width, or one
    that drops down under controls spread over more than a panel's height above it (a
    column beside it, as on a toaster oven, stays; "a dishwasher" came out with its knobs in
    a column down the middle of its front and the door cut between them to a 1.4 cm strip,
    or a knob column above a door a third of the front tall).
    The controls go into one row across a panel at the top, their left-to-right order kept,
    and the door fills the face below it (down to a drawer under it). Not where the prompt
    places the door or a control ("a microwave": its usual control column), nor on a face
    with more than one door or with another front that is not below the door. -> 1 when laid
    out, else 0."""
    if obj.category != "Oven" or obj.parts[par].parent >= 0 or k == 2:
        return 0
    doors = [i for i in members if obj.parts[i].label == "door"]
    ctrl = [i for i in members if obj.parts[i].label in CONTROLS]
    if len(doors) != 1 or not ctrl or any(
            set((stated or {}).get(lab) or {}) & (POSITION_KEYS | ARRANGEMENT_KEYS)
            for lab in {obj.parts[i].label for i in doors + ctrl}):
        return 0
    door = obj.parts[doors[0]]
    H, V = [d for d in range(3) if d not in (k, 2)][0], 2
    (dlo, dhi), (plo, phi) = _lohi(door), _lohi(obj.parts[par])
    others = [i for i in members if obj.parts[i].label in FRONTS and i != doors[0]]
    if any(obj.parts[i].bbox_center[V] >= door.bbox_center[V] for i in others):
        return 0
    boxes = [_lohi(obj.parts[i]) for i in ctrl]
    on_door = any(_beside(box, (dlo, dhi), H) and _beside(box, (dlo, dhi), V) for box in boxes)
    small = (dhi[V] - dlo[V] < SMALL_DOOR * (phi[V] - plo[V])
             or dhi[H] - dlo[H] < SMALL_DOOR * (phi[H] - plo[H]))
    drops = door.joint.type.rotates and abs(door.joint.axis[V]) < 0.9
    over = [(lo, hi) for lo, hi in boxes if lo[V] >= dhi[V] - 1e-6]   # not a side column
    rows = bool(over) and max(hi[V] for _, hi in over) - min(lo[V] for lo, _ in over) \
        > PANEL_TALL[1]
    if not (on_door or small or (drops and rows)):
        return 0
    side = max(max(hi[d] - lo[d] for d in (H, V)) for lo, hi in boxes)
    tall = min(float(np.clip(side / PANEL_KNOB, *PANEL_TALL)), PANEL_SHARE * (phi[V] - plo[V]))
    frame = FILL_FRAME[obj.category][0]
    below = max((_lohi(obj.parts[i])[1][V] + GAP for i in others), default=plo[V] + frame)
    lo, hi = dlo.copy(), dhi.copy()           # the door's new box
    lo[H], hi[H] = plo[H] + frame, phi[H] - frame
    lo[V], hi[V] = below, phi[V] - tall - GAP
    if hi[V] - lo[V] < SMALL_DOOR * (phi[V] - plo[V]):
        return 0    # (not reached for the data's sizes: a drawer under the door is lower)
    width = phi[H] - plo[H]
    slot = width / (len(ctrl) + 1)
    cap = min(PANEL_KNOB * tall, SLOT_KNOB * slot)
    order = sorted(ctrl, key=lambda i: (obj.parts[i].bbox_center[H],
                                        -obj.parts[i].bbox_center[V]))
    usual = {lab: np.median([obj.parts[i].bbox_size for i in ctrl
                             if obj.parts[i].label == lab], axis=0)
             for lab in {obj.parts[i].label for i in ctrl}}
    for n, i in enumerate(order):
        p = obj.parts[i]
        centre, size = p.bbox_center.copy(), p.bbox_size.copy()
        centre[H], centre[V] = plo[H] + slot * (n + 1), phi[V] - tall / 2
        size = np.maximum(size, usual[p.label])    # a speck the cuts left: its siblings' size
        size[H], size[V] = min(size[H], cap), min(size[V], cap)
        if p.label in ("knob", "dial"):       # round, as the panel lets it be
            size[H] = size[V] = min(size[H], size[V])
        _move_subtree(obj, i, centre - p.bbox_center)
        p.bbox_size = np.maximum(size, MIN_SIDE)
    # the door's handle keeps its place on the door, below the top edge of one that drops
    # down (the data's: HANDLE_DROP under it)
    carry_children(obj, doors[0], (dlo, dhi), (lo, hi), (H, V), drop=drops)
    _set(door, lo, hi)
    return 1


def carry_children(obj: ArticulatedObject, i: int, old: tuple, new: tuple, axes: tuple,
                   drop: bool = False) -> None:
    """The children of panel ``i`` (its handle) keep their place on it while its box goes
    from ``old`` to ``new`` ((lo, hi) each): along each of ``axes`` (across, up its face)
    at the same share of its extent, inside the new box; with ``drop`` (a door that drops
    down) ``HANDLE_DROP`` under its new top edge instead."""
    (olo, ohi), (lo, hi) = old, new
    up = axes[-1]
    for c in obj.children(i):
        q = obj.parts[c]
        move = np.zeros(3)
        for d in axes:
            t = (q.bbox_center[d] - olo[d]) / max(ohi[d] - olo[d], 1e-9)
            half = min(q.bbox_size[d], hi[d] - lo[d]) / 2
            at = hi[up] - max(HANDLE_DROP, half + CLEAR) if drop and d == up \
                else lo[d] + t * (hi[d] - lo[d])
            move[d] = np.clip(at, lo[d] + half, hi[d] - half) - q.bbox_center[d]
        _move_subtree(obj, c, move)


def _beside(a: tuple, b: tuple, d: int) -> bool:
    """Whether boxes ``a`` and ``b`` ((lo, hi) each) overlap in extent along axis ``d``: a
    front grown to its height (the fill's first pass) meets sideways only the parts that
    stand beside it, not those above or below it (an oven door 3 cm wide under a row of
    knobs and buttons stayed a 3 cm pole; "a cabinet with seven drawers" kept its one bottom
    drawer as narrow as the column of drawers above it, holes either side)."""
    return bool(a[0][d] < b[1][d] - 1e-6 and b[0][d] < a[1][d] - 1e-6)


# An oven's racks in the data (model/data/synth/cabinets.py, every tray of the category): wire
# frames 6.5 mm thick on ledges of the side walls, spanning the cavity between them (3 mm
# clear of each wall) from 1 cm off the back wall to 4.5 cm behind the front, one at 30 % of
# the cavity's height or two at 30 % and 65 % (each +-10 %); in a 150-object v4 sample they
# span 84-88 % of the body's depth and 91-93 % of its width
RACKS = ("Oven",)
RACK_CLEAR = 0.003        # m from each side wall
RACK_BACK = 0.01          # m off the back wall
RACK_FRONT = 0.045        # m behind the front face (behind the door: GAP behind it)
RACK_OUT = 0.03           # m a rack fully out stands past the front face, at least
RACK_THICK = (0.006, 0.012)  # m: the thickness a rack keeps (the data's 6.5 mm, a decoded
                            # box up to 1.2 cm)
RACK_SPACING = 0.2        # of the cavity height: racks closer than this are re-spaced
RACK_LEVELS = (0.3, 0.65)  # of the cavity height, bottom up: the data's rack heights
RACK_BAND = (0.25, 0.75)  # of the cavity height: decoded heights kept within it (the data's
                          # racks: 27-72 %)
RACK_RISE = 1.1           # a rack slides out at most this times its height above the door's
                          # hinge (the data's rule: it clears the open door, 70-90 degrees)


def _racks(obj: ArticulatedObject, parent: int, members: list[int], k: int, s: float,
           stated: Optional[dict] = None) -> int:
    """The trays of an oven's front span its cavity as the data's racks do (``RACKS``): the
    network often decodes a second rack as a small box high in the body or a rack half as
    deep as the oven. Across the face and in depth a rack reaches from wall to wall (the
    category's ``FILL_FRAME`` walls; across the face no further than the door spans) and
    from the back wall to behind the door; its thickness is kept within ``RACK_THICK``.
    Heights stay as decoded while every rack is within ``RACK_BAND`` of the cavity (the
    height the door covers, else the body's inside) and ``RACK_SPACING`` from the next;
    otherwise they go to ``RACK_LEVELS``. A rack slides out 40-60 % of its depth, at most
    ``RACK_RISE`` times its height above the cavity's floor and at least ``RACK_OUT`` past
    the front. Where the prompt places the trays vertically
    ("a crumb tray under the door", "a rack at the top") their heights stay, and only those
    in the cavity span it. -> racks changed."""
    trays = [i for i in members if obj.parts[i].label == "tray"]
    if not trays or obj.category not in RACKS or k == 2:     # k == 2: not a front
        return 0
    placed = _placed_trays(stated)
    wall = FILL_FRAME[obj.category][0]
    P0, P1 = _lohi(obj.parts[parent])
    doors = [i for i in members if obj.parts[i].label in PANELS]
    if doors:
        D0, D1 = _union([obj.parts[i] for i in doors])
        cav = (max(D0[2], P0[2] + wall), min(D1[2], P1[2] - wall))
        front = (D0[k] - GAP) if s > 0 else (D1[k] + GAP)
    else:
        cav = (P0[2] + wall, P1[2] - wall)
        front = P1[k] if s > 0 else P0[k]
    front = min(front, P1[k] - RACK_FRONT) if s > 0 else max(front, P0[k] + RACK_FRONT)
    back = (P0[k] + wall + RACK_BACK) if s > 0 else (P1[k] - wall - RACK_BACK)
    h = cav[1] - cav[0]
    if h <= 0 or (front - back) * s <= 0:
        return 0
    if placed:
        trays = [i for i in trays if cav[0] <= obj.parts[i].bbox_center[2] <= cav[1]]
    trays.sort(key=lambda i: obj.parts[i].bbox_center[2])
    zs = [float(obj.parts[i].bbox_center[2]) for i in trays]
    inside = all(cav[0] + RACK_BAND[0] * h <= z <= cav[0] + RACK_BAND[1] * h for z in zs)
    spaced = all(b - a >= RACK_SPACING * h for a, b in zip(zs, zs[1:]))
    if not (inside and spaced or placed):
        levels = RACK_LEVELS if len(trays) <= len(RACK_LEVELS) else \
            np.linspace(RACK_LEVELS[0], RACK_LEVELS[-1], len(trays))
        zs = [cav[0] + f * h for f in levels]
    for i, z in zip(trays, zs):
        lo, hi = _lohi(obj.parts[i])
        t = float(np.clip(hi[2] - lo[2], *RACK_THICK))
        lo[2], hi[2] = z - t / 2, z + t / 2
        lo[k], hi[k] = min(back, front), max(back, front)
        for d in range(2):     # wall to wall, within the door's span (a microwave's door
            if d != k:          # leaves its control panel beside it)
                lo[d] = max(P0[d] + wall, D0[d] if doors else -np.inf) + RACK_CLEAR
                hi[d] = min(P1[d] - wall, D1[d] if doors else np.inf) - RACK_CLEAR
        _set(obj.parts[i], lo, hi)
        # it slides 40-60 % of its depth and at most RACK_RISE times its height above the
        # cavity's floor, as the data's racks do, and at least RACK_OUT past the front face
        # (the opening it leaves through)
        j, depth = obj.parts[i].joint, hi[k] - lo[k]
        face = P1[k] if s > 0 else P0[k]
        travel = float(np.clip(max(abs(j.t_range[0]), abs(j.t_range[1])), 0.4 * depth,
                               0.6 * depth))
        travel = min(travel, max(RACK_OUT, RACK_RISE * (z - cav[0])))
        j.t_range = (0.0, max(travel, abs(face - front) + RACK_OUT))
    return len(trays)


def _placed_trays(stated: Optional[dict]) -> bool:
    """Whether the prompt places the trays vertically ("a crumb tray under the door")."""
    return bool(set((stated or {}).get("tray") or {}) & {"vpos", "below", "above"})


def _racks_to_the_door(obj: ArticulatedObject, faces: dict) -> None:
    """A tray decoded sliding out of another face of an oven than its door's (out of its
    back or side) is turned to slide out of the door's face, where every rack of the data
    leaves; ``faces`` ((axis, sign) -> members) is updated, and ``_racks`` then places it in
    the cavity (so not where the prompt places the trays itself). Only with one door face."""
    doors = [f for f, m in faces.items() if any(obj.parts[c].label in PANELS for c in m)]
    if len(doors) != 1:
        return
    k, s = doors[0]
    for f in [f for f in faces if f != doors[0]]:
        for c in [c for c in faces[f] if obj.parts[c].label == "tray"]:
            j = obj.parts[c].joint
            j.axis = np.eye(3)[k] * s
            j.t_range = (0.0, float(max(abs(j.t_range[0]), abs(j.t_range[1]))))
            faces[f].remove(c)
            faces[doors[0]].append(c)
        if not faces[f]:
            del faces[f]


def siblings(obj: ArticulatedObject, cfg: LayoutConfig, report: dict,
             stated: Optional[dict] = None) -> None:
    """Align repeated parts and cut overlapping siblings apart, parent by parent; children
    of a changed part are re-attached to it afterwards."""
    for par in obj.topological_order():
        faces: dict[tuple, list[int]] = {}
        for c in obj.children(par):
            f = face_of(obj, c)
            if f is not None:
                faces.setdefault(f, []).append(c)
        if cfg.fill and obj.category in RACKS and not _placed_trays(stated):
            _racks_to_the_door(obj, faces)
        for (k, s), members in faces.items():
            heaps: list[tuple] = []
            if cfg.align:
                by_label: dict[str, list[int]] = {}
                for c in members:
                    by_label.setdefault(obj.parts[c].label, []).append(c)
                for label, same in by_label.items():
                    if cfg.heaps and k == 0 and label in HEAPS and len(same) >= 2 \
                            and _heaped(obj, same, k) and _alone(obj, same, members, k):
                        heaps.append((same, _unheap(obj, same)))
                        report["unheaped"] = report.get("unheaped", 0) + 1
                    elif cfg.heaps and k == 0 and _uneven(obj, same, stated) \
                            and _alone(obj, same, members, k):
                        heaps.append((same, _unheap(obj, same)))
                        report["evened"] = report.get("evened", 0) + 1
                    if len(same) >= 2:
                        _align(obj, same, k, s)
                        if label in SMALL:
                            facts = set((stated or {}).get(label) or {})
                            _space_small(obj, same, k, bool(facts & ARRANGED))
                        report["aligned_groups"] += 1
            if cfg.separate:
                report["separated"] += _separate_all(obj, members, k, stated)
                report["rounded"] = report.get("rounded", 0) + _round_controls(obj, members, k,
                                                                               s)
                report["cleared"] = report.get("cleared", 0) + _clear_panels(obj, members, k)
            if cfg.fill and obj.category in FILL_FRAME:
                report["filled"] = report.get("filled", 0) + _fill(obj, par, members, k,
                                                                        stated or {})
            if cfg.fill:
                report["oven_panel"] = report.get("oven_panel", 0) + _oven_panel(
                    obj, par, members, k, stated)
            storage_front = cfg.heaps and k == 0 and obj.category == "StorageFurniture"
            if storage_front:
                report["retiled"] = report.get("retiled", 0) + _retile(obj, members,
                                                                       stated or {})
            if cfg.fill and obj.category in RACKS:
                report["racks"] = report.get("racks", 0) + _racks(obj, par, members, k, s,
                                                                  stated)
            if cfg.heaps and k == 0:      # drawers and doors in rows of equal cells
                heaped = {tuple(g) for g, _ in heaps}
                for g in _groups(obj, members):
                    if tuple(g) not in heaped:
                        report["regular"] = report.get("regular", 0) + _regular(obj, members, g)
            for same, per in heaps:       # a heap's grid grown by the fill: equal cells again
                _relay(obj, members, same, per)
            drawers = [c for c in members if obj.parts[c].label == "drawer"]
            if cfg.heaps and k == 0 and len(drawers) >= 2 and _restack(     # as the fill
                    obj, drawers, (stated or {}).get("drawer") or {}):          # grew them
                report["restacked"] = report.get("restacked", 0) + 1
                _regular(obj, members, drawers)      # one column of equal drawers again
            if storage_front:
                report["retiled"] = report.get("retiled", 0) + _retile(    # tall strips
                    obj, members, stated or {}, tall=True)                  # still left
            if cfg.align and k == 0 and drawers:
                report["handles"] = report.get("handles", 0) + _drawer_handles(obj, drawers)
            if cfg.attach:
                for c in members:
                    for g in obj.children(c):
                        f = face_of(obj, g)
                        if f is not None:
                            _attach(obj, g, f)


__all__ = ["LayoutConfig", "refine_layout", "face_of"]
