"""The configuration of an `artformer eval` run (model.metrics.evaluate.run_eval)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional


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
