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
"""
from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from model.core import ArticulatedObject

from . import alignment as al
from .distribution import set_metrics
from .instantiation import diversity as diversity_of
from .instantiation import id_matrix, posed_clouds
from .por import part_overlap_ratio
from .reference import Dataset, Retriever, freeform_prompts, pick_description

log = logging.getLogger(__name__)

PUBLISHED = {  # DESIGN §7 anchors (PartNet-Mobility, not our data)
    "ArtFormer (paper)": {"por": 0.709e-2, "mmd": 0.0292, "cov": 0.5213, "nna": 0.5266},
    "CAGE (paper)": {"por": 0.251e-2},
}


@dataclass
class EvalConfig:
    data: str                                   # prepared dataset root
    out: str = "eval_out"
    checkpoint: Optional[str] = None            # None = shipped model
    split: str = "test"
    n: int = 20                                 # test prompts (records)
    n_freeform: Optional[int] = None            # None = all shipped free-form prompts
    freeform_file: Optional[str] = None
    seed: int = 0
    points: int = 4096                          # ID surface points per posed object
    poses: int = 10                             # ID instantiations per object
    por_states: int = 10
    diversity_prompts: int = 4                  # prompts sampled several times
    diversity_samples: int = 4
    ablations: dict = field(default_factory=dict)   # name -> checkpoint folder
    model: bool = True                          # False: score the baselines only
    part_retrieval: bool = True                 # the "Ours-PR" row (geometry = retrieve)
    retrieval: bool = True
    train_floor: bool = True
    validity: bool = True
    workers: int = 1                            # KD-tree query threads
    collision: str = "pipeline"                 # URDF collision geometry: "pipeline" (the
                                                # generator's own export), auto|hull|vhacd|none
    steps: Optional[int] = None                 # generation overrides (None = config default)
    resolution: Optional[int] = None
    structure_temperature: Optional[float] = None   # tree decoding (None = product default)
    follow_plan: Optional[bool] = None              # plan-guided END for text (None = default)
    text_encoder: str = "all-minilm-l6-v2"
    plots: bool = True
    progress: bool = False


# --------------------------------------------------------------------------------------------
# one method's objects
# --------------------------------------------------------------------------------------------
@dataclass
class MethodOutput:
    name: str
    objects: list                      # per prompt: ArticulatedObject or None (failed)
    urdfs: list                        # per prompt: URDF path or None
    prompts: list                      # per prompt text, or None (no prompt: train floor)
    timings: list = field(default_factory=list)
    errors: list = field(default_factory=list)
    diversity_sets: list = field(default_factory=list)   # list of lists of objects
    extra: dict = field(default_factory=dict)            # copied into the results row


def _export(obj: ArticulatedObject, folder: Path, collision: str = "hull") -> Optional[str]:
    """Write a URDF without preview. ``collision`` "pipeline" = the exporter's default
    (V-HACD for non-convex parts, seconds a part); "hull" = one convex hull per part (validity
    checks loading and joint motion, which the collision detail does not change)."""
    from model.export.urdf import CollisionConfig, export_object
    cc = CollisionConfig() if collision == "pipeline" else CollisionConfig(method=collision)
    try:
        return export_object(obj, folder, preview=False, collision=cc).urdf_path
    except Exception as e:
        log.warning("export of %s failed: %s", obj.name, e)
        return None


def generate_method(name: str, checkpoint: Optional[str], prompts: list[str], cfg: EvalConfig,
                    out_dir: Path, loader: Optional[Callable] = None,
                    geometry: str = "generate") -> Optional[MethodOutput]:
    """Run the generator on every prompt (seed = cfg.seed + i), export each result.

    ``geometry="retrieve"`` is the paper's "Ours-PR" row (each part's latent replaced by the
    nearest training latent); None when the checkpoint has no retrieval bank."""
    from model.pipeline.api import GenerationConfig
    gcfg = GenerationConfig(checkpoint=checkpoint, geometry=geometry)
    if cfg.steps is not None:
        gcfg.steps = cfg.steps
    if cfg.resolution is not None:
        gcfg.resolution = cfg.resolution
    if cfg.structure_temperature is not None:
        gcfg.structure_temperature = cfg.structure_temperature
    if cfg.follow_plan is not None:
        gcfg.follow_plan = ("text",) if cfg.follow_plan else ()
    if loader is None:
        from model.pipeline import Generator
        loader = Generator.load
    gen = loader(gcfg)
    if geometry == "retrieve":
        bank = getattr(getattr(gen, "shape", None), "bank", None) or {}
        if bank.get("latents") is None:
            log.warning("%s: the checkpoint's prior has no retrieval bank; row skipped", name)
            return None
    res = MethodOutput(name, [], [], list(prompts))
    it = list(enumerate(prompts))
    if cfg.progress:
        from tqdm import tqdm
        it = tqdm(it, desc=f"generate [{name}]")
    for i, prompt in it:
        try:
            g = gen.generate(prompt, seed=cfg.seed + i, samples=1)[0]
        except Exception as e:
            log.warning("[%s] prompt %d failed: %s", name, i, e)
            res.objects.append(None)
            res.urdfs.append(None)
            res.errors.append(f"prompt {i}: {type(e).__name__}: {e}")
            continue
        res.objects.append(g.obj)
        res.timings.append(dict(g.timings))
        urdf = None
        if cfg.validity:
            folder = out_dir / _slug(name) / f"{i:03d}"   # no spaces: file:// URIs in URDFs
            try:
                if cfg.collision == "pipeline":
                    urdf = gen.export(g, str(folder), preview=False).urdf_path
                else:
                    urdf = _export(g.obj, folder, cfg.collision)
            except Exception as e:
                res.errors.append(f"export {i}: {type(e).__name__}: {e}")
        res.urdfs.append(urdf)
    for i, prompt in enumerate(prompts[:cfg.diversity_prompts]):
        if cfg.diversity_samples < 2:
            break
        try:
            samples = gen.generate(prompt, seed=cfg.seed + 1000 + i, samples=cfg.diversity_samples)
            res.diversity_sets.append([s.obj for s in samples])
        except Exception as e:
            res.errors.append(f"diversity {i}: {type(e).__name__}: {e}")
    return res


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in text).strip("_") or "row"


def assemble_checkpoint(path: str, base: Optional[str], folder: Path) -> str:
    """A checkpoint folder the Generator can load for an ablation given as a transformer file
    (or a folder with only some stages): missing stages are linked from ``base`` (the
    checkpoint under test; None = the shipped weights)."""
    from model.pipeline.generator import STAGES, WEIGHTS_DIR
    p = Path(path)
    have: dict[str, Path] = {}
    if p.is_file():
        have["transformer"] = p
    elif p.is_dir():
        for stage in STAGES:
            exact = p / f"{stage}.pt"
            cands = [exact] if exact.exists() else sorted(p.glob(f"{stage}_*.pt"))
            if cands:
                have[stage] = cands[0]
    else:
        raise FileNotFoundError(f"ablation checkpoint {path} does not exist")
    if all(s in have for s in STAGES[:3]):
        return str(p)
    if "transformer" not in have:
        raise FileNotFoundError(f"{path} holds no transformer checkpoint")
    src = Path(base) if base else WEIGHTS_DIR
    folder.mkdir(parents=True, exist_ok=True)
    for stage in STAGES:
        f = have.get(stage)
        if f is None:
            exact = src / f"{stage}.pt"
            cands = [exact] if exact.exists() else sorted(src.glob(f"{stage}_*.pt"))
            f = cands[0] if cands else None
        link = folder / f"{stage}.pt"
        if link.is_symlink() or link.exists():
            link.unlink()
        if f is not None:
            link.symlink_to(Path(f).resolve())
    return str(folder)


# --------------------------------------------------------------------------------------------
# scoring
# --------------------------------------------------------------------------------------------
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


# --------------------------------------------------------------------------------------------
# free-form alignment by category, by part count and by spatial fact
# --------------------------------------------------------------------------------------------
PART_BUCKETS: tuple[tuple[int, Optional[int]], ...] = ((1, 3), (4, 7), (8, None))


def part_bucket(n: int) -> str:
    """'1-3' / '4-7' / '8+' (0 asked-for parts counts as '1-3')."""
    for lo, hi in PART_BUCKETS:
        if hi is None or n <= hi:
            return f"{lo}+" if hi is None else f"{lo}-{hi}"
    raise AssertionError("unreachable")


def _annotations(path) -> list:
    """(prompt, ExpectedStructure) of an annotated free-form file; [] when it has none."""
    from .prompt_parse import read_annotated_prompts
    try:
        return read_annotated_prompts(path)
    except ValueError:
        log.warning("%s has no complete '#>' structure lines: free-form prompts are scored "
                    "against their parsed structure", path or "prompts_freeform.txt")
        return []


def freeform_breakdown(expected: list, results: list) -> dict:
    """Alignment summaries (model.metrics.alignment.summarise) over all prompts, per category,
    per bucket of asked-for parts (:data:`PART_BUCKETS`), with the spatial-fact shares."""
    if len(expected) != len(results):
        raise ValueError(f"{len(expected)} expected structures for {len(results)} results")
    by_cat: dict[str, list] = {}
    by_parts: dict[str, list] = {}
    for e, r in zip(expected, results):
        by_cat.setdefault(e.category or "-", []).append(r)
        by_parts.setdefault(part_bucket(e.num_parts), []).append(r)
    order = [f"{lo}+" if hi is None else f"{lo}-{hi}" for lo, hi in PART_BUCKETS]
    return {"all": al.summarise(results),
            "by_category": {c: al.summarise(v) for c, v in sorted(by_cat.items())},
            "by_parts": {b: al.summarise(by_parts[b]) for b in order if b in by_parts}}


def freeform_table(bd: dict) -> str:
    """Markdown table of :func:`freeform_breakdown`: alignment (count / label / joint checks)
    and spatial-fact accuracy per row, each with the number of prompts behind it."""
    def pct(v, n):
        return "–" if v is None or not n else f"{100 * v:.1f} % ({n})"

    head = ("| prompts | alignment | counts | joints | spatial facts | hinge side | opening "
            "| arrangement | position |\n|---|---|---|---|---|---|---|---|---|")
    lines = [head]

    def row(name, s):
        lines.append(f"| {name} | {pct(s['alignment'], s['n_checked'])} "
                     f"| {pct(s['counts'], s['n_checked'])} | {pct(s['joints'], s['n_checked'])} "
                     f"| {pct(s['spatial'], s['n_spatial'])} "
                     + " ".join(f"| {pct(s['spatial_' + k], s['n_spatial_' + k])}"
                                for k in al.SPATIAL_KIND_NAMES) + " |")

    row("**all**", bd["all"])
    for c, s in bd["by_category"].items():
        row(c, s)
    for b, s in bd["by_parts"].items():
        row(f"{b} parts asked", s)
    return "\n".join(lines)


@dataclass
class FreeformConfig:
    """``artformer eval --freeform-only``: structure of the free-form prompts, decoded only."""
    checkpoint: Optional[str] = None          # folder (None / "shipped": the packaged model)
    prompts_file: Optional[str] = None        # annotated file (default: the shipped one)
    seeds: int = 1                            # seeds 0..seeds-1 per prompt (+ seed)
    seed: int = 0
    structure_temperature: Optional[float] = None   # None: the product default
    follow_plan: Optional[bool] = None
    refine: bool = True                       # the product's layout refinement before scoring
    limit: Optional[int] = None
    progress: bool = False


def freeform_alignment(cfg: FreeformConfig) -> dict:
    """Decode one tree per prompt and seed with the product's decoding settings (the
    generator's temperature, plan guidance, node limits and layout refinement; no shapes, which
    do not change the structure) and score it against the prompt's hand-written structure."""
    import torch

    from model.articulation import ArticulationModel
    from model.core.runtime import torch_threads
    from model.pipeline.api import GenerationConfig
    from model.pipeline.generator import find_checkpoints

    from .prompt_parse import read_annotated_prompts

    t0 = time.perf_counter()
    items = read_annotated_prompts(cfg.prompts_file)
    if cfg.limit:
        items = items[:cfg.limit]
    if cfg.seeds < 1:
        raise ValueError(f"seeds must be >= 1, got {cfg.seeds}")
    g = GenerationConfig()
    temp = g.structure_temperature if cfg.structure_temperature is None else cfg.structure_temperature
    plan = ("text" in g.follow_plan) if cfg.follow_plan is None else bool(cfg.follow_plan)
    ckpt = None if cfg.checkpoint in (None, "", "shipped") else cfg.checkpoint
    path = find_checkpoints(ckpt)["transformer"]
    am = ArticulationModel.load(path)
    jobs = [(k, s) for s in range(cfg.seeds) for k in range(len(items))]
    it = jobs
    if cfg.progress:
        from tqdm import tqdm
        it = tqdm(jobs, desc="free-form structures")
    cond_cache: dict[int, tuple] = {}
    expected, results, rows = [], [], []
    for k, s in it:
        prompt, exp = items[k]
        with torch_threads(g.token_threads), torch.no_grad():
            if k not in cond_cache:
                cond_cache[k] = am.encode_text([prompt])
            cond, mask = cond_cache[k]
            tree = am.decode(cond, mask, seed=cfg.seed + s, max_nodes=g.max_nodes,
                             max_depth=g.max_depth, max_children=g.max_children,
                             modality="text", temperature=temp, follow_plan=plan)[0]
        obj = tree.to_object()
        if cfg.refine:
            from model.refine import refine_layout
            refine_layout(obj)
        r = al.check_alignment(exp, al.GeneratedStructure.from_object(obj))
        expected.append(exp)
        results.append(r)
        rows.append({"prompt": prompt, "seed": cfg.seed + s, "expected": exp.to_line(),
                     "aligned": r.aligned, "spatial_ok": r.spatial_ok, "failures": r.failures})
    bd = freeform_breakdown(expected, results)
    return {"config": asdict(cfg), "checkpoint": str(path), "n_prompts": len(items),
            "structure_temperature": temp, "follow_plan": plan, "breakdown": bd,
            "table": freeform_table(bd), "rows": rows, "seconds": time.perf_counter() - t0}


# --------------------------------------------------------------------------------------------
# the run
# --------------------------------------------------------------------------------------------
def run_eval(cfg: EvalConfig, loader: Optional[Callable] = None) -> dict:
    """Everything ``artformer eval`` does; returns the results dict (also written to disk).

    ``loader``: how to build a generator from a ``GenerationConfig`` (default
    ``Generator.load``)."""
    t_start = time.perf_counter()
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(cfg.seed)
    data = Dataset.open(cfg.data)
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
    prompts = test_prompts + free
    n_test = len(test_prompts)
    log.info("eval: %d test prompts + %d free-form prompts", n_test, len(free))

    clouds = CloudCache(cfg)
    cr = [clouds(o) for o in refs]
    D_rr = id_matrix(cr, workers=cfg.workers, progress=cfg.progress)

    # Each method is generated, scored and dropped before the next one: a generated object
    # with dense marching-cubes meshes holds ~25 MB, and six rows of 68 objects kept together
    # reached 22 GB.
    ckpt = None if cfg.checkpoint in (None, "", "shipped") else cfg.checkpoint
    skipped = []
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

    from model.core.runtime import release_free_memory
    rows = []
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
    gt = MethodOutput("test (GT)", refs, [], test_prompts)
    gt_row = score_method(gt, [], None, clouds, EvalConfig(**{**asdict(cfg), "validity": False}),
                          n_test)
    rows.append(gt_row)

    results = {"config": asdict(cfg), "n_test": n_test, "n_freeform": len(free),
               "test_ids": test_ids, "prompts": prompts, "rows": rows,
               "published": PUBLISHED, "skipped_rows": skipped,
               "seconds": time.perf_counter() - t_start,
               "id_points": cfg.points, "id_poses": cfg.poses}
    from model.data.format import atomic_write_json
    atomic_write_json(out / "results.json", _jsonable(results))
    from .report import results_markdown, results_plots
    md = results_markdown(results)
    (out / "results.md").write_text(md)
    if cfg.plots:
        results["figures"] = results_plots(results, out)
        atomic_write_json(out / "results.json", _jsonable(results))
    return results


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
