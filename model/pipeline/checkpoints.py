"""The stage checkpoints of a generator folder: which file holds each stage, whether the
transformer's codebook logits fit the shape prior, and the files' digests (provenance)."""
from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Optional, Union

from model.pipeline.api import GenerationError

WEIGHTS_DIR = Path(__file__).resolve().parent.parent / "weights"
STAGES = ("transformer", "sdf", "prior", "image")
# a sub-folder with the shape prior (sdf*.pt + prior*.pt) the image model was trained against,
# for a folder whose text model has moved on to a newer prior than its image model
IMAGE_PRIOR_DIR = "image_prior"


def find_checkpoints(folder: Union[str, os.PathLike, None]) -> dict[str, Optional[Path]]:
    """Stage → checkpoint file in a folder (``<stage>.pt`` or the one ``<stage>_*.pt``).

    The image stage is optional; the other three must exist. ``image_sdf`` / ``image_prior``:
    the image model's own shape prior from the ``image_prior/`` sub-folder, both or neither
    (None: the image model runs with the folder's prior).
    """
    root = Path(folder) if folder else WEIGHTS_DIR
    if not root.is_dir():
        raise GenerationError(f"checkpoint folder {root} does not exist; pass the folder that "
                              f"holds transformer*.pt, sdf*.pt and prior*.pt")
    found = {stage: _one(root, stage) for stage in STAGES}
    missing = [s for s in STAGES[:3] if found[s] is None]
    if missing:
        raise GenerationError(f"{root} has no checkpoint for {missing}; train them with "
                              f"`artformer train ...` or use the shipped model (no --checkpoint)")
    sub = root / IMAGE_PRIOR_DIR
    own = {s: _one(sub, s) if sub.is_dir() else None for s in ("sdf", "prior")}
    if (own["sdf"] is None) != (own["prior"] is None):
        raise GenerationError(f"{sub} must hold both sdf*.pt and prior*.pt (the shape prior "
                              f"the image model was trained against), or neither")
    found.update(image_sdf=own["sdf"], image_prior=own["prior"])
    return found


def _one(root: Path, stage: str) -> Optional[Path]:
    """``<stage>.pt`` or the one ``<stage>_*.pt`` in root (None when there is none)."""
    exact = root / f"{stage}.pt"
    cands = [exact] if exact.exists() else sorted(root.glob(f"{stage}_*.pt"))
    if len(cands) > 1:
        raise GenerationError(f"{root} holds several {stage} checkpoints "
                              f"({[c.name for c in cands]}); keep one or name it {stage}.pt")
    return cands[0] if cands else None


def check_codebooks(cfg, shape, ckpt: Path, prior: Path) -> None:
    """A transformer's codebook logits P (text or image stage) must have the prior's layout
    (C codebooks x N codes); the one_codebook ablation needs a prior trained with one codebook."""
    if cfg.predict_z or shape.prior is None:
        return
    want = (int(shape.prior.cfg.n_codebooks), int(shape.prior.cfg.codebook_size))
    have = (int(cfg.num_codebooks), int(cfg.codebook_size))
    if have != want:
        raise GenerationError(
            f"{ckpt} predicts {have[0]} x {have[1]} codebook logits but the shape "
            f"prior {prior} has {want[0]} x {want[1]} codebooks; put the prior it was "
            f"trained with beside it (`artformer train prior --codebooks {have[0]} "
            f"--codebook-size {have[1]}` for the one_codebook ablation)")


def file_digest(path: Path, n: int = 12) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()[:n]
