"""A URDF folder read into plain data for the format converters (MJCF, USD, ROS package).

    model = read_urdf_folder("out/cabinet")      # the folder of `artformer export` / generate
    model.root, model.links["drawer"].collisions, model.joints[0].lower

Links keep their visuals, collision pieces and inertial exactly as the URDF states them
(origins as 4x4 matrices in the link frame, mesh files resolved to absolute paths); joints
keep type, parent, child, origin, axis and limits. The converters write from this, so a
converted model has the same links, joint names and limits as the URDF, screw helpers
included.
"""
from __future__ import annotations

import json
import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

log = logging.getLogger(__name__)

MOVING_TYPES = ("revolute", "prismatic", "continuous")


class ConvertError(ValueError):
    """A folder or URDF cannot be converted; the message says what and where."""


@dataclass
class Geom:
    kind: str                              # mesh | box | cylinder | sphere
    origin: np.ndarray                     # 4x4 in the link frame
    name: str = ""
    mesh: Optional[Path] = None            # absolute mesh file (kind == "mesh")
    scale: np.ndarray = field(default_factory=lambda: np.ones(3))
    size: np.ndarray = field(default_factory=lambda: np.zeros(3))  # box extents | (r, length) | (r,)
    rgba: Optional[tuple] = None           # visuals: material colour
    material: str = ""


@dataclass
class Link:
    name: str
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.eye(4))   # inertial origin, link frame
    inertia: Optional[np.ndarray] = None   # 3x3 about the COM, in the inertial origin frame
    visuals: list[Geom] = field(default_factory=list)
    collisions: list[Geom] = field(default_factory=list)

    def inertia_in_link_frame(self) -> np.ndarray:
        """Inertia tensor about the COM expressed in link-frame axes."""
        R = self.com[:3, :3]
        I = self.inertia if self.inertia is not None else np.zeros((3, 3))
        return R @ I @ R.T


@dataclass
class Joint:
    name: str
    type: str                               # fixed | revolute | prismatic | continuous
    parent: str
    child: str
    origin: np.ndarray                      # 4x4, parent link frame -> child link frame
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    lower: float = 0.0
    upper: float = 0.0
    effort: float = 0.0
    velocity: float = 0.0

    @property
    def moving(self) -> bool:
        return self.type in MOVING_TYPES


@dataclass
class URDFModel:
    name: str
    path: Path                              # the URDF file
    links: dict[str, Link]                  # in URDF order
    joints: list[Joint]
    root: str
    materials: dict[str, tuple] = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)   # metadata.json beside the URDF, if any

    def child_joints(self, link: str) -> list[Joint]:
        return [j for j in self.joints if j.parent == link]

    def moving_joints(self) -> list[Joint]:
        return [j for j in self.joints if j.moving]

    def mesh_files(self) -> list[Path]:
        """Every distinct mesh file the URDF references, in order of first use."""
        seen: dict[Path, None] = {}
        for link in self.links.values():
            for g in [*link.visuals, *link.collisions]:
                if g.kind == "mesh":
                    seen.setdefault(g.mesh, None)
        return list(seen)

    def rest_link_frames(self) -> dict[str, np.ndarray]:
        """Link name -> 4x4 pose in the root link frame with every joint at 0."""
        out = {self.root: np.eye(4)}
        stack = [self.root]
        while stack:
            parent = stack.pop()
            for j in self.child_joints(parent):
                out[j.child] = out[parent] @ j.origin
                stack.append(j.child)
        return out


def find_urdf(folder: os.PathLike) -> Path:
    """The URDF of an exported object folder (or the file itself when given a .urdf)."""
    p = Path(folder).expanduser()
    if p.is_file():
        if p.suffix.lower() != ".urdf":
            raise ConvertError(f"{p} is not a .urdf file nor an object folder")
        return p.resolve()
    if not p.is_dir():
        raise ConvertError(f"{p} does not exist; give an object folder written by "
                           f"`artformer export` or `artformer generate`")
    meta = p / "metadata.json"
    if meta.exists():
        try:
            name = json.loads(meta.read_text()).get("urdf")
        except (json.JSONDecodeError, AttributeError):
            name = None
        if name and (p / name).is_file():
            return (p / name).resolve()
    found = sorted(p.glob("*.urdf"))
    if len(found) != 1:
        raise ConvertError(f"{p} holds {len(found)} .urdf files; expected exactly one "
                           f"(or a metadata.json naming it)")
    return found[0].resolve()


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


def _floats(text, n, default, where) -> np.ndarray:
    if text is None:
        return np.asarray(default, dtype=np.float64)
    try:
        vals = np.array([float(v) for v in text.split()], dtype=np.float64)
    except ValueError:
        raise ConvertError(f"{where}: not numbers: {text!r}") from None
    if vals.size == 1 and n == 3:
        vals = np.repeat(vals, 3)
    if vals.shape != (n,) or not np.all(np.isfinite(vals)):
        raise ConvertError(f"{where}: expected {n} finite numbers, got {text!r}")
    return vals


def _origin(el, where) -> np.ndarray:
    from model.core.objects import rpy_matrix
    T = np.eye(4)
    if el is None:
        return T
    T[:3, :3] = rpy_matrix(_floats(el.get("rpy"), 3, (0, 0, 0), where + " rpy"))
    T[:3, 3] = _floats(el.get("xyz"), 3, (0, 0, 0), where + " xyz")
    return T


def _material(el, materials: dict, where: str) -> tuple[Optional[tuple], str]:
    mat = el.find("material")
    if mat is None:
        return None, ""
    name = mat.get("name", "")
    col = mat.find("color")
    if col is not None:
        return tuple(_floats(col.get("rgba"), 4, (0.6, 0.6, 0.6, 1), where + " rgba")), name
    return materials.get(name), name


def _geom(el, path: Path, materials: dict, where: str, lenient: bool) -> Optional[Geom]:
    g = el.find("geometry")
    if g is None:
        return None
    origin = _origin(el.find("origin"), where)
    rgba, mat_name = _material(el, materials, where)
    kw = dict(name=el.get("name", ""), rgba=rgba, material=mat_name)
    if g.find("mesh") is not None:
        m = g.find("mesh")
        fname = m.get("filename", "")
        file = resolve_mesh_path(fname, path.parent)
        if not file.is_file():
            if lenient:
                log.warning("%s: %s: mesh %s missing, skipped", path, where, fname)
                return None
            raise ConvertError(f"{path}: {where}: mesh file not found: {fname} (looked for {file})")
        return Geom("mesh", origin, mesh=file.resolve(),
                    scale=_floats(m.get("scale"), 3, (1, 1, 1), where + " scale"), **kw)
    if g.find("box") is not None:
        return Geom("box", origin, size=_floats(g.find("box").get("size"), 3, (0, 0, 0),
                                                where + " box size"), **kw)
    if g.find("cylinder") is not None:
        c = g.find("cylinder")
        size = np.array([float(c.get("radius", 0)), float(c.get("length", 0))])
        return Geom("cylinder", origin, size=size, **kw)
    if g.find("sphere") is not None:
        return Geom("sphere", origin, size=np.array([float(g.find("sphere").get("radius", 0))]),
                    **kw)
    log.warning("%s: %s has no supported geometry; skipped", path, where)
    return None


def _link(el, path: Path, materials: dict, lenient: bool, geometry: bool = True) -> Link:
    name = el.get("name")
    link = Link(name)
    inert = el.find("inertial")
    if inert is not None:
        link.com = _origin(inert.find("origin"), f"link {name} inertial")
        mel = inert.find("mass")
        link.mass = float(mel.get("value", 0.0)) if mel is not None else 0.0
        iel = inert.find("inertia")
        if iel is not None:
            g = {k: float(iel.get(k, 0.0)) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
            link.inertia = np.array([[g["ixx"], g["ixy"], g["ixz"]],
                                     [g["ixy"], g["iyy"], g["iyz"]],
                                     [g["ixz"], g["iyz"], g["izz"]]])
    for role, out in (("visual", link.visuals), ("collision", link.collisions)):
        for k, v in enumerate(el.findall(role) if geometry else ()):
            geom = _geom(v, path, materials, f"link {name} {role} {k}", lenient)
            if geom is not None:
                out.append(geom)
    return link


def _limits(j: Joint, lim, path: Path, lenient: bool) -> None:
    """Range, effort and velocity of ``j`` from its <limit> (continuous joints: the range
    when the URDF gives one, else one turn either way)."""
    if lim is not None:
        j.effort, j.velocity = float(lim.get("effort", 0.0)), float(lim.get("velocity", 0.0))
    if j.type == "continuous":
        lo, hi = (float(lim.get("lower", 0.0)), float(lim.get("upper", 0.0))) \
            if lim is not None else (0.0, 0.0)
        j.lower, j.upper = (lo, hi) if hi > lo else (-math.pi, math.pi)
        return
    if j.type == "fixed":
        return
    if lim is None:
        if lenient:
            return
        raise ConvertError(f"{path}: {j.type} joint {j.name!r} has no <limit>")
    j.lower, j.upper = float(lim.get("lower", 0.0)), float(lim.get("upper", 0.0))
    if not (math.isfinite(j.lower) and math.isfinite(j.upper)):
        raise ConvertError(f"{path}: joint {j.name!r} has a non-finite limit")
    if j.lower > j.upper and lenient:
        j.lower, j.upper = j.upper, j.lower
    elif j.lower > j.upper:
        raise ConvertError(f"{path}: joint {j.name!r} limits inverted "
                           f"(lower {j.lower} > upper {j.upper})")


def _joint(el, path: Path, links: dict, lenient: bool) -> Optional[Joint]:
    name, jtype = el.get("name"), el.get("type")
    if lenient:
        jtype = (jtype or "fixed").lower()
    p_el, c_el = el.find("parent"), el.find("child")
    if p_el is None or c_el is None:
        if lenient:
            log.warning("%s: joint %s without parent/child skipped", path, name)
            return None
        raise ConvertError(f"{path}: joint {name!r} needs <parent> and <child>")
    if jtype not in ("fixed", *MOVING_TYPES) and lenient:
        log.info("%s: %s joint %s read as fixed", path, jtype, name)
        jtype = "fixed"
    if jtype not in ("fixed", *MOVING_TYPES):
        raise ConvertError(f"{path}: joint {name!r} has unsupported joint type {jtype!r}; "
                           f"supported: continuous, fixed, prismatic, revolute")
    parent, child = p_el.get("link"), c_el.get("link")
    for ln in (parent, child):
        if ln not in links:
            raise ConvertError(f"{path}: joint {name!r} names unknown link {ln!r}")
    j = Joint(name, jtype, parent, child, _origin(el.find("origin"), f"joint {name} origin"))
    if jtype != "fixed":
        axis = _floats(el.find("axis").get("xyz") if el.find("axis") is not None else None,
                       3, (1, 0, 0), f"joint {name} axis")
        n = np.linalg.norm(axis)
        if n < 1e-12 and lenient:
            log.info("%s: joint %s has a zero axis; read as fixed", path, name)
            j.type = "fixed"
        elif n < 1e-12:
            raise ConvertError(f"{path}: joint {name!r} has a zero axis")
        else:
            j.axis = axis / n
    _limits(j, el.find("limit"), path, lenient)
    return j


def _parse(path: Path, lenient: bool):
    from lxml import etree
    if not path.is_file():
        raise ConvertError(f"URDF file not found: {path}")
    parser = etree.XMLParser(remove_comments=True, recover=lenient)
    try:
        root = etree.parse(str(path), parser).getroot()
    except (OSError, etree.XMLSyntaxError) as e:
        raise ConvertError(f"malformed URDF XML in {path}: {e}") from None
    if root is None:
        raise ConvertError(f"{path}: empty URDF")
    if root.tag != "robot":
        raise ConvertError(f"{path}: root element is <{root.tag}>, expected <robot>")
    return root


def read_urdf(path: os.PathLike, *, lenient: bool = False, geometry: bool = True) -> URDFModel:
    """Parse a URDF file; raises ConvertError naming what is wrong. ``geometry=False``
    reads the tree, joints and inertials only (visuals and collisions are not read, so mesh
    files need not exist).

    ``lenient`` (datasets such as PartNet-Mobility): broken XML is recovered where possible,
    a missing mesh file or a joint without parent / child is skipped with a warning, joint
    types are read case-insensitively, an unsupported type (floating, planar) or a zero axis
    is read as fixed, inverted limits are swapped and a revolute / prismatic joint without
    <limit> gets the range (0, 0)."""
    path = Path(path)
    root = _parse(path, lenient)
    materials = {}
    for m in root.findall("material"):
        col = m.find("color")
        if col is not None and m.get("name"):
            materials[m.get("name")] = tuple(_floats(col.get("rgba"), 4, (0.6, 0.6, 0.6, 1),
                                                     f"material {m.get('name')}"))
    links: dict[str, Link] = {}
    for el in root.findall("link"):
        name = el.get("name")
        if not name or name in links:
            raise ConvertError(f"{path}: a link has no name or a duplicate link name ({name!r})")
        links[name] = _link(el, path, materials, lenient, geometry)
    if not links:
        raise ConvertError(f"{path}: the URDF has no links")
    joints, parent_joint = [], {}
    for el in root.findall("joint"):
        j = _joint(el, path, links, lenient)
        if j is None:
            continue
        if j.child in parent_joint:
            raise ConvertError(f"{path}: link {j.child!r} has two parent joints "
                               f"({parent_joint[j.child]!r} and {j.name!r})")
        parent_joint[j.child] = j.name
        joints.append(j)
    roots = [n for n in links if n not in parent_joint]
    if len(roots) != 1:
        if not roots:
            raise ConvertError(f"{path}: the joints form a cycle (no root link)")
        raise ConvertError(f"{path}: expected one root link, found {len(roots)}: {roots}")
    model = URDFModel(root.get("name") or path.stem, path, links, joints, roots[0], materials)
    frames = model.rest_link_frames()
    if len(frames) != len(links):
        raise ConvertError(f"{path}: the joints form a cycle through links "
                           f"{sorted(set(links) - set(frames))}")
    meta = path.parent / "metadata.json"
    if meta.exists():
        try:
            model.metadata = json.loads(meta.read_text())
        except json.JSONDecodeError as e:
            log.warning("ignoring unreadable %s: %s", meta, e)
    return model


def read_urdf_folder(folder: os.PathLike) -> URDFModel:
    return read_urdf(find_urdf(folder))


def load_mesh(path: Path, scale=None):
    """A trimesh.Trimesh of a mesh file (GLB scenes concatenated), ``scale`` applied."""
    import trimesh
    try:
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except Exception as e:
        raise ConvertError(f"cannot read mesh file {path}: {e}") from None
    m = trimesh.Trimesh(vertices=np.asarray(loaded.vertices, dtype=np.float64),
                        faces=np.asarray(loaded.faces), process=False)
    if scale is not None and not np.allclose(scale, 1.0):
        m.apply_transform(np.diag([*np.asarray(scale, dtype=np.float64), 1.0]))
    return m


def rpy_from_matrix(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw (R = Rz(y) Ry(p) Rx(r)) of a rotation matrix."""
    p = math.asin(-max(-1.0, min(1.0, R[2, 0])))
    if abs(math.cos(p)) > 1e-9:
        r = math.atan2(R[2, 1], R[2, 2])
        y = math.atan2(R[1, 0], R[0, 0])
    else:                                   # gimbal lock: put everything into yaw
        r = 0.0
        y = math.atan2(-R[0, 1], R[1, 1])
    return r, p, y


def quat_wxyz(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    R = np.asarray(R, dtype=np.float64)
    t = np.trace(R)
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2
        q = [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif R[1, 1] > R[2, 2]:
        s = math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
    else:
        s = math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
    q = np.asarray(q)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q
