"""The articulated-object data model (DESIGN §2).

Conventions
-----------
* Metres, REP-103 axes (x forward, y left, z up); base on z = 0, front facing +x.
* Every geometric quantity of a part (bbox, joint origin, joint axis, mesh) is expressed in
  the **object frame at rest** (all joints at their zero value). This is the convention of
  the published token, and it makes a part's token independent of its ancestors' poses.
* A joint's motion is a translation ``t`` along the unit axis followed by a rotation ``r``
  (right hand) about the axis line through ``origin``; for a screw both act. The posed
  transform of a part is ``T_parent @ T_joint(t, r)``, so a joint moves its whole subtree.
* Rest pose = joint value 0. Limits may straddle 0 or not; the openness ratio maps
  ``r in [0, 1]`` to ``lerp(lower, upper, r)`` for every joint.
"""
from __future__ import annotations

import copy
import enum
import math
from dataclasses import dataclass, field
from typing import Iterable, Mapping, Sequence, Union

import numpy as np

from model.core.files import slug

TOKEN_DIM = 16  # [size(3), centre(3), origin(3), axis(3), t_min, t_max, r_min, r_max]

JointValue = Union[float, tuple[float, float]]


class ObjectValidationError(ValueError):
    """An articulated object breaks a structural or numeric rule; the message names it."""


class JointType(enum.IntEnum):
    FIXED = 0
    REVOLUTE = 1
    PRISMATIC = 2
    CONTINUOUS = 3
    SCREW = 4

    @property
    def translates(self) -> bool:
        return self in (JointType.PRISMATIC, JointType.SCREW)

    @property
    def rotates(self) -> bool:
        return self in (JointType.REVOLUTE, JointType.CONTINUOUS, JointType.SCREW)

    @property
    def dof(self) -> int:
        return int(self.translates) + int(self.rotates)

    @classmethod
    def parse(cls, value: Union[str, int, "JointType"]) -> "JointType":
        if isinstance(value, JointType):
            return value
        if isinstance(value, (int, np.integer)):
            try:
                return cls(int(value))
            except ValueError:
                raise ObjectValidationError(
                    f"unknown joint type {int(value)}; expected 0..{len(cls) - 1} "
                    f"({', '.join(t.name.lower() for t in cls)})") from None
        try:
            return cls[str(value).strip().upper()]
        except KeyError:
            raise ObjectValidationError(
                f"unknown joint type {value!r}; expected one of "
                f"{[t.name.lower() for t in cls]}") from None


def _vec3(value, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.shape != (3,):
        raise ObjectValidationError(f"{name} must have 3 components, got shape {arr.shape}")
    return arr


@dataclass
class Joint:
    """Joint of a part to its parent, in the object frame at rest.

    ``lower``/``upper`` of translation in metres, of rotation in radians. Unused ranges are 0.
    """
    type: JointType = JointType.FIXED
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    t_range: tuple[float, float] = (0.0, 0.0)
    r_range: tuple[float, float] = (0.0, 0.0)
    effort: float = 50.0     # N or N·m, written to the URDF <limit>
    velocity: float = 1.0    # m/s or rad/s

    def __post_init__(self) -> None:
        self.type = JointType.parse(self.type)
        self.origin = _vec3(self.origin, "joint origin")
        self.axis = _vec3(self.axis, "joint axis")
        self.t_range = (float(self.t_range[0]), float(self.t_range[1]))
        self.r_range = (float(self.r_range[0]), float(self.r_range[1]))

    # -- values ---------------------------------------------------------------------------
    def value_at(self, ratio: float) -> tuple[float, float]:
        """(translation, rotation) at openness ``ratio`` in [0, 1]."""
        ratio = float(ratio)
        t = self.t_range[0] + ratio * (self.t_range[1] - self.t_range[0]) if self.type.translates else 0.0
        r = self.r_range[0] + ratio * (self.r_range[1] - self.r_range[0]) if self.type.rotates else 0.0
        return t, r

    def split_value(self, value: JointValue) -> tuple[float, float]:
        """Interpret a user joint value as (translation, rotation) for this joint type."""
        if self.type == JointType.SCREW:
            if np.ndim(value) == 0:
                raise ObjectValidationError("a screw joint needs a (translation, rotation) pair")
            t, r = value
            return float(t), float(r)
        if np.ndim(value) != 0:
            raise ObjectValidationError(f"a {self.type.name.lower()} joint takes one value")
        if self.type.translates:
            return float(value), 0.0
        if self.type.rotates:
            return 0.0, float(value)
        return 0.0, 0.0

    def transform(self, t: float = 0.0, r: float = 0.0) -> np.ndarray:
        """4x4 motion of the child in the object frame for translation t and rotation r."""
        T = np.eye(4)
        if self.type == JointType.FIXED:
            return T
        a = self.axis / max(np.linalg.norm(self.axis), 1e-12)
        if self.type.rotates and r != 0.0:
            R = rotation_matrix(a, r)
            T[:3, :3] = R
            T[:3, 3] = self.origin - R @ self.origin
        if self.type.translates and t != 0.0:
            T[:3, 3] += t * a
        return T

    def validate(self, where: str) -> None:
        vals = np.concatenate([self.origin, self.axis, self.t_range, self.r_range,
                               [self.effort, self.velocity]])
        if not np.all(np.isfinite(vals)):
            raise ObjectValidationError(f"{where}: joint has a non-finite number (NaN or inf)")
        if self.type != JointType.FIXED:
            n = float(np.linalg.norm(self.axis))
            if abs(n - 1.0) > 1e-4:
                raise ObjectValidationError(f"{where}: joint axis must be a unit vector (norm {n:.4g})")
        if self.t_range[0] > self.t_range[1]:
            raise ObjectValidationError(f"{where}: translation limits inverted "
                                        f"(lower {self.t_range[0]} > upper {self.t_range[1]})")
        if self.r_range[0] > self.r_range[1]:
            raise ObjectValidationError(f"{where}: rotation limits inverted "
                                        f"(lower {self.r_range[0]} > upper {self.r_range[1]})")
        if self.effort <= 0 or self.velocity <= 0:
            raise ObjectValidationError(f"{where}: joint effort and velocity must be positive")


def rotation_matrix(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues rotation about a unit axis (right hand)."""
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    C = 1.0 - c
    return np.array([
        [c + x * x * C, x * y * C - z * s, x * z * C + y * s],
        [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
        [z * x * C - y * s, z * y * C + x * s, c + z * z * C],
    ])


def rpy_matrix(rpy) -> np.ndarray:
    """URDF roll-pitch-yaw (fixed axes x, y, z) as a 3x3 rotation: Rz(y) Ry(p) Rx(r)."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp = math.cos(r), math.sin(r), math.cos(p), math.sin(p)
    cy, sy = math.cos(y), math.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


@dataclass
class Part:
    """One rigid part (a node of the tree).

    ``mesh`` is a ``trimesh.Trimesh`` in the object frame at rest (or None before geometry
    exists); ``latent`` the geometry code z (np.ndarray) when a shape model produced it;
    ``collision`` optional convex collision pieces (trimesh, object frame at rest; boxes as
    ``trimesh.primitives.Box``) that the exporter uses instead of deriving its own.
    """
    name: str
    label: str
    parent: int                     # index of the parent part; -1 for the root
    bbox_center: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bbox_size: np.ndarray = field(default_factory=lambda: np.ones(3))
    joint: Joint = field(default_factory=Joint)
    mesh: object = None
    latent: np.ndarray | None = None
    collision: list | None = None

    def __post_init__(self) -> None:
        self.bbox_center = _vec3(self.bbox_center, f"part {self.name!r} bbox centre")
        self.bbox_size = _vec3(self.bbox_size, f"part {self.name!r} bbox size")

    def fit_bbox_to_mesh(self) -> None:
        if self.mesh is not None and len(self.mesh.vertices):
            lo, hi = self.mesh.bounds
            self.bbox_center = (lo + hi) / 2.0
            self.bbox_size = hi - lo

    # -- token ----------------------------------------------------------------------------
    def token(self) -> np.ndarray:
        """16-float articulation token (DESIGN §2) — joint type is kept separately."""
        j = self.joint
        return np.concatenate([self.bbox_size, self.bbox_center, j.origin, j.axis,
                               [j.t_range[0], j.t_range[1], j.r_range[0], j.r_range[1]]]
                              ).astype(np.float64)

    @classmethod
    def from_token(cls, token: Sequence[float], joint_type: Union[int, str, JointType], *,
                   name: str, label: str, parent: int, normalise_axis: bool = True) -> "Part":
        tok = np.asarray(token, dtype=np.float64).reshape(-1)
        if tok.shape != (TOKEN_DIM,):
            raise ObjectValidationError(f"token must have {TOKEN_DIM} floats, got {tok.shape}")
        jt = JointType.parse(joint_type)
        axis = tok[9:12].copy()
        if normalise_axis:
            n = np.linalg.norm(axis)
            axis = axis / n if n > 1e-9 else np.array([0.0, 0.0, 1.0])
        t_lo, t_hi, r_lo, r_hi = tok[12:16]
        # The type decides which ranges exist; the other range is zeroed.
        t_range = (min(t_lo, t_hi), max(t_lo, t_hi)) if jt.translates else (0.0, 0.0)
        r_range = (min(r_lo, r_hi), max(r_lo, r_hi)) if jt.rotates else (0.0, 0.0)
        joint = Joint(jt, tok[6:9], axis, t_range, r_range)
        return cls(name=name, label=label, parent=parent, bbox_center=tok[3:6],
                   bbox_size=np.abs(tok[0:3]), joint=joint)


@dataclass
class ArticulatedObject:
    """A tree of parts. ``parts[0]`` is not required to be the root; ``root`` finds it."""
    parts: list[Part]
    category: str = ""
    name: str = "object"
    metadata: dict = field(default_factory=dict)

    # -- structure ------------------------------------------------------------------------
    @property
    def root(self) -> int:
        roots = [i for i, p in enumerate(self.parts) if p.parent < 0]
        if len(roots) != 1:
            raise ObjectValidationError(f"object must have exactly one root part, found {len(roots)}")
        return roots[0]

    def children(self, index: int) -> list[int]:
        return [i for i, p in enumerate(self.parts) if p.parent == index]

    def topological_order(self) -> list[int]:
        """Indices with every parent before its children (breadth first from the root)."""
        order, queue = [], [self.root]
        while queue:
            i = queue.pop(0)
            order.append(i)
            queue.extend(self.children(i))
        return order

    def depth(self, index: int) -> int:
        d = 0
        while self.parts[index].parent >= 0:
            index = self.parts[index].parent
            d += 1
            if d > len(self.parts):  # a cycle would otherwise loop forever
                raise ObjectValidationError(
                    f"cycle in the part tree through {self.parts[index].name!r}")
        return d

    def index_of(self, name: str) -> int:
        for i, p in enumerate(self.parts):
            if p.name == name:
                return i
        raise KeyError(f"no part named {name!r}")

    def subtree(self, index: int) -> list[int]:
        """``index`` and every part below it (the parts a joint moves)."""
        out, todo = [], [index]
        while todo:
            i = todo.pop()
            out.append(i)
            todo.extend(self.children(i))
        return out

    def movable_parts(self) -> list[int]:
        return [i for i, p in enumerate(self.parts) if p.joint.type != JointType.FIXED]

    def validate(self) -> "ArticulatedObject":
        """Raise ObjectValidationError naming the first problem; return self if sound."""
        if not self.parts:
            raise ObjectValidationError("object has no parts")
        n = len(self.parts)
        names = [p.name for p in self.parts]
        dup = {x for x in names if names.count(x) > 1}
        if dup:
            raise ObjectValidationError(f"duplicate part names: {sorted(dup)}")
        for i, p in enumerate(self.parts):
            if not p.name or not all(c.isalnum() or c in "_-" for c in p.name):
                raise ObjectValidationError(
                    f"part name {p.name!r} must be non-empty and use only letters, digits, _ or -")
            if p.parent >= n:
                raise ObjectValidationError(f"part {p.name!r}: parent index {p.parent} does not exist")
            if p.parent == i:
                raise ObjectValidationError(f"part {p.name!r} is its own parent (cycle)")
        # Cycles first: a tree whose every part has a parent is a cycle, and saying so is
        # clearer than "found 0 roots".
        for i in range(n):  # every chain must reach the root without revisiting
            seen, j = set(), i
            while self.parts[j].parent >= 0:
                if j in seen:
                    raise ObjectValidationError(
                        f"cycle in the part tree through {self.parts[j].name!r}")
                seen.add(j)
                j = self.parts[j].parent
        root = self.root
        if self.parts[root].joint.type != JointType.FIXED:
            raise ObjectValidationError(f"root part {self.parts[root].name!r} must have a fixed joint")
        for p in self.parts:
            where = f"part {p.name!r}"
            p.joint.validate(where)
            if not (np.all(np.isfinite(p.bbox_center)) and np.all(np.isfinite(p.bbox_size))):
                raise ObjectValidationError(f"{where}: bbox has a non-finite number (NaN or inf)")
            if np.any(p.bbox_size < 0):
                raise ObjectValidationError(f"{where}: bbox size must be non-negative")
            if p.mesh is not None and not np.all(np.isfinite(np.asarray(p.mesh.vertices))):
                raise ObjectValidationError(f"{where}: mesh has non-finite vertices")
        return self

    # -- kinematics -----------------------------------------------------------------------
    def joint_values_at(self, ratio: Union[float, Mapping[str, float]]) -> dict[str, tuple[float, float]]:
        """(t, r) per part name at an openness ratio (one for all joints, or per part)."""
        out = {}
        for p in self.parts:
            rr = ratio.get(p.name, 0.0) if isinstance(ratio, Mapping) else ratio
            out[p.name] = p.joint.value_at(rr)
        return out

    def link_transforms(self, values: Mapping[str, JointValue] | None = None, *,
                        ratio: Union[float, Mapping[str, float], None] = None) -> dict[str, np.ndarray]:
        """4x4 posed transform of every part (object frame at rest → posed object frame).

        Give explicit ``values`` (part name → joint value; a screw takes (t, r)); parts not
        named stay at 0. Or give ``ratio`` for openness. A joint moves its whole subtree.
        """
        if values is not None and ratio is not None:
            raise ValueError("give joint values or an openness ratio, not both")
        if ratio is not None:
            tr = self.joint_values_at(ratio)
        else:
            values = values or {}
            unknown = set(values) - {p.name for p in self.parts}
            if unknown:
                raise KeyError(f"joint values for unknown parts: {sorted(unknown)}")
            tr = {p.name: p.joint.split_value(values[p.name]) if p.name in values else (0.0, 0.0)
                  for p in self.parts}
        T: dict[str, np.ndarray] = {}
        for i in self.topological_order():
            p = self.parts[i]
            local = p.joint.transform(*tr[p.name])
            T[p.name] = local if p.parent < 0 else T[self.parts[p.parent].name] @ local
        return T

    def posed_meshes(self, values: Mapping[str, JointValue] | None = None, *,
                     ratio: Union[float, Mapping[str, float], None] = None) -> dict[str, object]:
        """Copies of the part meshes moved to the given pose (parts without mesh skipped)."""
        T = self.link_transforms(values, ratio=ratio)
        out = {}
        for p in self.parts:
            if p.mesh is not None:
                m = p.mesh.copy()
                m.apply_transform(T[p.name])
                out[p.name] = m
        return out

    # -- tokens ---------------------------------------------------------------------------
    def tokens(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
        """(tokens (N,16), joint types (N,), parents (N,), labels) in topological order."""
        order = self.topological_order()
        remap = {old: new for new, old in enumerate(order)}
        toks = np.stack([self.parts[i].token() for i in order])
        types = np.array([int(self.parts[i].joint.type) for i in order], dtype=np.int64)
        parents = np.array([remap[self.parts[i].parent] if self.parts[i].parent >= 0 else -1
                            for i in order], dtype=np.int64)
        return toks, types, parents, [self.parts[i].label for i in order]

    @classmethod
    def from_tokens(cls, tokens: np.ndarray, joint_types: Iterable, parents: Iterable,
                    labels: Sequence[str], *, category: str = "", name: str = "object") -> "ArticulatedObject":
        parts = []
        counts: dict[str, int] = {}
        for tok, jt, par, lab in zip(np.asarray(tokens), joint_types, parents, labels):
            k = counts.get(lab, 0)
            counts[lab] = k + 1
            parts.append(Part.from_token(tok, jt, name=f"{slug(lab, default='part', lower=True)}_{k}", label=lab, parent=int(par)))
        return cls(parts=parts, category=category, name=name)

    def copy(self) -> "ArticulatedObject":
        return copy.deepcopy(self)

    def summary(self) -> dict:
        """Structured summary: category, count per part label, joint types per label."""
        counts: dict[str, int] = {}
        joints: dict[str, list[str]] = {}
        for p in self.parts:
            counts[p.label] = counts.get(p.label, 0) + 1
            joints.setdefault(p.label, []).append(p.joint.type.name.lower())
        return {"category": self.category, "counts": counts,
                "joint_types": {k: sorted(set(v)) for k, v in joints.items()},
                "num_parts": len(self.parts), "num_movable": len(self.movable_parts())}
