"""Cached encoder features of the render set (computed once, reused by every training run).

The frozen EfficientNet-Lite0 trunk up to the input of its last MBConv block is run once over
every rendered view and stored as fp16 (K views × 192 × 7 × 7 per object, ~19 KB a view).
Training then runs only the cheap tail (last block + 1×1 head conv, ~50 MFLOP a view) per
step: frozen (no grad) or lightly fine-tuned. That keeps both options affordable on a CPU.
Multiscale tokens also need the 14×14 × 112 output of block 10 (``FINE_SPLIT``), cached the
same way in its own file (~44 KB a view).

    OUT/features/trunk<split>.pt   {"ids": [...], "feats": (N, K, C, H, W) fp16,
                                    "split": int, "render_version": int, "weights": str}
    OUT/features/trunk<split>-<tag>.pt   the same with a fine-tuned trunk (model.imaging.trunk;
                                    "weights" = the trunk's content hash) or another input
                                    size (tag "<weights>-448px": 2x-upsampled views, maps
                                    pooled to 7×7; ``feature_tag``)
"""
from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import torch

from model.core.files import atomic_torch_save

from .renders import load_render_manifest, rendered_ids, view_paths

log = logging.getLogger(__name__)

CACHE_SPLIT = 15        # trunk = stem + blocks 0..14; the cache serves trainable_blocks <= 1
IMAGENET = "imagenet"   # the tag of the packaged ImageNet weights


def feature_tag(encoder, trunk_tag: str = IMAGENET) -> str:
    """The cache tag of an encoder: its weights' tag, plus the input size unless 224 px
    (and where the finer map is pooled, unless before the last block)."""
    from model.encoders.image import IMAGE_SIZE, NUM_BLOCKS
    cfg = encoder.config
    if cfg.image_size == IMAGE_SIZE:
        return trunk_tag
    pool = "" if cfg.grid_pool_at == NUM_BLOCKS - 1 else f"-pool{cfg.grid_pool_at}"
    return f"{trunk_tag}-{cfg.image_size}px{pool}"


def encoder_cache_args(encoder, weights: str = IMAGENET) -> dict:
    """``build_feature_cache``'s ``encoder``/``tag`` for ``encoder`` carrying ``weights``
    (IMAGENET or a fine-tuned trunk's tag): none when its tag is the default cache's."""
    tag = feature_tag(encoder, weights)
    return {} if tag == IMAGENET else {"encoder": encoder, "tag": tag}


def cache_path(render_root: os.PathLike, split: int = CACHE_SPLIT, tag: str = IMAGENET) -> Path:
    """OUT/features/trunk<split>.pt for the ImageNet weights, trunk<split>-<tag>.pt for a
    fine-tuned trunk (model.imaging.trunk)."""
    name = f"trunk{split}" if tag == IMAGENET else f"trunk{split}-{tag}"
    return Path(render_root) / "features" / f"{name}.pt"


def build_feature_cache(render_root: os.PathLike, ids: list[str], *, batch_size: int = 0,
                        progress: bool = False, split: int = CACHE_SPLIT,
                        encoder=None, tag: str = IMAGENET) -> dict:
    """Features after the first ``split`` encoder blocks of every view of ``ids``
    (already-cached ids are reused). An ``encoder`` other than the default (ImageNet
    weights, 224 px) needs its ``tag`` (``feature_tag``: the fine-tuned trunk's
    ``trunk_tag`` and the input size).

    Batches of 16 with the heap kept mapped (``keep_heap_mapped``) encode 34.9 views/s on two
    threads, against 16.4 with batches of 32 and glibc's default mmap threshold (session 11,
    runs of 480 views through a fine-tuned trunk). Smaller passes are faster still, so the
    default (``batch_size`` 0) is the encoder's ``ENCODE_BATCH`` (session 13: 28 views/s in
    passes of 4 against 19 in 16 on one thread, 27-30 against 23 on two; 448 px 6.8 views/s
    a thread in passes of 4)."""
    from model.core.runtime import keep_heap_mapped
    from model.encoders.image import (ENCODE_BATCH, IMAGE_SIZE, ImageEncoder, ImageEncoderConfig,
                                      preprocess)
    batch_size = batch_size or ENCODE_BATCH
    keep_heap_mapped()
    if (encoder is None) != (tag == IMAGENET):
        raise ValueError("a feature cache of a fine-tuned or resized encoder needs both the "
                         "encoder and its tag (feature_tag)")
    manifest = load_render_manifest(render_root)
    path = cache_path(render_root, split, tag)
    size = encoder.config.image_size if encoder is not None else IMAGE_SIZE
    cache = load_feature_cache(render_root, split, tag) if path.exists() else None
    if cache is not None and (cache.get("render_version") != manifest["render_version"]
                              or cache.get("weights", IMAGENET) != tag
                              or cache.get("image_size", IMAGE_SIZE) != size):
        cache = None
    have = {} if cache is None else {i: k for k, i in enumerate(cache["ids"])}
    ids = rendered_ids(render_root, list(dict.fromkeys(ids)))      # unique, in order
    todo = [i for i in ids if i not in have]
    if not todo and cache is not None:
        return cache
    if not todo:
        raise ValueError(f"no rendered views of the given objects in {render_root}")
    enc = encoder if encoder is not None else ImageEncoder(ImageEncoderConfig())
    views = int(manifest["views"])
    new = None
    flat = [(n, k, p) for n, oid in enumerate(todo) for k, p in enumerate(view_paths(render_root, oid))]
    rng = range(0, len(flat), batch_size)
    if progress:
        from tqdm import tqdm
        rng = tqdm(rng, desc=f"encode renders (blocks 0-{split - 1})", unit="batch")
    for s in rng:
        chunk = flat[s:s + batch_size]
        x = preprocess([str(p) for _, _, p in chunk], size)            # (b, 3, S, S)
        h = enc.features_at(x, split).numpy().astype(np.float16)      # (b, C, H, W)
        if new is None:
            new = np.zeros((len(todo), views, *h.shape[1:]), np.float16)
        for j, (n, k, _) in enumerate(chunk):
            new[n, k] = h[j]
    if cache is not None:
        all_ids = list(cache["ids"]) + todo
        feats = np.concatenate([cache["feats"].numpy(), new], 0)
    else:
        all_ids, feats = todo, new
    out = {"ids": all_ids, "feats": torch.from_numpy(feats), "split": split,
           "render_version": manifest["render_version"], "weights": tag, "image_size": size}
    atomic_torch_save(path, out)
    log.info("cached trunk features of %d objects (%d new) -> %s", len(all_ids), len(todo), path)
    return out


def load_feature_cache(render_root: os.PathLike, split: int = CACHE_SPLIT, tag: str = IMAGENET) -> dict:
    path = cache_path(render_root, split, tag)
    if not path.exists():
        raise FileNotFoundError(f"no feature cache at {path}; `artformer train image` builds it")
    from model.core.checkpoint import load_weights_only
    return load_weights_only(path)


class ViewFeatures:
    """id → (K, C, H, W) fp16 cached features of its views ((192, 7, 7) for the trunk)."""

    def __init__(self, cache: dict):
        self.ids = list(cache["ids"])                                  # row order of feats
        self.index = {i: n for n, i in enumerate(self.ids)}
        self.feats = cache["feats"]                                    # (N, K, C, 7, 7) fp16
        self.views = int(self.feats.shape[1])
        self.split = int(cache.get("split", CACHE_SPLIT))   # first encoder block after the cache

    def __contains__(self, obj_id: str) -> bool:
        return obj_id in self.index

    def batch(self, ids: list[str], views: list[int]) -> torch.Tensor:
        """-> (B, C, H, W) float32."""
        rows = torch.tensor([self.index[i] for i in ids])
        return self.feats[rows, torch.as_tensor(views)].float()
