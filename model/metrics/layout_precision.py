"""How precisely the decoded layout matches the ground truth: for held-out objects, decode a
tree from the object's own description (free-running, as the product does) and compare its
parts' boxes and joints with the true object's.

Parts are matched label by label (Hungarian assignment on centre distance); parts with no
partner of their label count as missed or extra. Per matched pair: axis-aligned box IoU,
centre error and size error (metres, and relative to the true body's diagonal); per matched
moving pair of one joint type: the angle between the joint axes (unsigned, degrees) and, for
turning joints, the distance between the axis lines (metres). Scored twice: the network's
layout as decoded (``raw``) and after the layout refinement the product runs (``refined``).

    artformer eval layout --data data/prepared/v1 [--n 100] [--length sentence] [--seed 0]

Teacher-forced figures (the network given the true prefix) are not measured here.
"""
from __future__ import annotations

import argparse
import json
import sys
from typing import Optional

import numpy as np

from model.core import ArticulatedObject, JointType

KEYS = ("iou", "centre_m", "centre_rel", "size_m", "axis_deg", "axis_line_m")


def box_iou(a, b) -> float:
    """Axis-aligned 3D IoU of two parts' boxes."""
    alo, ahi = a.bbox_center - a.bbox_size / 2, a.bbox_center + a.bbox_size / 2
    blo, bhi = b.bbox_center - b.bbox_size / 2, b.bbox_center + b.bbox_size / 2
    inter = float(np.prod(np.clip(np.minimum(ahi, bhi) - np.maximum(alo, blo), 0.0, None)))
    union = float(np.prod(a.bbox_size)) + float(np.prod(b.bbox_size)) - inter
    return inter / union if union > 0 else 0.0


def axis_line_distance(o1, a1, o2, a2) -> float:
    """Distance between two lines (origin, direction)."""
    a1 = np.asarray(a1, float) / max(np.linalg.norm(a1), 1e-12)
    a2 = np.asarray(a2, float) / max(np.linalg.norm(a2), 1e-12)
    d = np.asarray(o2, float) - np.asarray(o1, float)
    n = np.cross(a1, a2)
    if np.linalg.norm(n) < 1e-6:                       # parallel: point to line
        return float(np.linalg.norm(d - (d @ a1) * a1))
    return float(abs(d @ n) / np.linalg.norm(n))


def match_parts(pred: ArticulatedObject, true: ArticulatedObject) -> tuple[list, int, int]:
    """[(pred index, true index)] matched within each label, and the counts of extra
    (unmatched predicted) and missed (unmatched true) parts."""
    from scipy.optimize import linear_sum_assignment
    pairs, extra, missed = [], 0, 0
    for label in sorted({p.label for p in pred.parts} | {p.label for p in true.parts}):
        pi = [i for i, p in enumerate(pred.parts) if p.label == label]
        ti = [i for i, p in enumerate(true.parts) if p.label == label]
        if pi and ti:
            cost = np.array([[np.linalg.norm(pred.parts[i].bbox_center - true.parts[j].bbox_center)
                              for j in ti] for i in pi])
            rows, cols = linear_sum_assignment(cost)
            pairs += [(pi[r], ti[c]) for r, c in zip(rows, cols)]
        extra += max(0, len(pi) - len(ti))
        missed += max(0, len(ti) - len(pi))
    return pairs, extra, missed


def compare_layouts(pred: ArticulatedObject, true: ArticulatedObject) -> dict:
    """Per-pair errors of one decoded object against the true one (lists under KEYS), and
    its extra / missed part counts."""
    pairs, extra, missed = match_parts(pred, true)
    root = true.parts[true.root]
    diag = max(float(np.linalg.norm(root.bbox_size)), 1e-6)
    out = {k: [] for k in KEYS}
    for i, j in pairs:
        p, t = pred.parts[i], true.parts[j]
        out["iou"].append(box_iou(p, t))
        c = float(np.linalg.norm(p.bbox_center - t.bbox_center))
        out["centre_m"].append(c)
        out["centre_rel"].append(c / diag)
        out["size_m"].append(float(np.linalg.norm(p.bbox_size - t.bbox_size)))
        if t.joint.type != JointType.FIXED and p.joint.type == t.joint.type:
            a1, a2 = np.asarray(p.joint.axis, float), np.asarray(t.joint.axis, float)
            cos = abs(a1 @ a2) / max(np.linalg.norm(a1) * np.linalg.norm(a2), 1e-12)
            out["axis_deg"].append(float(np.degrees(np.arccos(min(1.0, cos)))))
            if t.joint.type.rotates:
                out["axis_line_m"].append(axis_line_distance(p.joint.origin, a1,
                                                             t.joint.origin, a2))
    out["extra"], out["missed"], out["pairs"] = extra, missed, len(pairs)
    return out


def layout_precision(data_root: str, *, n: int = 100, split: str = "test",
                     length: str = "sentence", seed: int = 0, checkpoint: Optional[str] = None,
                     progress: bool = False) -> dict:
    """Free-running layout errors of the product's decoding on ``n`` objects of ``split``
    (the first description of ``length`` of each), raw and refined."""
    from model.data import format as fmt
    from model.pipeline.api import GenerationConfig
    from model.pipeline.generator import Generator

    gen = Generator.load(GenerationConfig(checkpoint=checkpoint))
    ids = fmt.split_ids(data_root, split)[:n]
    rows = {"raw": {k: [] for k in KEYS}, "refined": {k: [] for k in KEYS}}
    counts = {"raw": [0, 0, 0], "refined": [0, 0, 0]}       # pairs, extra, missed
    used = 0
    it = ids
    if progress:
        from tqdm import tqdm
        it = tqdm(ids, desc="layouts", unit="obj")
    for i in it:
        rec = fmt.load_record(data_root, i)
        texts = rec.descriptions.get(length) or []
        if not texts:
            continue
        true = ArticulatedObject.from_tokens(np.asarray(rec.tokens), rec.joint_types,
                                             rec.parents, rec.labels, category=rec.category,
                                             name=rec.id)
        tree = gen.decode_trees(texts[0], seed=seed)[0][0]
        used += 1
        for mode in rows:
            got = compare_layouts(gen.layout(tree, refine=mode == "refined"), true)
            for k in KEYS:
                rows[mode][k] += got[k]
            counts[mode] = [a + b for a, b in zip(counts[mode],
                                                  (got["pairs"], got["extra"], got["missed"]))]
    summary = {}
    for mode, vals in rows.items():
        pairs, extra, missed = counts[mode]
        summary[mode] = {**{f"{k}_mean": _stat(v, np.mean) for k, v in vals.items()},
                         **{f"{k}_median": _stat(v, np.median) for k, v in vals.items()},
                         "pairs": pairs, "extra": extra, "missed": missed}
    return {"objects": used, "split": split, "length": length, "seed": seed,
            "checkpoint": checkpoint or "shipped", "summary": summary}


def _stat(v, fn) -> Optional[float]:
    return float(fn(v)) if v else None


def table(report: dict) -> str:
    s = report["summary"]
    lines = ["| layout | box IoU (mean / median) | centre error, m (median) | centre error / body "
             "diagonal (median) | size error, m (median) | joint axis, deg (mean / median) | "
             "hinge line, m (median) | matched / extra / missed parts |",
             "|---|---|---|---|---|---|---|---|"]
    for mode in ("raw", "refined"):
        m = s[mode]
        lines.append(f"| {mode} | {m['iou_mean']:.3f} / {m['iou_median']:.3f} | "
                     f"{m['centre_m_median']:.3f} | {m['centre_rel_median']:.3f} | "
                     f"{m['size_m_median']:.3f} | {m['axis_deg_mean']:.1f} / "
                     f"{m['axis_deg_median']:.1f} | {m['axis_line_m_median']:.3f} | "
                     f"{m['pairs']} / {m['extra']} / {m['missed']} |")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="artformer eval layout", description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True, help="prepared dataset (its test split)")
    p.add_argument("--n", type=int, default=100)
    p.add_argument("--split", default="test")
    p.add_argument("--length", default="sentence", help="description length used "
                   "(detailed, sentences, sentence, words)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--checkpoint", default=None)
    p.add_argument("--out", default=None, help="write the report as JSON here")
    a = p.parse_args(argv)
    rep = layout_precision(a.data, n=a.n, split=a.split, length=a.length, seed=a.seed,
                           checkpoint=a.checkpoint, progress=sys.stderr.isatty())
    if not rep["summary"]["raw"]["pairs"]:
        print(f"artformer eval layout: no {a.split} object of {a.data} has a {a.length!r} "
              "description", file=sys.stderr)
        return 1
    print(f"Layout against the truth, {rep['objects']} {a.split} objects ({a.length} "
          f"descriptions, seed {a.seed}), free-running decoding:\n")
    print(table(rep))
    if a.out:
        with open(a.out, "w") as f:
            json.dump(rep, f, indent=1)
    return 0
