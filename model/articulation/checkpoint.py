"""Articulation-transformer checkpoints (text and image models) in the one format of
``model.core.checkpoint``.

Kind ``articulation``; besides the common header (data_version, seed, command, step, device,
recipe, train_config, prior) it holds ``config`` (asdict(ArticulationConfig)), ``state_dict``,
``stats`` (token / z / c_s normalisation), ``label_table`` (c_s of every training (category,
label) pair, for decoding labels), ``text_encoder`` and, in run checkpoints only,
``optimizer`` / ``elapsed`` / ``history`` for resuming. Image models add ``condition =
"image"``, ``image_encoder``, ``renders`` and optional ``count_head`` / ``count_tokens``.
"""
from __future__ import annotations

import logging
import os
from dataclasses import asdict
from pathlib import Path
from typing import Optional, Sequence, Union

from model.core.checkpoint import (FORMAT, CheckpointError, CheckpointMeta, read_checkpoint as
                                   _read, write_checkpoint)
from model.core.state import half_state

from .config import ArticulationConfig
from .network import ArticulationTransformer

log = logging.getLogger(__name__)

KIND = "articulation"
HOW = ("train one with `artformer train transformer` or use the shipped "
       "model/weights/transformer_small.pt")
_HEADER = {"data_version", "seed", "command", "step", "device", "recipe", "train_config", "prior"}

__all__ = ["KIND", "FORMAT", "CheckpointError", "save_checkpoint", "read_checkpoint",
           "build_network", "save_dict"]


def save_checkpoint(path: os.PathLike, net: ArticulationTransformer, *, stats: dict,
                    label_table: dict, text_encoder: str, data_version: str, seed: int,
                    command: str, step: int, train_config: dict | None = None,
                    extra: dict | None = None, half: bool = False, prior: str = "",
                    device: str = "cpu", recipe: Optional[list] = None) -> None:
    """Atomic write. ``half`` stores floating weights as fp16 (the shipped file); ``prior``:
    the fingerprint of the shape prior the targets came from."""
    sd = net.state_dict()
    sd = half_state(sd) if half else {k: v.detach().cpu().clone() for k, v in sd.items()}
    extra = dict(extra or {})
    meta = CheckpointMeta(kind=KIND, data_version=str(data_version), seed=int(seed),
                          command=command, step=int(step), device=device,
                          recipe=list(recipe or extra.pop("recipe", [])),
                          train_config=dict(train_config or {}), prior=prior or extra.pop("prior", ""))
    extra.pop("prior", None)
    write_checkpoint(path, meta, {"config": asdict(net.cfg), "state_dict": sd, "stats": stats,
                                  "label_table": label_table, "text_encoder": text_encoder,
                                  **extra})


def save_dict(path: os.PathLike, ck: dict) -> None:
    """Write a checkpoint dict as read by ``read_checkpoint`` (e.g. with a head added)."""
    meta = CheckpointMeta.of({**ck, "kind": KIND})
    write_checkpoint(path, meta, {k: v for k, v in ck.items()
                                  if k not in _HEADER | {"kind", "format"}})


def read_checkpoint(path: os.PathLike, prior: Union[str, Sequence[str], None] = None) -> dict:
    """Load and check a text or image transformer checkpoint (a file, or a run folder with
    transformer.pt / last.pt); ``prior``: see model.core.checkpoint.check_prior."""
    path = Path(path)
    if path.is_dir():
        for name in ("transformer.pt", "last.pt", "transformer_small.pt"):
            if (path / name).exists():
                path = path / name
                break
        else:
            raise CheckpointError(f"{path} is a folder without transformer.pt / last.pt; "
                                  f"train one with `artformer train transformer --out {path}`")
    if not path.exists():
        raise CheckpointError(f"no articulation checkpoint at {path}; {HOW}")
    try:
        return _read(path, KIND, how=HOW, prior=prior)
    except CheckpointError as e:
        if "one is needed" in str(e):    # keep the wording users grep for
            raise CheckpointError(f"{path} is not an articulation-transformer checkpoint "
                                  f"({e}); pass the transformer's .pt file") from None
        raise


def build_network(ckpt: dict) -> ArticulationTransformer:
    """Rebuild the network of a checkpoint dict, weights in fp32, eval mode."""
    try:
        cfg = ArticulationConfig.from_dict(ckpt["config"])
    except (TypeError, ValueError, KeyError) as e:
        raise CheckpointError(f"the checkpoint's ArticulationConfig does not fit this code "
                              f"({e}); retrain with this version") from None
    net = ArticulationTransformer(cfg)
    sd = {k: v.float() if v.is_floating_point() else v for k, v in ckpt["state_dict"].items()}
    try:
        missing, unexpected = net.load_state_dict(sd, strict=False)
    except RuntimeError as e:                  # a tensor of another shape than the config's
        raise CheckpointError(f"checkpoint weights do not fit its config: {e}") from e
    if missing or unexpected:
        raise CheckpointError(f"checkpoint weights do not fit its config: missing {missing[:5]}, "
                              f"unexpected {unexpected[:5]}")
    return net.eval()
