"""The MJCF body tree of a URDF model: default classes, bodies with inertials, joints,
visual and collision geoms, mesh assets, screw couplings and position actuators (gains are
set afterwards by model.export.mjcf from the compiled model)."""
from __future__ import annotations

import logging
import math
import shutil
from pathlib import Path
from typing import Optional

import numpy as np

from .urdfmodel import Geom, Joint, URDFModel, quat_wxyz

log = logging.getLogger(__name__)

MESH_EXTS = (".obj", ".stl")           # formats written as they are; others become OBJ
HELPER_SUFFIX = "_screw_helper"        # model.export.urdf's helper link of a screw
TIMESTEP = 0.002


def fmt(v) -> str:
    arr = np.atleast_1d(np.asarray(v, dtype=np.float64))
    return " ".join(f"{x:.9g}" for x in arr)


def _screw_pairs(model: URDFModel) -> dict[str, tuple[Joint, Joint]]:
    """helper link -> (slide joint into it, hinge joint out of it), for our screw pattern:
    a geometry-free link between a prismatic and a revolute/continuous joint with an
    identity origin and a parallel axis."""
    out = {}
    for j in model.joints:
        if j.type != "prismatic":
            continue
        helper = model.links[j.child]
        kids = model.child_joints(helper.name)
        if (len(kids) != 1 or helper.visuals or helper.collisions
                or not helper.name.endswith(HELPER_SUFFIX)):
            continue
        k = kids[0]
        if (k.type in ("revolute", "continuous") and np.allclose(k.origin, np.eye(4), atol=1e-9)
                and abs(abs(float(np.dot(k.axis, j.axis))) - 1.0) < 1e-6):
            out[helper.name] = (j, k)
    return out


def _mesh_ok(mesh, role: str) -> bool:
    """Can MuJoCo compile this mesh? Visual meshes (``inertia="shell"``, no contacts) need
    4 vertices; collision meshes need a convex hull with a volume (measured errors: "at least
    4 vertices required", "qhull error" on flat collision meshes; flat visual meshes compile
    with shell inertia)."""
    if mesh is None or len(mesh.vertices) < 4 or len(mesh.faces) == 0:
        return False
    if role == "visual":
        return True
    try:
        return bool(mesh.convex_hull.volume > 0.0)
    except Exception:  # qhull fails on flat / collinear input
        return False


class Assets:
    """Mesh files copied (or converted to OBJ) into assets/, one <mesh> asset per file, scale
    and role (visual meshes get ``inertia="shell"`` so flat panels compile)."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.names: dict[tuple, Optional[str]] = {}
        self.used: set[str] = set()
        self.entries: list[tuple[str, str, np.ndarray, str]] = []   # (name, file, scale, role)

    def add(self, g: Geom, role: str) -> Optional[str]:
        """Asset name of a mesh geom, or None when MuJoCo cannot compile the mesh."""
        from .urdfmodel import load_mesh
        key = (str(g.mesh), tuple(np.round(g.scale, 12)), role)
        if key in self.names:
            return self.names[key]
        mesh = load_mesh(g.mesh, g.scale)
        if not _mesh_ok(mesh, role):
            self.names[key] = None
            return None
        stem = "".join(c if c.isalnum() or c in "_-" else "_" for c in g.mesh.stem) or "mesh"
        name, n = stem, 1
        while name in self.used:
            n += 1
            name = f"{stem}_{n}"
        self.used.add(name)
        self.names[key] = name
        ext = g.mesh.suffix.lower()
        if ext in MESH_EXTS:
            fname = f"{name}{ext}"
            shutil.copyfile(g.mesh, self.folder / fname)
            scale = np.asarray(g.scale, dtype=np.float64)
        else:                               # GLB / DAE...: MuJoCo reads OBJ, STL, MSH
            from trimesh.exchange.obj import export_obj
            fname = f"{name}.obj"
            (self.folder / fname).write_text(export_obj(mesh, include_normals=False,
                                                        include_color=False,
                                                        include_texture=False, header=None))
            scale = np.ones(3)              # already applied by load_mesh
        self.entries.append((name, fname, scale, role))
        return name


def rest_bounds(model: URDFModel) -> Optional[np.ndarray]:
    """(2, 3) bounds of every visual and collision geometry at rest, root link frame."""
    from .urdfmodel import load_mesh
    frames = model.rest_link_frames()
    pts = []
    for name, link in model.links.items():
        for g in [*link.visuals, *link.collisions]:
            T = frames[name] @ g.origin
            if g.kind == "mesh":
                v = load_mesh(g.mesh, g.scale).vertices
            elif g.kind == "box":
                h = np.asarray(g.size) / 2.0
                v = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                              for sz in (-1, 1)]) * h
            elif g.kind == "cylinder":
                r, half = g.size[0], g.size[1] / 2.0
                v = np.array([[sx * r, sy * r, sz * half] for sx in (-1, 1) for sy in (-1, 1)
                              for sz in (-1, 1)])
            else:
                r = g.size[0]
                v = np.array([[sx * r, sy * r, sz * r] for sx in (-1, 1) for sy in (-1, 1)
                              for sz in (-1, 1)])
            if len(v):
                pts.append(v @ T[:3, :3].T + T[:3, 3])
    if not pts:
        return None
    allp = np.concatenate(pts)
    return np.stack([allp.min(0), allp.max(0)])


def _geom_el(parent, g: Geom, cls: str, assets: Assets, materials: dict, name: str):
    from lxml import etree
    attrs = {"class": cls, "name": name}
    if g.kind == "mesh":
        mesh = assets.add(g, "visual" if cls == "visual" else "collision")
        if mesh is None:
            return None
        attrs.update(type="mesh", mesh=mesh)
    elif g.kind == "box":
        attrs.update(type="box", size=fmt(np.maximum(np.asarray(g.size) / 2.0, 1e-6)))
    elif g.kind == "cylinder":
        attrs.update(type="cylinder", size=fmt([g.size[0], g.size[1] / 2.0]))
    else:
        attrs.update(type="sphere", size=fmt(g.size[:1]))
    if not np.allclose(g.origin[:3, 3], 0.0, atol=1e-12):
        attrs["pos"] = fmt(g.origin[:3, 3])
    if not np.allclose(g.origin[:3, :3], np.eye(3), atol=1e-12):
        attrs["quat"] = fmt(quat_wxyz(g.origin[:3, :3]))
    if cls == "visual" and g.rgba is not None:
        key = tuple(np.round(g.rgba, 4))
        if key not in materials:
            base = "".join(c if c.isalnum() or c in "_-" else "_" for c in g.material) or "colour"
            mname, n = base, 1
            while mname in {v for v in materials.values()}:
                n += 1
                mname = f"{base}_{n}"
            materials[key] = mname
        attrs["material"] = materials[key]
    return etree.SubElement(parent, "geom", attrib=attrs)




def _skeleton(name: str, source: str):
    """<mujoco> with compiler, option, the default classes, an empty asset and worldbody."""
    from lxml import etree

    root = etree.Element("mujoco", model=name)
    root.append(etree.Comment(f" {name}: converted by artformer_ros from {source} "))
    etree.SubElement(root, "compiler", angle="radian", meshdir="assets", autolimits="true",
                     balanceinertia="true")
    etree.SubElement(root, "option", integrator="implicitfast", timestep=f"{TIMESTEP:g}")
    default = etree.SubElement(root, "default")
    top = etree.SubElement(default, "default", attrib={"class": name})
    etree.SubElement(top, "joint", damping="0", armature="0.001")
    etree.SubElement(top, "position", dampratio="1")
    vis = etree.SubElement(top, "default", attrib={"class": "visual"})
    etree.SubElement(vis, "geom", type="mesh", contype="0", conaffinity="0", group="2",
                     density="0")
    col = etree.SubElement(top, "default", attrib={"class": "collision"})
    etree.SubElement(col, "geom", group="3", density="0", condim="3", friction="0.8 0.005 0.0001")
    return root, etree.SubElement(root, "asset"), etree.SubElement(root, "worldbody")


class BodyTree:
    """The body tree of one URDF model, its screw couplings and actuated joints."""

    def __init__(self, model: URDFModel, assets: Assets, floating: bool):
        self.model, self.assets, self.floating = model, assets, floating
        self.root, self.asset, self.world = _skeleton(model.name, model.path.name)
        self.screws = _screw_pairs(model)
        self.materials: dict[tuple, str] = {}
        self.dropped: list[str] = []
        self.joints_out: list[str] = []
        self.actuated: list[Joint] = []
        self.couplings: dict[str, str] = {}
        self.equality: list[tuple] = []

    def add_link(self, parent_el, link_name: str, pos_T: np.ndarray, joints: list[Joint]):
        from lxml import etree

        link = self.model.links[link_name]
        attrs = {"name": link_name}
        if parent_el is self.world:
            attrs["childclass"] = self.model.name
        if not np.allclose(pos_T[:3, 3], 0.0, atol=1e-12):
            attrs["pos"] = fmt(pos_T[:3, 3])
        if not np.allclose(pos_T[:3, :3], np.eye(3), atol=1e-12):
            attrs["quat"] = fmt(quat_wxyz(pos_T[:3, :3]))
        body = etree.SubElement(parent_el, "body", attrib=attrs)
        if parent_el is self.world and self.floating:
            etree.SubElement(body, "freejoint", name=f"{link_name}_free")
        if link.mass > 0 and link.inertia is not None:
            I = link.inertia_in_link_frame()
            etree.SubElement(body, "inertial", pos=fmt(link.com[:3, 3]), mass=f"{link.mass:.9g}",
                             fullinertia=fmt([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]))
        for j in joints:
            jattrs = {"name": j.name, "type": "slide" if j.type == "prismatic" else "hinge",
                      "axis": fmt(j.axis)}
            if j.type in ("revolute", "prismatic"):
                jattrs["range"] = fmt([j.lower, j.upper])
            if j.effort > 0:    # on the joint too, as MuJoCo's own URDF import puts it
                jattrs["actuatorfrcrange"] = fmt([-j.effort, j.effort])
            etree.SubElement(body, "joint", attrib=jattrs)
            self.joints_out.append(j.name)
        for role, geoms in (("visual", link.visuals), ("collision", link.collisions)):
            for k, g in enumerate(geoms):
                if _geom_el(body, g, role, self.assets, self.materials,
                            g.name or f"{link_name}_{role}_{k}") is None:
                    self.dropped.append(f"{link_name}: {g.mesh.name}")
        for j in self.model.child_joints(link_name):
            if j.child in self.screws:
                self._add_screw(body, j)
            else:
                joint_list = [] if j.type == "fixed" else [j]
                self.add_link(body, j.child, j.origin, joint_list)
                self.actuated.extend(joint_list)

    def _add_screw(self, body, j: Joint) -> None:
        """A slide into a screw helper: one body (the hinge's child) with both joints, the
        slide coupled to the hinge by an equality; the hinge carries the actuator."""
        slide, hinge = self.screws[j.child]
        self.add_link(body, hinge.child, j.origin @ hinge.origin, [slide, hinge])
        if hinge.type == "revolute" and hinge.upper - hinge.lower > 1e-12:
            a1 = (slide.upper - slide.lower) / (hinge.upper - hinge.lower)
            a0 = slide.lower - a1 * hinge.lower
            self.equality.append((slide.name, hinge.name, a0, a1))
            self.couplings[slide.name] = hinge.name
        else:                               # nothing to couple: the slide is driven itself
            self.actuated.append(slide)
        self.actuated.append(hinge)

    def finish(self) -> None:
        """Materials, mesh assets, screw equalities and one position actuator per joint."""
        from lxml import etree

        for key, mname in self.materials.items():
            etree.SubElement(self.asset, "material", name=mname, rgba=fmt(key))
        for aname, fname, scale, role in self.assets.entries:
            attrs = {"name": aname, "file": fname}
            if not np.allclose(scale, 1.0):
                attrs["scale"] = fmt(scale)
            if role == "visual":
                attrs["inertia"] = "shell"
            etree.SubElement(self.asset, "mesh", attrib=attrs)
        if self.equality:
            eq = etree.SubElement(self.root, "equality")
            for slide, hinge, a0, a1 in self.equality:
                etree.SubElement(eq, "joint", name=f"{slide}_screw", joint1=slide, joint2=hinge,
                                 polycoef=fmt([a0, a1, 0, 0, 0]), solref="0.005 1")
        act = etree.SubElement(self.root, "actuator")
        for j in self.actuated:
            attrs = {"class": self.model.name, "name": j.name, "joint": j.name, "kp": "1"}
            attrs["ctrlrange"] = fmt([j.lower, j.upper] if j.type in ("revolute", "prismatic")
                                      else [-math.pi, math.pi])
            if j.effort > 0:
                attrs["forcerange"] = fmt([-j.effort, j.effort])
            etree.SubElement(act, "position", attrib=attrs)


