"""The one checkpoint format and loader of the shape prior (STYLE.md #7).

A checkpoint is a ``torch.save``d dict::

    {"format": 1, "kind": "sdf" | "prior", "config": asdict(config), "model": state_dict,
     "data_version": str, "seed": int, "argv": [str], "step": int,
     "extra": {...}                      # prior: latent stats / retrieval bank
     "optimizer": state_dict, "train": asdict(TrainConfig)}   # only in training checkpoints

``load_checkpoint(path, kind)`` rebuilds the network from the stored config alone.
"""
from __future__ import annotations

import io
import os
from dataclasses import asdict
from pathlib import Path
from typing import Any, Optional

import torch

from model.core.state import half_state

from .config import PriorConfig, SDFConfig, config_from_dict

CKPT_FORMAT = 1
KINDS = {"sdf": ("SDFAutoEncoder", SDFConfig, "artformer train sdf"),
         "prior": ("ShapePrior", PriorConfig, "artformer train prior")}


class CheckpointError(RuntimeError):
    """A checkpoint is missing, corrupt or does not match; the message says what to do."""


def _build(kind: str, cfg):
    if kind == "sdf":
        from .autoencoder import SDFAutoEncoder
        return SDFAutoEncoder(cfg)
    from .prior import ShapePrior
    return ShapePrior(cfg)


def save_checkpoint(path: os.PathLike, kind: str, model: torch.nn.Module, *, data_version: str = "",
                    seed: int = 0, argv: Optional[list[str]] = None, step: int = 0,
                    extra: Optional[dict] = None, optimizer: Optional[torch.optim.Optimizer] = None,
                    train_cfg=None, half: bool = False) -> None:
    """Write atomically (temp file + rename). ``half`` stores float tensors as fp16."""
    if kind not in KINDS:
        raise ValueError(f"unknown checkpoint kind {kind!r}")
    state = model.state_dict()
    state = half_state(state) if half else {k: v.detach().cpu().clone() for k, v in state.items()}
    ckpt: dict[str, Any] = {"format": CKPT_FORMAT, "kind": kind, "config": asdict(model.cfg),
                            "model": state, "data_version": str(data_version), "seed": int(seed),
                            "argv": list(argv or []), "step": int(step), "extra": extra or {}}
    if optimizer is not None:
        ckpt["optimizer"] = optimizer.state_dict()
    if train_cfg is not None:
        ckpt["train"] = asdict(train_cfg)
    buf = io.BytesIO()
    torch.save(ckpt, buf)
    from model.data.format import atomic_write_bytes
    atomic_write_bytes(path, buf.getvalue())


def read_checkpoint(path: os.PathLike, kind: str) -> dict:
    """Load and check the raw dict (map_location cpu)."""
    path = Path(path)
    what, _, how = KINDS[kind]
    if not path.is_file():
        raise CheckpointError(f"{kind} checkpoint {path} does not exist; train one with "
                              f"`{how}` or pass the path of an existing one")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:   # truncated / not a torch file / pickled foreign objects
        raise CheckpointError(f"{path} is corrupt or not an artformer checkpoint ({type(e).__name__}: "
                              f"{str(e).splitlines()[0][:200]}); delete it and re-run `{how}`, "
                              f"or restore the shipped file with `git checkout -- model/weights`") from None
    if not isinstance(ckpt, dict) or "kind" not in ckpt or "config" not in ckpt or "model" not in ckpt:
        raise CheckpointError(f"{path} is not an artformer geometry checkpoint (no kind/config/model "
                              f"entries); re-run `{how}`")
    if ckpt["kind"] != kind:
        raise CheckpointError(f"{path} is a {ckpt['kind']!r} checkpoint but a {kind!r} one is needed "
                              f"(did you swap --sdf and --prior?)")
    if ckpt.get("format") != CKPT_FORMAT:
        raise CheckpointError(f"{path}: checkpoint format {ckpt.get('format')} != {CKPT_FORMAT}; "
                              f"re-run `{how}`")
    return ckpt


def load_checkpoint(path: os.PathLike, kind: str, *, expect_config=None):
    """-> (model in eval mode, float32, on cpu; the raw checkpoint dict).

    ``expect_config``: a config the stored one must equal (e.g. when resuming a preset).
    """
    ckpt = read_checkpoint(path, kind)
    what, cls, how = KINDS[kind]
    try:
        cfg = config_from_dict(cls, ckpt["config"])
    except (TypeError, ValueError) as e:
        raise CheckpointError(f"{path}: stored {cls.__name__} does not fit this code ({e}); "
                              f"re-run `{how}`") from None
    if expect_config is not None and asdict(expect_config) != asdict(cfg):
        diff = {k: (v, asdict(expect_config)[k]) for k, v in asdict(cfg).items()
                if asdict(expect_config)[k] != v}
        raise CheckpointError(f"{path}: its {cls.__name__} differs from the requested one "
                              f"(stored vs requested: {diff}); use a fresh --out folder or the "
                              f"preset the checkpoint was trained with")
    model = _build(kind, cfg)
    state = {k: v.float() if v.is_floating_point() else v for k, v in ckpt["model"].items()}
    missing, unexpected = model.load_state_dict(state, strict=False)
    if missing or unexpected:
        raise CheckpointError(f"{path}: weights do not match the {what} built from its config "
                              f"(missing {list(missing)[:5]}, unexpected {list(unexpected)[:5]}); "
                              f"the file is damaged or from another version — re-run `{how}`")
    model.eval()
    return model, ckpt
