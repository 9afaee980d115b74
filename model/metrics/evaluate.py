"""`artformer eval`: generate for the test prompts, score everything, write JSON / markdown / PNG.

Rows of the results table (each a *method* producing one object per prompt):

* ``model``          — the checkpoint under test (``shipped`` = the packaged model)
* ``<ablation>``     — further checkpoints given with ``--ablation NAME=DIR`` (no_tpe, ...)
* ``retrieval``      — the training object whose description embedding is nearest the prompt
* ``train (floor)``  — a random training subset of the test set's size: the data's own
  MMD / COV / 1-NNA floor (no prompts, so no alignment)
* ``test (GT)``      — the reference objects themselves: their POR and how well their own
  descriptions parse back to their structure (the ceiling of the alignment metric)

Prompts: ``n`` test-split records (one description each, rotating over the four lengths)
plus the hand-written free-form prompts (``prompts_freeform.txt``). MMD / COV / 1-NNA use the
test prompts only (they have a reference object); POR, alignment and validity use all prompts.

Modules: the run's configuration in eval_config.py, each method's objects in eval_methods.py,
the scores of one method in eval_scoring.py, the free-form breakdown and ``--freeform-only``
in freeform.py (their names are importable from here too); here, the run.
"""
from __future__ import annotations

import logging
import time
from dataclasses import asdict
from pathlib import Path
from typing import Callable, Optional

import numpy as np

# the parts of the run, re-exported: model.metrics.evaluate stays the one import of callers
from .eval_config import EvalConfig
from .eval_methods import (MethodOutput, _export, _slug, assemble_checkpoint,  # noqa: F401
                           generate_method)
from .eval_scoring import CloudCache, _por_stats, score_method  # noqa: F401
from .freeform import (PART_BUCKETS, FreeformConfig, _annotations,  # noqa: F401
                       freeform_alignment, freeform_breakdown, freeform_table, part_bucket)
from .instantiation import id_matrix
from .reference import Dataset, Retriever, freeform_prompts, pick_description

log = logging.getLogger(__name__)

PUBLISHED = {  # DESIGN §7 anchors (PartNet-Mobility, not our data)
    "ArtFormer (paper)": {"por": 0.709e-2, "mmd": 0.0292, "cov": 0.5213, "nna": 0.5266},
    "CAGE (paper)": {"por": 0.251e-2},
}


def run_eval(cfg: EvalConfig, loader: Optional[Callable] = None) -> dict:
    """Everything ``artformer eval`` does; returns the results dict (also written to disk).

    ``loader``: how to build a generator from a ``GenerationConfig`` (default
    ``Generator.load``)."""
    t_start = time.perf_counter()
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(cfg.seed)
    data = Dataset.open(cfg.data)
    test_ids, test_prompts, refs, free = _prompts(cfg, data, rng)
    prompts = test_prompts + free
    n_test = len(test_prompts)
    log.info("eval: %d test prompts + %d free-form prompts", n_test, len(free))

    clouds = CloudCache(cfg)
    cr = [clouds(o) for o in refs]
    D_rr = id_matrix(cr, workers=cfg.workers, progress=cfg.progress)

    producers = _producers(cfg, data, prompts, n_test, out, loader, rng)
    rows, skipped = _score_methods(producers, refs, D_rr, clouds, cfg, n_test)
    gt = MethodOutput("test (GT)", refs, [], test_prompts)
    gt_row = score_method(gt, [], None, clouds, EvalConfig(**{**asdict(cfg), "validity": False}),
                          n_test)
    rows.append(gt_row)

    results = {"config": asdict(cfg), "n_test": n_test, "n_freeform": len(free),
               "test_ids": test_ids, "prompts": prompts, "rows": rows,
               "published": PUBLISHED, "skipped_rows": skipped,
               "seconds": time.perf_counter() - t_start,
               "id_points": cfg.points, "id_poses": cfg.poses}
    _write_results(results, out, cfg.plots)
    return results


def _prompts(cfg: EvalConfig, data: Dataset, rng: np.random.Generator
             ) -> tuple[list, list[str], list, list[str]]:
    """The scored test records (``cfg.n`` of the split, drawn with ``rng``): their ids,
    prompts (one description each, rotating over the lengths) and reference objects; and the
    free-form prompts."""
    test_ids = data.ids(cfg.split)
    if not test_ids:
        raise ValueError(f"{cfg.data}: split {cfg.split!r} is empty")
    test_ids = sorted(test_ids)
    if cfg.n < len(test_ids):
        test_ids = sorted(rng.choice(test_ids, size=cfg.n, replace=False).tolist())
    recs = [data.record(i) for i in test_ids]
    test_prompts = [pick_description(r, k) for k, r in enumerate(recs)]
    refs = [data.object(i) for i in test_ids]
    free = freeform_prompts(cfg.freeform_file)
    if cfg.n_freeform is not None:
        free = free[:cfg.n_freeform]
    return test_ids, test_prompts, refs, free


def _producers(cfg: EvalConfig, data: Dataset, prompts: list[str], n_test: int, out: Path,
               loader: Optional[Callable], rng: np.random.Generator
               ) -> list[tuple[str, Callable[[], Optional[MethodOutput]]]]:
    """(row name, a callable that makes the row's objects) per method of the results table.

    Each method is generated, scored and dropped before the next one: a generated object
    with dense marching-cubes meshes holds ~25 MB, and six rows of 68 objects kept together
    reached 22 GB."""
    ckpt = None if cfg.checkpoint in (None, "", "shipped") else cfg.checkpoint
    producers: list[tuple[str, Callable[[], Optional[MethodOutput]]]] = []
    if cfg.model:
        producers.append(("model", lambda: generate_method("model", ckpt, prompts, cfg,
                                                           out / "objects", loader)))
        if cfg.part_retrieval:
            producers.append(("model (part retrieval)", lambda: generate_method(
                "model (part retrieval)", ckpt, prompts, cfg, out / "objects", loader,
                geometry="retrieve")))
    for name, path in cfg.ablations.items():
        def ablation(name=name, path=path):
            p = assemble_checkpoint(path, ckpt, out / "checkpoints" / _slug(name))
            return generate_method(name, p, prompts, cfg, out / "objects", loader)
        producers.append((name, ablation))
    if cfg.retrieval:
        def retrieval():
            retr = Retriever(data, "train", cfg.text_encoder)
            ids = retr.nearest(prompts)
            objs = [data.object(i) for i in ids]
            urdfs = [_export(o, out / "objects" / "retrieval" / f"{k:03d}", cfg.collision)
                     if cfg.validity else None
                     for k, o in enumerate(objs)]
            return MethodOutput("retrieval", objs, urdfs, list(prompts),
                                extra={"retrieved_ids": ids})
        producers.append(("retrieval", retrieval))
    if cfg.train_floor:
        def floor():
            train_ids = sorted(data.ids("train"))
            k = min(len(train_ids), n_test)
            pick = sorted(rng.choice(train_ids, size=k, replace=False).tolist()) if k else []
            objs = [data.object(i) for i in pick]
            return MethodOutput("train (floor)", objs, [], [None] * len(objs))
        producers.append(("train (floor)", floor))
    return producers


def _score_methods(producers: list, refs: list, D_rr: np.ndarray, clouds: CloudCache,
                   cfg: EvalConfig, n_test: int) -> tuple[list[dict], list[str]]:
    """Make, score and drop each method's objects in turn (see :func:`_producers`).
    -> (result rows, why rows were skipped)."""
    from model.core.runtime import release_free_memory
    rows, skipped = [], []
    for name, produce in producers:
        m = produce()
        if m is None:
            if name == "model (part retrieval)":
                skipped.append("model (part retrieval): no retrieval bank in the prior checkpoint")
            continue
        log.info("scoring %s", m.name)
        # the floor row has no prompts: all its objects stand against the references
        nt = len(m.objects) if m.name == "train (floor)" else n_test
        rows.append(score_method(m, refs, D_rr, clouds, cfg, nt))
        clouds.drop(m.objects + [o for s in m.diversity_sets for o in s])
        del m
        release_free_memory()
    return rows, skipped


def _write_results(results: dict, out: Path, plots: bool) -> None:
    """results.json and results.md into ``out``; with ``plots`` the PNG figures too (their
    paths are added to ``results`` and to results.json)."""
    from model.data.format import atomic_write_json
    atomic_write_json(out / "results.json", _jsonable(results))
    from .report import results_markdown, results_plots
    md = results_markdown(results)
    (out / "results.md").write_text(md)
    if plots:
        results["figures"] = results_plots(results, out)
        atomic_write_json(out / "results.json", _jsonable(results))


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x
