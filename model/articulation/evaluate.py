"""A decoded tree's structure against an object record's: category, count of every part
label (body included) and set of joint types per label. The text and image checkpoints'
alignment reports score with these (model.metrics.text_alignment, model.imaging.evaluate).
"""
from __future__ import annotations

from model.data import format as fmt

from .trees import label_summary


def record_structure(rec: fmt.ObjectRecord) -> dict:
    return {"category": rec.category, **label_summary(rec.labels, rec.joint_types)}


def compare(decoded: dict, truth: dict) -> dict:
    """Which parts of the structure match (category, counts, joint types, all)."""
    cat = decoded["category"] == truth["category"]
    counts = decoded["counts"] == truth["counts"]
    joints = decoded["joint_types"] == truth["joint_types"]
    return {"category": cat, "counts": counts, "joint_types": joints,
            "all": cat and counts and joints}
