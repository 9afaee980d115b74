"""Shape prior (DESIGN §4): tri-plane SDF auto-encoder, codebook diffusion prior, fast meshing
and part retrieval. Heavy submodules (torch networks, trimesh, skimage) load on first use.

Public API (stable; see docs/geometry.md): ``ShapeModel`` (``load``, ``code_distribution``,
``semantic_condition``, ``sample_from_logits``, ``decode_meshes``, ``retrieve``),
``load_shape_model``, ``fit_to_bbox``, ``label_text``, ``PRESETS`` / ``get_preset``.
"""
from __future__ import annotations

import importlib

_LAZY = {
    "ShapeModel": "api", "load_shape_model": "api", "DEFAULT_SDF": "api", "DEFAULT_PRIOR": "api",
    "fit_to_bbox": "meshing", "mesh_sdf_batch": "meshing", "MeshResult": "meshing",
    "label_text": "data", "PRESETS": "config", "get_preset": "config",
    "SDFConfig": "config", "PriorConfig": "config", "TrainConfig": "config",
    "SDFAutoEncoder": "autoencoder", "ShapePrior": "prior", "Denoiser": "prior",
    "Diffusion": "diffusion", "load_checkpoint": "checkpoint", "CheckpointError": "checkpoint",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
