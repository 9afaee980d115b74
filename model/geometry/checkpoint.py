"""Shape-prior checkpoints (kinds ``sdf`` and ``prior``) in the one format of
``model.core.checkpoint``: the common header plus ``config`` (asdict of SDFConfig /
PriorConfig), ``state_dict``, ``extra`` (prior: latent stats source, SDF config, retrieval
bank) and, in training checkpoints, ``optimizer`` / ``elapsed`` / ``history``.

``load_checkpoint(path, kind)`` rebuilds the network from the stored config alone.
"""
from __future__ import annotations

import os
import shlex
from dataclasses import asdict
from typing import Optional

import torch

from model.core.checkpoint import CheckpointError, CheckpointMeta, read_checkpoint as _read
from model.core.checkpoint import write_checkpoint
from model.core.state import half_state

from .config import PriorConfig, SDFConfig, config_from_dict

KINDS = {"sdf": ("SDFAutoEncoder", SDFConfig, "artformer train sdf"),
         "prior": ("ShapePrior", PriorConfig, "artformer train prior")}

__all__ = ["KINDS", "CheckpointError", "save_checkpoint", "read_checkpoint", "load_checkpoint"]


def _build(kind: str, cfg):
    if kind == "sdf":
        from .autoencoder import SDFAutoEncoder
        return SDFAutoEncoder(cfg)
    from .prior import ShapePrior
    return ShapePrior(cfg)


def save_checkpoint(path: os.PathLike, kind: str, model: torch.nn.Module, *, data_version: str = "",
                    seed: int = 0, argv: Optional[list[str]] = None, step: int = 0,
                    extra: Optional[dict] = None, optimizer: Optional[torch.optim.Optimizer] = None,
                    train_cfg=None, half: bool = False, command: str = "",
                    device: str = "cpu", run: Optional[dict] = None) -> None:
    """Write atomically (temp file + rename). ``half`` stores float tensors as fp16; ``run``:
    more resume state (elapsed seconds, history)."""
    if kind not in KINDS:
        raise ValueError(f"unknown checkpoint kind {kind!r}")
    state = model.state_dict()
    state = half_state(state) if half else {k: v.detach().cpu().clone() for k, v in state.items()}
    meta = CheckpointMeta(kind=kind, data_version=str(data_version), seed=int(seed),
                          command=command or (shlex.join(argv) if argv else ""), step=int(step),
                          device=device,
                          train_config=asdict(train_cfg) if train_cfg is not None else {})
    payload = {"config": asdict(model.cfg), "state_dict": state, "extra": extra or {},
               **(run or {})}
    if optimizer is not None:
        payload["optimizer"] = optimizer.state_dict()
    write_checkpoint(path, meta, payload)


def read_checkpoint(path: os.PathLike, kind: str) -> dict:
    """Load and check the raw dict (map_location cpu)."""
    if kind not in KINDS:
        raise ValueError(f"unknown checkpoint kind {kind!r}")
    how = f"re-run `{KINDS[kind][2]}`"
    try:
        return _read(path, kind, how=how)
    except CheckpointError as e:
        if "one is needed" in str(e):
            raise CheckpointError(f"{e} (did you swap --sdf and --prior?)") from None
        raise


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
    state = {k: v.float() if v.is_floating_point() else v for k, v in ckpt["state_dict"].items()}
    missing, unexpected = model.load_state_dict(state, strict=False)
    if missing or unexpected:
        raise CheckpointError(f"{path}: weights do not match the {what} built from its config "
                              f"(missing {list(missing)[:5]}, unexpected {list(unexpected)[:5]}); "
                              f"the file is damaged or from another version — re-run `{how}`")
    model.eval()
    return model, ckpt
