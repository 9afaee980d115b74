"""PartNet-Mobility folder format and its loader, for ours and for the real dataset (the
writer of our procedural folders is model.data.partnet_writer) — DESIGN §3.1, §3.2.

A PartNet-Mobility object folder::

    mobility.urdf          links link_<k> with one <visual> per OBJ piece, joints joint_<k>
    mobility_v2.json       [{"id": k, "parent": p, "joint": "hinge|slider|static|free|heavy|junk",
                             "name": "<semantic>", "jointData": {"axis": {...}, "limit": {...}}}]
    semantics.txt          "link_<k> <joint word> <semantic>" per line
    meta.json              {"model_cat": "<Category>", ...}
    textured_objs/*.obj    the part pieces
    descriptions.json      (ours) {"descriptions": {length: [texts]}, "summary": {...}}

Up axis: the real dataset is y-up (its URDF puts a fixed joint from the empty ``base`` link
with rpy = (π/2, 0, -π/2) in front of the tree). Our writer marks its own folders with
``meta.json: {"up_axis": "z", "front_axis": "+x"}``. The loader reads ``up_axis`` from
meta.json; when it is absent the folder is treated as real (y-up) data: the transforms of the
joints leaving the empty root link are dropped and :data:`Y_UP_TO_Z_UP` (the same rotation as
the dataset's standard root joint: OBJ +y → +z, OBJ +x → -y, OBJ -z → +x) is applied, then
the object is put on z = 0 and centred on the z axis. Real objects keep their (unit-less,
roughly unit-sized) scale.

Joints: URDF revolute → revolute; continuous → continuous (range 0..2π); prismatic →
prismatic; fixed / floating / planar (the dataset's "free", "heavy", "junk") → fixed, logged;
a slider with ``"rotates": true`` in mobility_v2.json → screw; and the export convention of a
screw (prismatic joint → link without visuals → revolute/continuous joint on the same axis
line) is folded back into one screw joint.
"""
from __future__ import annotations

import json
import logging
import math
import os
from pathlib import Path
from typing import Iterator, Optional

import numpy as np

from model.core.objects import ArticulatedObject, Joint, JointType, Part
from model.data import vocab
from model.data.partnet_writer import write_partnet  # noqa: F401  (re-exported)

log = logging.getLogger(__name__)

# Rz(-90°) @ Rx(90°): the rotation of PartNet-Mobility's standard base joint.
Y_UP_TO_Z_UP = np.array([[0.0, 0.0, -1.0],
                         [-1.0, 0.0, 0.0],
                         [0.0, 1.0, 0.0]])


# =============================================================================================
# loader
# =============================================================================================
class PartNetFormatError(ValueError):
    """The folder is not a readable PartNet-Mobility object; the message says what is missing."""


def _read_urdf(path: Path) -> tuple[dict, list[dict]]:
    """Link name -> [(visual origin, mesh file)] and the joints as dicts, from the lenient
    URDF parser (model.export.urdfmodel.read_urdf)."""
    from model.export.urdfmodel import ConvertError, read_urdf
    try:
        model = read_urdf(path, lenient=True)
    except ConvertError as e:
        raise PartNetFormatError(str(e)) from None
    links = {name: [(g.origin if np.allclose(g.scale, 1.0) else g.origin @ np.diag([*g.scale, 1.0]),
                     str(g.mesh)) for g in link.visuals if g.kind == "mesh"]
             for name, link in model.links.items()}
    joints = [{"name": j.name, "type": j.type, "parent": j.parent, "child": j.child,
               "origin": j.origin, "axis": j.axis, "lower": j.lower, "upper": j.upper}
              for j in model.joints]
    return links, joints


def _load_pieces(folder: Path, files: list[tuple[np.ndarray, str]]):
    """Load and transform every OBJ piece of a link; concatenate. None if nothing loads."""
    import trimesh
    pieces = []
    for T, fname in files:
        fname = fname.replace("package://", "")
        path = (folder / fname) if not os.path.isabs(fname) else Path(fname)
        if not path.exists():
            log.warning("%s: mesh %s missing, skipped", folder, fname)
            continue
        try:
            m = trimesh.load(str(path), force="mesh", process=False, skip_materials=True)
        except Exception as e:  # a broken piece must not sink the object
            log.warning("%s: cannot read %s (%s), skipped", folder, fname, e)
            continue
        if m is None or len(getattr(m, "faces", [])) == 0:
            continue
        m = trimesh.Trimesh(vertices=np.asarray(m.vertices, dtype=np.float64), faces=np.asarray(m.faces),
                            process=False)
        m.apply_transform(T)
        pieces.append(m)
    if not pieces:
        return None
    merged = trimesh.util.concatenate(pieces) if len(pieces) > 1 else pieces[0]
    merged.merge_vertices()
    return merged


def _read_json(path: Path):
    if not path.exists():
        return None
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        log.warning("%s: unreadable (%s), ignored", path, e)
        return None


def load_partnet(folder: os.PathLike, up_axis: str = "auto") -> ArticulatedObject:
    """Read one PartNet-Mobility object folder into an ArticulatedObject (z-up, object frame).

    up_axis: "auto" (meta.json's ``up_axis``, default "y" as in the real dataset), "y" or "z".
    Descriptions, when present, land in ``obj.metadata["descriptions"]``.
    """
    folder = Path(folder)
    urdf_path = folder / "mobility.urdf"
    if not urdf_path.exists():
        raise PartNetFormatError(f"{folder}: no mobility.urdf")
    meta = _read_json(folder / "meta.json") or {}
    if up_axis == "auto":
        up_axis = str(meta.get("up_axis", "y")).lower()
    if up_axis not in ("y", "z"):
        raise PartNetFormatError(f"{folder}: up_axis must be y or z, got {up_axis!r}")
    links, joints = _read_urdf(urdf_path)
    tree = _Tree(folder, links, joints, up_axis)
    labels = _Labels(folder, meta, tree)
    parts: list[Part] = []
    index: dict[str, int] = {}
    for ln in tree.kept():
        mesh = _load_pieces(folder, links[ln])
        if mesh is not None:
            mesh.apply_transform(tree.world[ln])
        label, name = labels.of(ln)
        joint = _joint_of(ln, tree.child_of, tree.helper_of, tree.joint_frame, labels.v2_by_link,
                          folder)
        index[ln] = len(parts)
        parts.append(Part(name=name, label=label, parent=tree.kept_parent(ln, index),
                          joint=joint, mesh=mesh))
    if not parts:
        raise PartNetFormatError(f"{folder}: no parts with geometry")
    _single_root(parts)
    obj = ArticulatedObject(parts=parts, category=str(meta.get("model_cat", meta.get("category", ""))),
                            name=str(meta.get("name", folder.name)))
    if up_axis == "y":
        _place_on_floor(obj)
    for p in parts:
        p.fit_bbox_to_mesh()
    texts = _descriptions(folder)
    if texts is not None:
        obj.metadata["descriptions"] = texts
    obj.metadata["source"] = str(folder)
    obj.metadata["up_axis"] = up_axis
    if isinstance(meta.get("metadata"), dict):
        for k, v in meta["metadata"].items():
            obj.metadata.setdefault(k, v)
    return obj.validate()


class _Tree:
    """The link tree of a PartNet URDF at rest in the z-up object frame: link poses, joint
    frames, screw helpers and the links that become parts."""

    def __init__(self, folder: Path, links: dict, joints: list[dict], up_axis: str):
        self.links = links
        self.child_of = {j["child"]: j for j in joints}
        roots = [ln for ln in links if ln not in self.child_of]
        if len(roots) != 1:
            raise PartNetFormatError(f"{folder}: URDF must have one root link, found {roots}")
        self.root = roots[0]
        self.empty_root = not links[self.root]
        self.children: dict[str, list[dict]] = {}
        for j in joints:
            self.children.setdefault(j["parent"], []).append(j)
        self._poses(folder, up_axis)
        self.helper_of = self._screw_helpers()

    def _poses(self, folder: Path, up_axis: str) -> None:
        C = np.eye(4)
        C[:3, :3] = Y_UP_TO_Z_UP if up_axis == "y" else np.eye(3)
        self.world: dict[str, np.ndarray] = {self.root: C}
        self.joint_frame: dict[str, np.ndarray] = {}
        pending = [self.root]
        while pending:
            ln = pending.pop()
            for j in self.children.get(ln, []):
                origin = j["origin"]
                if up_axis == "y" and ln == self.root and self.empty_root:
                    origin = np.eye(4)   # the dataset's own y-up → z-up turn; C does it instead
                F = self.world[ln] @ origin
                self.joint_frame[j["child"]] = F
                self.world[j["child"]] = F
                if j["child"] in self.world and j["child"] in pending:
                    raise PartNetFormatError(f"{folder}: cycle in URDF at {j['child']}")
                pending.append(j["child"])

    def _screw_helpers(self) -> dict[str, dict]:
        """A link without visuals between a prismatic and a rotating joint on one axis:
        the rotating child -> the prismatic joint."""
        helper_of: dict[str, dict] = {}
        for ln, vis in self.links.items():
            if vis or ln == self.root or ln not in self.child_of:
                continue
            up, downs = self.child_of[ln], self.children.get(ln, [])
            if up["type"] == "prismatic" and len(downs) == 1 \
                    and downs[0]["type"] in ("revolute", "continuous"):
                a1 = self.joint_frame[ln][:3, :3] @ up["axis"]
                a2 = self.joint_frame[downs[0]["child"]][:3, :3] @ downs[0]["axis"]
                if abs(abs(np.dot(a1, a2)) - np.linalg.norm(a1) * np.linalg.norm(a2)) < 1e-6:
                    helper_of[downs[0]["child"]] = up
        return helper_of

    def kept(self) -> list[str]:
        """Links that become parts, depth-first in URDF order: screw helpers fold into their
        child, geometry-less fixed links vanish (their children attach to the nearest kept
        ancestor), geometry-less moving links stay as mesh-less parts."""
        order: list[str] = []
        stack = [self.root]
        while stack:
            ln = stack.pop(0)
            order.append(ln)
            stack = [j["child"] for j in self.children.get(ln, [])] + stack
        helpers = {self.child_of[c]["parent"] for c in self.helper_of}
        return [ln for ln in order
                if (ln != self.root or not self.empty_root) and ln not in helpers
                and (self.links[ln] or ln == self.root
                     or self.child_of[ln]["type"] not in ("fixed", "floating", "planar"))]

    def kept_parent(self, ln: str, index: dict[str, int]) -> int:
        """Index of the nearest ancestor of ``ln`` that is a part (-1: none)."""
        up = self.child_of.get(ln)
        while up is not None:
            if up["parent"] in index:
                return index[up["parent"]]
            up = self.child_of.get(up["parent"])
        return -1


class _Labels:
    """Part labels and names: mobility_v2.json ids ↔ link_<id>, semantics.txt as fallback,
    then the link name; names from meta.json's ``part_names`` or ``<label>_<k>``."""

    def __init__(self, folder: Path, meta: dict, tree: _Tree):
        self.tree = tree
        v2 = _read_json(folder / "mobility_v2.json")
        self.v2_by_link = {f"link_{e['id']}": e for e in v2 if isinstance(e, dict) and "id" in e} \
            if isinstance(v2, list) else {}
        self.sem = {}
        if (folder / "semantics.txt").exists():
            for line in (folder / "semantics.txt").read_text(errors="replace").splitlines():
                bits = line.split()
                if len(bits) >= 3:
                    self.sem[bits[0]] = (bits[1], bits[2])
        self.names = meta.get("part_names", {}) if isinstance(meta.get("part_names"), dict) else {}
        self.count: dict[str, int] = {}

    def of(self, ln: str) -> tuple[str, str]:
        if ln in self.v2_by_link and self.v2_by_link[ln].get("name"):
            label = vocab.map_partnet_label(str(self.v2_by_link[ln]["name"]))
        elif ln in self.sem:
            label = vocab.map_partnet_label(self.sem[ln][1])
        else:
            label = vocab.map_partnet_label(ln)
        t, up = self.tree, self.tree.child_of.get(ln)
        if ln == t.root or (up is not None and up["parent"] == t.root and t.empty_root
                            and up["type"] == "fixed" and label == "other"):
            label = "body" if label == "other" else label
        name = self.names.get(ln)
        if not name:
            k = self.count.get(label, 0)
            self.count[label] = k + 1
            name = f"{label}_{k}"
        return label, name


def _descriptions(folder: Path):
    texts = _read_json(folder / "descriptions.json")
    if isinstance(texts, dict) and "descriptions" in texts:
        return texts["descriptions"]
    for fname in ("descriptions.txt", "description.txt", "text.txt"):
        if (folder / fname).exists():
            lines = [x.strip() for x in (folder / fname).read_text(errors="replace").splitlines()
                     if x.strip()]
            return {"sentence": lines} if lines else None
    return None


def _joint_of(ln, child_of, helper_of, joint_frame, v2_by_link, folder) -> Joint:
    j = child_of.get(ln)
    if j is None:
        return Joint()
    F = joint_frame[ln]
    origin = F[:3, 3].copy()
    t = j["type"]
    axis = F[:3, :3] @ j["axis"]
    n = np.linalg.norm(axis)
    axis = axis / n if n > 1e-9 else np.array([0.0, 0.0, 1.0])
    lo, hi = sorted((j["lower"], j["upper"]))
    if ln in helper_of:
        up = helper_of[ln]
        tlo, thi = sorted((up["lower"], up["upper"]))
        if t == "continuous":
            lo, hi = 0.0, 2 * math.pi
        return Joint(JointType.SCREW, origin, axis, t_range=(tlo, thi), r_range=(lo, hi))
    e = v2_by_link.get(ln, {})
    limit = (e.get("jointData") or {}).get("limit") or {}
    if t == "prismatic" and limit.get("rotates"):
        rl = limit.get("rotates_limit") or {}
        if rl.get("noLimit", True) or "a" not in rl:
            rr = (0.0, 2 * math.pi)
        else:
            rr = tuple(sorted((math.radians(float(rl["a"])), math.radians(float(rl["b"])))))
        return Joint(JointType.SCREW, origin, axis, t_range=(lo, hi), r_range=rr)
    if t == "revolute":
        return Joint(JointType.REVOLUTE, origin, axis, r_range=(lo, hi))
    if t == "continuous":
        return Joint(JointType.CONTINUOUS, origin, axis, r_range=(0.0, 2 * math.pi))
    if t == "prismatic":
        return Joint(JointType.PRISMATIC, origin, axis, t_range=(lo, hi))
    if t != "fixed":
        log.info("%s: %s joint of %s read as fixed", folder, t, ln)
    return Joint()


def _single_root(parts: list[Part]) -> None:
    """Several parts hanging off the (dropped) empty base: keep the largest fixed one as the
    root and attach the others to it (joints are in the object frame, so nothing moves)."""
    roots = [i for i, p in enumerate(parts) if p.parent < 0]
    if len(roots) <= 1:
        if roots and parts[roots[0]].joint.type != JointType.FIXED:
            parts[roots[0]].joint = Joint()
        return

    def size(i):
        m = parts[i].mesh
        return float(np.prod(np.ptp(m.vertices, axis=0) + 1e-9)) if m is not None and len(m.vertices) else 0.0
    fixed = [i for i in roots if parts[i].joint.type == JointType.FIXED] or roots
    main = max(fixed, key=size)
    parts[main].joint = Joint()
    for i in roots:
        if i != main:
            parts[i].parent = main


def _place_on_floor(obj: ArticulatedObject) -> None:
    meshes = [p.mesh for p in obj.parts if p.mesh is not None and len(p.mesh.vertices)]
    if not meshes:
        return
    lo = np.min([m.bounds[0] for m in meshes], axis=0)
    hi = np.max([m.bounds[1] for m in meshes], axis=0)
    shift = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    for p in obj.parts:
        if p.mesh is not None:
            p.mesh.apply_translation(shift)
        if p.joint.type != JointType.FIXED:
            p.joint.origin = p.joint.origin + shift


def find_object_folders(root: os.PathLike) -> list[Path]:
    """Object folders (containing mobility.urdf) under ``root`` (itself or any depth), sorted."""
    root = Path(root)
    if (root / "mobility.urdf").exists():
        return [root]
    return sorted(p.parent for p in root.rglob("mobility.urdf"))


def iter_partnet_dataset(root: os.PathLike, up_axis: str = "auto") -> Iterator[tuple[Path, Optional[ArticulatedObject], Optional[str]]]:
    """(folder, object or None, error or None) for every object folder; never raises per object."""
    for folder in find_object_folders(root):
        try:
            yield folder, load_partnet(folder, up_axis), None
        except Exception as e:  # one broken object must not stop a dataset pass
            log.warning("%s: skipped (%s)", folder, e)
            yield folder, None, f"{type(e).__name__}: {e}"
