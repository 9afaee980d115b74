"""Arrangements a prompt states, held in the layout: "six drawers in two columns", "a 3 x 4
keypad", "four doors in a row", "two drawers stacked", "a door on the left". The transformer
decodes the parts a prompt names (counts are held during decoding); where they sit is its own
guess, and for groups of 6-12 parts it is rarely the stated grid.

* :func:`arrange_stated`, before the layout refinement — rows and columns (``layout`` row /
  column / grid, ``rows``, ``columns``): the group's members are put on that grid inside the
  rectangle they already cover on their parent's front or back face, top row first, equal
  cells, :data:`GAP_SHARE` of a cell between them; each keeps its depth, its children move
  with it. Then groups stated one above the other (``above`` / ``below``, or ``vpos`` top /
  bottom against the other drawers, trays, doors and lids on the face) or on one side of
  the others (``hpos`` left / right) that are not get an upper and a lower (or a left and a
  right) band of the span they cover, each group mapped into its band with its own layout.
  A group stated on one side or in the middle that no other group was banded against
  ("a dial on the right") is moved there on the body, within its parent's face. The
  refinement then attaches, aligns and separates as usual.
* :func:`place_stated_sides`, after it — a side (``hpos`` left / right): a group wholly on
  the other side of its face has the face's layout mirrored left to right (every sibling on
  that face, with its children and joints), so the rest of the front keeps its arrangement.

"left" is the viewer's, facing the front (``model.data.vocab``). Facts are read by
``model.data.prompt_parse``. Labels, counts, joint types and the tree never change.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from model.core import ArticulatedObject
from model.data.expected_structure import ARRANGEMENT_KEYS, POSITION_KEYS
from model.data.spatial import HPOS_MARGIN

from .layout import (CLEAR, GAP, MIN_SIDE, ON_FACE, PANELS, SIDE_HINGED, _lohi, _move_subtree,
                     _union, box_doors_to_front, face_of, frame_of)

GAP_SHARE = 0.06       # of a cell's side, between neighbouring cells
KEY = 0.03             # m: a keypad key's side at most (the data's safe keys: 2.2 cm at most)
DEEP = 1.5             # a knob's or dial's depth at most this many times its width
THIN = 0.5             # a panel's thickness at most this share of its smaller side
FRONT = 0              # the face normal of a front / back face (object frame: x forward)
BANDED = ("drawer", "tray", "door", "lid")   # the groups a "drawers on top" is above
SIDES = {1: ("left", "right"), 2: ("top", "bottom")}
H, V = 1, 2            # horizontal (the viewer's left-right) and vertical axes on such a face


def arrange_stated(obj: ArticulatedObject, spatial: Optional[dict]) -> list[str]:
    """Hold the rows and columns of ``spatial`` (``ExpectedStructure.spatial``: label ->
    facts), then its bands (above / below / left / right of the others), in ``obj``'s boxes,
    in place, before the layout refinement. Returns what it did, e.g. ["drawer: 3 x 2",
    "door left of drawer"] (rows x parts in the widest row)."""
    done, grids = [], []
    if box_doors_to_front(obj):
        done.append("door: a panel on the front")
    for label, facts in (spatial or {}).items():
        grid = _grid(_sides_as_line(obj, label, facts), sum(p.label == label for p in obj.parts))
        group = _grid_group(obj, label) if grid is not None else None
        if group is not None and _lay_out(obj, group, grid):
            grids.append(group)
            done.append(f"{label}: {len(grid)} x {max(grid)}")
    for outer, inner in _flanks(spatial):
        if _flanked(obj, outer, inner, spatial):
            done.append(f"{outer} either side of {inner}")
    laid = {lab for lab, f in (spatial or {}).items()          # a stated row stays a row
            if _arranged(f)}
    for label, facts in (spatial or {}).items():
        banded = set()
        for low, high, ax, share in _stated_bands(obj, label, spatial):
            banded.add(ax)
            stack = not {obj.parts[i].label for i in low + high} & laid
            if _bands(obj, low, high, ax, share, stack):
                a, b = obj.parts[high[0]].label, obj.parts[low[0]].label
                done.append(f"{a} above {b}" if ax == V else f"{b} left of {a}")
            for g in (low, high) if ax == H else ():    # drawers beside the others
                if all(obj.parts[i].label == "drawer" for i in g) \
                        and _column_beside(obj, "drawer", spatial.get("drawer") or {}):
                    done.append("drawer: a column")
            for g in (low, high) if ax == V else ():
                if _doors_in_a_row(obj, g, spatial):
                    done.append("door: a row")
        for key, ax in (("hpos", H), ("vpos", V)):
            want = facts.get(key) or []
            if ax not in banded and len(want) == 1 \
                    and _to_place(obj, label, ax, want[0], column=not _arranged(facts)):
                done.append(f"{label} to the {want[0]}")
    for group in grids:
        _clear_grid(obj, group, keep=set(spatial))
    return done


def safe_keypads(obj: ArticulatedObject, spatial: Optional[dict] = None) -> list[str]:
    """A safe's buttons on a door are a keypad in every object of the data (rows x columns
    of 2 x 2, 3 x 3, 4 x 3, 2 x 3 or 1 x 3, square keys 1.6 keys apart,
    model/data/synth/cabinets.py): two or more buttons on a safe's door that the prompt
    neither arranges nor places ("a safe with nine buttons", an image request) become such a
    block, three keys to a row (two for four keys), the rows top to bottom and the keys left
    to right in the network's order, about the middle of where it put them
    (:func:`_lay_out`); handles and dials reaching into the block move off it
    (:func:`_clear_grid`). They had come out scattered over the door or as a strip two keys
    wide. -> what it did, e.g. ["button: keypad 3 x 3"]."""
    facts = set((spatial or {}).get("button") or {})
    if obj.category != "Safe" or facts & (ARRANGEMENT_KEYS | POSITION_KEYS):
        return []
    doors: dict[tuple, list[int]] = {}
    for i, p in enumerate(obj.parts):
        if p.label == "button" and p.parent >= 0 and obj.parts[p.parent].label == "door":
            face = face_of(obj, i)
            if face is not None and face[0] == FRONT:
                doors.setdefault((p.parent, face), []).append(i)
    done = []
    for group in doors.values():
        n = len(group)
        per_row = _grid({"columns": 2 if n == 4 else min(n, 3)}, n)
        if per_row is not None and _lay_out(obj, group, per_row):
            _clear_grid(obj, group, keep=set(spatial or {}))
            done.append(f"button: keypad {len(per_row)} x {max(per_row)}")
    return done


def _arranged(facts: dict) -> bool:
    """Whether ``facts`` (a label's stated spatial facts) arrange its group: a row, column or
    grid, or a number of rows or columns."""
    return any(facts.get(k) for k in ARRANGEMENT_KEYS)


SQUEEZE = 0.9      # of the room a place leaves, what a too-wide group of controls spans there
PLACE_AT = 0.6     # where a group stated on one side goes: its centre this many half-widths
                   # (half-heights) of the body from the body's centre (the summary's
                   # left / right starts at model.data.spatial.HPOS_MARGIN = 0.2)


def _to_place(obj: ArticulatedObject, label: str, ax: int, where: str,
              column: bool = False) -> bool:
    """A group stated on one side or in the middle of the object ("a dial on the right",
    "three drawers in the middle", "buttons at the top") that no other group was banded
    against: moved along ``ax`` to that place on the body, within its parent's face, unless
    it is there already. Not up or down where a panel on the face turns about a horizontal
    axis (an oven's drop-down door stays at the bottom). Fronts take the band of the face
    on that side (on the left or right: where they are all their face holds; drawers with no
    arrangement of their own, ``column``, are then one column in it, a desk's pedestal)."""
    from model.data.spatial import HPOS_MARGIN, VPOS_MARGIN, body_box

    group = _front_group(obj, label, every=False)
    if group is None or where not in SIDES[ax] + ("middle",):
        return False
    parent = obj.parts[group[0]].parent
    if ax == V and any(_turns_horizontally(obj, c) for c in obj.children(parent)):
        return False
    margin = HPOS_MARGIN if ax == H else VPOS_MARGIN
    bc, bs = body_box(obj)
    half = float(bs[ax]) / 2
    sign = {"middle": 0.0, "left": -1.0, "bottom": -1.0, "right": 1.0, "top": 1.0}[where]
    u = np.array([obj.parts[i].bbox_center[ax] for i in group]) - float(bc[ax])
    if (sign == 0 and np.all(np.abs(u) <= margin * half)) or \
            (sign != 0 and np.all(sign * u > margin * half)):
        return False                                      # already there
    size = max(float(obj.parts[i].bbox_size[ax]) for i in group)
    room = 2 * margin * half if sign == 0 else (1 - margin) * half - size
    f = 1.0           # controls too spread for their place come closer ("knobs on the left")
    if obj.parts[group[0]].label in ON_FACE and np.ptp(u) > SQUEEZE * room > 0:
        f = SQUEEZE * room / float(np.ptp(u))
    steps = np.diff(np.unique(np.round(u, 4)))
    narrow = f * float(steps.min()) * (1 - GAP_SHARE) if f < 1 and len(steps) else math.inf
    lo, hi = _cspan(obj, group, ax)
    band, shrink = 2 * (1 - PLACE_AT) * half, 1.0
    face = face_of(obj, group[0])
    others = [c for c in obj.children(parent) if c not in group and face_of(obj, c) == face]
    banded = sign and obj.parts[group[0]].label in BANDED and hi - lo > band \
        and (ax == V or not others)      # left or right: when the group is all its face holds
    if banded:
        # fronts at the top or bottom (on the left or right) take that band of the face, as
        # they would above or below (beside) another group: two doors "at the bottom" of a
        # bookcase, decoded over 79 % of its height, stayed in its middle third; "three
        # drawers on the right", decoded over 90 % of a cabinet's width, stayed in its middle
        f = shrink = band / (hi - lo)
    mid = (u.max() + u.min()) / 2
    new = [(float(bc[ax]) + sign * PLACE_AT * half + f * (c - mid), min(s * shrink, narrow))
           for c, s in ((u[n], float(obj.parts[i].bbox_size[ax])) for n, i in enumerate(group))]
    plo, phi = _cspan(obj, [parent], ax)
    d = min(max(0.0, plo - min(c - s / 2 for c, s in new)),
            phi - max(c + s / 2 for c, s in new))         # stays on its parent's face
    for (c, s), i in zip(new, group):
        centre, box = obj.parts[i].bbox_center.copy(), obj.parts[i].bbox_size.copy()
        centre[ax], box[ax] = c + d, s
        _place(obj, i, centre, _round(obj.parts[i].label, box))
    if banded and ax == H and column and len(group) > 1 and obj.parts[group[0]].label == "drawer":
        _lay_out(obj, group, [1] * len(group))     # a pedestal: one column in its band
    return True


def _flanks(spatial: Optional[dict]) -> list[tuple[str, str]]:
    """(outer, inner) label pairs the prompt puts one on each side of the other: "a door on
    the left and a door on the right and two drawers in the middle"."""
    spatial = spatial or {}
    return [(a, b) for a, fa in spatial.items() for b, fb in spatial.items()
            if a != b and a in BANDED and b in BANDED
            and set(fa.get("hpos") or []) == {"left", "right"}
            and (fb.get("hpos") or []) == ["middle"]]


def _flanked(obj: ArticulatedObject, outer: str, inner: str, spatial: dict) -> bool:
    """The fronts of ``outer`` (an even number: as many on each side) either side of the
    fronts of ``inner`` on one face: three equal columns across the face (within its frame)
    over the height they all cover, the outer fronts the side columns (the left half of
    them by the network's order the left one; two or more to a side one stack), the inner
    group the middle one (one stack, or as the prompt arranges it: "three drawers in a row
    in the middle" had come out a stack). The network had put the two doors of "a door on
    the left and a door on the right and two drawers in the middle" under the drawers as
    22 x 6 cm slivers (seed 2), and "two drawers on the left, two doors in the middle and
    two drawers on the right" as a row of drawers over a row of doors and drawers."""
    sides, mid = _front_group(obj, outer), _front_group(obj, inner)
    if sides is None or mid is None or len(sides) < 2 or len(sides) % 2 \
            or not _same_face(obj, sides, mid):
        return False
    lo, hi = _union([obj.parts[i] for i in sides + mid])
    plo, phi = _cspan(obj, [obj.parts[sides[0]].parent], H)
    frame = frame_of(phi - plo)
    w = (phi - plo - 2 * frame - 2 * GAP) / 3
    left = plo + frame
    order = sorted(sides, key=lambda i: obj.parts[i].bbox_center[H])
    half = len(order) // 2
    columns = (order[:half], mid, order[half:])
    for g in columns:
        for i in g:
            centre, size = obj.parts[i].bbox_center.copy(), obj.parts[i].bbox_size.copy()
            centre[H], size[H] = left + w / 2, w
            centre[V], size[V] = (lo[V] + hi[V]) / 2, hi[V] - lo[V]
            _place(obj, i, centre, size)
        left += w + GAP
    for g in (columns[0], columns[2]):
        if len(g) > 1:      # a side column of several: one stack
            _lay_out(obj, g, [1] * len(g))
    facts = spatial.get(inner) or {}
    if len(mid) > 1:        # in the middle column: as the prompt arranges it, else one stack
        _lay_out(obj, mid, _grid(facts, len(mid)) or [1] * len(mid))
    return True


def _column_beside(obj: ArticulatedObject, label: str, facts: dict) -> bool:
    """Drawers banded beside the others ("a door on the left and three drawers on the
    right", or only "three drawers and a door on the left") with no arrangement of their own
    are one column in their band, as a desk's or kitchen unit's drawer pedestal is: the
    network's own layout mapped into the band had a drawer over two side by side, one of
    them 13 cm wide and 50 cm tall (the README's example: two unequal drawers, 15 and 27 cm
    wide, over a third with 1 seed of 4)."""
    group = _front_group(obj, label, every=False)
    if label != "drawer" or group is None or len(group) < 2 \
            or _arranged(facts):
        return False
    return _lay_out(obj, group, [1] * len(group))


def _doors_in_a_row(obj: ArticulatedObject, group: list[int], spatial: dict) -> bool:
    """Doors banded above or below another group ("two doors at the bottom and three
    drawers side by side above them", "a wardrobe with two doors and a drawer at the
    bottom") with no arrangement of their own stand side by side in their band, as a
    kitchen unit's or wardrobe's do: the network stacked them, two full-width doors 15 cm
    tall under the drawers (free-form set, seeds 0-2)."""
    facts = spatial.get("door") or {}
    if len(group) < 2 or any(obj.parts[i].label != "door" for i in group) \
            or _arranged(facts):
        return False
    if len({round(float(obj.parts[i].bbox_center[V]), 3) for i in group}) == 1:
        return False                                        # a row already
    return _lay_out(obj, group, [len(group)])


def _stated_bands(obj: ArticulatedObject, label: str, spatial: dict) -> list[tuple]:
    """(low group, high group, axis, share) on one face that ``spatial[label]`` puts side by
    side along the axis: "drawers above the doors" and "a door below the drawer" (V: low =
    lower), "drawers across the top" (above every other drawer, tray, door or lid on that
    face), "a door on the left" (H: low = the viewer's left, of the others on that face);
    ``share``: the groups also share the other extent (not for a corner, "at the top left")."""
    group, facts = _front_group(obj, label, every=False), spatial[label]
    placed = any(facts.get(k) for k in ("above", "below", "beside", "vpos", "hpos"))
    if group is None and label in BANDED and placed:
        group = _turned_to_front(obj, label)
    if group is None:
        return []
    out = []
    for key in ("above", "below"):
        for other in facts.get(key) or []:
            og = _front_group(obj, other, every=False)
            if og is not None and _same_face(obj, group, og):
                out.append((og, group, V, True) if key == "above" else (group, og, V, True))
    for other in facts.get("beside") or []:
        # side by side, the group on the side the network put it (its centre's side of the
        # other group's centre)
        og = _front_group(obj, other, every=False)
        if og is not None and _same_face(obj, group, og):
            mine = np.mean([obj.parts[i].bbox_center[H] for i in group])
            theirs = np.mean([obj.parts[i].bbox_center[H] for i in og])
            out.append((group, og, H, True) if mine < theirs else (og, group, H, True))
    face = face_of(obj, group[0])
    rest = [c for c in obj.children(obj.parts[group[0]].parent)
            if c not in group and obj.parts[c].label in BANDED and face_of(obj, c) == face]
    if label not in BANDED:
        # controls on a side are banded against the panels they sit beside (a toaster
        # oven's dials right of its door), not against those stated above or below controls
        # (a washer's door below its dial and buttons) or below them on the face (a range's),
        # unless the prompt puts the panel on the other side ("door on the right, knobs on
        # the left")
        glo, ghi = _cspan(obj, group, V)
        over = _vertical(facts) | {lab for lab, f in spatial.items()
                                   if _vertical(f) & set(ON_FACE)}
        spans = {c: _cspan(obj, [c], V) for c in rest}
        other = {"left": "right", "right": "left"}.get(_one(facts.get("hpos")))
        rest = [c for c in rest if obj.parts[c].label not in over
                and (min(ghi, spans[c][1]) - max(glo, spans[c][0]) > 0.5 * (ghi - glo)
                     or (other and _one((spatial.get(obj.parts[c].label) or {}).get("hpos"))
                         == other))]
    for key, ax, low_word in (("vpos", V, "bottom"), ("hpos", H, "left")):
        want = facts.get(key) or []
        if rest and len(want) == 1 and want[0] in SIDES[ax]:
            # a corner ("at the top left"): the band above at the group's own width, then
            # the side place (_to_place)
            share = ax == H or not facts.get("hpos")
            out.append((group, rest, ax, share) if want[0] == low_word else
                       (rest, group, ax, share))
            break
    return out


def _turned_to_front(obj: ArticulatedObject, label: str) -> Optional[list[int]]:
    """Drawers or doors of ``label`` that the network put on a side, top or back face of
    their parent while other drawers, trays, doors or lids sit on its front ("one drawer at
    the top and two doors below it", the drawer decoded on the cabinet's side): each is turned
    onto that front (its box rotated so its depth runs along the front's normal, centred
    across the front, its joint along the normal) so that the stated bands can place it.
    None where they have different parents or the parent has no front."""
    idx = [i for i, p in enumerate(obj.parts) if p.label == label]
    parent = obj.parts[idx[0]].parent if idx else -1
    if parent < 0 or any(obj.parts[i].parent != parent for i in idx):
        return None
    fronts = [face_of(obj, c) for c in obj.children(parent)
              if obj.parts[c].label in BANDED and obj.parts[c].label != label]
    fronts = [f for f in fronts if f is not None and f[0] == FRONT]
    if not fronts:
        return None
    s = max(set(fronts), key=fronts.count)[1]
    plo, phi = _lohi(obj.parts[parent])
    for i in idx:
        p, face = obj.parts[i], face_of(obj, i)
        if face == (FRONT, s):
            continue
        size = p.bbox_size.copy()
        if face is not None and face[0] != FRONT:      # rotate the box about the third axis
            size[FRONT], size[face[0]] = size[face[0]], size[FRONT]
        size = np.minimum(size, phi - plo)
        centre = p.bbox_center.copy()
        centre[FRONT] = (phi[FRONT] if s > 0 else plo[FRONT]) - s * size[FRONT] / 2
        centre[H] = (plo[H] + phi[H]) / 2
        _place(obj, i, centre, size)
        j = p.joint
        j.origin = centre.copy()
        if j.type.translates:
            j.axis = np.eye(3)[FRONT] * s
            j.t_range = (0.0, float(max(abs(j.t_range[0]), abs(j.t_range[1]))))
    return idx


PITCH = 1.6       # sizes between the centres of neighbouring controls drawn together


def _compact(obj: ArticulatedObject, group: list[int], ax: int) -> None:
    """Controls spread along ``ax`` drawn together about their middle, to ``PITCH`` of their
    size between neighbouring columns (rows and columns kept)."""
    c = np.array([obj.parts[i].bbox_center[ax] for i in group])
    size = max(obj.parts[i].bbox_size[ax] for i in group)
    cols = np.unique(np.round(c / max(size / 2, 1e-6)))
    if len(cols) < 2 or np.ptp(c) <= PITCH * size * (len(cols) - 1):
        return
    f = PITCH * size * (len(cols) - 1) / np.ptp(c)
    mid = (c.min() + c.max()) / 2
    for i, ci in zip(group, c):
        p = obj.parts[i]
        centre = p.bbox_center.copy()
        centre[ax] = mid + (ci - mid) * f
        _place(obj, i, centre, p.bbox_size.copy())


def _stack(obj: ArticulatedObject, group: list[int], panel: list[int]) -> None:
    """A single row of controls turned into a column at its own middle, from the top of the
    panel beside it down, ``PITCH`` of their size apart."""
    if len(group) < 2:
        return
    zs = [obj.parts[i].bbox_center[V] for i in group]
    size = max(max(obj.parts[i].bbox_size[V], obj.parts[i].bbox_size[H]) for i in group)
    if np.ptp(zs) > size:
        return                                  # already more than one row
    top = _cspan(obj, panel, V)[1] - size / 2
    y = float(np.mean([obj.parts[i].bbox_center[H] for i in group]))
    order = sorted(group, key=lambda i: obj.parts[i].bbox_center[H])
    for n, i in enumerate(order):
        p = obj.parts[i]
        centre = p.bbox_center.copy()
        centre[H], centre[V] = y, top - n * PITCH * size
        _place(obj, i, centre, p.bbox_size.copy())


def _one(values) -> Optional[str]:
    """The single value of a stated fact, or None (none or several)."""
    return values[0] if values and len(values) == 1 else None


def _vertical(facts: dict) -> set:
    """The labels ``facts`` put above or below their group."""
    return set((facts.get("above") or []) + (facts.get("below") or []))


def _same_face(obj: ArticulatedObject, a: list[int], b: list[int]) -> bool:
    return (obj.parts[a[0]].parent == obj.parts[b[0]].parent
            and face_of(obj, a[0]) == face_of(obj, b[0]))


def _bands(obj: ArticulatedObject, low: list[int], high: list[int], ax: int,
           share: bool = True, stack: bool = True) -> bool:
    """Unless ``low`` already sits wholly below (V) or left of (H) ``high``: the span both
    groups cover along ``ax`` is split into a low and a high band as long as each group's
    own span (scaled to fill it), and each group is mapped into its band with its own
    layout (relative places and sizes) kept; groups of panels (drawers, doors...) are also
    stretched across the extent both cover on the other axis (``share``), and fill their
    face's height when one is above the other. Controls banded beside a panel keep their
    size instead, and beside a door the two share the face's width (``_control_band``). Not
    top to bottom on a face where a panel turns about a horizontal axis (an oven's
    drop-down door stays at the bottom)."""
    (alo, ahi), (blo, bhi) = _cspan(obj, low, ax), _cspan(obj, high, ax)
    fronts = all(obj.parts[i].label in BANDED for i in low + high)
    ctrl = [g for g in (low, high) if not any(obj.parts[i].label in BANDED for i in g)]
    # panels overlapping by under a centimetre count as banded (the refinement cuts that
    # much apart); controls of a few millimetres must not overlap at all
    if ahi < blo + (0.01 if ctrl != [low, high] else 0.0):
        return False
    if ax == V and any(_turns_horizontally(obj, i) for i in low + high):
        return _above_drop_down(obj, low, high)
    lo, hi = min(alo, blo), max(ahi, bhi)
    if ctrl == [low, high]:       # two groups of controls keep their size: the span grows
        mid, need = (lo + hi) / 2, (ahi - alo) + (bhi - blo) + GAP   # about its middle
        plo, phi = _cspan(obj, [obj.parts[low[0]].parent], ax)       # within the face
        lo = min(lo, max(plo, min(mid - need / 2, phi - need)))
        hi = max(hi, lo + need)
    # panels side by side share the other extent too: a door left of a stack of drawers is
    # as tall as the stack (else tiling the front grows each across the other's band)
    panels = fronts and share
    if fronts and ax == V:        # fronts one above the other fill the face's height: a door
        plo, phi = _cspan(obj, [obj.parts[low[0]].parent], V)   # "at the bottom" below two
        frame = frame_of(phi - plo)                              # drawers reaches down
        lo, hi = min(lo, plo + frame), max(hi, phi - frame)
    if len(ctrl) == 1 and ax == H:   # controls beside a door: the two share the front's width
        plo, phi = _cspan(obj, [obj.parts[low[0]].parent], H)
        frame = frame_of(phi - plo)
        lo, hi = min(lo, plo + frame), max(hi, phi - frame)
    banded = _control_band(obj, ctrl[0], low, high, ax, lo, hi, stack) if len(ctrl) == 1 \
        else None
    (alo, ahi), (blo, bhi) = _cspan(obj, low, ax), _cspan(obj, high, ax)
    if banded is None:            # the two bands GAP apart: touching fronts would rub
        scale = (hi - lo - GAP) / max((ahi - alo) + (bhi - blo), 1e-9)
        banded = ({id(low): scale, id(high): scale}, {id(low): lo,
                                                     id(high): hi - (bhi - blo) * scale})
    scales, bases = banded
    cross = V if ax == H else H
    (c1, d1), (c2, d2) = _cspan(obj, low, cross), _cspan(obj, high, cross)
    clo, chi = min(c1, c2), max(d1, d2)
    for g, glo in ((low, alo), (high, blo)):
        sc, base = scales[id(g)], bases[id(g)]
        glo2, ghi2 = _cspan(obj, g, cross)
        cscale = (chi - clo) / max(ghi2 - glo2, 1e-9)
        for i in g:
            p = obj.parts[i]
            centre, size = p.bbox_center.copy(), p.bbox_size.copy()
            centre[ax] = base + (centre[ax] - glo) * sc
            size[ax] *= sc
            if panels:
                centre[cross] = clo + (centre[cross] - glo2) * cscale
                size[cross] *= cscale
            _place(obj, i, centre, size)
    return True


SIDE_BAND = 0.25   # of a face's width, the least a column of controls beside a door takes


def _control_band(obj: ArticulatedObject, ctrl: list[int], low: list[int], high: list[int],
                  ax: int, lo: float, hi: float, stack: bool = True
                  ) -> Optional[tuple[dict, dict]]:
    """Controls banded beside a panel keep their size: a single row beside a door becomes a
    column (a toaster oven's, ``_stack``; not a row or grid the prompt states: ``stack``
    False), controls spread apart are drawn together, and they take a band of their own
    span (beside a door: at least ``SIDE_BAND`` of the extent), centred in it; the panel is
    scaled into the rest. -> ({id(group): scale}, {id(group): where its low edge goes}), or
    None where they would not fit."""
    panel = high if ctrl is low else low
    if ax == H and stack:
        _stack(obj, ctrl, panel)
    _compact(obj, ctrl, ax)
    (cl, ch), (pl, ph) = _cspan(obj, ctrl, ax), _cspan(obj, panel, ax)
    span = ch - cl
    band = max(span, SIDE_BAND * (hi - lo)) if ax == H else span
    if band + CLEAR >= SQUEEZE * (hi - lo):
        return None
    ps = (hi - lo - band - CLEAR) / max(ph - pl, 1e-9)
    if ctrl is low:
        bases = {id(low): lo + (band - span) / 2, id(high): hi - (ph - pl) * ps}
    else:
        bases = {id(low): lo, id(high): hi - span - (band - span) / 2}
    return {id(ctrl): 1.0, id(panel): ps}, bases


def _above_drop_down(obj: ArticulatedObject, low: list[int], high: list[int]) -> bool:
    """Controls stated above a panel that turns about a horizontal axis ("knobs above the
    oven door"): the panel keeps its place, the controls' rows are mapped (squeezed where
    needed) into the strip between its top and its parent's top."""
    if any(obj.parts[i].label not in ON_FACE for i in high):
        return False
    (_, top), (blo, bhi) = _cspan(obj, low, V), _cspan(obj, high, V)
    _, ptop = _cspan(obj, [obj.parts[high[0]].parent], V)
    room = ptop - top
    gap = GAP_SHARE * room
    c = np.array([obj.parts[i].bbox_center[V] for i in high])
    rows = len(np.unique(np.round(c, 4)))
    if room < 0.02 or bhi - blo <= 0:
        return False
    fit = (room - 2 * gap) / rows * (1 - GAP_SHARE)        # a row's height at most
    sizes = [min(float(obj.parts[i].bbox_size[V]), fit) for i in high]
    spread = float(np.ptp(c))
    scale = min(1.0, (room - 2 * gap - max(sizes)) / spread) if spread > 0 else 1.0
    mid = top + room / 2
    for n, i in enumerate(high):
        centre, size = obj.parts[i].bbox_center.copy(), obj.parts[i].bbox_size.copy()
        centre[V], size[V] = mid + (c[n] - (c.max() + c.min()) / 2) * scale, sizes[n]
        _place(obj, i, centre, _round(obj.parts[i].label, size))
    return True


def _round(label: str, size: np.ndarray) -> np.ndarray:
    """A knob's or dial's box as round as the room it was given: its face as wide as tall
    (the smaller of the two), no deeper than ``DEEP`` times that."""
    if label not in ("knob", "dial"):
        return size
    size = size.copy()
    size[H] = size[V] = min(size[H], size[V])
    size[FRONT] = min(size[FRONT], DEEP * size[H])
    return size


def _cspan(obj: ArticulatedObject, group: list[int], ax: int) -> tuple[float, float]:
    """The extent ``group`` covers along ``ax``."""
    lo, hi = _union([obj.parts[i] for i in group])
    return float(lo[ax]), float(hi[ax])


def _turns_horizontally(obj: ArticulatedObject, i: int) -> bool:
    """A door or lid turning about a horizontal axis (a cabinet's, safe's or washer's door
    counts as vertical: the layout refinement hinges those on a vertical edge)."""
    p = obj.parts[i]
    if p.label == "door" and obj.category in SIDE_HINGED:
        return False
    return bool(p.joint.type.rotates and p.label in PANELS and abs(p.joint.axis[V]) < 0.9)


def place_stated_sides(obj: ArticulatedObject, spatial: Optional[dict]) -> list[str]:
    """Hold the sides (``hpos`` left / right) of ``spatial`` after the layout refinement,
    when siblings no longer overlap: a group wholly on the other side of its face gets the
    face mirrored. Returns e.g. ["door: mirrored"]."""
    done = []
    for label, facts in (spatial or {}).items():
        group = _front_group(obj, label)
        if group is None:
            continue
        side = facts.get("hpos")
        if side and len(side) == 1 and side[0] in ("left", "right") \
                and _mirror_if_opposite(obj, group, side[0], H):
            done.append(f"{label}: mirrored left to right")
        for key, want in (("vpos", facts.get("vpos")), ("above", facts.get("above")),
                          ("below", facts.get("below"))):
            if want and _mirror_vertically(obj, label, group, key, want):
                done.append(f"{label}: mirrored top to bottom")
    return done


def _mirror_vertically(obj: ArticulatedObject, label: str, group: list[int], key: str,
                       want: list) -> bool:
    """"Drawers on top" / "a drawer above the door" read the wrong way up: mirror the face top
    to bottom, unless a panel on it turns about a horizontal axis (a drop-down door stays at
    the bottom of its oven)."""
    if key == "vpos":
        if len(want) != 1 or want[0] not in ("top", "bottom"):
            return False
        side = "top" if want[0] == "top" else "bottom"
        return _mirror_if_opposite(obj, group, side, V)
    parent = obj.parts[group[0]].parent
    face = face_of(obj, group[0])
    z = float(np.mean([obj.parts[i].bbox_center[V] for i in group]))
    for other in want:
        others = [i for i, p in enumerate(obj.parts) if p.label == other
                  and p.parent == parent and face_of(obj, i) == face]
        if not others:
            return False
        oz = float(np.mean([obj.parts[i].bbox_center[V] for i in others]))
        if (z > oz) == (key == "above"):
            return False          # already the stated way round
    return _mirror(obj, group, V)


def _sides_as_line(obj: ArticulatedObject, label: str, facts: dict) -> dict:
    """``facts`` with a row (a column) for a group stated on as many sides left / middle /
    right (top / middle / bottom) as it has members and no arrangement: "a left door and a
    right door" are side by side, "an upper and a lower door" one above the other. The
    network stacked a wardrobe's "left door and right door" (seed 1). Unchanged when the
    members already sit on those sides."""
    from model.data.spatial import part_position

    idx = [i for i, p in enumerate(obj.parts) if p.label == label]
    if len(idx) < 2 or _arranged(facts):
        return facts
    for k, (key, layout) in enumerate((("hpos", "row"), ("vpos", "column"))):
        want = set(facts.get(key) or [])
        if len(want) == len(idx) and want != {part_position(obj, i)[k] for i in idx}:
            return {**facts, "layout": layout}
    return facts


def _grid(facts: dict, n: int) -> Optional[list[int]]:
    """Parts per row, top row first, for ``n`` parts and the stated facts (None: nothing
    stated, or nothing that fits ``n``)."""
    layout, rows, cols = facts.get("layout"), facts.get("rows"), facts.get("columns")
    per_row = facts.get("per_row")
    if per_row and n >= 2:            # "two small drawers on top and three below": as said
        return list(per_row) if sum(per_row) == n else None
    if n < 2 or not (layout in ("row", "column") or rows or cols):
        return None
    if layout == "row":
        rows, cols = 1, n
    elif layout == "column":
        rows, cols = n, 1
    elif rows and cols:
        if rows * cols < n or (rows - 1) * cols >= n:
            return None
    elif cols:
        rows = math.ceil(n / cols)
    else:
        cols = math.ceil(n / rows)
    rows, cols = int(rows), int(cols)
    if rows < 1 or cols < 1:
        return None
    per = [cols] * rows
    per[-1] = n - cols * (rows - 1)             # the bottom row takes what is left
    return per if per[-1] >= 1 else None


def _front_group(obj: ArticulatedObject, label: str, every: bool = True,
                 largest: bool = False) -> Optional[list[int]]:
    """The parts of ``label`` on one parent's front or back face: all of them (``every``:
    None unless all are there), or those on the face most of them share (``largest``: the
    face most of those on a front or back face share, however few)."""
    idx = [i for i, p in enumerate(obj.parts) if p.label == label]
    where: dict = {}
    for i in idx:
        face = face_of(obj, i)
        if face is not None and face[0] == FRONT:
            where.setdefault((obj.parts[i].parent, face), []).append(i)
    if not where:
        return None
    best = max(where.values(), key=len)
    if every:
        return best if len(best) == len(idx) else None
    return best if largest or 2 * len(best) > len(idx) else None


def _grid_group(obj: ArticulatedObject, label: str) -> Optional[list[int]]:
    """Every part of ``label``, for a stated grid, on the front or back face of one parent
    that most of those on a front or back face share; members the network decoded on
    another face of that parent (a locker door on the side, a keypad button pressing
    upwards, six of twelve doors on the bottom) are moved onto it first, with
    the depth and joint axis of a member of their joint type. None where a member has another
    parent (the tree never changes) or no member on the face shares its joint type."""
    group = _front_group(obj, label, every=False, largest=True)
    if group is None:
        return None
    rest = [i for i, p in enumerate(obj.parts) if p.label == label and i not in group]
    like = {i: next((g for g in group if obj.parts[g].joint.type == obj.parts[i].joint.type),
                    None) for i in rest}
    parent = obj.parts[group[0]].parent
    if any(obj.parts[i].parent != parent or m is None for i, m in like.items()):
        return None
    lo, hi = _union([obj.parts[g] for g in group])
    for i, m in like.items():
        p, q = obj.parts[i], obj.parts[m]
        centre, size = (lo + hi) / 2, np.median([obj.parts[g].bbox_size for g in group], axis=0)
        centre[FRONT], size[FRONT] = q.bbox_center[FRONT], q.bbox_size[FRONT]
        _place(obj, i, centre, size)
        p.joint.axis = np.asarray(q.joint.axis, dtype=np.float64).copy()
        p.joint.t_range = tuple(q.joint.t_range)
    return group + rest


def _lay_out(obj: ArticulatedObject, group: list[int], per_row: list[int],
             gap: Optional[float] = None) -> bool:
    """``group`` in rows of equal cells over the rectangle it covers, ``per_row`` parts per
    row, top row first; ``gap`` m between cells (None: :data:`GAP_SHARE` of a cell)."""
    lo, hi = _union([obj.parts[i] for i in group])
    lo, hi = lo - (gap or 0.0) / 2, hi + (gap or 0.0) / 2
    own = np.median([obj.parts[i].bbox_size for i in group], axis=0)   # controls keep theirs
    if all(obj.parts[i].label in ON_FACE for i in group):
        # a control's cell holds the control (at least the thinnest box a part keeps) with
        # GAP either side: two 5 mm buttons decoded touching get room, as do two 13 mm
        # knobs decoded 6 mm apart (the rectangle grows about its middle)
        for ax, n in ((H, max(per_row)), (V, len(per_row))):
            need = (max(MIN_SIDE, float(own[ax])) + 2 * GAP) * n
            if hi[ax] - lo[ax] < need:
                mid = (lo[ax] + hi[ax]) / 2
                lo[ax], hi[ax] = mid - need / 2, mid + need / 2
    parent = obj.parts[group[0]].parent
    if parent >= 0:                   # within its parent's face: a keypad stays on its door
        plo, phi = _lohi(obj.parts[parent])
        for ax in (H, V):
            if phi[ax] - plo[ax] > 0.5 * (hi[ax] - lo[ax]):
                lo[ax], hi[ax] = max(lo[ax], plo[ax]), min(hi[ax], phi[ax])
    rows = len(per_row)
    keypad = parent >= 0 and obj.parts[parent].label in PANELS and all(
        obj.parts[i].label == "button" for i in group)
    if keypad:   # the data's keypads: square keys PITCH of a key apart, a block about the
        key = min(own[H], own[V], KEY)   # middle (a hotel safe's keys were spread 7 cm apart)
        plo, phi = _lohi(obj.parts[parent])
        for ax, n in ((H, max(per_row)), (V, rows)):
            span = PITCH * key * n
            mid = (lo[ax] + hi[ax]) / 2
            if phi[ax] - plo[ax] > span:                 # kept on its door
                mid = float(np.clip(mid, plo[ax] + span / 2, phi[ax] - span / 2))
            lo[ax], hi[ax] = mid - span / 2, mid + span / 2
    height = (hi[V] - lo[V]) / rows
    # top row first, then the viewer's left first: the model's own order where it had one
    order = sorted(group, key=lambda i: -obj.parts[i].bbox_center[V])
    start = 0
    for r, count in enumerate(per_row):
        row = sorted(order[start:start + count], key=lambda i: obj.parts[i].bbox_center[H])
        start += count
        width = (hi[H] - lo[H]) / count
        for c, i in enumerate(row):
            centre = obj.parts[i].bbox_center.copy()
            size = obj.parts[i].bbox_size.copy()
            centre[H] = lo[H] + (c + 0.5) * width
            centre[V] = hi[V] - (r + 0.5) * height
            if gap is None:
                size[H], size[V] = width * (1 - GAP_SHARE), height * (1 - GAP_SHARE)
            else:
                size[H], size[V] = width - gap, height - gap
            if obj.parts[i].label in ON_FACE:
                size[H], size[V] = min(size[H], own[H]), min(size[V], own[V])
                if keypad:                       # a keypad's keys: square
                    size[H] = size[V] = min(size[H], size[V], KEY)
                size = _round(obj.parts[i].label, size)
            if obj.parts[i].label in PANELS:    # a panel stays thinner than it is wide, so
                size[FRONT] = min(size[FRONT], THIN * min(size[H], size[V]))   # its face holds
            _place(obj, i, centre, size)
    return True


def _clear_grid(obj: ArticulatedObject, group: list[int], keep: set) -> None:
    """Handles, knobs, buttons and dials on the face of a stated grid that reach into the
    rectangle it covers (a door's handle across its keypad) move out of it, with their
    children, by the shortest way that keeps them on their parent's face; where none does
    they stay (the layout refinement then cuts them apart). Parts of the labels in ``keep``
    (placed by the prompt themselves) stay."""
    parent, face = obj.parts[group[0]].parent, face_of(obj, group[0])
    lo, hi = _union([obj.parts[i] for i in group])
    plo, phi = _lohi(obj.parts[parent])
    for c in obj.children(parent):
        label = obj.parts[c].label
        if c in group or label in keep or label not in ON_FACE or face_of(obj, c) != face:
            continue
        clo, chi = _lohi(obj.parts[c])
        if not all(clo[ax] < hi[ax] and chi[ax] > lo[ax] for ax in (H, V)):
            continue
        gap = GAP_SHARE * float(min(hi[H] - lo[H], hi[V] - lo[V])) / 2
        moves = [(d, ax) for ax in (H, V)
                 for d in (hi[ax] + gap - clo[ax], lo[ax] - gap - chi[ax])
                 if plo[ax] <= clo[ax] + d and chi[ax] + d <= phi[ax]]
        if moves:
            d, ax = min(moves, key=lambda m: abs(m[0]))
            _move_subtree(obj, c, np.eye(3)[ax] * d)


def _place(obj: ArticulatedObject, i: int, centre: np.ndarray, size: np.ndarray) -> None:
    """Part ``i`` to the box (centre, size); its joint origin and its children follow the
    move of its centre (the layout refinement re-attaches them to its new face)."""
    _move_subtree(obj, i, centre - obj.parts[i].bbox_center)
    obj.parts[i].bbox_size = np.maximum(size, 1e-4)


def _mirror_if_opposite(obj: ArticulatedObject, group: list[int], side: str, ax: int) -> bool:
    """Mirror the face's layout along ``ax`` (H: left to right, V: top to bottom) when the
    whole group sits on the other side of its parent's centre than ``side``."""
    from model.data import vocab

    mid = float(obj.parts[obj.parts[group[0]].parent].bbox_center[ax])
    unit = np.eye(3)[ax]
    sides = {vocab.side_of(unit * (float(obj.parts[i].bbox_center[ax]) - mid))
             for i in group if abs(float(obj.parts[i].bbox_center[ax]) - mid) > 1e-6}
    if len(sides) != 1 or sides == {side}:
        return False
    return _mirror(obj, group, ax)


def _mirror(obj: ArticulatedObject, group: list[int], ax: int) -> bool:
    """Reflect every part on the group's face (with its children and joints) across the
    parent's centre plane normal to ``ax``. Not top to bottom when a part on the face turns
    about a horizontal axis (a drop-down or lift-up panel would change its meaning)."""
    parent = obj.parts[group[0]].parent
    face = face_of(obj, group[0])
    on_face = [c for c in obj.children(parent) if face_of(obj, c) == face]
    moving = [c for k in on_face for c in obj.subtree(k)]
    if ax == V and any(_turns_horizontally(obj, c) for c in moving):
        return False
    mid = float(obj.parts[parent].bbox_center[ax])
    for c in moving:
        q = obj.parts[c]
        q.bbox_center = q.bbox_center.copy()
        q.bbox_center[ax] = 2 * mid - q.bbox_center[ax]
        o = np.asarray(q.joint.origin, dtype=np.float64).copy()
        o[ax] = 2 * mid - o[ax]
        q.joint.origin = o
        a = np.asarray(q.joint.axis, dtype=np.float64).copy()
        a[ax] = -a[ax]
        # a mirror turns a rotation about a into one about -(mirrored a): same opening
        q.joint.axis = -a if q.joint.type.rotates else a
    return True


NARROW_DOOR = 0.8      # a side-hinged door under this share of the room beside its controls'
                       # column (either side) gets that room
SIDE_SPARE = 0.04      # of the front's width: such a door's centre this much further out than
                       # the margin that reads as on its side (model.data.spatial.HPOS_MARGIN)


def door_beside_controls(obj: ArticulatedObject, stated: Optional[dict] = None) -> list[str]:
    """An oven's one side-hinged door beside its controls (a microwave's usual layout: a
    door on the left, a column of controls on the right) fills the front up to them: the
    controls go into one column at the front's far side from the door (inside its frame,
    their heights kept, where no two of them then overlap), and the door spans from the
    frame at its own side to ``CLEAR`` short of the column (at most as wide as keeps it on
    its side of the front: ``SIDE_SPARE``), and the frame's height. The
    network decodes the door from the text alone, the fill grows it only until it meets a
    control, and the stated sides come after: "a microwave with a pull handle and a column
    of buttons" had a 3 cm wide door between its controls, "a microwave with a door that
    opens to the left and six buttons" a column of buttons in the middle of its front and a
    door a third of it (4 of 24 microwaves of six prompts under half the front). Only where
    every control on the front is on one side of the door's centre (or the door's side is
    stated, ``stated``: label -> facts; the column then goes to the other side), no other
    door, drawer or tray is on it, and the door is under ``NARROW_DOOR`` of the room or
    does not read as on its side ("a microwave with a door on the left" had a door 76 % of
    the front wide, centred, with 2 of 4 seeds). Its handle keeps its
    place on it (``free_edge_handles`` then sets it at the free edge); its hinge goes onto
    the new edge (``layout._hinge``). Run after the stated sides are placed. Returns e.g.
    ["door_0: beside the controls"]."""
    from .layout import CONTROLS, _hinge, _set
    from .siblings import FILL_FRAME, carry_children

    if obj.category != "Oven":
        return []
    root = obj.root
    front = [c for c in obj.children(root) if face_of(obj, c) == (FRONT, 1.0)]
    doors = [c for c in front if obj.parts[c].label == "door"]
    ctrl = [c for c in front if obj.parts[c].label in CONTROLS]
    others = [c for c in front if obj.parts[c].label in ("drawer", "tray")]
    if len(doors) != 1 or not ctrl or others:
        return []
    i = doors[0]
    door = obj.parts[i]
    if not door.joint.type.rotates or abs(float(door.joint.axis[V])) < 0.9:
        return []
    (blo, bhi), (dlo, dhi) = _lohi(obj.parts[root]), _lohi(door)
    frame = FILL_FRAME["Oven"][0]
    centres = [obj.parts[c].bbox_center[H] for c in ctrl]
    boxes = [_lohi(obj.parts[c]) for c in ctrl]
    side = ((stated or {}).get("door") or {}).get("hpos")
    spans = sorted((clo[V], chi[V]) for clo, chi in boxes)
    stack = all(a[1] + GAP <= b[0] for a, b in zip(spans, spans[1:]))
    if side in (["left"], ["right"]) and stack:
        # the controls on the side away from the stated door (+y is the viewer's right)
        sign = 1.0 if side == ["left"] else -1.0
    elif max(centres) < door.bbox_center[H]:
        sign = -1.0                           # the controls on the door's -y side
    elif min(centres) > door.bbox_center[H]:
        sign = 1.0
    else:
        return []
    wide = max(float(obj.parts[c].bbox_size[H]) for c in ctrl)
    column = (bhi[H] - frame - wide / 2) if sign > 0 else (blo[H] + frame + wide / 2)
    near = column - sign * (wide / 2 + CLEAR) if stack else (
        min(clo[H] for clo, _ in boxes) - CLEAR if sign > 0 else
        max(chi[H] for _, chi in boxes) + CLEAR)
    # at most as wide as keeps it on its side of the front (HPOS_MARGIN, with SIDE_SPARE)
    most = (bhi[H] - blo[H]) * (1.0 - HPOS_MARGIN - SIDE_SPARE) - 2 * frame
    lo, hi = dlo.copy(), dhi.copy()
    lo[H], hi[H] = (blo[H] + frame, min(near, blo[H] + frame + most)) if sign > 0 else \
        (max(near, bhi[H] - frame - most), bhi[H] - frame)
    lo[V], hi[V] = blo[V] + frame, bhi[V] - frame
    apart = all(sign * (obj.parts[c].bbox_center[H] - door.bbox_center[H]) > 0 for c in ctrl)
    u = (door.bbox_center[H] - (blo[H] + bhi[H]) / 2) / ((bhi[H] - blo[H]) / 2)
    sided = -sign * u > HPOS_MARGIN           # the door reads as on its side of the front
    if hi[H] - lo[H] <= MIN_SIDE or (apart and sided
                                     and dhi[H] - dlo[H] >= NARROW_DOOR * (hi[H] - lo[H])
                                     and dhi[V] - dlo[V] >= NARROW_DOOR * (hi[V] - lo[V])):
        return []
    if stack:
        for c in ctrl:
            move = np.zeros(3)
            move[H] = column - obj.parts[c].bbox_center[H]
            _move_subtree(obj, c, move)
    carry_children(obj, i, (dlo, dhi), (lo, hi), (H, V))     # its handle stays on it
    _set(door, lo, hi)
    _hinge(obj, i, (FRONT, 1.0))
    return [f"{door.name}: beside the controls"]
