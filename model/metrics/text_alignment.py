"""Structure alignment of a transformer checkpoint on a held-out split (the headline metric
at tree level, before any geometry): for every object and description, decode one tree and
check (1) ``alignment``: it has exactly the object's category, count of every part label
(body included) and set of joint types per label (model.articulation.evaluate.compare);
(2) ``prompt_alignment``: the project's metric (model.metrics.alignment) — the structure the
prompt text asks for, parsed from it.

    artformer train transformer --eval CKPT --data data/prepared/v1 --split test
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from model.articulation.evaluate import compare, record_structure
from model.data import format as fmt

from .alignment import GeneratedStructure, check_alignment
from model.data.prompt_parse import parse_prompt


def alignment_report(ckpt: str, data_root: str, *, split: str = "test",
                     lengths: Optional[list[str]] = None, limit: int = 0, seed: int = 0,
                     temperature: float = 1.0, batch: int = 32, progress: bool = True,
                     max_nodes: int = 32, max_depth: int = 4, max_children: int = 16,
                     follow_plan: bool = False) -> dict:
    from model.articulation import ArticulationModel
    am = ArticulationModel.load(ckpt)
    ids = fmt.split_ids(data_root, split)
    if limit:
        ids = ids[:limit]
    lengths = list(lengths or fmt.DESCRIPTION_LENGTHS)
    jobs = []   # (record, length, text)
    for i in ids:
        rec = fmt.load_record(data_root, i)
        for L in lengths:
            texts = rec.descriptions.get(L) or []
            if texts:   # first wording of each length: deterministic and comparable
                jobs.append((rec, L, texts[0]))
    rows = []
    rng = range(0, len(jobs), batch)
    if progress:
        from tqdm import tqdm
        rng = tqdm(rng, desc=f"decode {split}", unit="batch")
    for s in rng:
        chunk = jobs[s:s + batch]
        tok, mask = am.encode_text([t for _, _, t in chunk])
        trees = am.decode(tok, mask, seed=seed + s, temperature=temperature,
                          max_nodes=max_nodes, max_depth=max_depth, max_children=max_children,
                          follow_plan=follow_plan)
        for (rec, L, text), tree in zip(chunk, trees):
            ok = compare(tree.summary(), record_structure(rec))
            row = {"id": rec.id, "length": L, "text": text, **ok,
                   "decoded": tree.summary(), "truth": record_structure(rec)}
            res = _prompt_check(text, tree)
            row["prompt_checked"], row["prompt_aligned"] = res.checked, res.aligned
            rows.append(row)
    def share(rs, key="all"):
        return float(np.mean([r[key] for r in rs])) if rs else float("nan")
    rep = {"checkpoint": str(ckpt), "data": str(data_root), "split": split,
           "objects": len(ids), "prompts": len(rows), "seed": seed, "temperature": temperature,
           "follow_plan": follow_plan,
           "alignment": share(rows), "category": share(rows, "category"),
           "counts": share(rows, "counts"), "joint_types": share(rows, "joint_types"),
           "by_length": {L: share([r for r in rows if r["length"] == L]) for L in lengths},
           "rows": rows}
    checked = [r for r in rows if r.get("prompt_checked")]
    if checked:   # the project's alignment metric: what the prompt text asks for
        rep["prompt_alignment"] = share(checked, "prompt_aligned")
        rep["prompt_checked"] = len(checked)
        rep["prompt_by_length"] = {L: share([r for r in checked if r["length"] == L],
                                            "prompt_aligned") for L in lengths}
    return rep


def _prompt_check(text: str, tree):
    """The project's alignment check (model.metrics.alignment) of a decoded tree against the
    structure its prompt text asks for."""
    got = GeneratedStructure.from_labels(tree.category or None, tree.labels, tree.joint_types)
    return check_alignment(parse_prompt(text), got)
