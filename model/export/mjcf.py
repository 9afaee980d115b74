"""URDF folder → MJCF model laid out as MuJoCo Menagerie lays out its models.

    res = export_mjcf("out/cabinet")          # writes out/cabinet/mjcf/
    mujoco.MjModel.from_xml_path(res.scene_xml)

Output folder (built beside its destination and renamed into place)::

    <name>.xml     the object: compiler/option, defaults (class "visual", "collision"),
                   assets (meshes, materials), the body tree, contact excludes, screw
                   couplings, one position actuator per moving joint
    scene.xml      includes <name>.xml and adds a floor, a light, a skybox and a camera framing
    assets/        visual meshes and collision pieces (OBJ / STL; other formats become OBJ)

Mapping from the URDF:

* Each link becomes a body with the link's name, placed at its joint origin. It keeps its
  inertial (mass, centre of mass and full inertia tensor) and its visuals (class "visual":
  group 2, no contacts). Its collision pieces (class "collision": group 3) are written as
  boxes where the URDF has boxes and as convex meshes otherwise.
* Revolute and continuous joints become hinges; prismatic joints become slides. Joint names,
  axes and ranges are kept.
* A screw (``<part>_slide`` → ``<part>_screw_helper`` → ``<part>_joint`` in our URDFs) becomes
  one body with both joints. An equality constraint couples the slide to the hinge across
  their ranges, so the part travels as it turns; the hinge's actuator drives both.
* A position actuator per actuated joint, named after the joint. ``ctrlrange`` is the joint
  range and ``forcerange`` (and the joint's ``actuatorfrcrange``) is the URDF effort. Gains
  and joint armature come from ``servo_gains`` (the rule the audit's physics check uses):
  the joint-space inertia at rest times (2π ``kp_hz``)², or the effort at a tenth of the
  range off target where that is stiffer, critically damped.
* The root body is fixed to the world, lifted so the object's lowest point is 1 mm above
  the floor (no part starts in contact with it). With ``floating=True`` it gets a free joint
  instead and its lowest point is at z = 0.
* A parent and child body never collide with each other (MuJoCo's rule for moving parents,
  written out as ``<contact><exclude>`` for the children of the fixed root). Other pairs of
  bodies whose collision geometry already interpenetrates at rest (more than
  ``exclude_depth``) are excluded too, so that a model whose parts touch does not start in
  contact and jam. Parts that only meet while moving still collide.
* Visual meshes are compiled with ``inertia="shell"`` (the body inertials are explicit), so
  flat panels load. Meshes MuJoCo still cannot compile (fewer than 4 vertices, a collision
  piece without a volume) are left out and logged (``MJCFResult.dropped_meshes``).
"""
from __future__ import annotations

import logging
import math
import os
import re
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from .urdfmodel import ConvertError, Geom, Joint, URDFModel, quat_wxyz, read_urdf_folder

log = logging.getLogger(__name__)

MESH_EXTS = (".obj", ".stl")           # formats written as they are; others become OBJ
HELPER_SUFFIX = "_screw_helper"        # model.export.urdf's helper link of a screw
TIMESTEP = 0.002
# A fixed object hovers this far above the floor: a moving part resting on the floor would
# otherwise start in contact with it and be held by friction (a wheel, a door's lower edge).
FLOOR_CLEARANCE = 0.001                # m
MIN_ARMATURE = 0.01                    # kg or kg m^2: motor-like inertia of a driven joint


def servo_gains(inertia: float, effort: float, span: float, *, hz: float,
                timestep: float = TIMESTEP, min_armature: float = MIN_ARMATURE
                ) -> tuple[float, float, float]:
    """(kp, kv, armature) of a position servo on a joint with joint-space ``inertia``: the
    bandwidth ``hz`` or, when stiffer, the joint's ``effort`` at a tenth of its range
    (``span``) off target, so a 20 g knob is pushed as hard as its joint allows rather than
    by a servo scaled to its own 20 g. The armature (a motor's reflected inertia) keeps the
    servo stable at ``timestep`` (omega dt <= 0.2); kv damps it critically."""
    w = 2.0 * math.pi * hz
    kp = max(inertia * w * w, effort / (0.1 * max(span, 1e-9)) if effort > 0 else 0.0, 1e-6)
    armature = max(min_armature, kp * (timestep / 0.2) ** 2 - inertia)
    kv = 2.0 * math.sqrt(kp * (inertia + armature))
    return kp, kv, armature


@dataclass
class MJCFResult:
    out_dir: str
    model_xml: str                      # the object
    scene_xml: str                      # floor + light, includes model_xml
    joints: list[str]                   # every URDF moving joint, present in the MJCF
    actuators: list[str]
    couplings: dict[str, str] = field(default_factory=dict)   # slide joint -> hinge joint
    excluded_pairs: list[tuple[str, str]] = field(default_factory=list)
    dropped_meshes: list[str] = field(default_factory=list)   # "link: file" MuJoCo cannot compile


def _fmt(v) -> str:
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


class _Assets:
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


def _rest_bounds(model: URDFModel) -> Optional[np.ndarray]:
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


def _geom_el(parent, g: Geom, cls: str, assets: _Assets, materials: dict, name: str):
    from lxml import etree
    attrs = {"class": cls, "name": name}
    if g.kind == "mesh":
        mesh = assets.add(g, "visual" if cls == "visual" else "collision")
        if mesh is None:
            return None
        attrs.update(type="mesh", mesh=mesh)
    elif g.kind == "box":
        attrs.update(type="box", size=_fmt(np.maximum(np.asarray(g.size) / 2.0, 1e-6)))
    elif g.kind == "cylinder":
        attrs.update(type="cylinder", size=_fmt([g.size[0], g.size[1] / 2.0]))
    else:
        attrs.update(type="sphere", size=_fmt(g.size[:1]))
    if not np.allclose(g.origin[:3, 3], 0.0, atol=1e-12):
        attrs["pos"] = _fmt(g.origin[:3, 3])
    if not np.allclose(g.origin[:3, :3], np.eye(3), atol=1e-12):
        attrs["quat"] = _fmt(quat_wxyz(g.origin[:3, :3]))
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


def _build(model: URDFModel, assets: _Assets, *, floating: bool, on_floor: bool):
    """The object's <mujoco> tree (actuator gains set to placeholders) and bookkeeping."""
    from lxml import etree

    name = model.name
    root = etree.Element("mujoco", model=name)
    root.append(etree.Comment(f" {name}: converted by artformer_ros from {model.path.name} "))
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
    asset = etree.SubElement(root, "asset")
    world = etree.SubElement(root, "worldbody")

    screws = _screw_pairs(model)
    materials: dict[tuple, str] = {}
    dropped: list[str] = []
    joints_out: list[str] = []
    actuated: list[Joint] = []
    couplings: dict[str, str] = {}
    equality = []

    def add_link(parent_el, link_name: str, pos_T: np.ndarray, joints: list[Joint]):
        link = model.links[link_name]
        attrs = {"name": link_name}
        if parent_el is world:
            attrs["childclass"] = name
        if not np.allclose(pos_T[:3, 3], 0.0, atol=1e-12):
            attrs["pos"] = _fmt(pos_T[:3, 3])
        if not np.allclose(pos_T[:3, :3], np.eye(3), atol=1e-12):
            attrs["quat"] = _fmt(quat_wxyz(pos_T[:3, :3]))
        body = etree.SubElement(parent_el, "body", attrib=attrs)
        if parent_el is world and floating:
            etree.SubElement(body, "freejoint", name=f"{link_name}_free")
        if link.mass > 0 and link.inertia is not None:
            I = link.inertia_in_link_frame()
            etree.SubElement(body, "inertial", pos=_fmt(link.com[:3, 3]), mass=f"{link.mass:.9g}",
                             fullinertia=_fmt([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]))
        for j in joints:
            jattrs = {"name": j.name, "type": "slide" if j.type == "prismatic" else "hinge",
                      "axis": _fmt(j.axis)}
            if j.type in ("revolute", "prismatic"):
                jattrs["range"] = _fmt([j.lower, j.upper])
            if j.effort > 0:    # on the joint too, as MuJoCo's own URDF import puts it
                jattrs["actuatorfrcrange"] = _fmt([-j.effort, j.effort])
            etree.SubElement(body, "joint", attrib=jattrs)
            joints_out.append(j.name)
        for k, g in enumerate(link.visuals):
            if _geom_el(body, g, "visual", assets, materials, g.name or f"{link_name}_visual_{k}") is None:
                dropped.append(f"{link_name}: {g.mesh.name}")
        for k, g in enumerate(link.collisions):
            if _geom_el(body, g, "collision", assets, materials,
                        g.name or f"{link_name}_collision_{k}") is None:
                dropped.append(f"{link_name}: {g.mesh.name}")
        for j in model.child_joints(link_name):
            if j.child in screws:           # slide into a helper: merge helper + hinge child
                slide, hinge = screws[j.child]
                add_link(body, hinge.child, j.origin @ hinge.origin, [slide, hinge])
                if hinge.type == "revolute" and hinge.upper - hinge.lower > 1e-12:
                    a1 = (slide.upper - slide.lower) / (hinge.upper - hinge.lower)
                    a0 = slide.lower - a1 * hinge.lower
                    equality.append((slide.name, hinge.name, a0, a1))
                    couplings[slide.name] = hinge.name
                else:                       # nothing to couple: the slide is driven itself
                    actuated.append(slide)
                actuated.append(hinge)
                continue
            joint_list = [] if j.type == "fixed" else [j]
            add_link(body, j.child, j.origin, joint_list)
            actuated.extend(joint_list)

    base = np.eye(4)
    if on_floor:
        b = _rest_bounds(model)
        if b is not None:
            base[2, 3] = -b[0, 2] + (0.0 if floating else FLOOR_CLEARANCE)
    add_link(world, model.root, base, [])

    for key, mname in materials.items():
        etree.SubElement(asset, "material", name=mname, rgba=_fmt(key))
    for aname, fname, scale, role in assets.entries:
        attrs = {"name": aname, "file": fname}
        if not np.allclose(scale, 1.0):
            attrs["scale"] = _fmt(scale)
        if role == "visual":
            attrs["inertia"] = "shell"
        etree.SubElement(asset, "mesh", attrib=attrs)
    if equality:
        eq = etree.SubElement(root, "equality")
        for slide, hinge, a0, a1 in equality:
            etree.SubElement(eq, "joint", name=f"{slide}_screw", joint1=slide, joint2=hinge,
                             polycoef=_fmt([a0, a1, 0, 0, 0]), solref="0.005 1")
    act = etree.SubElement(root, "actuator")
    for j in actuated:
        attrs = {"class": name, "name": j.name, "joint": j.name, "kp": "1"}
        if j.type in ("revolute", "prismatic"):
            attrs["ctrlrange"] = _fmt([j.lower, j.upper])
        else:
            attrs["ctrlrange"] = _fmt([-math.pi, math.pi])
        if j.effort > 0:
            attrs["forcerange"] = _fmt([-j.effort, j.effort])
        etree.SubElement(act, "position", attrib=attrs)
    return root, joints_out, [j.name for j in actuated], couplings, dropped


def _drop_uncompilable(root, xml_path: Path, write, max_tries: int = 50) -> list[str]:
    """Compile; while MuJoCo rejects a mesh asset (a degenerate hull our checks let through),
    remove the asset and its geoms and try again. Returns "body: file" of what was removed."""
    import mujoco
    removed = []
    for _ in range(max_tries):
        try:
            mujoco.MjModel.from_xml_path(str(xml_path))
            return removed
        except ValueError as e:
            hit = re.search(r"Element name '([^']+)'", str(e))
            asset = root.find("asset")
            mesh = asset.find(f"mesh[@name='{hit.group(1)}']") if hit else None
            if mesh is None:
                raise ConvertError(f"MuJoCo cannot compile the converted model {xml_path}: {e}") from None
            for geom in list(root.iter("geom")):
                if geom.get("mesh") == mesh.get("name"):
                    removed.append(f"{geom.getparent().get('name')}: {mesh.get('file')}")
                    geom.getparent().remove(geom)
            asset.remove(mesh)
            (xml_path.parent / "assets" / mesh.get("file")).unlink(missing_ok=True)
            write()
    raise ConvertError(f"MuJoCo still rejects meshes of {xml_path} after {max_tries} removals")


def _compile(xml_path: Path):
    import mujoco
    try:
        return mujoco.MjModel.from_xml_path(str(xml_path))
    except ValueError as e:
        raise ConvertError(f"MuJoCo cannot compile the converted model {xml_path}: {e}") from None


def _tune(root, xml_path: Path, *, kp_hz: float, exclude_depth: float):
    """Second pass on the compiled model: actuator gains from the joint-space inertia at rest
    and contact excludes for body pairs that interpenetrate at rest."""
    import mujoco
    from lxml import etree

    m = _compile(xml_path)
    d = mujoco.MjData(m)
    for k in range(m.nu):                   # start each joint at its control range's nearest point
        jid = int(m.actuator_trnid[k, 0])
        d.qpos[m.jnt_qposadr[jid]] = float(np.clip(0.0, *m.actuator_ctrlrange[k]))
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, M, d.qM)
    gains = {}
    for k in range(m.nu):
        jid = int(m.actuator_trnid[k, 0])
        dof = int(m.jnt_dofadr[jid])
        lo, hi = m.actuator_ctrlrange[k]
        effort = float(np.abs(m.actuator_forcerange[k]).max()) if m.actuator_forcelimited[k] \
            else 0.0
        gains[m.actuator(k).name] = servo_gains(
            max(float(M[dof, dof]) - float(m.dof_armature[dof]), 1e-9), effort,
            float(hi - lo), hz=kp_hz)
    # MuJoCo does not filter parent-child contacts when the parent is welded to the world
    # (the fixed root): exclude them explicitly, as for moving parents.
    pairs = {tuple(sorted((m.body(int(m.body_parentid[b])).name, m.body(b).name)))
             for b in range(1, m.nbody)
             if m.body_parentid[b] > 0 and m.body_weldid[m.body_parentid[b]] == 0}
    n = int(d.ncon)
    for g1, g2, dist in zip(d.contact.geom1[:n], d.contact.geom2[:n], d.contact.dist[:n]):
        if -float(dist) > exclude_depth:
            b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
            if b1 and b2:                   # not the world (the floor lives in scene.xml)
                pairs.add(tuple(sorted((m.body(b1).name, m.body(b2).name))))
    for el in root.find("actuator"):
        kp, _, armature = gains[el.get("name")]   # MuJoCo's dampratio 1 gives kv
        el.set("kp", f"{kp:.6g}")
        joint = root.find(f".//joint[@name='{el.get('joint')}']")
        joint.set("armature", f"{armature:.6g}")
    if pairs:
        contact = etree.Element("contact")
        for a, b in sorted(pairs):
            etree.SubElement(contact, "exclude", body1=a, body2=b)
        root.find("actuator").addprevious(contact)
    return sorted(pairs)


def _scene(model_file: str, name: str, bounds: Optional[np.ndarray]) -> str:
    from lxml import etree
    root = etree.Element("mujoco", model=f"{name} scene")
    etree.SubElement(root, "include", file=model_file)
    if bounds is not None:
        size = bounds[1] - bounds[0]
        centre = (bounds[0] + bounds[1]) / 2.0
        centre[2] = size[2] / 2.0           # the object stands on the floor
        etree.SubElement(root, "statistic", center=_fmt(centre),
                         extent=f"{max(float(np.linalg.norm(size)), 0.1):.4g}")
    visual = etree.SubElement(root, "visual")
    etree.SubElement(visual, "headlight", diffuse="0.6 0.6 0.6", ambient="0.3 0.3 0.3",
                     specular="0 0 0")
    etree.SubElement(visual, "rgba", haze="0.15 0.25 0.35 1")
    etree.SubElement(visual, "global", azimuth="150", elevation="-20")
    asset = etree.SubElement(root, "asset")
    etree.SubElement(asset, "texture", type="skybox", builtin="gradient", rgb1="0.3 0.5 0.7",
                     rgb2="0 0 0", width="512", height="3072")
    etree.SubElement(asset, "texture", type="2d", name="groundplane", builtin="checker",
                     mark="edge", rgb1="0.2 0.3 0.4", rgb2="0.1 0.2 0.3", markrgb="0.8 0.8 0.8",
                     width="300", height="300")
    etree.SubElement(asset, "material", name="groundplane", texture="groundplane",
                     texuniform="true", texrepeat="5 5", reflectance="0.2")
    world = etree.SubElement(root, "worldbody")
    etree.SubElement(world, "light", pos="0 0 3", dir="0 0 -1", directional="true")
    etree.SubElement(world, "geom", name="floor", size="0 0 0.05", type="plane",
                     material="groundplane")
    etree.indent(root, space="  ")
    return etree.tostring(root, encoding="unicode") + "\n"


def export_mjcf(folder: os.PathLike, out_dir: Optional[os.PathLike] = None, *,
                floating: bool = False, on_floor: bool = True, kp_hz: float = 4.0,
                exclude_depth: float = 1e-3) -> MJCFResult:
    """Convert the URDF folder ``folder`` (or a .urdf file) to an MJCF folder.

    ``out_dir`` defaults to ``<folder>/mjcf``. ``floating``: a free joint on the root body
    instead of fixing it to the world. ``on_floor``: lift the object so its lowest point is
    on the floor (1 mm above it when fixed). ``kp_hz``: natural frequency of every position actuator at rest.
    ``exclude_depth`` (m): body pairs interpenetrating deeper than this at rest do not collide.
    Raises ConvertError when the URDF cannot be read or MuJoCo cannot compile the result.
    """
    from lxml import etree

    from .urdf import _replace_dir, object_slug

    if not (kp_hz > 0 and math.isfinite(kp_hz)):
        raise ConvertError(f"kp_hz must be a positive number, got {kp_hz!r}")
    src = Path(folder).expanduser()
    model = read_urdf_folder(src)
    if out_dir is None:
        out_dir = (src if src.is_dir() else src.parent) / "mjcf"
    out_dir = Path(out_dir).expanduser().resolve()
    name = object_slug(model.name)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out_dir.parent, prefix=f".{out_dir.name}.tmp-"))
    try:
        os.chmod(tmp, 0o755)
        (tmp / "assets").mkdir()
        assets = _Assets(tmp / "assets")
        root, joints, actuators, couplings, dropped = _build(model, assets, floating=floating,
                                                             on_floor=on_floor)
        model_file = f"{name}.xml"
        xml_path = tmp / model_file

        def write():
            etree.indent(root, space="  ")
            xml_path.write_text(etree.tostring(root, encoding="unicode") + "\n")

        write()
        dropped += _drop_uncompilable(root, xml_path, write)
        if dropped:
            log.warning("%s: %d mesh(es) MuJoCo cannot compile (flat or degenerate) left out: %s",
                        model.path.name, len(dropped), ", ".join(dropped[:8])
                        + (" ..." if len(dropped) > 8 else ""))
        pairs = _tune(root, xml_path, kp_hz=kp_hz, exclude_depth=exclude_depth)
        write()
        bounds = _rest_bounds(model)
        if bounds is not None and on_floor:
            bounds = bounds + np.array([0.0, 0.0, -bounds[0, 2]])   # for the camera framing
        (tmp / "scene.xml").write_text(_scene(model_file, name, bounds))
        _compile(tmp / "scene.xml")
        _replace_dir(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    missing = sorted({j.name for j in model.moving_joints()} - set(joints))
    if missing:                              # cannot happen for a tree; guards the mapping
        raise ConvertError(f"joints lost in the conversion: {missing}")
    log.info("MJCF of %s written to %s (%d joints, %d actuators)", model.name, out_dir,
             len(joints), len(actuators))
    return MJCFResult(str(out_dir), str(out_dir / model_file), str(out_dir / "scene.xml"),
                      joints, actuators, couplings, pairs, dropped)


@dataclass
class DriveReport:
    """What ``drive_check`` saw: each actuator driven to each end of its range."""
    loaded: bool = False
    missing_joints: list[str] = field(default_factory=list)
    finite: bool = True
    within_limits: bool = True
    reached: dict[str, float] = field(default_factory=dict)   # actuator -> worst share of the
                                                              # commanded travel achieved
    error: str = ""

    @property
    def ok(self) -> bool:
        return (self.loaded and not self.missing_joints and self.finite and self.within_limits
                and not self.error and all(v >= 0.9 for v in self.reached.values()))


def drive_check(scene_xml: os.PathLike, joints=(), *, seconds: float = 1.5,
                limit_tol: float = 0.02) -> DriveReport:
    """Load an MJCF scene, then, per actuator, command one end of its range and the other
    (the rest at their rest value), simulate ``seconds`` each, and record how much of the
    commanded travel its joint made, whether the state stayed finite and every limited joint
    stayed within its range (``limit_tol`` of the range). ``joints``: names that must exist."""
    import mujoco
    rep = DriveReport()
    try:
        m = mujoco.MjModel.from_xml_path(str(scene_xml))
    except Exception as e:
        rep.error = f"load: {e}"
        return rep
    rep.loaded = True
    have = {m.joint(k).name for k in range(m.njnt)}
    rep.missing_joints = sorted(set(joints) - have)
    d = mujoco.MjData(m)
    steps = max(1, int(round(seconds / m.opt.timestep)))
    rest = np.array([float(np.clip(0.0, *m.actuator_ctrlrange[k])) for k in range(m.nu)])
    lim = [(m.jnt_qposadr[k], m.jnt_range[k]) for k in range(m.njnt)
           if m.jnt_limited[k] and m.jnt_type[k] in (mujoco.mjtJoint.mjJNT_HINGE,
                                                     mujoco.mjtJoint.mjJNT_SLIDE)]
    for k in range(m.nu):
        jid = int(m.actuator_trnid[k, 0])
        adr = int(m.jnt_qposadr[jid])
        lo, hi = m.actuator_ctrlrange[k]
        worst = 1.0
        for target in (hi, lo):
            mujoco.mj_resetData(m, d)
            for j in range(m.nu):
                d.qpos[m.jnt_qposadr[int(m.actuator_trnid[j, 0])]] = rest[j]
            d.ctrl[:] = rest
            if target == lo:                 # start the way back from the upper end
                d.qpos[adr] = hi
                d.ctrl[k] = hi
            mujoco.mj_forward(m, d)
            start = float(d.qpos[adr])
            d.ctrl[k] = target
            for _ in range(steps):
                mujoco.mj_step(m, d)
            if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
                rep.finite = False
                break
            for a, (rlo, rhi) in lim:
                tol = limit_tol * max(rhi - rlo, 1e-9)
                if not (rlo - tol <= d.qpos[a] <= rhi + tol):
                    rep.within_limits = False
            travel = target - start
            if abs(travel) > 1e-12:
                worst = min(worst, float((d.qpos[adr] - start) / travel))
        rep.reached[m.actuator(k).name] = worst
    return rep
