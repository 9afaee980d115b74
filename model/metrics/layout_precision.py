"""How precisely the decoded layout matches the ground truth: for held-out objects, decode a
tree from the object's own description (free-running, as the product does) and compare its
parts' boxes and joints with the true object's.

Parts are matched label by label (Hungarian assignment on centre distance); parts with no
partner of their label count as missed or extra. Per matched pair: axis-aligned box IoU,
centre error and size error (metres, and relative to the true body's diagonal); per matched
moving pair of one joint type: the angle between the joint axes (unsigned, degrees) and, for
turning joints, the distance between the axis lines (metres). Scored three times: the
network's layout as decoded (``raw``), after the layout refinement the product runs
(``refined``), and **teacher-forced** (``teacher``): every true part predicted by the network
from the true tree before the round that adds it (its true parent included), the network's
articulation read in the true parent's frame, compared with that same part (no matching).
Sibling collapse is counted on its own: the share of pairs of siblings (same parent, both
moving) whose boxes overlap by more than ``COLLAPSE`` of the smaller box (the truth has none).

    artformer eval layout --data data/prepared/v1 [--n 100] [--length sentence] [--seed 0]
"""
from __future__ import annotations

import argparse
import json
import sys
from typing import Optional

import numpy as np

from model.core import ArticulatedObject, JointType

KEYS = ("iou", "centre_m", "centre_rel", "size_m", "axis_deg", "axis_line_m", "iou_body",
        "centre_body")
MODES = ("raw", "refined", "teacher")
COLLAPSE = 0.3             # sibling boxes sharing more than this of the smaller box's volume


def _box_intersection(a, b) -> float:
    """Volume shared by two parts' axis-aligned boxes."""
    alo, ahi = a.bbox_center - a.bbox_size / 2, a.bbox_center + a.bbox_size / 2
    blo, bhi = b.bbox_center - b.bbox_size / 2, b.bbox_center + b.bbox_size / 2
    return float(np.prod(np.clip(np.minimum(ahi, bhi) - np.maximum(alo, blo), 0.0, None)))


def box_iou(a, b) -> float:
    """Axis-aligned 3D IoU of two parts' boxes."""
    inter = _box_intersection(a, b)
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


def sibling_collapse(obj: ArticulatedObject) -> tuple[int, int]:
    """(pairs of moving siblings whose boxes overlap by > COLLAPSE of the smaller box, pairs
    of moving siblings)."""
    kids: dict[int, list] = {}
    for p in obj.parts:
        if p.parent >= 0 and p.joint.type != JointType.FIXED:
            kids.setdefault(p.parent, []).append(p)
    bad = total = 0
    for group in kids.values():
        for a in range(len(group)):
            for b in range(a + 1, len(group)):
                pa, pb = group[a], group[b]
                inter = _box_intersection(pa, pb)
                small = min(float(np.prod(pa.bbox_size)), float(np.prod(pb.bbox_size)))
                total += 1
                bad += inter > COLLAPSE * max(small, 1e-12)
    return bad, total


def _in_body(part, root):
    """A copy of ``part``'s box in its object's body frame: the root's box is the unit cube."""
    from copy import copy
    size = np.maximum(np.abs(root.bbox_size), 1e-6)
    q = copy(part)
    q.bbox_center = (part.bbox_center - root.bbox_center) / size
    q.bbox_size = part.bbox_size / size
    return q


def _pair_errors(p, t, diag: float, out: dict, proot, troot) -> None:
    """Append the errors of predicted part p against true part t to ``out`` (lists); the
    body-frame figures read each part in its own object's root box (sizes the prompt does not
    state drop out)."""
    out["iou"].append(box_iou(p, t))
    pb, tb = _in_body(p, proot), _in_body(t, troot)
    out["iou_body"].append(box_iou(pb, tb))
    out["centre_body"].append(float(np.linalg.norm(pb.bbox_center - tb.bbox_center)))
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


def _diag(root) -> float:
    """The diagonal of a body part's box (metres, at least 1 um)."""
    return max(float(np.linalg.norm(root.bbox_size)), 1e-6)


def compare_layouts(pred: ArticulatedObject, true: ArticulatedObject) -> dict:
    """Per-pair errors of one decoded object against the true one (lists under KEYS), and
    its extra / missed part counts."""
    pairs, extra, missed = match_parts(pred, true)
    diag = _diag(true.parts[true.root])
    out = {k: [] for k in KEYS}
    for i, j in pairs:
        _pair_errors(pred.parts[i], true.parts[j], diag, out, pred.parts[pred.root],
                     true.parts[true.root])
    out["extra"], out["missed"], out["pairs"] = extra, missed, len(pairs)
    return out


def teacher_forced(am, rec, text: str) -> dict:
    """Errors of every true part predicted from the true tree before its round (lists under
    KEYS; pairs = parts). ``am``: an ArticulationModel, ``rec``: a prepared record."""
    import torch
    from model.articulation.data import canonical_order, collate, make_item, round_sample
    from model.articulation.frames import token_from_frame
    from model.core.objects import Part
    toks = np.asarray(rec.tokens, dtype=np.float64)
    order, _, _ = canonical_order(rec.labels, rec.parents, toks)
    cs = torch.stack([am.label_cs(rec.category, lab) for lab in rec.labels]).numpy()
    shape = (am.cfg.z_dim,) if am.cfg.predict_z else (am.cfg.num_codebooks, am.cfg.codebook_size)
    item = make_item(rec, am.tok_mean.numpy(), am.tok_std.numpy(), cs,
                     np.zeros((len(toks),) + shape, np.float32), np.full(len(toks), -1),
                     am.frame)
    samples = [round_sample(item, k) for k in range(int(item.rounds.max()) + 1)]
    batch, _ = collate(samples, shape, None, am.cfg.count_labels)
    cond, cmask = am.encode_text([text])
    with torch.no_grad():
        out, _ = am.net(batch, cond, cmask, "text",
                        cond_index=torch.zeros(len(samples), dtype=torch.long))
    true_abs = toks[order]
    pred = {}
    for r, smp in enumerate(samples):
        for pos in np.nonzero(smp["target"] >= 0)[0]:
            node = int(smp["target"][pos])
            rel = (out["art"][r, pos].float() * am.tok_std + am.tok_mean).double().numpy()
            par = int(item.parents[node])
            pred[node] = token_from_frame(rel, None if par < 0 else true_abs[par], am.frame)
    res = {k: [] for k in KEYS}

    def part(tok, n: int, name: str):
        return Part.from_token(tok, int(item.jtypes[n]), name=name, label=item.labels[n],
                               parent=int(item.parents[n]))
    r = int(np.nonzero(item.parents < 0)[0][0])
    troot = part(true_abs[r], r, "t")
    diag = _diag(troot)
    for node, tok in pred.items():       # placed in the true tree: read in the true body too
        _pair_errors(part(tok, node, "p"), part(true_abs[node], node, "t"), diag, res, troot,
                     troot)
    res["extra"], res["missed"], res["pairs"] = 0, 0, len(pred)
    placed = ArticulatedObject.from_tokens(np.stack([pred[n] for n in range(len(pred))]),
                                           item.jtypes, item.parents, item.labels)
    res["collapsed"], res["sibling_pairs"] = sibling_collapse(placed)
    return res


def layout_precision(data_root: str, *, n: int = 100, split: str = "test",
                     length: str = "sentence", seed: int = 0, checkpoint: Optional[str] = None,
                     progress: bool = False, sibling_room: bool = True) -> dict:
    """Free-running layout errors of the product's decoding on ``n`` objects of ``split``
    (the first description of ``length`` of each), raw and refined."""
    from model.data import format as fmt
    from model.pipeline.api import GenerationConfig
    from model.pipeline.generator import Generator

    gen = Generator.load(GenerationConfig(checkpoint=checkpoint, sibling_room=sibling_room))
    ids = fmt.split_ids(data_root, split)[:n]
    rows = {m: {k: [] for k in KEYS} for m in MODES}
    counts = {m: [0, 0, 0] for m in MODES}                   # pairs, extra, missed
    collapse = {m: [0, 0] for m in MODES + ("truth",)}       # collapsed, sibling pairs
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
        collapse["truth"] = [a + b for a, b in zip(collapse["truth"], sibling_collapse(true))]
        for mode in MODES:
            if mode == "teacher":
                got = teacher_forced(gen.articulation, rec, texts[0])
                pair = (got["collapsed"], got["sibling_pairs"])
            else:
                laid = gen.layout(tree, refine=mode == "refined")
                pair = sibling_collapse(laid)
                got = compare_layouts(laid, true)
            collapse[mode] = [a + b for a, b in zip(collapse[mode], pair)]
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
        if mode in collapse:
            summary[mode]["collapsed"], summary[mode]["sibling_pairs"] = collapse[mode]
    summary["truth"] = {"collapsed": collapse["truth"][0], "sibling_pairs": collapse["truth"][1]}
    return {"objects": used, "split": split, "length": length, "seed": seed,
            "checkpoint": checkpoint or "shipped", "summary": summary}


def _stat(v, fn) -> Optional[float]:
    return float(fn(v)) if v else None


def table(report: dict) -> str:
    s = report["summary"]
    lines = ["| layout | box IoU (mean / median) | centre error, m (median) | centre error / body "
             "diagonal (median) | size error, m (median) | joint axis, deg (mean / median) | "
             "hinge line, m (median) | matched / extra / missed parts | collapsed sibling pairs | "
             "body frame: box IoU (mean) / centre error (median) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    f = lambda v, fmt: "–" if v is None else format(v, fmt)     # noqa: E731
    for mode in MODES:
        m = s[mode]
        coll = (f"{m['collapsed']} of {m['sibling_pairs']}" if "collapsed" in m else "–")
        lines.append(f"| {mode} | {f(m['iou_mean'], '.3f')} / {f(m['iou_median'], '.3f')} | "
                     f"{f(m['centre_m_median'], '.3f')} | {f(m['centre_rel_median'], '.3f')} | "
                     f"{f(m['size_m_median'], '.3f')} | {f(m['axis_deg_mean'], '.1f')} / "
                     f"{f(m['axis_deg_median'], '.1f')} | {f(m['axis_line_m_median'], '.3f')} | "
                     f"{m['pairs']} / {m['extra']} / {m['missed']} | {coll} | "
                     f"{f(m['iou_body_mean'], '.3f')} / {f(m['centre_body_median'], '.3f')} |")
    t = s["truth"]
    lines.append(f"| truth | | | | | | | | {t['collapsed']} of {t['sibling_pairs']} | |")
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
    p.add_argument("--no-sibling-room", dest="sibling_room", action="store_false",
                   help="decode without redrawing candidate boxes that cover a sibling")
    a = p.parse_args(argv)
    rep = layout_precision(a.data, n=a.n, split=a.split, length=a.length, seed=a.seed,
                           checkpoint=a.checkpoint, progress=sys.stderr.isatty(),
                           sibling_room=a.sibling_room)
    if not rep["summary"]["raw"]["pairs"]:
        print(f"artformer eval layout: no {a.split} object of {a.data} has a {a.length!r} "
              "description", file=sys.stderr)
        return 1
    print(f"Layout against the truth, {rep['objects']} {a.split} objects ({a.length} "
          f"descriptions, seed {a.seed}); raw / refined: free-running decoding, teacher: "
          f"the true tree before each part's round:\n")
    print(table(rep))
    if a.out:
        with open(a.out, "w") as f:
            json.dump(rep, f, indent=1)
    return 0
