"""What a moving part sweeps over its motion, for carving its parent (``meshes.carve_parents``)
and bounding the check of its range: convex hulls of posed states for drawers, doors and the
like, a solid of revolution for a part spinning about its own axis, slabs of turned shadows
for a part swinging about a fixed axis (a swivel cap), posed copies otherwise."""
from __future__ import annotations

import numpy as np

from model.core import ArticulatedObject, JointType, meshops


HULL_SWEEP = ("drawer", "tray", "door", "lid", "button", "knob", "dial")


def swept_hull(obj: ArticulatedObject, mans: dict, k: int, states: int = 8):
    """Union over ``states`` openness ratios of joint ``k`` of its moving subtree. Drawers,
    trays, doors, lids, buttons, knobs and dials sweep as convex hulls (their inside is
    theirs: a drawer's cavity, a button's pocket; exact for a box that slides), a turning
    one as the hulls of each two consecutive states; other parts (a cap around its neck) as
    their own meshes, so what they enclose stays."""
    sweep, _ = _sweep(obj, mans, k, states)
    return sweep


def _sweep(obj: ArticulatedObject, mans: dict, k: int, states: int = 8):
    """(:func:`swept_hull`, a convex bound of it that costs no boolean: the hull of every
    posed piece), both None without meshes. The sweep is a lazy CSG union: nothing is
    computed until it is used (48 posed copies of a turning handle take a second)."""
    mf = meshops._mf()
    sub = [i for i in obj.subtree(k) if i in mans]
    if not sub:
        return None, None
    hull = obj.parts[k].label in HULL_SWEEP
    jt = obj.parts[k].joint.type
    if not hull and jt in (JointType.SCREW, JointType.CONTINUOUS):
        sweep = revolved_sweep(obj, mans, k)
        return sweep, sweep
    if jt == JointType.PRISMATIC and hull:
        ratios = [0.0, 1.0]
    else:       # a turning part that is not a panel: fine steps, as it is not a hull
        ratios = np.linspace(0, 1, states if hull else (48 if jt.rotates else 2 * states))
    if not hull and jt.rotates:
        sweep = layered_sweep(obj, mans, k, ratios)
        if sweep is not None:
            return sweep, sweep.hull()
    pieces, last = [], {}
    for r in ratios:
        T = obj.link_transforms(ratio={obj.parts[k].name: float(r)})
        for i in sub:
            m = mans[i].transform(meshops.affine34(T[obj.parts[i].name]))
            if not hull:
                pieces.append(m)
                continue
            # a turning panel: the hull of two consecutive states holds the wedge its edges
            # cross between them (a lid's back edge dipping into its body between states)
            now = m.hull()
            pieces.append(now if i not in last or jt == JointType.PRISMATIC
                          else mf.Manifold.batch_boolean([last[i], now], mf.OpType.Add).hull())
            last[i] = now
    return mf.Manifold.batch_boolean(pieces, mf.OpType.Add), mf.Manifold.batch_hull(pieces)


def revolved_sweep(obj: ArticulatedObject, mans: dict, k: int, levels: int = 64,
                   segments: int = 48):
    """What a part spinning about its own axis (a screw cap) sweeps over its whole motion, as
    a solid of revolution: at each height along the axis, the ring from the nearest to the
    furthest point of its subtree over all of its travel, revolved in ``segments`` steps
    (faceted outwards, so it covers the true circle). A union of posed copies of a rough cap
    (48 states) adds tens of thousands of faces to the neck it is cut from and still misses
    slivers between states; a profile has a few thousand and misses nothing."""
    import trimesh

    mf = meshops._mf()
    j = obj.parts[k].joint
    a = np.asarray(j.axis, dtype=np.float64)
    a = a / max(float(np.linalg.norm(a)), 1e-12)
    o = np.asarray(j.origin, dtype=np.float64)
    pts = []
    for i in obj.subtree(k):
        if i in mans:
            m = meshops.to_trimesh(mans[i])
            pts += [m.vertices, trimesh.sample.sample_surface(m, 4000, seed=0)[0]]
    if not pts:
        return None
    rel = np.concatenate(pts) - o
    h = rel @ a                                                  # height along the axis
    r = np.linalg.norm(rel - np.outer(h, a), axis=1)            # distance from it
    lo_t, hi_t = (sorted(j.t_range) if j.type.translates else (0.0, 0.0))
    edges = np.linspace(h.min() + lo_t, h.max() + hi_t, levels + 1)
    width = edges[1] - edges[0]
    rmin, rmax = np.full(levels, np.inf), np.full(levels, -np.inf)
    # a point at height h covers [h + lo_t, h + hi_t] over the travel
    first = np.clip(((h + lo_t - edges[0]) / width).astype(int), 0, levels - 1)
    last = np.clip(((h + hi_t - edges[0]) / width).astype(int), 0, levels - 1)
    for b in range(levels):
        hit = (first <= b) & (last >= b)
        if hit.any():
            rmin[b], rmax[b] = float(r[hit].min()), float(r[hit].max())
    grow = 1.0 / np.cos(np.pi / segments)
    polys, run = [], []
    for b in list(range(levels)) + [None]:
        if b is not None and np.isfinite(rmin[b]) and rmax[b] > 1e-6:
            run.append(b)
            continue
        if run:
            right = [(rmax[c] * grow + 1e-4, edges[c + e]) for c in run for e in (0, 1)]
            left = [(max(rmin[c] * np.cos(np.pi / segments) - 1e-4, 0.0), edges[c + e])
                    for c in reversed(run) for e in (1, 0)]
            polys.append(np.array(right + left))
        run = []
    if not polys:
        return None
    solid = mf.Manifold.revolve(mf.CrossSection(polys), segments)   # axis = z
    return solid.transform(np.hstack([_z_to(a), o[:, None]]))


def _z_to(a: np.ndarray) -> np.ndarray:
    """The rotation taking +z onto the unit vector ``a``."""
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, a)
    c = float(z @ a)
    if np.linalg.norm(v) < 1e-9:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


LAYER = 0.001        # m: slab thickness of a layered sweep along its turning axis
MAX_LAYERS = 32


def layered_sweep(obj: ArticulatedObject, mans: dict, k: int, ratios):
    """What part ``k``'s subtree sweeps turning about its joint's fixed axis line through
    ``ratios`` of its range, from 2D: the subtree at rest cut into slabs across the axis
    (``LAYER`` thick, at most ``MAX_LAYERS``), each slab's shadow on the plane normal to the
    axis turned to every state and united (exact polygon booleans), then extruded back over
    the slab. It holds every posed copy (a slab's shadow holds each of its cross-sections),
    and costs milliseconds: uniting 48 posed copies of a flat swivel cap, all coplanar, took
    2-3 s and 650 MB. None when the motion is not a turn about the joint's axis line."""
    mf = meshops._mf()
    p = obj.parts[k]
    sub = [i for i in obj.subtree(k) if i in mans]
    a = np.asarray(p.joint.axis, dtype=np.float64)
    a = a / max(float(np.linalg.norm(a)), 1e-12)
    o = np.asarray(p.joint.origin, dtype=np.float64)
    R = _z_to(a)
    rest = obj.link_transforms(ratio={p.name: 0.0})
    home = np.linalg.inv(rest[p.name])
    angles = []
    for r in ratios:
        D = obj.link_transforms(ratio={p.name: float(r)})[p.name] @ home   # rest -> state r
        turn = R.T @ D[:3, :3] @ R
        if abs(turn[2, 2] - 1.0) > 1e-6 or not np.allclose(D[:3, :3] @ o + D[:3, 3], o, atol=1e-6):
            return None
        angles.append(float(np.degrees(np.arctan2(turn[1, 0], turn[0, 0]))))
    to_axis = np.hstack([R.T, (-R.T @ o)[:, None]])          # object frame -> axis frame
    local = mf.Manifold.batch_boolean(
        [mans[i].transform(meshops.affine34(rest[obj.parts[i].name])).transform(to_axis)
         for i in sub], mf.OpType.Add)
    if local.is_empty():
        return None
    box = np.asarray(local.bounding_box()).reshape(2, 3)
    n = int(np.clip(np.ceil((box[1, 2] - box[0, 2]) / LAYER), 1, MAX_LAYERS))
    edges = np.linspace(box[0, 2], box[1, 2], n + 1)
    slabs = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        shadow = local.trim_by_plane((0.0, 0.0, 1.0), float(lo)) \
                      .trim_by_plane((0.0, 0.0, -1.0), -float(hi)).project()
        if shadow.is_empty():
            continue
        area = mf.CrossSection.batch_boolean([shadow.rotate(t) for t in angles], mf.OpType.Add)
        slabs.append(mf.Manifold.extrude(area, float(hi - lo)).translate((0.0, 0.0, float(lo))))
    if not slabs:
        return None
    sweep = mf.Manifold.batch_boolean(slabs, mf.OpType.Add)
    return sweep.transform(np.hstack([R, o[:, None]]))
