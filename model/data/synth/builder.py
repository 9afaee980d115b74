"""The object builder, joint constructors and the small shapes (handles, knobs, buttons)
shared by every category."""
from __future__ import annotations

import math
from typing import Optional

from model.core import meshops
from model.core.objects import ArticulatedObject, Joint, JointType, Part

from .config import GENERATOR_VERSION

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


