"""Scoring one method of `artformer eval`: POR, MMD / COV / 1-NNA against the reference
objects (Instantiation Distance), structure alignment with the prompts, diversity, validity
and the generation timings."""
from __future__ import annotations

import logging
import time
from typing import Optional

import numpy as np

from model.core import ArticulatedObject

from . import alignment as al
from .distribution import set_metrics
from .eval_config import EvalConfig
from .eval_methods import MethodOutput
from .freeform import _annotations, freeform_breakdown
from .instantiation import diversity as diversity_of
from .instantiation import id_matrix, posed_clouds
from .por import part_overlap_ratio

log = logging.getLogger(__name__)


class CloudCache:
    """Posed clouds per object (same seed for all: identical objects → identical clouds)."""

    def __init__(self, cfg: EvalConfig):
        self.cfg = cfg
        self._c: dict[int, object] = {}

    def __call__(self, obj: ArticulatedObject):
        k = id(obj)
        if k not in self._c:
            self._c[k] = (posed_clouds(obj, self.cfg.poses, self.cfg.points, self.cfg.seed), obj)
        return self._c[k][0]

    def drop(self, objs) -> None:
        """Forget the clouds (and the references) of these objects."""
        for o in objs:
            if o is not None:
                self._c.pop(id(o), None)


def _por_stats(objs: list, states: int) -> dict:
    vals, maxes, bad, fails = [], [], 0, 0
    for o in objs:
        if o is None:
            continue
        try:
            r = part_overlap_ratio(o, states)
        except Exception as e:
            log.warning("POR of %s failed: %s", getattr(o, "name", "?"), e)
            fails += 1
            continue
        vals.append(r.mean)
        maxes.append(r.max)
        bad += r.nonwatertight_parts
    return {"por": float(np.mean(vals)) if vals else None,
            "por_max": float(np.mean(maxes)) if maxes else None,
            "por_per_object": vals, "nonwatertight_parts": bad, "por_failures": fails}


def score_method(out: MethodOutput, refs: list, D_rr: Optional[np.ndarray], clouds: CloudCache,
                 cfg: EvalConfig, n_test: int) -> dict:
    """All metrics of one method. The first ``n_test`` prompts are paired with ``refs``."""
    t0 = time.perf_counter()
    res: dict = {"name": out.name, "n_prompts": len(out.objects),
                 "n_failed": sum(o is None for o in out.objects), "errors": out.errors[:20]}
    res.update(_por_stats(out.objects, cfg.por_states))
    gen_test = [o for o in out.objects[:n_test] if o is not None]
    if refs and gen_test and D_rr is not None:
        cg = [clouds(o) for o in gen_test]
        cr = [clouds(o) for o in refs]
        D_gg = id_matrix(cg, workers=cfg.workers, progress=cfg.progress)
        D_gr = id_matrix(cg, cr, workers=cfg.workers, progress=cfg.progress)
        m = set_metrics(D_gg, D_gr, D_rr)
        res.update(mmd=m.mmd, cov=m.cov, nna=m.nna, n_generated=m.n_generated,
                   n_reference=m.n_reference)
        res["nearest_reference_id"] = D_gr.min(axis=1).tolist()
    if any(p is not None for p in out.prompts):
        results = []
        # free-form prompts are scored against their hand-written structure line
        annotated = dict(_annotations(cfg.freeform_file))
        free_expected = []
        for k, (prompt, o) in enumerate(zip(out.prompts, out.objects)):
            if prompt is None:
                continue
            exp = annotated.get(prompt) if k >= n_test else None
            exp = exp if exp is not None else al.parse_prompt(prompt)
            if k >= n_test:
                free_expected.append(exp)
            if o is None:
                r = al.check_alignment(exp, al.GeneratedStructure(None, {}, {}))
                r.aligned = False                    # a failed generation never aligns
                r.failures.append("generation failed")
            else:
                r = al.check_alignment(exp, al.GeneratedStructure.from_object(o))
            results.append(r)
        s_all = al.summarise(results)
        s_test = al.summarise(results[:n_test])
        s_free = al.summarise(results[n_test:])
        res["alignment"] = s_all["alignment"]
        res["alignment_test"] = s_test["alignment"]
        res["alignment_freeform"] = s_free["alignment"]
        res["alignment_detail"] = {"all": s_all, "test": s_test, "freeform": s_free}
        if free_expected:
            res["alignment_freeform_breakdown"] = freeform_breakdown(free_expected,
                                                                     results[n_test:])
        res["alignment_failures"] = [
            {"prompt": p, "failures": r.failures} for p, r in
            zip([p for p in out.prompts if p is not None], results) if r.checked and not r.aligned][:30]
    if out.diversity_sets:
        divs = [diversity_of([clouds(o) for o in s], cfg.workers) for s in out.diversity_sets
                if len(s) >= 2]
        res["diversity"] = float(np.mean(divs)) if divs else None
        res["diversity_per_prompt"] = divs
    if cfg.validity and out.urdfs:
        from .validity import validity
        paths = [u for u in out.urdfs if u is not None]
        objs = [o for u, o in zip(out.urdfs, out.objects) if u is not None]
        v = validity(paths, objs) if paths else None
        n_total = len(out.urdfs)
        res["validity"] = (sum(v.valid) / n_total) if v else 0.0   # failures count as invalid
        res["validity_detail"] = v.to_json() if v else {}
    if out.timings:
        stages = sorted({k for t in out.timings for k in t})
        res["timings_median"] = {s: float(np.median([t[s] for t in out.timings if s in t]))
                                 for s in stages}
    res.update(out.extra)
    res["score_seconds"] = time.perf_counter() - t0
    return res
