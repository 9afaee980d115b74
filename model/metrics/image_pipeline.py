"""Image requests through the whole product: the first N held-out renders of a split go
through ``Generator.generate(image=...)`` and export, and each object is scored by POR,
validity in yourdfpy / pybullet / MuJoCo and its structure against the record (as
model.imaging.evaluate scores the decoded trees).

    artformer train image --eval shipped --pipeline 24 --data data/prepared/v1 \
        --renders data/renders/v1 --split test
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np


def image_pipeline_report(data_root: str, render_root: str, *, checkpoint: Optional[str] = None,
                          split: str = "test", n: int = 32, view: int = 0, seed: int = 0,
                          out_dir: Optional[str] = None, por_states: int = 10,
                          progress: bool = True) -> dict:
    """Image requests through the whole product (``Generator.generate(image=...)`` + export
    with its own collision geometry): POR, validity in yourdfpy / pybullet / MuJoCo, and
    the structure of the exported object against the record, for the first ``n`` objects
    of ``split`` (rendered view ``view`` of each)."""
    import tempfile

    from model.articulation.evaluate import compare, record_structure
    from model.core.runtime import release_free_memory
    from model.data import format as fmt
    from model.metrics.por import part_overlap_ratio
    from model.metrics.validity import validity
    from model.pipeline import GenerationConfig, Generator

    from model.imaging.renders import rendered_ids, view_paths

    ids = rendered_ids(render_root, fmt.split_ids(data_root, split))[:n]
    gen = Generator.load(GenerationConfig(checkpoint=checkpoint))
    out = Path(out_dir or tempfile.mkdtemp(prefix="artformer_image_pipeline_"))
    rows, urdfs, pors, errors = [], [], [], []
    it = ids
    if progress:
        from tqdm import tqdm
        it = tqdm(ids, desc=f"image pipeline {split}", unit="image")
    for k, i in enumerate(it):
        rec = fmt.load_record(data_root, i)
        paths = view_paths(render_root, i)
        path = paths[min(view, len(paths) - 1)]
        try:
            res = gen.generate(image=str(path), seed=seed + k)[0]
            exp = gen.export(res, str(out / f"{k:03d}_{i}"), preview=False)
        except Exception as e:                              # counted as invalid below
            errors.append(f"{i}: {type(e).__name__}: {e}")
            urdfs.append(None)
            continue
        por = part_overlap_ratio(res.obj, por_states)
        pors.append(por.mean)
        ok = compare(res.obj.summary(), record_structure(rec))
        rows.append({"id": i, "image": str(path), "por": por.mean, "por_max": por.max,
                     "urdf": exp.urdf_path, **ok,
                     "timings": {s: round(t, 4) for s, t in res.timings.items()}})
        urdfs.append((exp.urdf_path, res.obj))
        release_free_memory()
    done = [u for u in urdfs if u is not None]
    v = validity([u for u, _ in done], [o for _, o in done]) if done else None

    def share(key):
        return float(np.mean([r[key] for r in rows])) if rows else float("nan")
    return {"checkpoint": checkpoint or "shipped", "data": str(data_root),
            "renders": str(render_root), "split": split, "images": len(ids), "view": view,
            "seed": seed, "failed": len(errors), "errors": errors[:20],
            "por": float(np.mean(pors)) if pors else None,
            "por_max": float(np.mean([r["por_max"] for r in rows])) if rows else None,
            "validity": (sum(v.valid) / len(ids)) if v else 0.0,
            "category": share("category"), "alignment": share("all"),
            "counts": share("counts"), "joint_types": share("joint_types"),
            "out": str(out), "rows": rows}
