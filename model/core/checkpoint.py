"""The one checkpoint format and loader of every stage (DESIGN §7).

A checkpoint is a ``torch.save``d dict read back with ``weights_only=True`` (tensors, numbers,
strings, lists, dicts and numpy arrays of plain dtypes; nothing that runs code)::

    {"format": 2, "kind": "articulation" | "sdf" | "prior" | "image_trunk",
     "config": asdict(network config), "state_dict": {name: tensor},
     # the header, read as a typed CheckpointMeta:
     "data_version": str, "seed": int, "command": str, "step": int, "device": str,
     "recipe": [command, ...], "train_config": dict, "prior": str,
     ...kind-specific entries (articulation: stats, label_table, text_encoder, condition,
     image_encoder, count_head; geometry: extra; run checkpoints: optimizer, elapsed, history)}

``prior`` is the fingerprint of the shape prior (SDF auto-encoder + codebook prior) whose
targets a transformer was trained on (``prior_fingerprint``); a transformer or image model is
only read together with that prior (``check_prior``).

Files of the earlier per-stage formats (format 1: the articulation layout with the same
entries, the geometry layout ``model`` / ``argv`` / ``train``, unversioned trunk files) are
read into this layout in memory, so the shipped weights load unchanged.
"""
from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import shlex
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, Iterable, Optional, Sequence, Union

import torch

from .files import atomic_write_bytes

log = logging.getLogger(__name__)

FORMAT = 2
KINDS = ("articulation", "sdf", "prior", "image_trunk")
# the fingerprint of the shape prior that every format-1 transformer trained on "prior"
# targets was made with (model/weights/{sdf,prior}_small.pt as shipped with format 1)
LEGACY_PRIOR = "6930d31a2b9cd97a"
STAND_IN = "stand-in"


class CheckpointError(RuntimeError):
    """A checkpoint is missing, corrupt, of another kind or made for another shape prior;
    the message says what to do."""


@dataclass
class CheckpointMeta:
    """The typed header every checkpoint carries."""
    kind: str
    format: int = FORMAT
    data_version: str = ""
    seed: int = 0
    command: str = ""           # the command line that made the file
    step: int = 0
    device: str = "cpu"         # where it was trained
    recipe: list = field(default_factory=list)   # commands that made a shipped file, in order
    train_config: dict = field(default_factory=dict)
    prior: str = ""             # prior_fingerprint of the shape prior it was trained against

    @classmethod
    def of(cls, ckpt: dict) -> "CheckpointMeta":
        """The header of a checkpoint dict (as ``read_checkpoint`` returns it)."""
        known = {f.name for f in fields(cls)}
        return cls(**{k: ckpt[k] for k in known if k in ckpt})

    def header(self) -> dict:
        return asdict(self)


def _numpy_globals() -> list:
    """The numpy pickling entry points of plain arrays (normalisation stats, label tables)."""
    import numpy as np
    try:
        from numpy._core.multiarray import _reconstruct
    except ImportError:            # numpy < 2
        from numpy.core.multiarray import _reconstruct
    out = [_reconstruct, np.ndarray, np.dtype]
    dtypes = getattr(np, "dtypes", None)
    if dtypes is not None:
        out += [getattr(dtypes, n) for n in ("Float16DType", "Float32DType", "Float64DType",
                                             "Int32DType", "Int64DType", "BoolDType",
                                             "UInt8DType") if hasattr(dtypes, n)]
    return out


def load_weights_only(path: Union[str, os.PathLike]) -> Any:
    """``torch.load`` of a cache file (tensors, plain containers, numpy arrays) without running
    pickled code; raises what torch raises."""
    with torch.serialization.safe_globals(_numpy_globals()):
        return torch.load(path, map_location="cpu", weights_only=True)


def write_checkpoint(path: Union[str, os.PathLike], meta: CheckpointMeta, payload: dict) -> None:
    """Atomic write (temp file + rename) of ``payload`` with ``meta`` as its header."""
    if meta.kind not in KINDS:
        raise ValueError(f"unknown checkpoint kind {meta.kind!r}; one of {KINDS}")
    ckpt = {**payload, **meta.header(), "format": FORMAT}
    buf = io.BytesIO()
    torch.save(ckpt, buf)
    atomic_write_bytes(path, buf.getvalue())


def _load(path: Path, how: str) -> Any:
    try:
        return load_weights_only(path)
    except Exception as e:  # noqa: BLE001 - truncated, not a torch file, foreign pickles
        first = (str(e).splitlines() or [""])[0][:200]
        if "Weights only load failed" in str(e) or "Unsupported global" in str(e):
            why = "it holds Python objects that a weights-only load refuses (a foreign file)"
        else:
            why = f"{type(e).__name__}: {first}"
        raise CheckpointError(f"{path} is corrupt or not an artformer checkpoint ({why}); "
                              f"{how}") from None


def _upgrade(ck: dict) -> dict:
    """A format-1 dict in the current layout (the tensors are not copied)."""
    if ck.get("kind") in ("sdf", "prior") and "model" in ck:
        ck["state_dict"] = ck.pop("model")
        argv = ck.pop("argv", [])
        ck.setdefault("command", shlex.join(argv) if argv else "")
        if "train" in ck:
            ck["train_config"] = ck.pop("train")
    if ck.get("kind") == "articulation" and "prior" not in ck:
        ck["prior"] = LEGACY_PRIOR if ck.get("targets") == "prior" else \
            STAND_IN if ck.get("targets") == STAND_IN else ""
    if ck.get("kind") == "image_trunk":
        train = ck.get("train") or {}
        ck.setdefault("command", train.get("command", ""))
        ck.setdefault("seed", train.get("seed", 0))
    ck["format"] = FORMAT
    return ck


def read_checkpoint(path: Union[str, os.PathLike], kind: Union[str, Iterable[str]], *,
                    how: str = "", prior: Union[str, Sequence[str], None] = None) -> dict:
    """Load and check a checkpoint dict (cpu). ``kind``: the kind(s) accepted; ``how``: the
    command that makes one (said in errors); ``prior``: the fingerprint(s) of the shape prior
    it will be used with (``check_prior``). Raises CheckpointError with what to do."""
    kinds = (kind,) if isinstance(kind, str) else tuple(kind)
    how = how or f"train one with `artformer train {kinds[0]}`"
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{kinds[0]} checkpoint {path} does not exist; {how}")
    ck = _load(path, f"delete it and {how}, or restore the shipped file with "
                     f"`git checkout -- model/weights`")
    if not isinstance(ck, dict) or "kind" not in ck:
        raise CheckpointError(f"{path} is not an artformer checkpoint (no kind entry); {how}")
    if ck["kind"] not in kinds:
        raise CheckpointError(f"{path} is a {ck['kind']!r} checkpoint but a "
                              f"{' or '.join(repr(k) for k in kinds)} one is needed; pass the "
                              f"right file")
    fmt = ck.get("format", 1)
    if not isinstance(fmt, int) or fmt > FORMAT:
        raise CheckpointError(f"{path}: checkpoint format {fmt!r} is newer than this code reads "
                              f"({FORMAT}); update artformer_ros")
    if fmt < FORMAT:
        ck = _upgrade(ck)
    if "state_dict" not in ck or not isinstance(ck["state_dict"], dict):
        raise CheckpointError(f"{path} has no weights (state_dict); {how}")
    if prior is not None:
        check_prior(ck, prior, path)
    return ck


def check_prior(ck: dict, prior: Union[str, Sequence[str]],
                path: Union[str, os.PathLike] = "checkpoint") -> None:
    """Refuse a transformer / image checkpoint trained against another shape prior than the
    one it is about to be used with. ``prior``: that prior's fingerprint, or the list of
    fingerprints whose predictions it reads (its own first, then those of the priors whose
    code space it adopted: ``code_space_hash``)."""
    accepted = [prior] if isinstance(prior, str) else list(prior)
    have = ck.get("prior", "")
    if not have:
        raise CheckpointError(f"{path} does not record the shape prior it was trained against; "
                              f"retrain it with this version so it can be checked")
    if have == STAND_IN:
        log.warning("%s was trained on stand-in targets (no shape prior): for development only",
                    path)
        return
    if have not in accepted:
        raise CheckpointError(f"{path} was trained against another shape prior (fingerprint "
                              f"{have}, this model's prior is {accepted[0]}): its codebook "
                              f"predictions would be mis-read. Retrain it against this prior "
                              f"(`artformer train transformer` / `artformer train image`) or "
                              f"use it with the sdf/prior checkpoints it was made with")


def _hash_weights(h, state_dict: dict, prefixes: tuple = ("",)) -> None:
    """Feed the tensors under ``prefixes`` to hash ``h`` by name, floats rounded to fp16 (so a
    training checkpoint and its fp16 export agree)."""
    for k in sorted(state_dict):
        if k.startswith(prefixes):
            v = state_dict[k].detach()
            v = v.to(torch.float16) if v.is_floating_point() else v
            h.update(k.encode())
            h.update(v.cpu().contiguous().view(torch.uint8).numpy().tobytes())


def prior_fingerprint(sdf: dict, prior: dict) -> str:
    """Identity of a shape prior: its SDF auto-encoder and codebook prior configs and weights
    (rounded to fp16, so a training checkpoint and its fp16 export agree), hashed."""
    h = hashlib.sha256()
    for ck in (sdf, prior):
        h.update(json.dumps(ck.get("config", {}), sort_keys=True, default=str).encode())
        _hash_weights(h, ck["state_dict"])
    return h.hexdigest()[:16]


# What a transformer's predictions for a prior (code logits P, semantic condition c_s) are read
# through: these prior config fields and the weights under these state-dict prefixes.
CODE_SPACE_FIELDS = ("n_codebooks", "codebook_size", "code_dim", "text_dim", "cs_dim",
                     "encoder_hidden", "text_encoder")
CODE_SPACE_WEIGHTS = ("codebooks", "sem_encoder.")


def code_space_hash(prior: dict) -> str:
    """Identity of a prior checkpoint's code space (CODE_SPACE_FIELDS of its config and the
    CODE_SPACE_WEIGHTS, rounded to fp16), hashed: two priors with equal hashes read a
    transformer's P and c_s alike."""
    h = hashlib.sha256()
    cfg = prior.get("config", {})
    h.update(json.dumps({k: cfg.get(k) for k in CODE_SPACE_FIELDS}, sort_keys=True,
                        default=str).encode())
    _hash_weights(h, prior["state_dict"], CODE_SPACE_WEIGHTS)
    return h.hexdigest()[:16]


def accepted_priors(sdf: dict, prior: dict, path: Union[str, os.PathLike] = "prior") -> list:
    """The fingerprints whose transformers this shape prior reads: its own, then those of
    the priors whose code space it adopted (``train prior --codes-from``), after checking
    that its code space is still that one."""
    own = prior_fingerprint(sdf, prior)
    cs = (prior.get("extra") or {}).get("code_space")
    if not cs:
        return [own]
    if code_space_hash(prior) != cs.get("hash"):
        raise CheckpointError(f"{path} claims the code space of shape prior "
                              f"{cs.get('accepts', ['?'])[0]}, but its codebooks or semantic "
                              f"encoder differ from it: that prior's transformers would be "
                              f"mis-read. Retrain it with `artformer train prior --codes-from`")
    return [own, *cs.get("accepts", [])]


def shape_prior_fingerprint(sdf_path: Union[str, os.PathLike],
                            prior_path: Union[str, os.PathLike]) -> str:
    """``prior_fingerprint`` of a pair of checkpoint files."""
    return prior_fingerprint(read_checkpoint(sdf_path, "sdf"), read_checkpoint(prior_path, "prior"))


__all__ = ["FORMAT", "KINDS", "CheckpointError", "CheckpointMeta", "load_weights_only",
           "write_checkpoint",
           "read_checkpoint", "check_prior", "prior_fingerprint", "shape_prior_fingerprint",
           "CODE_SPACE_FIELDS", "CODE_SPACE_WEIGHTS", "code_space_hash", "accepted_priors"]
