"""Where every part is in each rendered view: per-label part-centre maps on the encoder's grid.

Why it exists. A count label says *how many* handles a render shows, not *where* they are,
so the trunk fine-tuned on counts alone (``trunk.py``) must discover each part from the
total. The renders are synthetic, so the position of every part in every view is known: the
part-id render (``model.export.render.render_part_ids``, the colour render's own camera and
z-buffer) gives the pixels each part covers, and the centre of those pixels falls in one cell
of the encoder's 7 x 7 grid (a 224-px render has 32 x 32 pixels per cell). A map
``(labels, 7, 7)`` counts, per label and cell, the parts centred there; its sum over cells is
the label's *visible* count (a hidden part has no centre and is counted by the count head
alone). ``artformer train image-trunk --centre-weight W`` supervises a small head on the
trunk's 7 x 7 map with these maps besides the counts.

    artformer data partmaps --data data/prepared/v1 --renders data/renders/v1 --workers 2

writes ``RENDERS/partmaps/centres7.pt``::

    {"format": 1, "grid": 7, "size": 224, "labels": [...], "data_version": str,
     "ids": [object id, ...], "maps": uint8 tensor (objects, views, labels, 7, 7)}

An existing file with the same labels, grid and data version is reused; objects rendered
later are added (the file is rewritten atomically).
"""
from __future__ import annotations

import logging
import os
import time
from pathlib import Path
from typing import Optional

import numpy as np
import torch

from model.encoders.image import GRID as TOKEN_GRID

from .render import RENDER_SIZE

log = logging.getLogger(__name__)

PARTMAP_FORMAT = 1
GRID = TOKEN_GRID[0]      # the encoder's 7 x 7 token grid


def centre_map(ids: np.ndarray, part_labels: list[str], labels: list[str],
               grid: int = GRID) -> np.ndarray:
    """A part-id image ``(H, W)`` (-1 = background, k = part k) → ``(labels, grid, grid)``
    uint8: per label and cell, the parts whose visible pixels are centred in that cell."""
    H, W = ids.shape
    out = np.zeros((len(labels), grid, grid), np.uint8)
    seen = ids >= 0
    k = ids[seen].ravel()
    if not k.size:
        return out
    n = len(part_labels)
    ys, xs = np.nonzero(seen)
    px = np.bincount(k, minlength=n)[:n]
    sy = np.bincount(k, weights=ys + 0.5, minlength=n)[:n]
    sx = np.bincount(k, weights=xs + 0.5, minlength=n)[:n]
    index = {lab: i for i, lab in enumerate(labels)}
    for p in np.flatnonzero(px):
        li = index.get(part_labels[p])
        if li is None:
            continue
        r = min(grid - 1, int(sy[p] / px[p] * grid / H))
        c = min(grid - 1, int(sx[p] / px[p] * grid / W))
        out[li, r, c] = min(255, int(out[li, r, c]) + 1)
    return out


def object_maps(data_root: str, render_root: str, obj_id: str, labels: list[str],
                grid: int = GRID) -> np.ndarray:
    """Every rendered view of one object → (views, labels, grid, grid) uint8."""
    from model.data import format as fmt
    from .render import part_ids
    from .renders import object_from_record, view_specs
    obj = object_from_record(data_root, fmt.load_record(data_root, obj_id))
    part_labels = [p.label for p in obj.parts]
    return np.stack([centre_map(part_ids(obj, view), part_labels, labels, grid)
                     for view in view_specs(render_root, obj_id)])


def _one(job):
    data_root, render_root, obj_id, labels, grid = job
    try:
        return obj_id, object_maps(data_root, render_root, obj_id, labels, grid), ""
    except Exception as e:  # noqa: BLE001 - reported per object, the others go on
        return obj_id, None, f"{type(e).__name__}: {e}"


def partmap_path(render_root: os.PathLike, grid: int = GRID) -> Path:
    return Path(render_root) / "partmaps" / f"centres{grid}.pt"


def load_partmaps(render_root: os.PathLike, labels: list[str], grid: int = GRID) -> Optional[dict]:
    """The cached maps of a render set, or None when there are none for these labels."""
    p = partmap_path(render_root, grid)
    if not p.exists():
        return None
    try:
        pm = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001
        raise ValueError(f"{p} cannot be read ({e}); delete it to rebuild") from e
    if pm.get("format") != PARTMAP_FORMAT or list(pm.get("labels", [])) != list(labels):
        return None
    return pm


def build_partmaps(data_root: str, render_root: str, labels: list[str], *, workers: int = 1,
                   grid: int = GRID, progress: bool = True) -> dict:
    """Compute (or complete) the centre maps of every rendered object of every split."""
    from model.data import format as fmt
    from .renders import rendered_ids
    t0 = time.perf_counter()
    manifest = fmt.load_manifest(data_root)
    version = manifest.get("data_version", "?")
    ids = rendered_ids(render_root, list(dict.fromkeys(
        i for s in ("train", "val", "test") for i in manifest["splits"].get(s, []))))
    old = load_partmaps(render_root, labels, grid)
    have = {}
    if old is not None and old.get("data_version") == version and old.get("grid") == grid:
        have = {i: old["maps"][k] for k, i in enumerate(old["ids"])}
    jobs = [(str(data_root), str(render_root), i, list(labels), grid) for i in ids if i not in have]
    failed = {}
    bar = None
    if progress and jobs:
        from tqdm import tqdm
        bar = tqdm(total=len(jobs), desc="part maps", unit="obj")
    from model.core.runtime import map_jobs
    for oid, m, err in map_jobs(_one, jobs, workers):
        if err:
            failed[oid] = err
        else:
            have[oid] = torch.from_numpy(m)
        if bar:
            bar.update(1)
    if bar:
        bar.close()
    for oid, err in list(failed.items())[:5]:
        log.warning("part maps of %s failed: %s", oid, err)
    keep = [i for i in ids if i in have]
    if not keep:
        raise ValueError(f"{render_root}: no part maps could be made ({len(failed)} failures)")
    if len({tuple(have[i].shape) for i in keep}) != 1:
        raise ValueError(f"{render_root}: objects have different numbers of views")
    pm = {"format": PARTMAP_FORMAT, "grid": grid, "size": RENDER_SIZE, "labels": list(labels),
          "data_version": version, "ids": keep, "maps": torch.stack([have[i] for i in keep])}
    if jobs:
        from model.core.files import atomic_torch_save
        atomic_torch_save(partmap_path(render_root, grid), pm)
    log.info("part maps: %d objects (%d new, %d failed) in %.1f s", len(keep), len(jobs) - len(failed),
             len(failed), time.perf_counter() - t0)
    pm["failed"] = failed
    return pm
