"""Pose of a published object at an openness, for RViz without other nodes (no rclpy).

``ObjectPose.from_urdf(path)`` reads an exported URDF (and the ``metadata.json`` beside it)
into the core's ``ArticulatedObject`` (``model.export.import_urdf``); the core's forward
kinematics (``ArticulatedObject.link_transforms`` at an openness ratio) then gives

* ``link_poses(openness)``      URDF link of each part -> 4x4 pose of its link frame in the
                                object frame (= the root link's frame), every joint at
                                ``lerp(lower, upper, openness)``
* ``joint_positions(openness)`` (names, positions) of every movable URDF joint — a screw is
                                its ``<part>_slide`` (metres) and ``<part>_joint`` (radians)

so markers drawn at ``link_poses`` and a robot_state_publisher fed ``joint_positions`` show
the same pose. ``sweep(elapsed, period)`` is the back-and-forth openness of the ``animate``
parameter.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Optional

import numpy as np

MOVABLE = ("revolute", "prismatic", "continuous")


def origin_matrix(xyz: list[float], rpy: list[float]) -> np.ndarray:
    """4x4 of a URDF ``<origin>``: fixed-axis roll, pitch, yaw (R = Rz Ry Rx), then xyz."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    T = np.eye(4)
    T[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                 [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                 [-sp, cp * sr, cp * cr]]
    T[:3, 3] = xyz
    return T


def _origin_of(el) -> np.ndarray:
    o = el.find("origin")
    if o is None:
        return np.eye(4)
    xyz = [float(v) for v in (o.get("xyz") or "0 0 0").split()]
    rpy = [float(v) for v in (o.get("rpy") or "0 0 0").split()]
    if len(xyz) != 3 or len(rpy) != 3:
        raise ValueError(f"<origin> needs 3 numbers in xyz and rpy, got {dict(o.attrib)}")
    return origin_matrix(xyz, rpy)


def sweep(elapsed: float, period: float) -> float:
    """Openness of a back-and-forth sweep: 0 -> 1 in the first half of ``period`` s, back to
    0 in the second, repeating (a triangle wave in [0, 1])."""
    if period <= 0:
        raise ValueError(f"period must be positive, got {period}")
    phase = (elapsed / period) % 1.0
    return 2.0 * phase if phase < 0.5 else 2.0 - 2.0 * phase


@dataclass
class ObjectPose:
    obj: object                            # model.core.objects.ArticulatedObject
    root_link: str
    part_link: dict[str, str]              # part name -> URDF link holding its geometry
    rest_frames: dict[str, np.ndarray]     # URDF link -> 4x4 at rest, in the object frame
    joints: list[tuple[str, str, int]]     # (URDF joint, part name, 0: translation | 1: rotation)

    @classmethod
    def from_urdf(cls, urdf_path: str | os.PathLike, urdf_xml: Optional[str] = None
                  ) -> "ObjectPose":
        """Read an exported URDF (meshes are not loaded). Raises ValueError with the reason
        when it cannot be posed (e.g. a part whose link is not named like the part)."""
        from lxml import etree

        from model.export.importer import import_urdf   # lazy: numpy + lxml only

        if urdf_xml is None:
            with open(urdf_path, encoding="utf-8") as f:
                urdf_xml = f.read()
        root = etree.fromstring(urdf_xml.encode("utf-8"))
        obj = import_urdf(urdf_path, load_meshes=False)
        links = [el.get("name") for el in root.findall("link")]
        joint_els = root.findall("joint")
        parent_of = {j.find("child").get("link"): j for j in joint_els}
        roots = [ln for ln in links if ln not in parent_of]
        if len(roots) != 1:
            raise ValueError(f"expected one root link, found {roots}")
        # rest frames: chain the joint origins from the root (joints may come in any order)
        rest = {roots[0]: np.eye(4)}
        pending = list(joint_els)
        while pending:
            left = [j for j in pending if j.find("parent").get("link") not in rest]
            if len(left) == len(pending):
                raise ValueError("the URDF joints do not form a tree from the root link")
            for j in pending:
                parent = j.find("parent").get("link")
                if parent in rest:
                    rest[j.find("child").get("link")] = rest[parent] @ _origin_of(j)
            pending = left
        part_link = {}
        for p in obj.parts:
            if p.name not in rest:
                raise ValueError(f"part {p.name!r} has no URDF link of that name")
            part_link[p.name] = p.name
        joints = []
        for j in joint_els:
            kind = j.get("type")
            if kind not in MOVABLE:
                continue
            child = j.find("child").get("link")
            if child not in part_link:
                # a screw's helper link: the part is the child of its (only) joint
                below = [c for c in joint_els if c.find("parent").get("link") == child]
                if len(below) != 1 or below[0].find("child").get("link") not in part_link:
                    raise ValueError(f"joint {j.get('name')!r} moves link {child!r}, which is "
                                     "neither a part nor a screw helper")
                child = below[0].find("child").get("link")
            joints.append((j.get("name"), child, 0 if kind == "prismatic" else 1))
        return cls(obj, roots[0], part_link, rest, joints)

    def link_poses(self, openness: float) -> dict[str, np.ndarray]:
        """URDF link of every part -> 4x4 posed link frame in the object frame (a screw's
        helper link carries no geometry and is left out)."""
        T = self.obj.link_transforms(ratio=float(openness))   # part -> posed motion (4x4)
        return {link: T[part] @ self.rest_frames[link] for part, link in self.part_link.items()}

    def joint_positions(self, openness: float) -> tuple[list[str], list[float]]:
        """Names and positions of every movable URDF joint (document order)."""
        values = self.obj.joint_values_at(float(openness))    # part -> (t, r)
        names = [name for name, _, _ in self.joints]
        positions = [float(values[part][axis]) for _, part, axis in self.joints]
        return names, positions
