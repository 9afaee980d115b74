"""Free-form prompt alignment of `artformer eval`: summaries by category, by the number of
asked-for parts and by spatial fact, and ``--freeform-only`` (the free-form set's structures
decoded and scored without shapes)."""
from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass
from typing import Optional

from . import alignment as al

log = logging.getLogger(__name__)


PART_BUCKETS: tuple[tuple[int, Optional[int]], ...] = ((1, 3), (4, 7), (8, None))


def part_bucket(n: int) -> str:
    """'1-3' / '4-7' / '8+' (0 asked-for parts counts as '1-3')."""
    for lo, hi in PART_BUCKETS:
        if hi is None or n <= hi:
            return f"{lo}+" if hi is None else f"{lo}-{hi}"
    raise AssertionError("unreachable")


def _annotations(path) -> list:
    """(prompt, ExpectedStructure) of an annotated free-form file; [] when it has none."""
    from model.data.prompt_parse import read_annotated_prompts
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
            "| arrangement | position | size |\n|---|---|---|---|---|---|---|---|---|---|")
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
    prompt_structure: bool = True             # hold the parts the prompt states (the product)
    limit: Optional[int] = None
    progress: bool = False


def freeform_alignment(cfg: FreeformConfig) -> dict:
    """Decode one tree per prompt and seed exactly as the product decodes it
    (``Generator.decode_trees``: the generator's temperature, plan guidance, node limits,
    the parts the prompt states held unless ``prompt_structure`` is off, and layout
    refinement; no shapes, which do not change the structure) and score it against the
    prompt's hand-written structure."""
    from model.data.prompt_parse import read_annotated_prompts
    from model.pipeline.api import GenerationConfig
    from model.pipeline.generator import Generator

    t0 = time.perf_counter()
    items = read_annotated_prompts(cfg.prompts_file)
    if cfg.limit:
        items = items[:cfg.limit]
    if cfg.seeds < 1:
        raise ValueError(f"seeds must be >= 1, got {cfg.seeds}")
    g = GenerationConfig(checkpoint=None if cfg.checkpoint in (None, "", "shipped")
                         else cfg.checkpoint, prompt_structure=cfg.prompt_structure)
    if cfg.structure_temperature is not None:
        g.structure_temperature = cfg.structure_temperature
    if cfg.follow_plan is not None:
        g.follow_plan = ("text",) if cfg.follow_plan else ()
    gen = Generator.load(g)
    path = gen.loaded.paths.get("transformer") or cfg.checkpoint or "shipped"
    jobs = [(k, s) for s in range(cfg.seeds) for k in range(len(items))]
    it = jobs
    if cfg.progress:
        from tqdm import tqdm
        it = tqdm(jobs, desc="free-form structures")
    expected, results, rows = [], [], []
    for k, s in it:
        prompt, exp = items[k]
        tree = gen.decode_trees(prompt, seed=cfg.seed + s)[0][0]
        obj = gen.layout(tree, refine=cfg.refine)
        r = al.check_alignment(exp, al.GeneratedStructure.from_object(obj))
        expected.append(exp)
        results.append(r)
        rows.append({"prompt": prompt, "seed": cfg.seed + s, "expected": exp.to_line(),
                     "aligned": r.aligned, "spatial_ok": r.spatial_ok, "failures": r.failures})
    bd = freeform_breakdown(expected, results)
    return {"config": asdict(cfg), "checkpoint": str(path), "n_prompts": len(items),
            "structure_temperature": g.structure_temperature,
            "follow_plan": "text" in g.follow_plan, "breakdown": bd,
            "table": freeform_table(bd), "rows": rows, "seconds": time.perf_counter() - t0}
