"""Writing an ArticulatedObject as a PartNet-Mobility folder (the format is described in
model.data.partnet, which reads it back)."""
from __future__ import annotations

import logging
import math
import os
from pathlib import Path
from typing import Optional

import numpy as np

from model.core.files import jsonable
from model.core.objects import ArticulatedObject, JointType, Part
from model.data.format import atomic_write_bytes, atomic_write_json

log = logging.getLogger(__name__)

_JOINT_WORD = {JointType.FIXED: "static", JointType.REVOLUTE: "hinge", JointType.CONTINUOUS: "hinge",
               JointType.PRISMATIC: "slider", JointType.SCREW: "slider"}



def _translation(xyz) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = xyz
    return T


# =============================================================================================
# writer
# =============================================================================================
def write_partnet(obj: ArticulatedObject, folder: os.PathLike, *,
                  descriptions: Optional[dict] = None, extra_meta: Optional[dict] = None) -> Path:
    """Write ``obj`` as a PartNet-Mobility folder (z-up, marked in meta.json). Returns the folder."""
    import yourdfpy
    from lxml import etree

    obj.validate()
    folder = Path(folder)
    (folder / "textured_objs").mkdir(parents=True, exist_ok=True)
    n = len(obj.parts)
    link = {i: f"link_{i}" for i in range(n)}
    links = [yourdfpy.Link(name="base")]
    joints = []
    v2 = []
    sem_lines = []
    for i, p in enumerate(obj.parts):
        o = p.joint.origin if p.joint.type != JointType.FIXED else np.zeros(3)
        # Fixed joints keep their link frame at their parent's frame: origin = frame position.
        frame = _frame_pos(obj, i)
        frame_par = _frame_pos(obj, p.parent) if p.parent >= 0 else np.zeros(3)
        visuals, collisions = [], []
        if p.mesh is not None and len(p.mesh.faces):
            fname = f"textured_objs/original-{i}.obj"
            atomic_write_bytes(folder / fname, obj_bytes(p.mesh))
            geo = yourdfpy.Geometry(mesh=yourdfpy.Mesh(filename=fname))
            visuals.append(yourdfpy.Visual(name=f"{p.label}-{i}", origin=_translation(-frame), geometry=geo))
            collisions.append(yourdfpy.Collision(name=f"{p.label}-{i}", origin=_translation(-frame), geometry=geo))
        parent_link = "base" if p.parent < 0 else link[p.parent]
        jt = p.joint.type
        lim = None
        axis = np.asarray(p.joint.axis, dtype=np.float64)
        origin = _translation(frame - frame_par)
        if jt == JointType.SCREW:
            helper = f"{link[i]}_helper"
            links.append(yourdfpy.Link(name=helper))
            joints.append(yourdfpy.Joint(name=f"joint_{i}_slide", type="prismatic", parent=parent_link,
                                         child=helper, origin=origin, axis=axis,
                                         limit=yourdfpy.Limit(effort=p.joint.effort, velocity=p.joint.velocity,
                                                              lower=p.joint.t_range[0], upper=p.joint.t_range[1])))
            joints.append(yourdfpy.Joint(name=f"joint_{i}", type="revolute", parent=helper, child=link[i],
                                         origin=np.eye(4), axis=axis,
                                         limit=yourdfpy.Limit(effort=p.joint.effort, velocity=p.joint.velocity,
                                                              lower=p.joint.r_range[0], upper=p.joint.r_range[1])))
        else:
            urdf_type = {JointType.FIXED: "fixed", JointType.REVOLUTE: "revolute",
                         JointType.PRISMATIC: "prismatic", JointType.CONTINUOUS: "continuous"}[jt]
            if jt in (JointType.REVOLUTE, JointType.PRISMATIC):
                lo, hi = p.joint.r_range if jt == JointType.REVOLUTE else p.joint.t_range
                lim = yourdfpy.Limit(effort=p.joint.effort, velocity=p.joint.velocity, lower=lo, upper=hi)
            elif jt == JointType.CONTINUOUS:
                lim = yourdfpy.Limit(effort=p.joint.effort, velocity=p.joint.velocity)
            joints.append(yourdfpy.Joint(name=f"joint_{i}", type=urdf_type, parent=parent_link, child=link[i],
                                         origin=origin, axis=axis if jt != JointType.FIXED else None, limit=lim))
        links.append(yourdfpy.Link(name=link[i], visuals=visuals, collisions=collisions))
        v2.append(_v2_entry(i, p, o))
        sem_lines.append(f"{link[i]} {_JOINT_WORD[jt]} {p.label}")
    robot = yourdfpy.Robot(name=obj.name, links=links, joints=joints)
    # Mesh paths stay relative to the folder (as in the dataset); yourdfpy would warn that it
    # cannot resolve them from the working directory, which is expected here.
    ylog = logging.getLogger("yourdfpy")
    level = ylog.level
    ylog.setLevel(logging.ERROR)
    try:
        urdf = yourdfpy.URDF(robot=robot, build_scene_graph=False, load_meshes=False,
                             filename_handler=yourdfpy.filename_handler_null)
    finally:
        ylog.setLevel(level)
    xml = etree.tostring(urdf.write_xml(), encoding="unicode", pretty_print=True)
    atomic_write_bytes(folder / "mobility.urdf", xml.encode())
    atomic_write_json(folder / "mobility_v2.json", v2)
    atomic_write_bytes(folder / "semantics.txt", ("\n".join(sem_lines) + "\n").encode())
    meta = {"model_cat": obj.category, "up_axis": "z", "front_axis": "+x", "units": "m",
            "source": "artformer_ros procedural generator", "name": obj.name,
            "part_names": {link[i]: p.name for i, p in enumerate(obj.parts)},
            "metadata": jsonable(obj.metadata)}
    meta.update(extra_meta or {})
    atomic_write_json(folder / "meta.json", meta)
    if descriptions is not None:
        atomic_write_json(folder / "descriptions.json", {"descriptions": descriptions, "summary": obj.summary()})
    return folder


def _frame_pos(obj: ArticulatedObject, i: int) -> np.ndarray:
    """Link frame position (object frame at rest): the joint origin of the nearest moving
    joint on the way to the root, or 0."""
    while i >= 0:
        p = obj.parts[i]
        if p.joint.type != JointType.FIXED:
            return np.asarray(p.joint.origin, dtype=np.float64)
        i = p.parent
    return np.zeros(3)


def _v2_entry(i: int, p: Part, origin: np.ndarray) -> dict:
    j = p.joint
    jt = j.type
    entry = {"id": i, "parent": p.parent, "joint": _JOINT_WORD[jt], "name": p.label,
             "parts": [{"id": i, "name": p.label, "children": []}], "jointData": {}}
    if jt != JointType.FIXED:
        limit: dict = {"a": 0.0, "b": 0.0, "noLimit": jt == JointType.CONTINUOUS}
        if jt in (JointType.REVOLUTE, JointType.CONTINUOUS):
            limit["a"], limit["b"] = math.degrees(j.r_range[0]), math.degrees(j.r_range[1])
        else:
            limit["a"], limit["b"] = j.t_range
            limit["rotates"] = jt == JointType.SCREW
            if jt == JointType.SCREW:
                limit["rotates_limit"] = {"a": math.degrees(j.r_range[0]), "b": math.degrees(j.r_range[1]),
                                          "noLimit": False}
        entry["jointData"] = {"axis": {"origin": [float(x) for x in origin],
                                       "direction": [float(x) for x in j.axis]}, "limit": limit}
    return entry


def obj_bytes(mesh) -> bytes:
    """Wavefront OBJ text of a mesh (vertices and 1-based faces)."""
    V = np.asarray(mesh.vertices)
    F = np.asarray(mesh.faces) + 1
    lines = ["# artformer_ros part mesh (metres, object frame at rest)"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in V]
    lines += [f"f {a} {b} {c}" for a, b, c in F]
    return ("\n".join(lines) + "\n").encode()



