"""Hand-built example objects (a cabinet, a bottle) with watertight meshes.

They are used by the tests and by ``artformer export`` until a trained model exists. All
geometry follows the conventions of :mod:`model.core.objects`: metres, z up, front facing +x,
base on z = 0, every mesh in the object frame at rest. Each moving part clears its neighbours
by a few millimetres, so nothing interpenetrates anywhere over the joint ranges (a test checks
the intersection volumes with exact booleans at 10 openness states).
"""
from __future__ import annotations

import math

import numpy as np

from .objects import ArticulatedObject, Joint, JointType, Part

# -- mesh helpers (trimesh + manifold3d booleans; imported lazily) --------------------------


def _box(lo, hi):
    import trimesh
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(extents=hi - lo, transform=_translation((lo + hi) / 2.0))


def _cylinder(radius, z0, z1, *, sections=64, center_xy=(0.0, 0.0)):
    import trimesh
    c = (center_xy[0], center_xy[1], (z0 + z1) / 2.0)
    return trimesh.creation.cylinder(radius=radius, height=z1 - z0, sections=sections,
                                     transform=_translation(c))


def _translation(v) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = v
    return T


def _union(*meshes):
    import trimesh
    out = trimesh.boolean.union(list(meshes), engine="manifold")
    return _checked(out)


def _difference(a, *others):
    import trimesh
    out = trimesh.boolean.difference([a, *others], engine="manifold")
    return _checked(out)


def _checked(mesh):
    mesh.merge_vertices()
    if not mesh.is_watertight or mesh.volume <= 0:
        raise RuntimeError("example mesh construction produced a non-watertight mesh")
    return mesh


def _bar_handle(x_face: float, y: float, z: float, *, length: float, vertical: bool,
                stand_off: float = 0.035, bar: float = 0.012, overlap: float = 0.004):
    """A bar handle on a face at x = x_face: two posts and a bar, one watertight solid.

    The posts reach ``overlap`` into the face, so a union with the panel is manifold.
    """
    half = length / 2.0
    ends = [(y, z - half + 0.01), (y, z + half - 0.01)] if vertical else \
           [(y - half + 0.01, z), (y + half - 0.01, z)]
    pieces = []
    for py, pz in ends:
        pieces.append(_box((x_face - overlap, py - 0.005, pz - 0.005),
                           (x_face + stand_off, py + 0.005, pz + 0.005)))
    x0, x1 = x_face + stand_off - bar, x_face + stand_off
    if vertical:
        pieces.append(_box((x0, y - bar / 2, z - half), (x1, y + bar / 2, z + half)))
    else:
        pieces.append(_box((x0, y - half, z - bar / 2), (x1, y + half, z + bar / 2)))
    return _union(*pieces)


def _part(name, label, parent, mesh, joint: Joint) -> Part:
    p = Part(name=name, label=label, parent=parent, joint=joint, mesh=mesh)
    p.fit_bbox_to_mesh()
    return p


# -- objects --------------------------------------------------------------------------------


def example_cabinet() -> ArticulatedObject:
    """A 0.45 × 0.60 × 0.90 m cabinet: hollow carcass with three compartments, two drawers
    (open boxes with a front and a bar handle) that slide 0.30 m along +x, and a door below
    hinged on its left edge (+y side, 0° … 100° outward) carrying a handle as its own part.
    """
    D, W, H, t = 0.45, 0.60, 0.90, 0.018      # depth (x), width (y), height (z), panel
    xf, xb = D / 2.0, -D / 2.0                # front / back face
    yl, yr = W / 2.0 - t, -W / 2.0 + t        # inner side walls (left = +y)
    # Compartments (inner z ranges): door below, two drawers above, 18 mm shelves between.
    comps = [(t, 0.45), (0.45 + t, 0.666), (0.666 + t, H - t)]
    cavities = [_box((xb + t, yr, lo), (xf + 0.01, yl, hi)) for lo, hi in comps]
    body = _difference(_box((xb, -W / 2, 0.0), (xf, W / 2, H)), *cavities)
    parts = [_part("body", "body", -1, body, Joint(JointType.FIXED))]

    g = 0.003                                 # clearance of fronts in their openings
    for k, (lo, hi) in enumerate(comps[1:]):
        front = _box((xf - t, yr + g, lo + g), (xf, yl - g, hi - g))
        # Open box behind the front: 12 mm walls, 5 mm clear of the carcass all round.
        bx0, bx1 = xb + t + 0.01, xf - t + 0.002
        by0, by1 = yr + 0.008, yl - 0.008
        bz0, bz1 = lo + 0.005, hi - 0.03
        w = 0.012
        tray = _difference(_box((bx0, by0, bz0), (bx1, by1, bz1)),
                           _box((bx0 + w, by0 + w, bz0 + w), (bx1 - w, by1 - w, bz1 + 0.01)))
        handle = _bar_handle(xf, 0.0, (lo + hi) / 2.0, length=0.24, vertical=False)
        drawer = _union(front, tray, handle)
        joint = Joint(JointType.PRISMATIC, origin=(xf, 0.0, (lo + hi) / 2.0), axis=(1, 0, 0),
                      t_range=(0.0, 0.30), effort=50.0, velocity=0.5)
        parts.append(_part(f"drawer_{k}", "drawer", 0, drawer, joint))

    lo, hi = comps[0]
    y_hinge = yl - g
    door = _box((xf - t, yr + g, lo + g), (xf, y_hinge, hi - g))
    hinge = Joint(JointType.REVOLUTE, origin=(xf, y_hinge, (lo + hi) / 2.0), axis=(0, 0, 1),
                  r_range=(0.0, math.radians(100.0)), effort=20.0, velocity=1.5)
    parts.append(_part("door", "door", 0, door, hinge))
    door_index = len(parts) - 1
    # The handle sits near the free edge; it does not touch the door's volume except where
    # its posts rest on the front face (a 0.5 mm gap keeps the two meshes disjoint).
    handle = _bar_handle(xf + 0.0005, yr + 0.06, (lo + hi) / 2.0, length=0.16, vertical=True,
                         overlap=0.0)
    parts.append(_part("door_handle", "handle", door_index, handle,
                       Joint(JointType.FIXED, origin=handle.bounds.mean(axis=0))))
    obj = ArticulatedObject(parts=parts, category="StorageFurniture", name="example_cabinet",
                            metadata={"description": "a cabinet with two drawers above a "
                                                     "hinged door with a handle"})
    return obj.validate()


def example_bottle() -> ArticulatedObject:
    """A 0.22 m bottle (radius 35 mm) with a screw cap: the cap turns two full turns while
    rising 12 mm along +z (a screw joint: translation and rotation about the same axis)."""
    import trimesh
    profile = np.array([                      # (radius, z) of the solid body, bottom to top
        [0.0, 0.0], [0.035, 0.0], [0.035, 0.15], [0.0135, 0.185], [0.0135, 0.21], [0.0, 0.21]])
    body = _checked(trimesh.creation.revolve(profile, sections=64))
    cap = _difference(_cylinder(0.017, 0.192, 0.216), _cylinder(0.0145, 0.18, 0.213))
    screw = Joint(JointType.SCREW, origin=(0.0, 0.0, 0.21), axis=(0, 0, 1),
                  t_range=(0.0, 0.012), r_range=(0.0, 4.0 * math.pi), effort=2.0, velocity=3.0)
    parts = [_part("body", "body", -1, body, Joint(JointType.FIXED)),
             _part("cap", "cap", 0, cap, screw)]
    obj = ArticulatedObject(parts=parts, category="Bottle", name="example_bottle",
                            metadata={"description": "a bottle with a screw cap"})
    return obj.validate()


def example_objects() -> dict[str, ArticulatedObject]:
    """Name → freshly built example object."""
    return {"cabinet": example_cabinet(), "bottle": example_bottle()}


def structure_mismatch(obj: ArticulatedObject, structure) -> str | None:
    """Why a built example object does not have the parts a structure asks for (None: it has
    them). ``structure`` is a dict / JSON text / ``model.pipeline.api.StructureSpec``; the
    rules are those of structure control (docs/articulation.md): named labels with exact
    counts, joint types and hinge sides; unnamed labels absent except handles."""
    from model.core.structure import hinge_side, parse_structure

    spec = parse_structure(structure)
    if spec.category and spec.category.lower() != obj.category.lower():
        return f"it is a {obj.category}, not a {spec.category}"
    have: dict[str, list[Part]] = {}
    for p in obj.parts:
        have.setdefault(p.label, []).append(p)
    for lab, req in spec.parts.items():
        parts = have.get(lab, [])
        if req.count is not None and len(parts) != req.count:
            return f"it has {len(parts)} {lab} part(s), not {req.count}"
        if req.joint and any(p.joint.type.name.lower() != req.joint for p in parts):
            return f"its {lab} parts do not have {req.joint} joints"
        if req.hinge and [hinge_side(p.token()) for p in parts] != list(req.hinge):
            return (f"its {lab} hinges are {[hinge_side(p.token()) for p in parts]}, not "
                    f"{list(req.hinge)}")
    for lab, parts in have.items():
        if lab not in spec.parts and lab not in ("body", "handle"):
            return f"it has {len(parts)} {lab} part(s) the structure does not ask for"
    return None
