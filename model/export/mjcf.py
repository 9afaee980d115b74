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

from .mjcf_tree import TIMESTEP, Assets, fmt, rest_bounds, BodyTree
from .urdfmodel import ConvertError, URDFModel, read_urdf_folder

log = logging.getLogger(__name__)

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


def _build(model: URDFModel, assets: Assets, *, floating: bool, on_floor: bool):
    """The object's <mujoco> tree (actuator gains set to placeholders) and bookkeeping."""
    t = BodyTree(model, assets, floating)
    base = np.eye(4)
    if on_floor:
        b = rest_bounds(model)
        if b is not None:
            base[2, 3] = -b[0, 2] + (0.0 if floating else FLOOR_CLEARANCE)
    t.add_link(t.world, model.root, base, [])
    t.finish()
    return t.root, t.joints_out, [j.name for j in t.actuated], t.couplings, t.dropped


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
        etree.SubElement(root, "statistic", center=fmt(centre),
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
        assets = Assets(tmp / "assets")
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
        bounds = rest_bounds(model)
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


from .mjcf_check import DriveReport, drive_check  # noqa: E402,F401  (re-exported)
