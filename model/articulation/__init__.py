"""Articulation transformer (DESIGN §5): network, training, iterative decoding, editing.

Public API (stable; see docs/articulation.md):

    from model.articulation import ArticulationModel, DecodedTree
    am = ArticulationModel.load(path)                  # one loader, clear errors
    tokens, mask = am.encode_text(texts)               # (B, L, 384), (B, L)
    trees = am.decode(tokens, mask, seed=0, max_nodes=32, max_depth=4, max_children=16,
                      temperature=1.0, modality="text", keep=None)   # -> list[DecodedTree]

Configs: ``ArticulationConfig``, ``TrainConfig``, ``PRESETS``, ``preset(name, ablation)``.
Heavy modules (torch networks) are imported on first attribute access.
"""
from __future__ import annotations

import importlib

_LAZY = {
    "ArticulationConfig": "config", "TrainConfig": "config", "PRESETS": "config",
    "preset": "config", "ABLATIONS": "config",
    "ArticulationTransformer": "network", "TreeBatch": "network", "Targets": "network",
    "ArticulationModel": "model", "DecodedTree": "trees",
    "read_checkpoint": "checkpoint", "save_checkpoint": "checkpoint",
    "build_network": "checkpoint", "CheckpointError": "checkpoint",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
