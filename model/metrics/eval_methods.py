"""One method's objects for `artformer eval`: a row of the results table generates (the
checkpoint under test, its ablations) or looks up (retrieval, the training floor) one object
per prompt, and each object is exported to a URDF for the validity check."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

from model.core import ArticulatedObject

from .eval_config import EvalConfig

log = logging.getLogger(__name__)


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
    from model.pipeline.checkpoints import STAGES, WEIGHTS_DIR
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
