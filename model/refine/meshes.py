"""Mesh refinement after meshing: drop floaters, simplify to a face budget, carve each parent
where a moving child passes through it, and shrink a joint's range only where its sweep
still collides. Exact booleans through manifold3d; every output mesh is a closed manifold.
"""
from __future__ import annotations

import logging
from typing import Optional

import numpy as np

from model.core import ArticulatedObject, JointType, meshops

from .sweeps import HULL_SWEEP, _sweep, revolved_sweep, swept_hull  # noqa: F401

log = logging.getLogger(__name__)


def drop_floaters(man, min_share: float = 0.01):
    """Keep the shells of a Manifold holding at least ``min_share`` of its volume and of its
    surface (inside-out shells, i.e. enclosed voids, and specks go)."""
    mf = meshops._mf()
    shells = man.decompose()
    if len(shells) <= 1:
        return man
    vols = np.array([float(s.volume()) for s in shells])
    areas = np.array([float(s.surface_area()) for s in shells])
    keep = [s for s, v, a in zip(shells, vols, areas)
            if v > 0 and (v >= min_share * vols[vols > 0].sum() and a >= min_share * areas.sum())]
    if not keep:
        keep = [shells[int(np.argmax(vols))]]
    return keep[0] if len(keep) == 1 else mf.Manifold.compose(keep)


SIMPLIFY_STEPS = (0.001, 0.002, 0.004, 0.008)
FINE_STEPS = (0.0004, 0.0002, 0.0001)


def simplify_to_budget(mans: dict, budget: int, tolerances=SIMPLIFY_STEPS,
                       fine=FINE_STEPS, check: bool = True) -> tuple[dict, float]:
    """Simplify every Manifold, step by step through ``tolerances`` (m), until the total
    face count is within ``budget``; returns the meshes and the last tolerance used (0:
    untouched). Each step starts from the previous one's meshes (fast: the first step
    removes most faces), so the deviation stays under the sum of the steps used. A part's
    tolerance is capped at 3 % of its longest side, and a step that would empty a part or
    cost it a fifth of its volume is not taken for that part: small parts keep their shape.
    A part the first step cannot take tries the ``fine`` tolerances instead, coarsest
    first: a thin noisy panel (a 4 mm door, a 3 mm handle bar) loses half its volume at
    1 mm yet drops from ~50k faces to ~1k at 0.2-0.4 mm. Where the steps that keep each
    part's surface in place (:func:`_simplified`) leave the object over budget, the budget
    wins: the steps run again from ``mans`` without that check (``check=False``: only
    those)."""
    out, used = _steps(mans, budget, tolerances, fine, check)
    if check and budget > 0 and sum(m.num_tri() for m in out.values()) > budget:
        out, used = _steps(mans, budget, tolerances, fine, False)
    return out, used


def _steps(mans: dict, budget: int, tolerances, fine, check: bool) -> tuple[dict, float]:
    out, used = mans, 0.0
    for step, tol in enumerate(tolerances):
        if budget <= 0 or sum(m.num_tri() for m in out.values()) <= budget:
            break
        nxt = {}
        for k, m in out.items():
            s = first_step(m, tol, fine, check) if step == 0 else _simplified(m, tol, check)
            nxt[k] = m if s is None else s
        out, used = nxt, tol
    return out, used


def first_step(m, tol: float = SIMPLIFY_STEPS[0], fine=FINE_STEPS, check: bool = True):
    """The first simplification step of one part (:func:`simplify_to_budget`): ``m`` at
    ``tol``, else at the first of the ``fine`` tolerances that keeps it; else, where each
    of them moves the surface, at the finest one that keeps the volume (a 38k-face bar
    handle comes out in 2k faces, not as it was); None when none does."""
    s = _simplified(m, tol, check)
    if s is None:
        s = next((f for f in (_simplified(m, t, check) for t in fine) if f is not None), None)
    if s is None and fine and check:
        s = _simplified(m, fine[-1], check=False)
    return s


STRAY_SHARE = 0.01     # share of a part's surface a step may move farther than STRAY_TOLS
STRAY_TOLS = 2.0       # tolerances
STRAY_CHECKED = 4000   # results with more faces keep their detail and are not checked


def _simplified(m, tol: float, check: bool = True):
    """``m`` simplified at ``tol`` (capped at 3 % of its longest side), or None when that
    empties it, costs it a fifth of its volume or moves more than ``STRAY_SHARE`` of its
    surface farther than ``STRAY_TOLS`` tolerances. Manifold's edge collapses can fold a
    thin panel onto its back face (a drawer front dented 14 mm at a 4 mm step, 18 % of
    its volume) and collapse a small handle to a few dozen faces 15 mm off its shape.
    ``check=False`` skips that last test."""
    side = float(np.ptp(np.asarray(m.bounding_box()).reshape(2, 3), axis=0).max())
    t = min(tol, 0.03 * side)
    s = m.simplify(t)
    if s.is_empty() or float(s.volume()) < 0.8 * float(m.volume()):
        return None
    if not check or s.num_tri() > STRAY_CHECKED:
        return s
    return s if stray_share(m, s, STRAY_TOLS * t) <= STRAY_SHARE else None


def stray_share(m, s, dist: float, n: int = 512) -> float:
    """Share of ``n`` points spread evenly (by area, a fixed draw) over Manifold ``m``'s
    surface that lie farther than ``dist`` from Manifold ``s``'s surface."""
    import igl
    v, f = meshops.pack(m)
    sv, sf = meshops.pack(s)
    if len(f) == 0 or len(sf) == 0:
        return 1.0
    rng = np.random.default_rng(0)
    tri = v[f[rng.integers(len(f), size=8 * n)]]     # faces drawn evenly, then by area
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    cum = np.cumsum(area)
    pick = np.minimum(np.searchsorted(cum, rng.random(n) * cum[-1]), len(tri) - 1)
    r = rng.random((n, 2))
    flip = r.sum(1) > 1
    r[flip] = 1.0 - r[flip]
    t = tri[pick]
    pts = t[:, 0] + r[:, :1] * (t[:, 1] - t[:, 0]) + r[:, 1:] * (t[:, 2] - t[:, 0])
    d2 = igl.point_mesh_squared_distance(pts, np.asarray(sv, np.float64),
                                         np.asarray(sf, np.int64))[0]
    return float(np.mean(d2 > dist * dist))


def carve_parents(obj: ArticulatedObject, mans: dict) -> dict[int, object]:
    """Subtract from each moving part's parent the space its subtree sweeps. Returns the
    sweep (a Manifold) subtracted from each parent that changed."""
    mf = meshops._mf()
    carved: dict[int, object] = {}
    for k in obj.movable_parts():
        par = obj.parts[k].parent
        if par < 0 or par not in mans:
            continue
        sweep, bound = _sweep(obj, mans, k)
        if sweep is None:
            continue
        before = float(mans[par].volume())
        child = max(sum(float(mans[i].volume()) for i in obj.subtree(k) if i in mans), 1e-12)
        # nothing in the way: no cut, no extra faces (the bound, a superset, decides first
        # and spares computing the sweep itself in most cases)
        if float((mans[par] ^ bound).volume()) < 1e-3 * child or sweep.is_empty() \
                or float((mans[par] ^ sweep).volume()) < 1e-3 * child:
            continue
        cut = mf.Manifold.batch_boolean([mans[par], sweep], mf.OpType.Subtract)
        if cut.is_empty():
            log.debug("carving %s would empty it; left alone", obj.parts[par].name)
            continue
        if float(cut.volume()) < before - 1e-12:
            mans[par] = drop_floaters(cut)
            carved[par] = sweep if par not in carved else carved[par] + sweep
    return carved


def carve_collision(pieces: list, sweep) -> list:
    """A part's collision pieces minus a swept volume's bounding box: an axis-aligned box
    splits into at most six boxes (exact, microseconds); another convex piece that the
    sweep reaches is replaced by the hull of what is left of it."""
    import trimesh

    from model.export.collision import is_box
    clo, chi = np.asarray(sweep.bounding_box()).reshape(2, 3)
    out = []
    for piece in pieces:
        lo, hi = np.asarray(piece.bounds, dtype=np.float64)
        if np.any(lo >= chi) or np.any(clo >= hi):
            out.append(piece)
            continue
        if not is_box(piece):
            rest = meshops.to_manifold(piece, fallback="hull") - sweep
            if not rest.is_empty() and float(rest.volume()) > 1e-9:
                out.append(meshops.to_trimesh(rest.hull()))
            continue
        for blo, bhi in _box_minus_box(lo, hi, clo, chi):
            if np.all(bhi - blo > 1e-3):
                out.append(trimesh.primitives.Box(
                    extents=bhi - blo, transform=trimesh.transformations.translation_matrix(
                        (blo + bhi) / 2)))
    return out


def _box_minus_box(lo, hi, clo, chi) -> list[tuple[np.ndarray, np.ndarray]]:
    """[lo, hi] minus [clo, chi] as at most six disjoint axis-aligned boxes."""
    lo, hi = lo.copy(), hi.copy()
    out = []
    for d in range(3):
        if clo[d] > lo[d]:
            b_hi = hi.copy()
            b_hi[d] = clo[d]
            out.append((lo.copy(), b_hi))
            lo[d] = clo[d]
        if chi[d] < hi[d]:
            b_lo = lo.copy()
            b_lo[d] = chi[d]
            out.append((b_lo, hi.copy()))
            hi[d] = chi[d]
    return out


def shrink_limits(obj: ArticulatedObject, mans: dict, max_overlap: float = 0.01,
                  states: int = 10) -> int:
    """Each joint alone: where its sweep collides (intersection over the smaller volume
    above ``max_overlap``) or dips under the floor the object stands on, the range ends at
    the last free state. Then every joint together (the audit's "all joints at r" states):
    two parts clear of each other one joint at a time can still meet when both move (a
    safe's dial turned and its handle turned into it); the joints that move such a pair
    apart from each other end at the last free state of all of them together. -> the
    number of ranges shortened."""
    from model.core.contacts import checked_pairs

    vol = {i: max(float(m.volume()), 1e-15) for i, m in mans.items()}
    pairs = [(i, j) for i, j in checked_pairs(obj) if i in mans and j in mans]
    ground = min(float(m.bounding_box()[2]) for m in mans.values()) - 0.002 if mans else 0.0
    ratios = np.linspace(0.0, 1.0, states)[1:]
    subs = {k: set(obj.subtree(k)) for k in obj.movable_parts()}   # what each joint moves
    shrunk = _shrink_alone(obj, mans, vol, pairs, subs, ground, ratios, max_overlap)
    return shrunk + _shrink_together(obj, mans, vol, pairs, subs, ratios, max_overlap)


def _shrink_together(obj, mans, vol, pairs, subs, ratios, max_overlap: float,
                     rounds: int = 3) -> int:
    """shrink_limits' second pass: every joint at the same ratio of its range."""
    from model.core.contacts import pair_overlaps
    # only pairs that two or more joints move apart: one joint alone was the first pass
    pairs = [(i, j) for i, j in pairs
             if sum((i in sub) != (j in sub) for sub in subs.values()) >= 2]
    shrunk = 0
    for _ in range(rounds):
        last, hit = 0.0, []
        for r in ratios if pairs else ():
            T = obj.link_transforms(ratio={obj.parts[k].name: float(r) for k in subs})
            hit = [(i, j) for i, j, o in pair_overlaps(obj, mans, vol, pairs, T) if o > max_overlap]
            if hit:
                break
            last = float(r)
        if not hit or last <= 0.0:
            return shrunk          # free, or blocked at the first state: a layout fault
        movers = {k for i, j in hit for k, sub in subs.items() if (i in sub) != (j in sub)}
        for k in movers:
            _scale_range(obj.parts[k].joint, last)
        shrunk += len(movers)
    return shrunk


def _scale_range(j, share: float) -> None:
    """The joint's ranges end at ``share`` of their length."""
    lo_t, hi_t = j.t_range
    lo_r, hi_r = j.r_range
    j.t_range = (lo_t, lo_t + share * (hi_t - lo_t))
    j.r_range = (lo_r, lo_r + share * (hi_r - lo_r))


def _shrink_alone(obj, mans, vol, pairs, subs, ground: float, ratios,
                  max_overlap: float) -> int:
    """shrink_limits' first pass: each joint alone."""
    shrunk = 0
    for k, sub in subs.items():
        todo = [(i, j) for i, j in pairs if (i in sub) != (j in sub)]
        last = 0.0
        for r in ratios:
            T = obj.link_transforms(ratio={obj.parts[k].name: float(r)})
            if _collides(obj, mans, vol, todo, T, max_overlap) or \
                    _below_ground(obj, mans, sub, T, ground):
                break
            last = float(r)
        else:
            continue
        if last <= 0.0:
            continue               # blocked from the start: a layout fault, not a range
        _scale_range(obj.parts[k].joint, last)
        shrunk += 1
    return shrunk


def _below_ground(obj, mans, sub, T, ground: float) -> bool:
    return any(float(mans[i].transform(meshops.affine34(T[obj.parts[i].name])).bounding_box()[2]) < ground
               for i in sub if i in mans)


def _collides(obj, mans, vol, pairs, T, max_overlap) -> bool:
    from model.core.contacts import pair_overlaps
    return any(r > max_overlap for _, _, r in pair_overlaps(obj, mans, vol, pairs, T))


def _meshed_on_parent(obj: ArticulatedObject, mans: dict, labels) -> list[int]:
    """The moving parts with a label in ``labels`` that have a mesh in ``mans``, as their
    parent has."""
    return [k for k in obj.movable_parts() if obj.parts[k].label in labels
            and k in mans and obj.parts[k].parent in mans]


def add_runners(obj: ArticulatedObject, mans: dict, max_gap: float = 0.005,
                thickness: float = 0.005) -> list[str]:
    """A drawer or tray that does not touch its parent at rest or fully open gets a runner:
    a thin slab of the parent under its footprint, from its back to the parent's face, so
    it slides on something. Returns the parts given one."""
    from .layout import SLIDERS
    mf = meshops._mf()
    added = []
    for k in _meshed_on_parent(obj, mans, SLIDERS):
        p = obj.parts[k]
        par = p.parent
        T = obj.link_transforms(ratio={p.name: 1.0})[p.name]
        opened = mans[k].transform(meshops.affine34(T))
        if max(float(mans[k].min_gap(mans[par], 2 * max_gap)),
               float(opened.min_gap(mans[par], 2 * max_gap))) <= max_gap:
            continue
        lo, hi = np.asarray(mans[k].bounding_box()).reshape(2, 3)
        plo, phi = np.asarray(mans[par].bounding_box()).reshape(2, 3)
        slab_lo, slab_hi = lo.copy(), hi.copy()
        slab_hi[2], slab_lo[2] = lo[2], max(lo[2] - thickness, plo[2])
        d = int(np.argmax(np.abs(p.joint.axis)))
        if d != 2:          # reach back into the parent along the travel axis
            slab_lo[d], slab_hi[d] = max(min(lo[d], hi[d]), plo[d]), min(max(lo[d], hi[d]), phi[d])
        if np.any(slab_hi - slab_lo <= 1e-4):
            continue
        box = meshops.box(slab_hi - slab_lo, (slab_lo + slab_hi) / 2)
        # less what other parts hold: a door 2 mm under the drawer kept 3 mm of it
        others = {i: m for i, m in mans.items() if i not in (k, par)}
        runner = box
        if others:
            runner = mf.Manifold.batch_boolean([box, *others.values()], mf.OpType.Subtract)
            if runner.is_empty():
                continue
        joined = mf.Manifold.batch_boolean([mans[par], runner], mf.OpType.Add)
        pieces = len(mans[par].decompose())
        if len(joined.decompose()) > pieces:
            # under the part only it floats in a hollow parent: a ledge from side wall to
            # side wall (as an oven's rack ledges are), else from under the part to the
            # nearer side wall (a drawer of one column of two), where that runs through no
            # other part than the runner did (less those parts, as the runner); a runner
            # that neither joins to the parent stays as it is
            under = {i for i, m in others.items() if float((box ^ m).volume()) > 1e-9}
            side = [e for e in (0, 1) if e != d][0]
            if d != 2:       # under the part's own depth: clear of a door closing in front
                slab_lo[d], slab_hi[d] = max(lo[d], plo[d]), min(hi[d], phi[d])
            near = (plo[side], slab_hi[side]) if slab_lo[side] - plo[side] \
                <= phi[side] - slab_hi[side] else (slab_lo[side], phi[side])
            for span in ((plo[side], phi[side]), near):
                slab_lo[side], slab_hi[side] = span
                ledge = meshops.box(slab_hi - slab_lo, (slab_lo + slab_hi) / 2)
                if any(float((ledge ^ m).volume()) > 1e-9 for i, m in others.items()
                       if i not in under):
                    continue
                if under:
                    ledge = mf.Manifold.batch_boolean([ledge, *(others[i] for i in under)],
                                                      mf.OpType.Subtract)
                wide = mf.Manifold.batch_boolean([mans[par], ledge], mf.OpType.Add)
                if len(wide.decompose()) <= pieces:
                    joined = wide
                    break
        mans[par] = joined
        added.append(p.name)
    return added


SETTLED = ("lid", "cap")   # parts that rest on their parent
SETTLE_GAP = 0.002         # m: a lid's or cap's mesh this close to its parent's touches it


def settle_onto_parents(obj: ArticulatedObject, mans: dict, gap: float = SETTLE_GAP,
                        search: float = 0.1, tries: int = 4) -> list[str]:
    """A lid or cap whose mesh hovers over its parent's comes down onto it, with the parts
    below it (boxes, joint origins, meshes and collision pieces): the layout puts it on its
    parent's *box*, but the parent's mesh may end short of that box (a bottle's thin neck
    dropped as a floater, a washer's top decoded as a sunken rim). A cap moves along its joint
    axis, a lid along its thinnest side, towards the parent; each step is the current gap to
    the parent and to every other part (less ``gap`` / 2), so nothing is pushed into
    anything. Returns the parts that moved."""
    from .layout import _move_subtree
    moved = []
    for k in _meshed_on_parent(obj, mans, SETTLED):
        p = obj.parts[k]
        par = p.parent
        if p.label == "cap":
            d = np.asarray(p.joint.axis, dtype=np.float64)
        else:
            d = np.eye(3)[int(np.argmin(p.bbox_size))]
        d = d / max(float(np.linalg.norm(d)), 1e-12)
        d = d if float(np.dot(obj.parts[par].bbox_center - p.bbox_center, d)) >= 0 else -d
        sub = [c for c in obj.subtree(k) if c in mans]
        others = [m for i, m in mans.items() if i not in sub and i != par]
        total = 0.0
        for _ in range(tries):
            moving = meshops.union_manifolds([mans[c] for c in sub])
            g = float(moving.min_gap(mans[par], search))
            if g <= gap or g >= search:
                break
            step = min([g] + [float(moving.min_gap(m, search)) for m in others]) - gap / 2
            if step <= gap / 2:
                break
            for c in sub:
                mans[c] = mans[c].translate(tuple(d * step))
            total += step
        if total > 0:
            _move_subtree(obj, k, d * total)      # (its meshes are stored from mans later)
            moved.append(p.name)
    return moved


CONSOLE_REACH = (0.02, 0.45)   # of the body's depth: where a console's front may lie, from
                               # its back (the data's consoles: 8-14 cm of 50-65 cm)


def seat_console_controls(obj: ArticulatedObject, mans: dict) -> list[str]:
    """A top-loading washer's dials and buttons sit on the front of its console, the block
    along the back of its top (every top loader of the data), which lies inside the body's
    box: the network decodes them there, but the layout puts each control on a face of its
    parent's box, so they ended up on the body's back face, facing the wall. Each dial or
    button of the root on its back face above the lid's hinge moves forward to where a ray
    from behind the body through its centre leaves the body's mesh, if that is within
    ``CONSOLE_REACH`` of the depth and behind the lid: a dial with its back on that face, a
    button straddling it, both facing the front (a button pressing backwards). Where the
    mesh has no console for any of them, one is built (:func:`_add_console`) and they go
    onto its front at its middle height. Runs before carving (the buttons' pockets are cut
    into the console). Returns the parts moved."""
    import trimesh

    from .layout import _lohi, face_of
    lids = [i for i, p in enumerate(obj.parts) if p.label == "lid" and p.parent == 0
            and face_of(obj, i) == (2, 1.0)]
    if obj.category != "WashingMachine" or not lids or 0 not in mans:
        return []
    body = meshops.to_trimesh(mans[0])
    blo, bhi = np.asarray(mans[0].bounding_box()).reshape(2, 3)
    depth = bhi[0] - blo[0]
    lid_lo, _ = _lohi(obj.parts[lids[0]])
    moved, missed = [], []
    for i, p in enumerate(obj.parts):
        if p.parent != 0 or p.label not in ("dial", "button") or i not in mans \
                or face_of(obj, i) != (0, -1.0):
            continue
        if p.bbox_center[2] < lid_lo[2]:       # under the lid: no console there
            missed.append(i)
            continue
        lo, hi = _lohi(p)
        start = [blo[0] - 0.01, p.bbox_center[1], p.bbox_center[2]]
        hits, _, _ = trimesh.ray.ray_triangle.RayMeshIntersector(body).intersects_location(
            [start], [[1.0, 0.0, 0.0]])
        xs = np.sort(hits[:, 0]) if len(hits) else np.zeros(0)
        front = next((float(x) for x in xs[1:2]), None)     # where the ray leaves the mesh
        if front is None or not (blo[0] + CONSOLE_REACH[0] * depth <= front
                                 <= min(blo[0] + CONSOLE_REACH[1] * depth, lid_lo[0])):
            missed.append(i)
            continue
        _to_console(obj, mans, i, front)
        moved.append(p.name)
    if missed and not moved:          # no console in the body's mesh: one is built
        front = _add_console(obj, mans, missed, lids[0])
        for i in missed if front is not None else ():
            _to_console(obj, mans, i, front[0], front[1])
            moved.append(obj.parts[i].name)
    return moved


CONSOLE = (0.08, 0.14)   # m: the data's consoles' depth (and 8-15 cm height, top loaders)


def _to_console(obj: ArticulatedObject, mans: dict, i: int, front: float,
                z: Optional[float] = None) -> None:
    """Control ``i`` onto a console front at x = ``front`` (at height ``z`` if given): a dial
    with its back on it, a button straddling it, both facing the front."""
    from .layout import _lohi, _move_subtree
    p = obj.parts[i]
    lo, hi = _lohi(p)
    target = front - (hi[0] - lo[0]) / 2 if p.label == "button" else front
    move = np.array([target - lo[0], 0.0, 0.0 if z is None else z - p.bbox_center[2]])
    mans[i] = mans[i].translate(tuple(move))
    _move_subtree(obj, i, move)
    p.joint.axis = np.array([-1.0, 0.0, 0.0] if p.label == "button" else [1.0, 0.0, 0.0])


def _add_console(obj: ArticulatedObject, mans: dict, controls: list[int],
                 lid: int) -> Optional[tuple[float, float]]:
    """A console block along the back of a top loader's top, as every top loader of the
    data has (``CONSOLE`` deep, the body's width, tall enough for its controls), for
    ``controls`` the body's mesh gives no console to sit on: 2 of 18 top loaders of the
    bench audit had their dials facing the wall. It ends in front of the back far enough
    that the controls on it stay clear of the lid standing open on its hinge. Added to the
    body's mesh and, as a box, to its collision. -> (its front x, the height of its
    middle), or None where there is no room for it."""
    import trimesh

    from .layout import _lohi
    blo, bhi = np.asarray(mans[0].bounding_box(), dtype=np.float64).reshape(2, 3)
    boxes = [_lohi(obj.parts[i]) for i in controls]
    reach = max(hi[0] - lo[0] for lo, hi in boxes)
    tall = max(hi[2] - lo[2] for lo, hi in boxes)
    lid_p = obj.parts[lid]
    clear = float(lid_p.joint.origin[0]) - float(lid_p.bbox_size[2]) - reach - 0.01
    front = min(blo[0] + CONSOLE[1], clear)
    if front - blo[0] < CONSOLE[0] * 0.6:
        return None
    h = min(max(CONSOLE[0], 1.6 * tall), 0.15)
    lo = np.array([blo[0], blo[1], bhi[2] - 0.002])
    hi = np.array([front, bhi[1], bhi[2] + h])
    box = meshops.box(hi - lo, (lo + hi) / 2)
    mans[0] = meshops.union_manifolds([mans[0], box])
    body = obj.parts[0]
    if body.collision is not None:
        body.collision = list(body.collision) + [trimesh.primitives.Box(
            extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2))]
    return float(front), float(bhi[2] + h / 2)


NECK_GAP = 0.003   # m: a bottle lid's hinge line this much further from its body's mesh than
                   # the lid is thick is off the neck
RIM_DEPTH = 0.005  # m: the body's mesh this far below the lid is the rim its lid covers
LIP = 0.002        # m: how far a fitted lid reaches past the rim all round


def _flip_lids(obj: ArticulatedObject, mans: dict):
    """(part, thinnest axis, -1 if its parent is below it else +1) of each hinged lid of a
    bottle meshed on its meshed parent."""
    if obj.category != "Bottle":
        return
    for k in _meshed_on_parent(obj, mans, ("lid",)):
        p = obj.parts[k]
        if p.joint.type.rotates:
            n = int(np.argmin(p.bbox_size))
            yield k, n, float(np.sign(obj.parts[p.parent].bbox_center[n] - p.bbox_center[n])
                              or -1.0)


def fit_lids_to_necks(obj: ArticulatedObject, mans: dict) -> list[str]:
    """A bottle's flip lid wider than the neck its body's mesh ends in gets the neck's size:
    the layout sizes the lid to the body's *box*, and where the shape prior draws a narrower
    neck (a widened bottle's 9 cm lid over a 6 cm neck) the hinge on the lid's edge hangs in
    the air beside the neck (1.1 cm off it). The lid (mesh, collision pieces, box) is scaled
    in its plane about the rim's centre to the rim's outline plus ``LIP``, and its hinge moves
    with its edge; the data's flip lids cover the mouth and hinge on the neck. Lids with
    parts on them are left. Returns the lids fitted."""
    fitted = []
    for k, n, below in _flip_lids(obj, mans):
        p = obj.parts[k]
        par = p.parent
        if obj.children(k):
            continue
        line = meshops.axis_line(p.joint.origin, p.joint.axis, 1.0)
        if float(line.min_gap(mans[par], 0.05)) - float(p.bbox_size[n]) <= NECK_GAP:
            continue            # a hinge bridges the lid's thickness to its parent
        lo, hi = np.asarray(mans[k].bounding_box(), dtype=np.float64).reshape(2, 3)
        verts = np.asarray(mans[par].to_mesh().vert_properties)[:, :3]
        face = lo[n] if below < 0 else hi[n]
        rim = verts[np.abs(verts[:, n] - face) <= RIM_DEPTH]
        if not len(rim):
            continue
        plane = [d for d in range(3) if d != n]
        scale, centre = np.ones(3), np.zeros(3)
        for d in plane:
            want = float(np.ptp(rim[:, d])) + 2 * LIP
            scale[d] = min(1.0, want / max(hi[d] - lo[d], 1e-9))
            centre[d] = float(rim[:, d].min() + rim[:, d].max()) / 2
        if scale.min() > 0.999:
            continue
        _scale_part(obj, mans, k, scale, centre)
        fitted.append(p.name)
    return fitted


def _scale_part(obj: ArticulatedObject, mans: dict, k: int, scale: np.ndarray,
                centre: np.ndarray, shift: Optional[np.ndarray] = None) -> None:
    """Part ``k`` (manifold, mesh, collision pieces, box, joint origin) scaled by ``scale``
    per axis about ``centre``, then moved by ``shift``."""
    p = obj.parts[k]
    T = np.eye(4)
    T[:3, :3] = np.diag(scale)
    T[:3, 3] = centre * (1.0 - scale) + (0.0 if shift is None else shift)
    mans[k] = mans[k].transform(meshops.affine34(T))
    if p.mesh is not None:
        p.mesh.apply_transform(T)
    if p.collision:
        p.collision = [_scaled_piece(c, T) for c in p.collision]
    p.bbox_center = T[:3, :3] @ p.bbox_center + T[:3, 3]
    p.bbox_size = p.bbox_size * scale
    p.joint.origin = T[:3, :3] @ np.asarray(p.joint.origin, dtype=np.float64) + T[:3, 3]


CAP_WRAP = 0.0045   # m: the most the data's screw caps reach past their neck all round (the
                    # skirt's 0.8 mm clearance, a 1.5-3 mm wall and knurled ribs; handheld.py)


NECK = 0.9     # a body's mouth narrower than this share of the body is a neck's
NARROW = 0.8   # a cap narrower than this share of the mouth under it does not cover it (a
               # cap that wraps its neck is wider than the neck, and its lip at most 5 %)


def _slab_of(man, lo, hi, n: int, a: float, b: float):
    """(lo, hi) of Manifold ``man`` between ``a`` and ``b`` along axis ``n`` across the box
    ``lo``..``hi`` (grown by 1 m), or None where nothing of it is there."""
    part = man ^ _slab(lo - 1.0, hi + 1.0, n, a, b)
    if part.volume() < 1e-12:
        return None
    return np.asarray(part.bounding_box(), dtype=np.float64).reshape(2, 3)


def fit_caps_to_necks(obj: ArticulatedObject, mans: dict) -> list[str]:
    """A bottle's screw cap wider than the neck under it plus ``CAP_WRAP`` all round is
    scaled across its axis, about the neck's centre, to that size: the network sizes a cap it
    reads as a "lid" ("a glass bottle with a twist-off lid") like a flip lid, a disc up to
    1.6 times the neck's width standing out round it, where the data's caps wrap the neck.
    The neck is the body's mesh in the slab ``RIM_DEPTH`` deep under the cap's lower face;
    a cap on a body as wide as it (no neck) stays. A cap narrower than ``NARROW`` of the
    neck's mouth (the body's last ``RIM_DEPTH``, where that is narrower than ``NECK`` of the
    body or the cap is sunk into it) is grown to the mouth plus ``CAP_WRAP`` all round and
    set on it: "a thermos with a screw lid" had a 9 mm cap sunk 1 cm into a 41 mm neck,
    hidden (6 of 6 seeds). Caps with parts on them are left. Returns the caps fitted."""
    if obj.category != "Bottle":
        return []
    fitted = []
    for k in _meshed_on_parent(obj, mans, ("cap",)):
        p = obj.parts[k]
        if p.joint.type != JointType.SCREW or obj.children(k):
            continue
        n = int(np.argmax(np.abs(p.joint.axis)))
        lo, hi = np.asarray(mans[k].bounding_box(), dtype=np.float64).reshape(2, 3)
        blo, bhi = np.asarray(mans[p.parent].bounding_box(), dtype=np.float64).reshape(2, 3)
        up = p.bbox_center[n] >= obj.parts[p.parent].bbox_center[n]
        across = [d for d in range(3) if d != n]
        end = bhi[n] if up else blo[n]
        mouth = _slab_of(mans[p.parent], blo, bhi, n, *((end - RIM_DEPTH, end) if up
                                                         else (end, end + RIM_DEPTH)))
        # narrower than a neck's mouth, or sunk into the body's top (a cap on a body as wide
        # as its top, no neck, stays)
        narrow = mouth is not None and any(
            hi[d] - lo[d] < NARROW * (mouth[1][d] - mouth[0][d]) for d in across) and (
            any(mouth[1][d] - mouth[0][d] < NECK * (bhi[d] - blo[d]) for d in across)
            or ((end - hi[n]) if up else (lo[n] - end)) > CAP_RISE)
        neck = mouth if narrow else _slab_of(
            mans[p.parent], blo, bhi, n, *((lo[n] - RIM_DEPTH, lo[n]) if up
                                           else (hi[n], hi[n] + RIM_DEPTH)))
        if neck is None:
            continue
        nlo, nhi = neck
        scale, centre, shift = np.ones(3), np.zeros(3), np.zeros(3)
        for d in across:
            want = float(nhi[d] - nlo[d]) + 2 * CAP_WRAP
            scale[d] = want / max(hi[d] - lo[d], 1e-9)
            if not narrow:
                scale[d] = min(1.0, scale[d])
            centre[d] = float(nlo[d] + nhi[d]) / 2
        if narrow:              # on the mouth, not round it: the grown cap is no sleeve;
            shift[n] = max(0.0, end - lo[n]) if up else min(0.0, end - hi[n])
            for d in across:    # centred on it (grown, an offset would grow with it)
                shift[d] = (centre[d] - (lo[d] + hi[d]) / 2) * scale[d]
        if np.abs(scale - 1.0).max() < 1e-3 and not shift.any():
            continue
        _scale_part(obj, mans, k, scale, centre, shift)
        fitted.append(p.name)
    return fitted


LID_SEAT = 0.0008   # m: the data's flip lid rests this far over its neck (handheld.py)
MAX_TRIM = 0.1      # the share of a body that a lid's seat may take off it


def _seat_cut(lo, hi, body, n: int, up: bool, face: float) -> tuple[np.ndarray, np.ndarray]:
    """(size, centre) of the box of Manifold ``body`` that a part on it (box ``lo``..``hi``,
    on the ``up`` side of the body along axis ``n``) takes off it to seat on it: over the
    part's outline plus ``LIP``, from ``LID_SEAT`` under the plane ``face`` outwards past
    the body."""
    blo, bhi = np.asarray(body.bounding_box(), dtype=np.float64).reshape(2, 3)
    clo, chi = lo - LIP, hi + LIP
    if up:
        clo[n], chi[n] = face - LID_SEAT, max(hi[n], bhi[n]) + LIP
    else:
        clo[n], chi[n] = min(lo[n], blo[n]) - LIP, face + LID_SEAT
    return chi - clo, (clo + chi) / 2


def seat_lids(obj: ArticulatedObject, mans: dict) -> list[str]:
    """A bottle's body whose mesh rises into its flip lid ends ``LID_SEAT`` under the lid's
    underside, over the lid's outline plus ``LIP``: the shape prior fills the body's box, which
    the layout lets overlap a thick lid, and carving the lid's sweep out of the body later
    left a shard of neck standing in the open lid ("a shampoo bottle with a flip cap", seed
    0: 1.9 cm tall). In the data the body ends under the lid. A cut that would take more than
    ``MAX_TRIM`` of the body is not made. Returns the lids seated."""
    seated = []
    for k, n, below in _flip_lids(obj, mans):
        p = obj.parts[k]
        par = p.parent
        lo, hi = np.asarray(mans[k].bounding_box(), dtype=np.float64).reshape(2, 3)
        up = below < 0       # the body under the lid: everything above the seat goes
        cut = meshops.box(*_seat_cut(lo, hi, mans[par], n, up, lo[n] if up else hi[n]))
        was = float(mans[par].volume())
        taken = float((mans[par] ^ cut).volume())
        if taken < 1e-9 or taken > MAX_TRIM * was:
            continue
        mans[par] = drop_floaters(mans[par] - cut)
        seated.append(p.name)
    return seated


CAP_TOP = (0.0015, 0.003)   # m: the data's screw cap's top wall (handheld.py)
RING_CORE = 0.2             # of a cap's width: the column about its axis its top covers
RING_WALL = 0.0003          # m: a cap with less than this over its axis is a ring
CAP_RISE = 0.001            # m: a body reaching this far past its cap's top stands through it


def cap_necks(obj: ArticulatedObject, mans: dict) -> list[str]:
    """A bottle's body ends ``LID_SEAT`` under its screw cap's top wall, over the cap's
    outline plus ``LIP``, as the data's bodies end in the cap's skirt: the shape prior draws
    the body's box, which may reach past a cap the layout left lower, and the neck stood
    through the cap, 8 mm above it ("a thermos with a screw-on cap", seed 2; carving the
    cap's lift then left that top as a loose disc). The wall is a quarter of the cap's height
    (within ``CAP_TOP``); a cap decoded as a ring, open over its axis, gets it as a plate
    over its outline. Only bodies reaching ``CAP_RISE`` past the cap's top, or under a ring,
    are cut; a cut that would take more than ``MAX_TRIM`` of the body is not made, nor the
    plate. Caps with parts on them are left. Returns the caps whose neck was capped."""
    if obj.category != "Bottle":
        return []
    capped = []
    for k in _meshed_on_parent(obj, mans, ("cap",)):
        p = obj.parts[k]
        par = p.parent
        if not p.joint.type.rotates or obj.children(k):
            continue
        n = int(np.argmax(np.abs(p.joint.axis)))
        lo, hi = np.asarray(mans[k].bounding_box(), dtype=np.float64).reshape(2, 3)
        up = p.bbox_center[n] >= obj.parts[par].bbox_center[n]
        t = float(np.clip(0.25 * (hi[n] - lo[n]), *CAP_TOP))
        a, b = (hi[n] - t, hi[n]) if up else (lo[n], lo[n] + t)
        size, centre = _seat_cut(lo, hi, mans[par], n, up, a if up else b)
        cut = meshops.box(size, centre)
        clo, chi = centre - size / 2, centre + size / 2
        core = RING_CORE * (hi - lo)
        core[n] = hi[n] - lo[n]
        ring = float((mans[k] ^ meshops.box(core, (lo + hi) / 2)).volume()) \
            < RING_WALL * float(np.prod(core)) / core[n]     # under 0.3 mm over its axis
        over = mans[par] ^ _slab(clo, chi, n, hi[n] + CAP_RISE, chi[n]) if up else \
            mans[par] ^ _slab(clo, chi, n, clo[n], lo[n] - CAP_RISE)
        if not ring and float(over.volume()) < 1e-12:
            continue                  # a top on it and nothing of the body over it
        taken = float((mans[par] ^ cut).volume())
        if taken > MAX_TRIM * float(mans[par].volume()):
            continue
        if taken > 1e-12:
            mans[par] = drop_floaters(mans[par] - cut)
        if ring:
            verts = np.asarray(mans[k].to_mesh().vert_properties, dtype=np.float64)[:, :3]
            ends = np.repeat(verts, 2, axis=0)
            ends[0::2, n], ends[1::2, n] = a, b
            mans[k] = meshops.union_manifolds([mans[k], meshops.hull(ends)])
        capped.append(p.name)
    return capped


def _scaled_piece(piece, T: np.ndarray):
    """A collision piece under the axis-aligned scaling ``T``: an axis-aligned box (the
    pieces' kind, model.export.collision) stays a box over its scaled bounds; any other
    mesh is transformed."""
    import trimesh

    from model.export.collision import is_box
    if not is_box(piece):
        return piece.copy().apply_transform(T)
    lo, hi = (T[:3, :3] @ b + T[:3, 3] for b in np.asarray(piece.bounds, dtype=np.float64))
    return trimesh.primitives.Box(extents=hi - lo, transform=trimesh.transformations
                                  .translation_matrix((lo + hi) / 2))


PANEL = 0.015      # m: depth of the plate put behind controls with nothing behind them
BACKED = 0.3       # share of a control's footprint slab the parent must fill to hold it


def add_control_panels(obj: ArticulatedObject, mans: dict, depth: float = PANEL) -> list[str]:
    """Knobs, dials and buttons on a face of their parent with nothing of it behind them (a
    toaster oven's knobs beside its door, over a front the shape prior left open) get a
    plate of the parent behind them, as an appliance's control panel is: the rectangle their
    footprints cover, grown in the face plane to the parent's outline and up to any door,
    drawer or lid on that face, ``depth`` deep behind the face, less what other parts
    occupy. Runs before carving (buttons get their pockets from it). Returns the controls
    that were floating."""
    from .layout import CONTROLS, FRONT_LABELS, _lohi, face_of
    mf = meshops._mf()
    floating: dict[tuple, list[int]] = {}
    for c, p in enumerate(obj.parts):
        face = face_of(obj, c)
        if p.label not in CONTROLS or face is None or c not in mans or p.parent not in mans:
            continue
        k, s = face
        plo, phi = np.asarray(mans[p.parent].bounding_box()).reshape(2, 3)
        plane = phi[k] if s > 0 else plo[k]
        lo, hi = _lohi(p)
        lo[k], hi[k] = sorted((plane, plane - s * depth))
        probe = meshops.box(hi - lo, (lo + hi) / 2)
        if float((mans[p.parent] ^ probe).volume()) < BACKED * float(probe.volume()):
            floating.setdefault((p.parent, k, s), []).append(c)
    for (par, k, s), group in floating.items():
        plo, phi = np.asarray(mans[par].bounding_box()).reshape(2, 3)
        boxes = [_lohi(obj.parts[c]) for c in group]
        lo, hi = np.min([b[0] for b in boxes], 0), np.max([b[1] for b in boxes], 0)
        fronts = [_lohi(obj.parts[f]) for f in obj.children(par)
                  if obj.parts[f].label in FRONT_LABELS and face_of(obj, f) == (k, s)]
        for d in (d for d in range(3) if d != k):     # grow to the outline or to a front
            up, down = phi[d], plo[d]
            for flo, fhi in fronts:
                if flo[d] >= hi[d] - 1e-6:
                    up = min(up, flo[d])
                elif fhi[d] <= lo[d] + 1e-6:
                    down = max(down, fhi[d])
            lo[d], hi[d] = min(lo[d], down), max(hi[d], up)
        plane = phi[k] if s > 0 else plo[k]
        lo[k], hi[k] = sorted((plane, plane - s * depth))
        slab = meshops.box(hi - lo, (lo + hi) / 2)
        others = [m for i, m in mans.items() if i != par and i not in group]
        if others:
            slab = mf.Manifold.batch_boolean([slab, *others], mf.OpType.Subtract)
        if not slab.is_empty():
            mans[par] = mf.Manifold.batch_boolean([mans[par], slab], mf.OpType.Add)
    return sorted(obj.parts[c].name for g in floating.values() for c in g)


CLOSED_FRONTS = ("Oven",)   # categories whose front is closed around its doors and drawers
CLOSED_SIDES = ("WashingMachine",)   # categories whose side faces without a front are closed
OPEN_FACE = 0.75            # a side face whose outer PANEL covers less of its outline is open
FRONT_INSET = 0.001         # m: the plate stays this far inside the body's outline and face


def close_fronts(obj: ArticulatedObject, mans: dict, depth: float = PANEL) -> list[str]:
    """An oven's front is closed around its doors and drawers, as an appliance's is (the
    data's ovens: walls and a control panel around the door): the shape prior draws the
    body's opening across the whole front wherever the door is, and a door that covers half
    of it leaves the cavity showing beside it. Each face of the root that holds a door or
    drawer gets a plate ``depth`` deep behind it over its outline (``FRONT_INSET`` inside),
    with an opening ``GAP`` around each door, drawer or tray of that face, less what the
    other parts occupy. A washer's side face (front, back, left, right) that holds no door
    and whose outer ``depth`` covers less than ``OPEN_FACE`` of its outline (a top loader
    decoded with a front loader's body: a porthole and no door) gets the plate whole. Runs
    after :func:`add_control_panels` and before carving (which cuts the doors' sweep out of
    it). A plate whose union with the body would not export as a closed mesh is not added.
    Returns the faces closed, as "<part>:<axis><sign>"."""
    from .layout import FRONT_LABELS, GAP, _lohi, face_of
    if obj.category not in CLOSED_FRONTS + CLOSED_SIDES:
        return []
    mf = meshops._mf()
    faces: dict[tuple, list[int]] = {}
    if obj.category in CLOSED_FRONTS:
        for c, p in enumerate(obj.parts):
            face = face_of(obj, c)
            if p.label in FRONT_LABELS and face is not None and face[0] != 2 \
                    and obj.parts[p.parent].parent < 0 and p.parent in mans:
                faces.setdefault((p.parent, *face), []).append(c)
    else:                    # CLOSED_SIDES
        root = next((i for i, p in enumerate(obj.parts) if p.parent < 0 and i in mans), None)
        if root is not None:
            held = {face_of(obj, c) for c, p in enumerate(obj.parts)
                    if p.parent == root and p.label in FRONT_LABELS}
            for k in (0, 1):
                for sgn in (1, -1):
                    if (k, sgn) not in held and face_cover(mans[root], k, sgn, depth) < OPEN_FACE:
                        faces[(root, k, sgn)] = []
    closed = []
    for (par, k, s), fronts in faces.items():
        plo, phi = np.asarray(mans[par].bounding_box()).reshape(2, 3)
        lo, hi = plo + FRONT_INSET, phi - FRONT_INSET
        plane = (phi[k] if s > 0 else plo[k]) - s * FRONT_INSET
        lo[k], hi[k] = sorted((plane, plane - s * depth))
        cuts = []
        for f in fronts:
            flo, fhi = _lohi(obj.parts[f])
            flo, fhi = flo - GAP, fhi + GAP
            flo[k], fhi[k] = lo[k] - 1.0, hi[k] + 1.0
            cuts.append(meshops.box(fhi - flo, (flo + fhi) / 2))
        others = [m for i, m in mans.items() if i != par]
        plate = mf.Manifold.batch_boolean([meshops.box(hi - lo, (lo + hi) / 2), *cuts, *others],
                                          mf.OpType.Subtract)
        if plate.is_empty():
            continue
        body = mf.Manifold.batch_boolean([mans[par], plate], mf.OpType.Add)
        if not _merged_closed(_closed_on_export(body)):
            log.debug("closing %s's front would not export closed; left open",
                      obj.parts[par].name)
            continue
        mans[par] = body
        closed.append(f"{obj.parts[par].name}:{'xyz'[k]}{'+' if s > 0 else '-'}")
    return closed


SWIVEL_WALL = (0.0008, 0.002)   # m: the data's swivel caps' plates and end wall, 0.8-1.5 mm
SWIVEL_CLEAR = 0.001            # m: the end wall stands this far past the stick's end


def _slab(lo, hi, d: int, a: float, b: float):
    """The box ``lo``..``hi`` with its extent along axis ``d`` replaced by ``a``..``b``."""
    lo, hi = np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)
    lo[d], hi[d] = min(a, b), max(a, b)
    return meshops.box(hi - lo, (lo + hi) / 2)


def close_swivel_caps(obj: ArticulatedObject, mans: dict) -> list[str]:
    """A USB stick's swivel cap is two plates joined by a wall across the stick's plug end in
    every object of the data; the wall (under 1.5 mm) is thinner than a cell of the part's
    grid, so a decoded cap comes out as two loose plates. A swivel cap (turning about an
    axis across the stick) whose mesh is two or more pieces apart along that axis gets the
    wall: as thick as its plates, spanning them along the axis and across the stick, at its
    end away from the pivot, ``SWIVEL_CLEAR`` past the stick's far end (or the plates' end,
    if that is farther; plates that end short of it are lengthened to it), so the swing
    clears the plug as the data's does. Returns the caps closed."""
    from .layout import _principal
    closed = []
    if obj.category != "USB":
        return closed
    for i, p in enumerate(obj.parts):
        if p.label != "cap" or p.parent < 0 or i not in mans or p.parent not in mans \
                or not p.joint.type.rotates:
            continue
        k = _principal(p.joint.axis)[0]
        body = obj.parts[p.parent]
        long = int(np.argmax(body.bbox_size))
        pieces = mans[i].decompose()
        if k == long or len(pieces) < 2:
            continue
        boxes = [np.asarray(m.bounding_box()).reshape(2, 3) for m in pieces]
        if max(b[0][k] for b in boxes) < min(b[1][k] for b in boxes):
            continue                          # the pieces overlap along the axis: no plates
        lo = np.min([b[0] for b in boxes], axis=0)
        hi = np.max([b[1] for b in boxes], axis=0)
        blo, bhi = np.asarray(mans[p.parent].bounding_box()).reshape(2, 3)
        t = float(np.clip(np.median([b[1][k] - b[0][k] for b in boxes]), *SWIVEL_WALL))
        pivot = float(np.asarray(p.joint.origin, dtype=np.float64)[long])
        far = 1.0 if (hi[long] - pivot) >= (pivot - lo[long]) else -1.0
        end = max(hi[long], bhi[long] + SWIVEL_CLEAR) if far > 0 else \
            min(lo[long], blo[long] - SWIVEL_CLEAR)
        parts = [mans[i], _slab(lo, hi, long, end - far * t / 2, end + far * t)]
        for b in boxes:                # plates that end short of the wall reach it
            near = b[1][long] if far > 0 else b[0][long]
            if (end - near) * far > 0:
                parts.append(_slab(b[0], b[1], long, near - far * t, end + far * t / 2))
        joined = meshops.union_manifolds(parts)
        if len(joined.decompose()) >= len(pieces):
            continue
        mans[i] = joined
        closed.append(p.name)
    return closed


SLEEVE_COVER = 0.9    # a slide cap's wall covers its box face 0.92-1.0 when decoded whole
SLEEVE_PROBE = 0.003  # m: the outer depth of a face in which its wall is looked for


def _wall_thickness(man, k: int, sgn: int, cover: float) -> float:
    """Mean thickness of Manifold ``man``'s wall on its box face (axis ``k``, side ``sgn``):
    the volume of its outer ``SLEEVE_PROBE`` over the area that covers (``cover`` of the
    face: :func:`face_cover`), seen along the axis."""
    lo, hi = np.asarray(man.bounding_box()).reshape(2, 3)
    plane = hi[k] if sgn > 0 else lo[k]
    slab = man ^ _slab(lo, hi, k, plane, plane - sgn * SLEEVE_PROBE)
    a, b = [i for i in range(3) if i != k]
    area = cover * (hi[a] - lo[a]) * (hi[b] - lo[b])
    return float(slab.volume()) / area if area > 0 else 0.0


def sleeve_covers(cap, body, k: int) -> dict[tuple[int, int], float]:
    """(axis, side) -> :func:`face_cover` of the outer ``SLEEVE_PROBE`` of each face a slide
    cap's sleeve has (Manifolds ``cap`` on ``body``, sliding along axis ``k``): the four
    along the slide and the end away from the stick."""
    lo, hi = np.asarray(cap.bounding_box()).reshape(2, 3)
    blo, bhi = np.asarray(body.bounding_box()).reshape(2, 3)
    far = 1 if lo[k] + hi[k] >= blo[k] + bhi[k] else -1
    faces = [(d, s) for d in range(3) if d != k for s in (1, -1)] + [(k, far)]
    return {f: face_cover(cap, *f, SLEEVE_PROBE) for f in faces}


def close_slide_caps(obj: ArticulatedObject, mans: dict) -> list[str]:
    """A USB stick's slide-off cap is a sleeve in every object of the data: four walls along
    the slide and an end wall away from the stick, 0.8-2 mm thick, open towards the stick.
    Walls that thin are under a cell of the part's grid, so a decoded cap came out as its top
    and bottom plates alone ("a usb stick with a cap", seeds 0-7: 3 of 8; a fourth lacked
    its sides). Each wall of a slide cap whose outer ``SLEEVE_PROBE`` covers under
    ``SLEEVE_COVER`` of its box face is added over the whole face, as thick as the cap's
    walls that are there (within ``SWIVEL_WALL``), less the stick's mesh. A cap with no wall
    of the sleeve is left alone. Returns the caps closed."""
    from .layout import _principal
    closed = []
    if obj.category != "USB":
        return closed
    for i, p in enumerate(obj.parts):
        if p.label != "cap" or p.parent < 0 or i not in mans or p.parent not in mans \
                or p.joint.type != JointType.PRISMATIC:
            continue
        cap, body = mans[i], mans[p.parent]
        covers = sleeve_covers(cap, body, _principal(p.joint.axis)[0])
        missing = [f for f, c in covers.items() if c < SLEEVE_COVER]
        if not missing or len(missing) == len(covers):
            continue
        lo, hi = np.asarray(cap.bounding_box()).reshape(2, 3)
        t = float(np.clip(np.median([_wall_thickness(cap, *f, c) for f, c in covers.items()
                                     if f not in missing]), *SWIVEL_WALL))
        walls = [_slab(lo, hi, d, (hi if s > 0 else lo)[d], (hi if s > 0 else lo)[d] - s * t)
                 for d, s in missing]
        mans[i] = meshops.union_manifolds([cap, meshops.union_manifolds(walls) - body])
        closed.append(p.name)
    return closed


def face_cover(man, k: int, sgn: int, depth: float) -> float:
    """Share of the outline of Manifold ``man``'s box face (axis ``k``, side ``sgn``) that
    its outer ``depth`` covers, seen along the axis."""
    lo, hi = np.asarray(man.bounding_box()).reshape(2, 3)
    plane = hi[k] if sgn > 0 else lo[k]
    slo, shi = lo.copy(), hi.copy()
    slo[k], shi[k] = sorted((plane, plane - sgn * depth))
    slab = man ^ meshops.box(shi - slo, (slo + shi) / 2)
    if slab.is_empty():
        return 0.0
    if k != 2:      # look along the axis: turn it onto z
        slab = slab.rotate((0.0, 90.0, 0.0) if k == 0 else (90.0, 0.0, 0.0))
    a, b = [i for i in range(3) if i != k]
    return float(slab.project().area()) / float((hi[a] - lo[a]) * (hi[b] - lo[b]))


def round_collision(obj: ArticulatedObject, mans: dict, solid: float = 0.7) -> list[str]:
    """Knobs and dials collide as the convex hull of their mesh when it is nearly convex:
    box pieces fitted to a round part sweep their corners beyond the part when it turns (a
    cap keeps its pieces: its hull would swallow the neck). Returns the parts changed."""
    changed = []
    for k in obj.movable_parts():
        p = obj.parts[k]
        if k not in mans or p.label not in ("knob", "dial") or not p.joint.type.rotates:
            continue
        hull = mans[k].hull()
        if float(mans[k].volume()) >= solid * float(hull.volume()):
            p.collision = [meshops.to_trimesh(hull)]
            changed.append(p.name)
    return changed


VESSELS = ("Bottle",)


FOOTED = ("StorageFurniture", "Oven", "WashingMachine", "Safe")   # stand on the floor
FOOT = 0.005    # m: height of the slab a standing object's root collides with the floor on
FOOT_BAND = 0.01   # m: the mesh's points this close to its lowest one are what it stands on


def foot_collision(obj: ArticulatedObject) -> list[str]:
    """The root part of a piece of furniture or an appliance (``FOOTED``) also collides with
    a slab ``FOOT`` high over the rectangle of the points its mesh stands on (within
    ``FOOT_BAND`` of its lowest one). The boxes come from the meshing grid and stop where
    its cells do: a carcass's boxes stood on its 2 cm back wall alone, and it tipped over in
    MuJoCo with its front on the floor. Only the floor meets the slab (the simulator keeps
    a parent and its children apart), and it adds no support the mesh does not have. (32
    boxes cover 16-46 % of such a carcass; the exporter's V-HACD pieces instead cost 1 s and
    225 MB more on a 10-part object.) A root without box pieces gets the exporter's ``auto``
    pieces first. Returns the parts changed."""
    import trimesh

    from model.export.collision import CollisionConfig, collision_pieces

    changed = []
    for part in obj.parts:
        if part.parent >= 0 or part.mesh is None or not len(part.mesh.vertices) \
                or obj.category not in FOOTED:
            continue
        if not part.collision:
            others = [q.mesh for q in obj.parts if q is not part and q.mesh is not None]
            part.collision = collision_pieces(part.mesh, CollisionConfig(), others)
        v = np.asarray(part.mesh.vertices, dtype=np.float64)
        z0 = float(v[:, 2].min())
        low = v[v[:, 2] <= z0 + FOOT_BAND, :2]
        lo, hi = low.min(0), low.max(0)
        if np.any(hi - lo <= 1e-4):
            continue
        T = np.eye(4)
        T[:3, 3] = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, z0 + FOOT / 2]
        part.collision = list(part.collision) + [
            trimesh.primitives.Box(extents=[hi[0] - lo[0], hi[1] - lo[1], FOOT], transform=T)]
        changed.append(part.name)
    return changed


def vessel_collision(obj: ArticulatedObject, clearance: float = 0.002) -> list[str]:
    """A vessel's body (a bottle) collides below its closure as one convex hull: the part of
    its mesh under the lowest point its moving children reach (at rest, half and fully
    open), hulled, plus its own pieces reaching above that (the neck the cap turns on). A generated
    body is a thin shell, often perforated near the bottom, whose box pieces leave it
    standing on a few specks: the free-base physics check saw such bottles fall over when
    the cap turned (3 of 3 upright with the hull). Its inside is not for a robot to reach
    into, so the hull does not hide anything a vessel is used for. Returns the parts changed."""
    import trimesh

    if obj.category not in VESSELS:
        return []
    changed = []
    for k, part in enumerate(obj.parts):
        kids = [c for c in obj.movable_parts() if obj.parts[c].parent == k]
        if not kids or part.mesh is None or not part.collision:
            continue
        lowest = np.inf
        for r in (0.0, 0.5, 1.0):
            T = obj.link_transforms(ratio={obj.parts[c].name: r for c in kids})
            inv = np.linalg.inv(T[part.name])     # child meshes into this part's frame
            for c in kids:
                for i in obj.subtree(c):
                    if obj.parts[i].mesh is not None and len(obj.parts[i].mesh.vertices):
                        A = inv @ T[obj.parts[i].name]
                        z = obj.parts[i].mesh.vertices @ A[2, :3] + A[2, 3]   # heights only
                        lowest = min(lowest, float(z.min()))
        lo, hi = part.mesh.bounds[:, 2]
        cut = lowest - clearance
        if not np.isfinite(cut) or cut - lo < 0.5 * (hi - lo):
            continue
        below = trimesh.intersections.slice_mesh_plane(part.mesh, [0, 0, -1], [0, 0, cut],
                                                       cap=True)
        if below is None or len(below.faces) < 4:
            continue
        above = [b for b in part.collision if float(b.bounds[1][2]) > cut]
        part.collision = [below.convex_hull] + above
        changed.append(part.name)
    return changed


def manifolds_of(obj: ArticulatedObject) -> dict:
    out = {}
    for i, p in enumerate(obj.parts):
        if p.mesh is not None and len(p.mesh.faces):
            out[i] = meshops.to_manifold(p.mesh, fallback="hull")
    return out


def store(obj: ArticulatedObject, mans: dict) -> None:
    for i, m in mans.items():
        obj.parts[i].mesh = _without_specks(_closed_on_export(m))


def _without_specks(mesh, share: float = 0.01):
    """``mesh`` without its edge-connected pieces of under ``share`` of its surface: a
    sliver that a cut leaves touching the part only at a vertex (a 4-face tetrahedron on a
    carved carcass) is its own shell once written, and a floater to anyone who loads it.
    Each piece of a closed mesh is closed, so dropping whole pieces keeps it closed."""
    if len(mesh.faces) == 0 or len(mesh.face_adjacency) == 0:
        return mesh
    lab, area = meshops.edge_pieces(mesh)
    keep = area >= share * float(area.sum())
    return mesh if keep.all() else _pieces(mesh, lab, keep)


def largest_pieces(mesh, n: int):
    """``mesh`` with at most its ``n`` largest edge-connected pieces (by surface): a thin
    wall that simplification pinches off is the simplification's floater, not the model's.
    Each piece of a closed mesh is closed, so the result stays closed."""
    lab, area = meshops.edge_pieces(mesh)
    if len(area) <= max(n, 1):
        return mesh
    keep = np.zeros(len(area), dtype=bool)
    keep[np.argsort(-area)[:max(n, 1)]] = True
    return _pieces(mesh, lab, keep)


def _pieces(mesh, lab, keep):
    """``mesh`` with only the edge-connected pieces ``keep`` (bool per piece; ``lab``: piece
    per face, as meshops.edge_pieces gives them)."""
    import trimesh

    out = trimesh.Trimesh(mesh.vertices, np.asarray(mesh.faces)[keep[lab]], process=False)
    out.remove_unreferenced_vertices()
    return out


def _closed_on_export(man, rebuilt: bool = False):
    """A refined part (Manifold) as its mesh is written: zero-area slivers dropped, and
    sheets that touch only by vertex identity held micrometres apart
    (meshops.separate_coincident) where a reader that merges vertices would otherwise see
    it open. Exact booleans can also leave vertices that share a position and needle faces
    that no cleanup of the triangles closes; then the manifold simplified by 0.1, then 1
    micrometre is tried (a generated USB body carved by its swivel cap: 3 open edges
    before, closed after). Where none closes, the same again on the manifold rebuilt from
    its own float64 mesh (an oven body carved by its door kept a triangle of vertices
    0.2 micrometres apart through every tolerance; rebuilt, it closed). The first closed
    candidate wins, else the plain cleanup."""
    first = None
    for tol in (0.0, 1e-7, 1e-6):
        mesh = meshops.to_trimesh(man.simplify(tol) if tol else man)
        out = meshops.drop_degenerate(mesh)
        if _merged_closed(out):
            return out
        first = out if first is None else first
        apart = meshops.drop_degenerate(meshops.separate_coincident(mesh))
        if _merged_closed(apart):
            return apart
    if not rebuilt:
        again = _closed_on_export(meshops.unpack(meshops.pack(man)), rebuilt=True)
        if _merged_closed(again):
            return again
    return first


def _merged_closed(mesh) -> bool:
    m = mesh.copy()
    m.merge_vertices()
    return bool(m.is_watertight)


__all__ = ["revolved_sweep", "vessel_collision", "add_runners", "round_collision", "close_fronts",
           "close_slide_caps", "face_cover", "fit_caps_to_necks", "seat_console_controls",
           "seat_lids",
           "cap_necks", "sleeve_covers",
           "drop_floaters", "simplify_to_budget", "first_step", "carve_parents",
           "carve_collision", "shrink_limits", "swept_hull", "manifolds_of", "store"]
