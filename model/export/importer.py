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

import json
import logging
import math
import os
from pathlib import Path

import numpy as np

from model.core.objects import (ArticulatedObject, Joint, JointType, ObjectValidationError,
                                Part, rpy_matrix)

log = logging.getLogger(__name__)

_SUPPORTED = {"fixed": JointType.FIXED, "revolute": JointType.REVOLUTE,
              "prismatic": JointType.PRISMATIC, "continuous": JointType.CONTINUOUS}


class URDFImportError(ValueError):
    """A URDF cannot be read into an ArticulatedObject; the message says what and where."""


def resolve_mesh_path(filename: str, urdf_dir: Path) -> Path:
    """Absolute path of a URDF mesh reference (file://, package://, absolute or relative).

    ``package://pkg/rest`` is looked up in the ament index (``AMENT_PREFIX_PATH``
    ``share/pkg/rest``), then beside the URDF (``rest`` and its tail after any folder named
    like the URDF folder, then ``meshes/<file name>``)."""
    from urllib.parse import unquote, urlparse
    urdf_dir = Path(urdf_dir)
    if filename.startswith("file://"):
        return Path(unquote(urlparse(filename).path))
    if filename.startswith("package://"):
        rest = filename[len("package://"):]
        pkg, _, sub = rest.partition("/")
        cands = []
        for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
            if prefix:
                cands.append(Path(prefix) / "share" / pkg / sub)
        cands += [urdf_dir / sub, urdf_dir / "meshes" / Path(sub).name, urdf_dir / Path(sub).name]
        for c in cands:
            if c.exists():
                return c
        return cands[-3] if len(cands) >= 3 else urdf_dir / sub
    p = Path(filename)
    return p if p.is_absolute() else (urdf_dir / p)



def _origin_matrix(el) -> np.ndarray:
    T = np.eye(4)
    if el is None:
        return T
    xyz = [float(v) for v in (el.get("xyz") or "0 0 0").split()]
    rpy = [float(v) for v in (el.get("rpy") or "0 0 0").split()]
    if len(xyz) != 3 or len(rpy) != 3:
        raise URDFImportError(f"origin needs 3 values in xyz and rpy, got {el.attrib}")
    T[:3, :3] = rpy_matrix(rpy)
    T[:3, 3] = xyz
    return T


def _floats(text: str | None, n: int, default, what: str) -> np.ndarray:
    if text is None:
        return np.asarray(default, dtype=np.float64)
    vals = np.array([float(v) for v in text.split()], dtype=np.float64)
    if vals.size == 1 and n == 3:
        vals = np.repeat(vals, 3)
    if vals.shape != (n,):
        raise URDFImportError(f"{what}: expected {n} numbers, got {text!r}")
    return vals


def import_urdf(path: os.PathLike, *, load_meshes: bool = True,
                metadata: dict | None = None) -> ArticulatedObject:
    """Read a URDF into an ArticulatedObject (object frame = root link frame at rest).

    Raises URDFImportError naming the problem: malformed XML, unknown / unsupported joint
    type, a link with two parents or a cycle, a missing mesh file (its path), a joint naming
    an unknown link. ``metadata`` overrides a ``metadata.json`` next to the URDF.
    """
    from lxml import etree
    path = Path(path)
    if not path.exists():
        raise URDFImportError(f"URDF file not found: {path}")
    try:
        root = etree.parse(str(path)).getroot()
    except etree.XMLSyntaxError as e:
        raise URDFImportError(f"malformed URDF XML in {path}: {e}") from None
    if root.tag != "robot":
        raise URDFImportError(f"{path}: root element is <{root.tag}>, expected <robot>")
    if metadata is None:
        mpath = path.parent / "metadata.json"
        if mpath.exists():
            try:
                metadata = json.loads(mpath.read_text())
            except json.JSONDecodeError as e:
                log.warning("ignoring unreadable %s: %s", mpath, e)
    metadata = metadata or {}

    links = {}
    for el in root.findall("link"):
        name = el.get("name")
        if not name:
            raise URDFImportError(f"{path}: a <link> has no name")
        if name in links:
            raise URDFImportError(f"{path}: duplicate link name {name!r}")
        links[name] = el
    joints, parent_of, children = {}, {}, {}
    for el in root.findall("joint"):
        name, jtype = el.get("name"), el.get("type")
        p_el, c_el = el.find("parent"), el.find("child")
        if p_el is None or c_el is None:
            raise URDFImportError(f"{path}: joint {name!r} needs <parent> and <child>")
        parent, child = p_el.get("link"), c_el.get("link")
        for ln in (parent, child):
            if ln not in links:
                raise URDFImportError(f"{path}: joint {name!r} names unknown link {ln!r}")
        if jtype not in _SUPPORTED:
            raise URDFImportError(
                f"{path}: joint {name!r} has unsupported joint type {jtype!r}; supported: "
                f"{sorted(_SUPPORTED)}")
        if child in parent_of:
            raise URDFImportError(f"{path}: link {child!r} has two parent joints "
                                  f"({joints[parent_of[child]]['name']!r} and {name!r})")
        joints[name] = {"name": name, "type": jtype, "parent": parent, "child": child, "el": el}
        parent_of[child] = name
        children.setdefault(parent, []).append(name)
    roots = [ln for ln in links if ln not in parent_of]
    if len(roots) != 1:
        if not roots:
            raise URDFImportError(f"{path}: the joints form a cycle (no root link)")
        raise URDFImportError(f"{path}: expected one root link, found {len(roots)}: {roots}")
    # Cycle check: everything must be reachable from the root.
    reach, stack = [], [roots[0]]
    while stack:
        ln = stack.pop()
        reach.append(ln)
        stack.extend(joints[j]["child"] for j in children.get(ln, []))
    if len(reach) != len(links):
        lost = sorted(set(links) - set(reach))
        raise URDFImportError(f"{path}: the joints form a cycle through links {lost}")

    # Rest-pose link frames in the root frame (BFS order).
    W = {roots[0]: np.eye(4)}
    order = [roots[0]]
    for ln in order:
        for jn in children.get(ln, []):
            j = joints[jn]
            W[j["child"]] = W[ln] @ _origin_matrix(j["el"].find("origin"))
            order.append(j["child"])

    # Merge our screw helpers: prismatic into a link with no geometry, then one revolute with
    # the same axis and zero origin.
    merged_into = {}   # helper link -> (slide joint, revolute joint)
    for ln in order:
        el = links[ln]
        if ln == roots[0] or el.findall("visual") or len(children.get(ln, [])) != 1:
            continue
        js, jr = joints[parent_of[ln]], joints[children[ln][0]]
        if js["type"] != "prismatic" or jr["type"] not in ("revolute", "continuous"):
            continue
        o = _origin_matrix(jr["el"].find("origin"))
        ax_s = _axis(js["el"], path)
        ax_r = _axis(jr["el"], path)
        if np.allclose(o, np.eye(4), atol=1e-9) and np.allclose(ax_s, ax_r, atol=1e-6):
            merged_into[ln] = (js["name"], jr["name"])

    meta_parts = {p.get("link", p.get("name")): p for p in metadata.get("parts", [])}
    part_links = [ln for ln in order if ln not in merged_into]
    index = {ln: k for k, ln in enumerate(part_links)}
    parts = []
    for ln in part_links:
        el = links[ln]
        mesh = _link_mesh(el, W[ln], path) if load_meshes else None
        if ln == roots[0]:
            joint, parent = Joint(JointType.FIXED), -1
        else:
            j = joints[parent_of[ln]]
            parent_link = j["parent"]
            if parent_link in merged_into:      # screw: slide + revolute through a helper
                js = joints[merged_into[parent_link][0]]
                jr = j
                parent_link = js["parent"]
                frame = W[parent_link] @ _origin_matrix(js["el"].find("origin"))
                axis = frame[:3, :3] @ _axis(js["el"], path)
                t_lo, t_hi = _limits(js["el"], "prismatic", path, js["name"])
                r_lo, r_hi = _limits(jr["el"], jr["type"], path, jr["name"])
                joint = Joint(JointType.SCREW, frame[:3, 3], _unit(axis), (t_lo, t_hi),
                              (r_lo, r_hi), *_effort_velocity(jr["el"]))
            else:
                frame = W[parent_link] @ _origin_matrix(j["el"].find("origin"))
                jt = _SUPPORTED[j["type"]]
                axis = frame[:3, :3] @ _axis(j["el"], path) if jt != JointType.FIXED else np.array([0, 0, 1.0])
                lo, hi = _limits(j["el"], j["type"], path, j["name"])
                t_range = (lo, hi) if jt == JointType.PRISMATIC else (0.0, 0.0)
                r_range = (lo, hi) if jt in (JointType.REVOLUTE, JointType.CONTINUOUS) else (0.0, 0.0)
                joint = Joint(jt, frame[:3, 3], _unit(axis), t_range, r_range,
                              *_effort_velocity(j["el"]))
            parent = index[parent_link]
        mp = meta_parts.get(ln, {})
        if joint.type == JointType.CONTINUOUS and "token" in mp:   # URDF has no range for it
            tok = mp["token"]
            joint.r_range = (float(tok[14]), float(tok[15]))
        label = mp.get("label") or _guess_label(ln)
        name = mp.get("name") or _safe_name(ln)
        part = Part(name=name, label=label, parent=parent, joint=joint, mesh=mesh)
        if mesh is not None:
            part.fit_bbox_to_mesh()
        else:
            part.bbox_size = np.zeros(3)
            part.bbox_center = W[ln][:3, 3].copy()
        parts.append(part)
    obj = ArticulatedObject(parts=parts, category=metadata.get("category", ""),
                            name=metadata.get("name") or root.get("name") or path.stem,
                            metadata={"source_urdf": str(path)})
    try:
        return obj.validate()
    except ObjectValidationError as e:
        raise URDFImportError(f"{path}: {e}") from None


def _axis(el, path) -> np.ndarray:
    a = el.find("axis")
    v = _floats(a.get("xyz") if a is not None else None, 3, (1.0, 0.0, 0.0),
                f"{path}: axis of joint {el.get('name')!r}")
    if np.linalg.norm(v) < 1e-12:
        raise URDFImportError(f"{path}: joint {el.get('name')!r} has a zero axis")
    return v / np.linalg.norm(v)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _limits(el, jtype: str, path, name) -> tuple[float, float]:
    if jtype == "fixed":
        return 0.0, 0.0
    lim = el.find("limit")
    if jtype == "continuous":
        if lim is not None and lim.get("lower") is not None and lim.get("upper") is not None:
            lo, hi = float(lim.get("lower")), float(lim.get("upper"))
            if hi > lo:
                return lo, hi
        return -math.pi, math.pi
    if lim is None:
        raise URDFImportError(f"{path}: {jtype} joint {name!r} has no <limit>")
    lo, hi = float(lim.get("lower", 0.0)), float(lim.get("upper", 0.0))
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise URDFImportError(f"{path}: joint {name!r} has a non-finite limit")
    if lo > hi:
        raise URDFImportError(f"{path}: joint {name!r} limits inverted (lower {lo} > upper {hi})")
    return lo, hi


def _effort_velocity(el) -> tuple[float, float]:
    lim = el.find("limit")
    e = float(lim.get("effort", 50.0)) if lim is not None else 50.0
    v = float(lim.get("velocity", 1.0)) if lim is not None else 1.0
    return (e if e > 0 else 50.0), (v if v > 0 else 1.0)


def _link_mesh(el, W: np.ndarray, path: Path):
    """All visual meshes of a link (collision ones if it has no visual) in the root frame."""
    import trimesh
    sources = el.findall("visual") or el.findall("collision")
    pieces = []
    for vis in sources:
        g = vis.find("geometry")
        if g is None:
            continue
        T = W @ _origin_matrix(vis.find("origin"))
        m = _geometry_mesh(g, path)
        if m is None:
            continue
        m.apply_transform(T)
        pieces.append(m)
    if not pieces:
        return None
    return pieces[0] if len(pieces) == 1 else trimesh.util.concatenate(pieces)


def _geometry_mesh(g, path: Path):
    import trimesh
    if g.find("mesh") is not None:
        mel = g.find("mesh")
        fname = mel.get("filename", "")
        file = resolve_mesh_path(fname, path.parent)
        if not file.exists():
            raise URDFImportError(f"{path}: mesh file not found: {fname} (looked for {file})")
        try:
            loaded = trimesh.load(str(file), force="mesh", process=False)
        except Exception as e:
            raise URDFImportError(f"{path}: cannot read mesh file {file}: {e}") from None
        m = trimesh.Trimesh(vertices=np.asarray(loaded.vertices), faces=np.asarray(loaded.faces))
        scale = _floats(mel.get("scale"), 3, (1.0, 1.0, 1.0), f"{path}: mesh scale of {fname}")
        if not np.allclose(scale, 1.0):
            m.apply_transform(np.diag([*scale, 1.0]))   # a mirroring scale also flips winding
        return m
    if g.find("box") is not None:
        size = _floats(g.find("box").get("size"), 3, (0, 0, 0), f"{path}: box size")
        return trimesh.creation.box(extents=size)
    if g.find("cylinder") is not None:
        c = g.find("cylinder")
        return trimesh.creation.cylinder(radius=float(c.get("radius")), height=float(c.get("length")),
                                         sections=48)
    if g.find("sphere") is not None:
        return trimesh.creation.icosphere(subdivisions=3, radius=float(g.find("sphere").get("radius")))
    return None


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
