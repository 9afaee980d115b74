"""ArticulatedObject → robot-ready URDF folder (DESIGN §6).

Output folder (built in a temp folder beside ``out_dir`` and renamed into place)::

    out_dir/<name>.urdf        URDF built with yourdfpy dataclasses, provenance comment
    out_dir/meshes/<link>.obj  visual mesh per part, in the object frame at rest
    out_dir/meshes/<link>_collision_<k>.obj   convex collision pieces
    out_dir/metadata.json      labels, joint types, category, summary, provenance, tokens
    out_dir/preview.png        openness 0 / 0.5 / 1 side by side

Frames: link frame of a part = its joint origin in the object frame with identity rotation
(the root's link frame is the object frame; a part on a fixed joint, whose decoded origin
means nothing, has its frame at its box centre, so its TF frame sits on the part), so a
URDF joint origin is
``origin_child - origin_parent`` and every visual / collision origin is ``-origin_child``.
Posed link frame = ``T_part @ Trans(origin_part)`` with ``T_part`` from
``ArticulatedObject.link_transforms``. A screw joint becomes a prismatic joint
``<part>_slide`` to a near-massless helper link ``<part>_screw_helper`` followed by the
revolute joint ``<part>_joint``.
"""
from __future__ import annotations

import datetime as _dt
import json
import logging
import os
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from model.core.files import jsonable, slug
from model.core.objects import ArticulatedObject, JointType, ObjectValidationError, Part

from .collision import (CollisionConfig, collision_pieces, is_box,  # noqa: F401  (re-exported)
                        is_solid_enough)




@dataclass
class ExportResult:
    out_dir: str
    urdf_path: str
    mesh_paths: dict[str, str]          # link name -> mesh file
    metadata_path: str
    preview_path: Optional[str] = None

def object_slug(text: str) -> str:
    """The file and robot name of an object: letters, digits, '_' and '-'."""
    return slug(text, default="object", keep="_-")

log = logging.getLogger(__name__)

METADATA_FORMAT = 1
MESH_FORMATS = ("obj", "stl", "glb")
HELPER_SUFFIX = "_screw_helper"
SLIDE_SUFFIX = "_slide"
JOINT_SUFFIX = "_joint"
# Near-massless helper link of a screw: pybullet loads a helper of mass 0, MuJoCo refuses it
# ("mass and inertia of moving bodies must be larger than mjMINVAL", measured), so the
# helper gets a negligible positive mass and inertia that both accept.
HELPER_MASS = 1e-6          # kg
HELPER_INERTIA = 1e-9       # kg m^2 (diagonal)
MIN_MASS = 1e-4             # kg, floor for tiny / degenerate parts
LABEL_COLOURS = {
    "body": (0.72, 0.60, 0.45), "drawer": (0.85, 0.75, 0.55), "door": (0.80, 0.68, 0.50),
    "handle": (0.25, 0.25, 0.28), "knob": (0.25, 0.25, 0.28), "button": (0.8, 0.2, 0.2),
    "cap": (0.15, 0.35, 0.75), "lid": (0.55, 0.55, 0.6),
}
DEFAULT_COLOUR = (0.6, 0.6, 0.65)


def link_name(part: Part) -> str:
    return part.name


def joint_name(part: Part) -> str:
    return part.name + JOINT_SUFFIX


def link_origin(obj: ArticulatedObject, index: int) -> np.ndarray:
    """Link frame origin of part ``index`` in the object frame at rest: 0 for the root, the
    box centre for a part on a fixed joint (no axis to sit on; a decoded origin there is
    noise, metres away at times), else the joint origin."""
    p = obj.parts[index]
    if p.parent < 0:
        return np.zeros(3)
    if p.joint.type == JointType.FIXED:
        return np.asarray(p.bbox_center, dtype=np.float64)
    return np.asarray(p.joint.origin, dtype=np.float64)


def posed_link_frames(obj: ArticulatedObject, values=None, *, ratio=None) -> dict[str, np.ndarray]:
    """Link name → 4x4 pose of its URDF link frame for our own FK (parts only, no helpers)."""
    T = obj.link_transforms(values, ratio=ratio)
    out = {}
    for i, p in enumerate(obj.parts):
        L = np.eye(4)
        L[:3, 3] = link_origin(obj, i)
        out[link_name(p)] = T[p.name] @ L
    return out


def package_version() -> str:
    try:
        from importlib.metadata import version
        return version("artformer_ros")
    except Exception:  # not installed as a distribution: fall back to the source version
        from model.core.version import __version__
        return __version__


# -- physical properties --------------------------------------------------------------------


def mass_properties(mesh, density: float) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass kg, centre of mass (3,), inertia (3, 3) about the COM, object axes).

    Watertight meshes use their exact volume integrals; open or inverted meshes fall back to
    the convex hull, and flat / empty geometry to a thin box around the bounds. The tensor is
    symmetrised and its eigenvalues floored so it is always positive definite and satisfies
    the triangle inequality that simulators check.
    """
    com, inertia, mass = None, None, 0.0
    if mesh is not None and len(mesh.faces):
        props = _volume_integrals(mesh)
        if props is None:
            try:
                props = _volume_integrals(mesh.convex_hull)
            except Exception:  # qhull fails on flat or degenerate input
                props = None
        if props is not None:
            # one pass of trimesh's integrals (cached on the mesh), scaled to ``density``
            mass = float(props.volume) * density
            com = np.asarray(props.center_mass, dtype=np.float64)
            inertia = np.asarray(props.inertia, dtype=np.float64) * (density / props.density)
    if inertia is None:  # flat / empty: a solid box of the bounds, at least 2 mm thick
        lo, hi = (mesh.bounds if mesh is not None and len(mesh.vertices)
                  else (np.zeros(3), np.zeros(3)))
        ext = np.maximum(np.asarray(hi) - np.asarray(lo), 0.002)
        mass = float(density * np.prod(ext))
        com = (np.asarray(lo) + np.asarray(hi)) / 2.0
        a, b, c = ext
        inertia = mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    if mass < MIN_MASS:
        inertia = inertia * (MIN_MASS / max(mass, 1e-12))
        mass = MIN_MASS
    return mass, com, make_positive_definite(inertia)


def _volume_integrals(m):
    """trimesh's mass properties of a closed mesh with a positive volume, else None."""
    if not m.is_watertight:
        return None
    props = m.mass_properties
    return props if props.volume > 1e-12 else None


def make_positive_definite(inertia: np.ndarray, rel_floor: float = 1e-6) -> np.ndarray:
    """Symmetric, eigenvalues floored, principal moments obeying a + b >= c."""
    I = np.asarray(inertia, dtype=np.float64)
    I = (I + I.T) / 2.0
    w, V = np.linalg.eigh(I)                         # ascending (3,), columns (3, 3)
    w = np.maximum(w, max(float(w.max()) * rel_floor, 1e-12))
    # Principal moments of a real body obey a + b >= c; numerically flat parts can break it.
    w[2] = min(w[2], w[0] + w[1])
    return V @ np.diag(w) @ V.T


# -- export ---------------------------------------------------------------------------------


def export_object(obj: ArticulatedObject, out_dir: os.PathLike, *, mesh_format: str = "obj",
                  density: float = 600.0, provenance: dict | None = None,
                  mesh_uri: str = "file", preview: bool = True,
                  collision: CollisionConfig | None = None, name: str | None = None):
    """Write ``obj`` as a URDF folder at ``out_dir`` and return an ``ExportResult``.

    ``mesh_uri``: "file" for absolute ``file://`` paths (what a URDF on a ROS topic needs),
    "relative" for ``meshes/<file>`` beside the URDF (simulators; survives moving the
    folder), or a prefix such as ``"package://artformer_ros/objects/cabinet"`` that replaces
    ``out_dir`` in mesh URIs.
    ``density`` in kg/m³ (default 600: wood / filled plastic). ``provenance`` (prompt, seed,
    checkpoint hash...) goes into the URDF comment and ``metadata.json``. The folder appears
    atomically: it is built beside ``out_dir`` and renamed into place (an existing folder is
    replaced).
    """
    t0 = time.perf_counter()
    mesh_format = mesh_format.lower().lstrip(".")
    if mesh_format not in MESH_FORMATS:
        raise ValueError(f"mesh_format must be one of {MESH_FORMATS}, got {mesh_format!r}")
    if not (density > 0 and np.isfinite(density)):
        raise ValueError(f"density must be a positive number, got {density!r}")
    obj.validate()
    _check_names(obj)
    collision = collision or CollisionConfig()
    out_dir = Path(out_dir).expanduser().resolve()
    robot_name = object_slug(name or obj.name or "object")
    prov = {"package_version": package_version(),
            "exported_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}
    prov.update(provenance or {})

    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out_dir.parent, prefix=f".{out_dir.name}.tmp-"))
    try:
        os.chmod(tmp, 0o755)   # mkdtemp makes 0700; ROS consumers may run as another user
        (tmp / "meshes").mkdir()
        uri_base = _uri_base(mesh_uri, out_dir)
        robot, mesh_files = _build_robot(obj, robot_name, tmp, uri_base, mesh_format, density,
                                         collision)
        urdf_name = f"{robot_name}.urdf"
        # MuJoCo compiles visual meshes too and rejects flat ones; then it gets collision
        # geometry only (ROS consumers still see every visual).
        flat = sorted(p.name for p in obj.parts
                      if p.mesh is not None and len(p.mesh.faces) and not is_solid_enough(p.mesh))
        if flat:
            log.warning("flat visual meshes %s: MuJoCo will load collision geometry only", flat)
        xml = _robot_xml(robot, prov, discard_visual=bool(flat))
        (tmp / urdf_name).write_text(xml)
        meta = _metadata(obj, robot_name, urdf_name, mesh_format, mesh_files, prov)
        meta["mujoco_visuals_discarded_for"] = flat
        (tmp / "metadata.json").write_text(json.dumps(meta, indent=1))
        if preview:
            from .render import write_preview
            write_preview(obj, tmp / "preview.png")
        _replace_dir(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    log.info("exported %s to %s in %.2f s", obj.name, out_dir, time.perf_counter() - t0)
    return ExportResult(out_dir=str(out_dir), urdf_path=str(out_dir / urdf_name),
                        mesh_paths={k: str(out_dir / v) for k, v in mesh_files.items()},
                        metadata_path=str(out_dir / "metadata.json"),
                        preview_path=str(out_dir / "preview.png") if preview else None)


def _check_names(obj: ArticulatedObject) -> None:
    names = {p.name for p in obj.parts}
    for p in obj.parts:
        extra = [link_name(p) + HELPER_SUFFIX] if p.joint.type == JointType.SCREW else []
        for n in extra:
            if n in names:
                raise ObjectValidationError(f"part name {n!r} clashes with the screw helper link "
                                            f"of part {p.name!r}")



def _uri_base(mesh_uri: str, out_dir: Path) -> str:
    if mesh_uri == "file":
        uri = out_dir.as_uri()              # file:///abs/out_dir, percent-encoded
        if uri != "file://" + out_dir.as_posix():
            log.warning("output path %s needs percent-escapes in file:// URIs; RViz and MuJoCo "
                        "decode them but pybullet does not: export with mesh_uri='relative' "
                        "for pybullet, or use a folder without spaces", out_dir)
        return uri
    if mesh_uri == "relative":
        return "."                          # meshes/<file> beside the URDF (simulators)
    if mesh_uri.startswith("package://"):
        return mesh_uri.rstrip("/")
    raise ValueError(f"mesh_uri must be 'file', 'relative' or start with 'package://', "
                     f"got {mesh_uri!r}")


def _replace_dir(tmp: Path, out_dir: Path) -> None:
    """Rename ``tmp`` to ``out_dir``; an existing ``out_dir`` is moved aside first, then
    removed, so readers see either the old or the new folder, never a half-written one."""
    old = None
    if out_dir.exists() or out_dir.is_symlink():
        old = Path(tempfile.mkdtemp(dir=out_dir.parent, prefix=f".{out_dir.name}.old-"))
        os.rmdir(old)
        os.replace(out_dir, old)
    try:
        os.replace(tmp, out_dir)
    except BaseException:
        if old is not None:
            os.replace(old, out_dir)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _write_mesh(mesh, path: Path, fmt: str) -> None:
    if fmt == "obj":
        from trimesh.exchange.obj import export_obj
        path.write_text(export_obj(mesh, include_normals=False, include_color=False,
                                   include_texture=False, header=None))
    else:
        path.write_bytes(mesh.export(file_type=fmt))


def _origin(xyz) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = xyz
    return T


def _build_robot(obj, robot_name, tmp, uri_base, fmt, density, collision):
    import yourdfpy as y

    # Simulators cannot read GLB, so collision pieces are STL when the visuals are GLB.
    cfmt = "stl" if fmt == "glb" else fmt
    links, joints, materials, mesh_files = [], [], {}, {}
    for i in obj.topological_order():
        p = obj.parts[i]
        o = link_origin(obj, i)
        lname = link_name(p)
        visuals, collisions, inertial = [], [], None
        if p.mesh is not None and len(p.mesh.faces):
            rel = f"meshes/{lname}.{fmt}"
            _write_mesh(p.mesh, tmp / rel, fmt)
            mesh_files[lname] = rel
            colour = LABEL_COLOURS.get(p.label, DEFAULT_COLOUR)
            mat_name = f"{p.label}_colour" if p.label in LABEL_COLOURS else "default_colour"
            materials[mat_name] = y.Material(name=mat_name, color=y.Color(rgba=np.array([*colour, 1.0])))
            visuals.append(y.Visual(name=f"{lname}_visual", origin=_origin(-o),
                                    geometry=y.Geometry(mesh=y.Mesh(filename=f"{uri_base}/{rel}")),
                                    material=y.Material(name=mat_name)))
            if p.collision and collision.method == "auto":
                pieces = p.collision          # made with the part (e.g. boxes from its SDF)
            else:
                others = [q.mesh for q in obj.parts if q is not p and q.mesh is not None]
                pieces = collision_pieces(p.mesh, collision, others)
            for k, piece in enumerate(pieces):
                cname = f"{lname}_collision_{k}"
                if is_box(piece):             # a <box> primitive: exact and cheapest to collide
                    centre = np.asarray(piece.primitive.transform)[:3, 3]
                    collisions.append(y.Collision(
                        name=cname, origin=_origin(centre - o),
                        geometry=y.Geometry(box=y.Box(size=np.asarray(piece.primitive.extents)))))
                    continue
                crel = f"meshes/{cname}.{cfmt}"
                _write_mesh(piece, tmp / crel, cfmt)
                collisions.append(y.Collision(name=cname, origin=_origin(-o),
                                              geometry=y.Geometry(mesh=y.Mesh(filename=f"{uri_base}/{crel}"))))
        mass, com, inertia = mass_properties(p.mesh, density)
        inertial = y.Inertial(origin=_origin(com - o), mass=mass, inertia=inertia)
        links.append(y.Link(name=lname, inertial=inertial, visuals=visuals, collisions=collisions))
        if p.parent < 0:
            continue
        parent = obj.parts[p.parent]
        rel_origin = o - link_origin(obj, p.parent)
        j = p.joint
        axis = np.asarray(j.axis, dtype=np.float64)
        if j.type == JointType.SCREW:
            helper = lname + HELPER_SUFFIX
            links.append(y.Link(name=helper, visuals=[], collisions=[], inertial=y.Inertial(
                origin=np.eye(4), mass=HELPER_MASS, inertia=np.eye(3) * HELPER_INERTIA)))
            joints.append(y.Joint(name=lname + SLIDE_SUFFIX, type="prismatic",
                                  parent=link_name(parent), child=helper, origin=_origin(rel_origin),
                                  axis=axis, limit=y.Limit(effort=j.effort, velocity=j.velocity,
                                                           lower=j.t_range[0], upper=j.t_range[1])))
            joints.append(y.Joint(name=joint_name(p), type="revolute", parent=helper, child=lname,
                                  origin=np.eye(4), axis=axis,
                                  limit=y.Limit(effort=j.effort, velocity=j.velocity,
                                                lower=j.r_range[0], upper=j.r_range[1])))
            continue
        kw = {}
        if j.type == JointType.REVOLUTE:
            kw = dict(axis=axis, limit=y.Limit(effort=j.effort, velocity=j.velocity,
                                               lower=j.r_range[0], upper=j.r_range[1]))
        elif j.type == JointType.PRISMATIC:
            kw = dict(axis=axis, limit=y.Limit(effort=j.effort, velocity=j.velocity,
                                               lower=j.t_range[0], upper=j.t_range[1]))
        elif j.type == JointType.CONTINUOUS:
            kw = dict(axis=axis, limit=y.Limit(effort=j.effort, velocity=j.velocity))
        joints.append(y.Joint(name=joint_name(p), type=j.type.name.lower(), parent=link_name(parent),
                              child=lname, origin=_origin(rel_origin), **kw))
    robot = y.Robot(name=robot_name, links=links, joints=joints,
                    materials=list(materials.values()), transmission=[], gazebo=[])
    return robot, mesh_files


def _robot_xml(robot, provenance: dict, discard_visual: bool = False) -> str:
    """Serialise with lxml (yourdfpy's write_xml_string is broken), add the provenance
    comment and MuJoCo's compiler hints (mesh folder, keep visuals, keep every link)."""
    import yourdfpy as y
    from lxml import etree

    urdf = y.URDF(robot=robot, build_scene_graph=False, load_meshes=False,
                  filename_handler=y.filename_handler_null)
    tree = urdf.write_xml()
    root = tree.getroot()
    text = " artformer_ros export provenance: " + json.dumps(provenance, sort_keys=True) + " "
    root.insert(0, etree.Comment(_comment_safe(text)))
    mj = etree.SubElement(root, "mujoco")
    etree.SubElement(mj, "compiler", attrib={
        "meshdir": "meshes", "strippath": "true",
        "discardvisual": "true" if discard_visual else "false",
        "fusestatic": "false", "balanceinertia": "true"})
    etree.indent(tree, space="  ")
    return etree.tostring(tree, encoding="unicode", xml_declaration=False) + "\n"


def _comment_safe(text: str) -> str:
    # XML comments may not contain "--" nor end in "-".
    while "--" in text:
        text = text.replace("--", "- -")
    return text if not text.endswith("-") else text + " "


def _metadata(obj, robot_name, urdf_name, fmt, mesh_files, prov) -> dict:
    toks, types, parents, labels = obj.tokens()
    order = obj.topological_order()
    parts = []
    for k, i in enumerate(order):
        p = obj.parts[i]
        joints = ([p.name + SLIDE_SUFFIX, joint_name(p)] if p.joint.type == JointType.SCREW
                  else [] if p.parent < 0 else [joint_name(p)])
        parts.append({"name": p.name, "label": p.label, "link": link_name(p),
                      "parent": int(parents[k]), "joint_type": p.joint.type.name.lower(),
                      "urdf_joints": joints, "token": [float(x) for x in toks[k]],
                      "mesh": mesh_files.get(link_name(p))})
    return {"format": METADATA_FORMAT, "name": robot_name, "category": obj.category,
            "urdf": urdf_name, "mesh_format": fmt, "summary": obj.summary(), "parts": parts,
            "provenance": prov, "object_metadata": jsonable(obj.metadata)}
