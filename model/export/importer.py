"""URDF (+ meshes) → ArticulatedObject, so users can bring their own objects.

Works for our own exports (the screw helper pairs ``<part>_slide`` → ``<part>_screw_helper``
→ ``<part>_joint`` merge back into one screw joint; labels, category and continuous ranges
come from ``metadata.json`` when it lies beside the URDF) and for general URDFs: link frames
with any rotation, mesh ``scale``, several visuals per link, ``file://``, ``package://`` and
relative mesh paths. Everything is converted into the object-frame-at-rest convention of
``model.core.objects``: meshes, joint origins and axes are expressed in the root link frame
with every joint at 0.
"""
from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from model.core.objects import ArticulatedObject, Joint, JointType, ObjectValidationError, Part

from .urdfmodel import ConvertError, URDFModel, load_mesh, read_urdf
from .urdfmodel import Joint as UJoint
from .urdfmodel import resolve_mesh_path  # noqa: F401  (imported from here by older code)

log = logging.getLogger(__name__)

_SUPPORTED = {"fixed": JointType.FIXED, "revolute": JointType.REVOLUTE,
              "prismatic": JointType.PRISMATIC, "continuous": JointType.CONTINUOUS}


class URDFImportError(ConvertError):
    """A URDF cannot be read into an ArticulatedObject; the message says what and where."""


def _screw_helpers(model: URDFModel) -> dict[str, tuple[UJoint, UJoint]]:
    """Our screw helpers: a link with no visual, reached by a prismatic joint and carrying one
    revolute / continuous joint with the same axis at a zero origin -> (slide, turn)."""
    parent = {j.child: j for j in model.joints}
    out = {}
    for name, link in model.links.items():
        kids = model.child_joints(name)
        if name == model.root or link.visuals or len(kids) != 1:
            continue
        js, jr = parent[name], kids[0]
        if (js.type == "prismatic" and jr.type in ("revolute", "continuous")
                and np.allclose(jr.origin, np.eye(4), atol=1e-9)
                and np.allclose(js.axis, jr.axis, atol=1e-6)):
            out[name] = (js, jr)
    return out


def _effort_velocity(j: UJoint) -> tuple[float, float]:
    return (j.effort if j.effort > 0 else 50.0), (j.velocity if j.velocity > 0 else 1.0)


def _part_joint(j: UJoint, frames: dict, helpers: dict) -> tuple[Joint, str]:
    """The object-frame joint of the part below URDF joint ``j`` and its parent link (a
    screw's slide + turn through a helper become one screw joint)."""
    if j.parent in helpers:
        js = helpers[j.parent][0]
        frame = frames[js.parent] @ js.origin
        return Joint(JointType.SCREW, frame[:3, 3], _unit(frame[:3, :3] @ js.axis),
                     (js.lower, js.upper), (j.lower, j.upper), *_effort_velocity(j)), js.parent
    frame = frames[j.parent] @ j.origin
    jt = _SUPPORTED[j.type]
    axis = frame[:3, :3] @ j.axis if jt != JointType.FIXED else np.array([0, 0, 1.0])
    t_range = (j.lower, j.upper) if jt == JointType.PRISMATIC else (0.0, 0.0)
    r_range = (j.lower, j.upper) if jt in (JointType.REVOLUTE, JointType.CONTINUOUS) else (0.0, 0.0)
    return Joint(jt, frame[:3, 3], _unit(axis), t_range, r_range, *_effort_velocity(j)), j.parent


def import_urdf(path: os.PathLike, *, load_meshes: bool = True,
                metadata: dict | None = None) -> ArticulatedObject:
    """Read a URDF into an ArticulatedObject (object frame = root link frame at rest).

    Raises URDFImportError naming the problem: malformed XML, unknown / unsupported joint
    type, a link with two parents or a cycle, a missing mesh file (its path), a joint naming
    an unknown link. ``metadata`` overrides a ``metadata.json`` next to the URDF.
    """
    path = Path(path)
    try:
        model = read_urdf(path)
    except URDFImportError:
        raise
    except ConvertError as e:
        raise URDFImportError(str(e)) from None
    metadata = model.metadata if metadata is None else metadata
    frames = model.rest_link_frames()
    helpers = _screw_helpers(model)
    parent_joint = {j.child: j for j in model.joints}
    meta_parts = {p.get("link", p.get("name")): p for p in metadata.get("parts", [])}
    order = [ln for ln in _bfs(model) if ln not in helpers]
    index = {ln: k for k, ln in enumerate(order)}
    parts = []
    for ln in order:
        mesh = _link_mesh(model.links[ln], frames[ln], path) if load_meshes else None
        if ln == model.root:
            joint, parent = Joint(JointType.FIXED), -1
        else:
            joint, parent_link = _part_joint(parent_joint[ln], frames, helpers)
            parent = index[parent_link]
        mp = meta_parts.get(ln, {})
        if joint.type == JointType.CONTINUOUS and "token" in mp:   # URDF has no range for it
            tok = mp["token"]
            joint.r_range = (float(tok[14]), float(tok[15]))
        part = Part(name=mp.get("name") or _safe_name(ln), label=mp.get("label") or _guess_label(ln),
                    parent=parent, joint=joint, mesh=mesh)
        if mesh is not None:
            part.fit_bbox_to_mesh()
        else:
            part.bbox_size = np.zeros(3)
            part.bbox_center = frames[ln][:3, 3].copy()
        parts.append(part)
    obj = ArticulatedObject(parts=parts, category=metadata.get("category", ""),
                            name=metadata.get("name") or model.name,
                            metadata={"source_urdf": str(path)})
    try:
        return obj.validate()
    except ObjectValidationError as e:
        raise URDFImportError(f"{path}: {e}") from None


def _bfs(model: URDFModel) -> list[str]:
    order = [model.root]
    for ln in order:
        order.extend(j.child for j in model.child_joints(ln))
    return order


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _link_mesh(link, W: np.ndarray, path: Path):
    """All visual meshes of a link (collision ones if it has no visual) in the root frame."""
    import trimesh
    pieces = []
    for g in link.visuals or link.collisions:
        m = _geometry_mesh(g, path)
        m.apply_transform(W @ g.origin)
        pieces.append(m)
    if not pieces:
        return None
    return pieces[0] if len(pieces) == 1 else trimesh.util.concatenate(pieces)


def _geometry_mesh(g, path: Path):
    import trimesh
    if g.kind == "mesh":
        try:
            m = load_mesh(g.mesh)
        except ConvertError as e:
            raise URDFImportError(f"{path}: {e}") from None
        m = trimesh.Trimesh(vertices=m.vertices, faces=m.faces)     # merged vertices
        if not np.allclose(g.scale, 1.0):
            m.apply_transform(np.diag([*g.scale, 1.0]))   # a mirroring scale also flips winding
        return m
    if g.kind == "box":
        return trimesh.creation.box(extents=g.size)
    if g.kind == "cylinder":
        return trimesh.creation.cylinder(radius=float(g.size[0]), height=float(g.size[1]),
                                         sections=48)
    return trimesh.creation.icosphere(subdivisions=3, radius=float(g.size[0]))


_LABEL_WORDS = ("drawer", "door", "handle", "knob", "button", "lid", "cap", "wheel", "body",
                "base", "switch", "dial", "tray", "shelf", "hinge", "screen", "leg")


def _guess_label(link: str) -> str:
    """The label word that ends latest in the link name ("door_handle" → handle)."""
    low = link.lower()
    hits = [(low.rfind(w) + len(w), w) for w in _LABEL_WORDS if w in low]
    return max(hits)[1] if hits else "part"


def _safe_name(link: str) -> str:
    s = "".join(c if c.isalnum() or c in "_-" else "_" for c in link)
    return s or "link"
