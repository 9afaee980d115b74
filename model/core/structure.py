"""Explicit structure of a request (docs/structure.md): which part
labels, how many, which joint types and hinge sides; parsed and checked before decoding.
The layer every other one may use (the decoder, the example backend, the pipeline)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional


class GenerationError(RuntimeError):
    """A request could not produce a valid object; the message says why."""


# -- explicit structure (docs/structure.md) ------------------------------
HINGE_SIDES = ("left", "right", "top", "bottom")   # the hinge edge as seen from the front:
                                                   # "left" = the viewer's left (object -y)
AUTO = "auto"


def hinge_side(token) -> Optional[str]:
    """The hinge edge of a revolute part's token (object frame: x front, y left, z up) as
    seen from the front: left / right (vertical axis, origin on the part's -y / +y half),
    top / bottom (horizontal axis, origin above / below the part's centre); None for an axis
    along x (a knob)."""
    import numpy as np
    token = np.asarray(token, dtype=np.float64)
    c, o, a = token[3:6], token[6:9], np.abs(token[9:12])
    if a[2] >= a[1] and a[2] >= a[0]:
        return "left" if o[1] < c[1] else "right"
    if a[1] >= a[0]:
        return "bottom" if o[2] < c[2] else "top"
    return None


@dataclass(frozen=True)
class PartRequest:
    """What a structure asks of one part label: ``count`` parts (None = the model decides,
    "auto"), every one with joint type ``joint`` (None = the model's choice) and, for hinged
    parts, hinge sides ``hinge`` (one per part, None = the model's choice)."""
    count: Optional[int]
    joint: Optional[str] = None
    hinge: Optional[tuple] = None


@dataclass(frozen=True)
class StructureSpec:
    """A parsed ``structure``: the parts an object must have (see :func:`parse_structure`)."""
    parts: dict            # label -> PartRequest (labels the structure names)
    category: Optional[str] = None

    def to_dict(self) -> dict:
        out: dict = {"category": self.category} if self.category else {}
        for lab, r in self.parts.items():
            d = {"count": AUTO if r.count is None else r.count}
            if r.joint:
                d["joint"] = r.joint
            if r.hinge:
                d["hinge"] = list(r.hinge)
            out[lab] = d
        return out


def parse_structure(value) -> StructureSpec:
    """A structure (a dict, or its JSON text) -> StructureSpec; GenerationError says what is
    wrong with it. Only the form is checked here; whether the model can produce it is checked
    by ``ArticulationModel.resolve_structure`` before decoding.

    Form: ``{"category": str (optional), <label>: <part>, ...}`` where ``<part>`` is a count
    (int >= 0), ``"auto"`` (the model decides how many), or an object
    ``{"count": int | "auto" (default 1), "joint": "fixed|revolute|prismatic|continuous|screw",
    "hinge": "left|right|top|bottom" | [one side per part]}``. ``hinge`` implies (and needs)
    a revolute joint.
    """
    import json

    if isinstance(value, StructureSpec):
        return value
    if isinstance(value, (str, bytes)):
        try:
            value = json.loads(value)
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise GenerationError(f"structure is not valid JSON: {e}") from None
    if not isinstance(value, dict):
        raise GenerationError(f"structure must be a JSON object {{label: count, ...}}, got "
                              f"{type(value).__name__}")
    category = value.get("category")
    if category is not None and (not isinstance(category, str) or not category.strip()):
        raise GenerationError("structure 'category' must be a non-empty string")
    parts: dict[str, PartRequest] = {}
    for key, spec in value.items():
        if key == "category":
            continue
        if not isinstance(key, str) or not key.strip():
            raise GenerationError(f"structure label {key!r} must be a non-empty string")
        label = key.strip().lower()
        if label in parts:
            raise GenerationError(f"structure names {label!r} twice")
        parts[label] = _part_request(label, spec)
    if not parts:
        raise GenerationError("structure names no part labels (e.g. {\"drawer\": 3})")
    return StructureSpec(parts=parts, category=category.strip() if category else None)


def _part_request(label: str, spec) -> PartRequest:
    where = f"structure[{label!r}]"
    if not isinstance(spec, dict):
        spec = {"count": spec}
    unknown = sorted(set(spec) - {"count", "joint", "hinge"})
    if unknown:
        raise GenerationError(f"{where}: unknown field(s) {unknown}; allowed: count, joint, hinge")
    count = spec.get("count", 1)
    if count == AUTO:
        count = None
    elif isinstance(count, bool) or not isinstance(count, int):
        raise GenerationError(f"{where}: count must be an integer >= 0 or \"auto\", got {count!r}")
    elif count < 0:
        raise GenerationError(f"{where}: count must be >= 0, got {count}")
    joint = spec.get("joint")
    if joint is not None:
        from model.core import JointType, ObjectValidationError
        try:
            joint = JointType.parse(joint).name.lower() if isinstance(joint, str) else None
        except ObjectValidationError as e:
            raise GenerationError(f"{where}: {e}") from None
        if joint is None:
            raise GenerationError(f"{where}: joint must be a string such as \"revolute\"")
    hinge = spec.get("hinge")
    if hinge is not None:
        sides = [hinge] if isinstance(hinge, str) else hinge
        if not isinstance(sides, list) or not sides or any(not isinstance(s, str) for s in sides):
            raise GenerationError(f"{where}: hinge must be one of {list(HINGE_SIDES)} or a list "
                                  f"of them (one per part)")
        sides = [s.strip().lower() for s in sides]
        bad = [s for s in sides if s not in HINGE_SIDES]
        if bad:
            raise GenerationError(f"{where}: unknown hinge side(s) {bad}; use {list(HINGE_SIDES)} "
                                  f"(left = the viewer's left, facing the object's front)")
        if joint is not None and joint != "revolute":
            raise GenerationError(f"{where}: a hinge needs a revolute joint, not {joint!r}")
        joint = "revolute"
        if count is None:
            raise GenerationError(f"{where}: a hinge needs an exact count, not \"auto\"")
        if count == 0:
            raise GenerationError(f"{where}: count 0 with a hinge side is contradictory")
        if len(sides) == 1:
            sides = sides * count
        if len(sides) != count:
            raise GenerationError(f"{where}: {len(sides)} hinge sides for {count} parts; give one "
                                  f"side, or one per part")
        hinge = tuple(sides)
    if count == 0 and joint is not None:
        raise GenerationError(f"{where}: count 0 with a joint type is contradictory")
    return PartRequest(count=count, joint=joint, hinge=hinge)


SIZE_DIMENSIONS = ("width", "height", "depth", "length")   # of the body, m
SIZE_LIMITS = (0.01, 5.0)                                  # m: sizes an object can take


def parse_size(value) -> dict[str, float]:
    """A size given outright (API, ``--size``, the node's JSON request): ``{"width": 0.6,
    "height": 0.8}`` in metres, or its JSON text -> that dict; GenerationError says what is
    wrong with it (model.refine.size gives it to the body)."""
    import json
    if isinstance(value, str):
        try:
            value = json.loads(value)
        except json.JSONDecodeError as e:
            raise GenerationError(f"size is not valid JSON: {e.msg}") from None
    if not isinstance(value, dict) or not value:
        raise GenerationError('a size is an object such as {"width": 0.6, "height": 0.8} '
                              '(metres)')
    out = {}
    lo, hi = SIZE_LIMITS
    for dim, v in value.items():
        if dim not in SIZE_DIMENSIONS:
            raise GenerationError(f"size: unknown dimension {dim!r} "
                                  f"(one of {list(SIZE_DIMENSIONS)})")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
            raise GenerationError(f"size: {dim} must be a number of metres in [{lo}, {hi}], "
                                  f"got {v!r}")
        out[dim] = float(v)
    return out
