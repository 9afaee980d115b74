"""The one checkpoint loader/saver of the articulation transformer (STYLE §7).

A checkpoint is a dict with ``kind == "articulation"``, ``format``, ``config``
(asdict(ArticulationConfig)), ``train_config``, ``state_dict``, ``stats`` (token / z
normalisation), ``label_table`` (c_s of every training (category, label) pair, for decoding
labels), ``text_encoder``, ``data_version``, ``seed``, ``command``, ``step`` and, in run
checkpoints only, ``optimizer`` / ``scheduler`` / ``rng`` for resuming.
"""
from __future__ import annotations

import io
import logging
import os
from dataclasses import asdict
from pathlib import Path

import torch

from model.core.state import half_state
from model.data.format import atomic_write_bytes

from .config import ArticulationConfig
from .network import ArticulationTransformer

log = logging.getLogger(__name__)

KIND = "articulation"
FORMAT = 1


class CheckpointError(RuntimeError):
    """A checkpoint is missing or is not an articulation-transformer checkpoint."""


def save_checkpoint(path: os.PathLike, net: ArticulationTransformer, *, stats: dict,
                    label_table: dict, text_encoder: str, data_version: str, seed: int,
                    command: str, step: int, train_config: dict | None = None,
                    extra: dict | None = None, half: bool = False) -> None:
    """Atomic write. ``half`` stores floating weights as fp16 (the shipped file)."""
    sd = net.state_dict()
    if half:
        sd = half_state(sd)
    ckpt = {"kind": KIND, "format": FORMAT, "config": asdict(net.cfg),
            "train_config": train_config or {}, "state_dict": sd, "stats": stats,
            "label_table": label_table, "text_encoder": text_encoder,
            "data_version": data_version, "seed": seed, "command": command, "step": step}
    ckpt.update(extra or {})
    buf = io.BytesIO()
    torch.save(ckpt, buf)
    atomic_write_bytes(path, buf.getvalue())


def read_checkpoint(path: os.PathLike) -> dict:
    """Load and check a checkpoint dict (map_location cpu); clear errors on misuse."""
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
        raise CheckpointError(f"no articulation checkpoint at {path}; train one with "
                              f"`artformer train transformer` or use the shipped "
                              f"model/weights/transformer_small.pt")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as e:  # noqa: BLE001 - report any unpickling problem the same way
        raise CheckpointError(f"{path} is not a readable torch checkpoint ({e})") from e
    if not isinstance(ckpt, dict) or ckpt.get("kind") != KIND:
        kind = ckpt.get("kind") if isinstance(ckpt, dict) else type(ckpt).__name__
        raise CheckpointError(f"{path} is not an articulation-transformer checkpoint "
                              f"(kind {kind!r}); pass the transformer's .pt file")
    if ckpt.get("format") != FORMAT:
        raise CheckpointError(f"{path}: checkpoint format {ckpt.get('format')} != {FORMAT}; "
                              f"retrain with this code version")
    return ckpt


def build_network(ckpt: dict) -> ArticulationTransformer:
    """Rebuild the network of a checkpoint dict, weights in fp32, eval mode."""
    cfg = ArticulationConfig.from_dict(ckpt["config"])
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
