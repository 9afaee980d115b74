"""Alignment (DESIGN §7): does the generated object have the structure the prompt asks for?

The structure asked for comes from :func:`model.metrics.prompt_parse.parse_prompt` (category,
exact counts / lower bounds per part kind, acceptable joint types per part kind). The structure
generated is read from the object's part labels, joint types and category. A prompt is
*aligned* when every check it asks for passes; prompts that ask for nothing parseable are
reported separately (``checked=False``) and left out of the alignment share.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Iterable, Sequence

from model.core import ArticulatedObject, JointType

from .prompt_parse import ExpectedStructure, parse_prompt


@dataclass
class GeneratedStructure:
    category: str | None
    counts: dict[str, int]
    joint_types: dict[str, list[str]]   # label -> joint type name of every part, in order

    @classmethod
    def from_object(cls, obj: ArticulatedObject) -> "GeneratedStructure":
        return cls.from_labels(obj.category or None, [p.label for p in obj.parts],
                               [p.joint.type for p in obj.parts])

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

    def to_json(self) -> dict:
        return asdict(self)


def check_alignment(expected: ExpectedStructure, got: GeneratedStructure) -> AlignmentResult:
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
    return AlignmentResult(bool(checks) and all(checks), bool(checks), cat_ok, counts_ok,
                           joints_ok, fails)


def alignment_of(prompt: str, obj: ArticulatedObject) -> AlignmentResult:
    return check_alignment(parse_prompt(prompt), GeneratedStructure.from_object(obj))


def summarise(results: Sequence[AlignmentResult]) -> dict:
    """Shares over the prompts that asked for something (each check over those asking it)."""
    checked = [r for r in results if r.checked]

    def share(vals):
        vals = [v for v in vals if v is not None]
        return float(sum(vals) / len(vals)) if vals else None

    return {"alignment": share([r.aligned for r in checked]),
            "category": share([r.category_ok for r in checked]),
            "counts": share([r.counts_ok for r in checked]),
            "joints": share([r.joints_ok for r in checked]),
            "n_checked": len(checked), "n_prompts": len(results)}
