"""Alignment (DESIGN §7): does the generated object have the structure the prompt asks for?

The structure asked for comes from :func:`model.data.prompt_parse.parse_prompt` (category,
exact counts / lower bounds per part kind, acceptable joint types per part kind, spatial facts)
or from the free-form set's hand-written annotation. The structure generated is read from the
object's part labels, joint types and category, and its spatial facts from its boxes and joints
(:func:`model.data.describe.spatial_summary`). A prompt is *aligned* when every count / label /
joint check it asks for passes; prompts that ask for nothing parseable are reported separately
(``checked=False``) and left out of the alignment share.

Spatial facts are scored apart (``spatial_ok``, and per kind in ``spatial``): hinge side,
opening direction, arrangement (row / column / grid, rows, columns, parts per row) and position
(the viewer's left / right, top / bottom, one part kind above another), only over prompts that
state one.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Iterable, Sequence

from model.core import ArticulatedObject, JointType

from model.data.expected_structure import ARRANGEMENT_KEYS, RELATION_KEYS
from model.data.prompt_parse import SPATIAL_KINDS, ExpectedStructure, parse_prompt

SPATIAL_KIND_NAMES = ("hinge", "opening", "arrangement", "position", "size")
SIZE_TOLERANCE = 0.05   # a stated dimension of the body is right within 5 %


@dataclass
class GeneratedStructure:
    category: str | None
    counts: dict[str, int]
    joint_types: dict[str, list[str]]   # label -> joint type name of every part, in order
    spatial: dict[str, dict] = field(default_factory=dict)   # describe.spatial_summary
    body_size: list[float] | None = None   # the root part's box (depth x, width y, height z)

    @classmethod
    def from_object(cls, obj: ArticulatedObject) -> "GeneratedStructure":
        from model.data.describe import spatial_summary
        out = cls.from_labels(obj.category or None, [p.label for p in obj.parts],
                              [p.joint.type for p in obj.parts])
        out.spatial = spatial_summary(obj)
        out.body_size = [float(v) for v in obj.parts[obj.root].bbox_size]
        return out

    @classmethod
    def from_labels(cls, category: str | None, labels: Sequence[str],
                    joint_types: Iterable) -> "GeneratedStructure":
        counts: dict[str, int] = {}
        joints: dict[str, list[str]] = {}
        for lab, jt in zip(labels, joint_types):
            counts[lab] = counts.get(lab, 0) + 1
            joints.setdefault(lab, []).append(JointType.parse(jt).name.lower())
        return cls(category, counts, joints)


@dataclass
class AlignmentResult:
    aligned: bool
    checked: bool                   # the prompt asked for something checkable
    category_ok: bool | None        # None: not asked
    counts_ok: bool | None
    joints_ok: bool | None
    failures: list[str] = field(default_factory=list)
    spatial_ok: bool | None = None      # every spatial fact right (None: the prompt states none)
    spatial: dict = field(default_factory=dict)   # kind (SPATIAL_KIND_NAMES) -> all right

    def to_json(self) -> dict:
        return asdict(self)


def _fact_ok(key: str, want, label: str, got: dict) -> bool:
    """One spatial fact of one part kind against the generated object's spatial summary."""
    have = got.get(label)
    if not have:
        return False
    if key in ARRANGEMENT_KEYS:
        return have.get(key) == want
    if key in ("above", "below"):
        from model.data.describe import is_above
        return all(bool(is_above(got, label, o) if key == "above" else is_above(got, o, label))
                   for o in want)
    if key == "beside":
        from model.data.spatial import is_beside
        return all(bool(is_beside(got, label, o)) for o in want)
    g = set(have.get(key) or [])
    w = set(want)
    if key == "hinge" and "side" in w:       # "side-hinged": on the left or on the right
        w.discard("side")
        return bool(g) and g <= (w | {"left", "right"}) and w <= g and bool(g & {"left", "right"})
    # one value ("a door on the left"): every part of the kind has it; several ("a drawer on
    # top and one at the bottom"): each of them is taken by some part of the kind
    return g == w if len(w) == 1 else w <= g


def check_spatial(expected: ExpectedStructure, got: GeneratedStructure) -> tuple[dict, list[str]]:
    """Per kind (hinge / opening / arrangement / position / size): are all its stated facts
    right."""
    kinds: dict[str, bool] = {}
    fails: list[str] = []
    if expected.size and got.body_size is not None:
        from model.data.prompt_size import AXIS
        ext = got.body_size
        for dim, want in expected.size.items():
            have = max(ext) if dim == "length" else ext[AXIS[dim]]
            ok = abs(have - want) <= SIZE_TOLERANCE * want
            kinds["size"] = kinds.get("size", True) and ok
            if not ok:
                fails.append(f"size.{dim}: {have:.3f} m != {want:.3f} m")
    for label, facts in expected.spatial.items():
        for key, want in facts.items():
            ok = _fact_ok(key, want, label, got.spatial)
            kind = SPATIAL_KINDS[key]
            kinds[kind] = kinds.get(kind, True) and ok
            if not ok:
                have = (got.spatial.get(label) or {}).get(key, "missing") \
                    if key not in RELATION_KEYS else "not so"
                fails.append(f"{label}.{key}: {have} != {want}")
    return kinds, fails


def check_alignment(expected: ExpectedStructure, got: GeneratedStructure) -> AlignmentResult:
    """Every check the prompt asks for, in the part names of the category asked for (a
    cabinet's "knobs" are its handles, a safe's "knob" its dial: the dataset's labels)."""
    from model.pipeline.prompt_structure import in_category_names
    expected = in_category_names(expected, expected.category)
    fails: list[str] = []
    cat_ok = None
    if expected.category:
        cat_ok = got.category == expected.category
        if not cat_ok:
            fails.append(f"category {got.category!r} != {expected.category!r}")
    counts_ok = None
    if expected.counts or expected.min_counts:
        counts_ok = True
        for lab, n in expected.counts.items():
            if got.counts.get(lab, 0) != n:
                counts_ok = False
                fails.append(f"{lab}: {got.counts.get(lab, 0)} != {n}")
        for lab, n in expected.min_counts.items():
            if got.counts.get(lab, 0) < n:
                counts_ok = False
                fails.append(f"{lab}: {got.counts.get(lab, 0)} < {n}")
    joints_ok = None
    if expected.joint_types:
        joints_ok = True
        for lab, ok_types in expected.joint_types.items():
            have = got.joint_types.get(lab, [])
            bad = [t for t in have if t not in ok_types]
            if not have or bad:
                joints_ok = False
                fails.append(f"{lab} joints {have or 'missing'} not in {ok_types}")
    checks = [c for c in (cat_ok, counts_ok, joints_ok) if c is not None]
    kinds, sfails = check_spatial(expected, got)
    return AlignmentResult(bool(checks) and all(checks), bool(checks), cat_ok, counts_ok,
                           joints_ok, fails + sfails,
                           spatial_ok=all(kinds.values()) if kinds else None, spatial=kinds)


def alignment_of(prompt: str, obj: ArticulatedObject) -> AlignmentResult:
    return check_alignment(parse_prompt(prompt), GeneratedStructure.from_object(obj))


def summarise(results: Sequence[AlignmentResult]) -> dict:
    """Shares over the prompts that asked for something (each check over those asking it)."""
    checked = [r for r in results if r.checked]

    def share(vals):
        vals = [v for v in vals if v is not None]
        return float(sum(vals) / len(vals)) if vals else None

    out = {"alignment": share([r.aligned for r in checked]),
           "category": share([r.category_ok for r in checked]),
           "counts": share([r.counts_ok for r in checked]),
           "joints": share([r.joints_ok for r in checked]),
           "n_checked": len(checked), "n_prompts": len(results),
           "spatial": share([r.spatial_ok for r in results]),
           "n_spatial": sum(r.spatial_ok is not None for r in results)}
    for kind in SPATIAL_KIND_NAMES:
        vals = [r.spatial.get(kind) for r in results]
        out[f"spatial_{kind}"] = share(vals)
        out[f"n_spatial_{kind}"] = sum(v is not None for v in vals)
    return out
