"""A fine-tuned encoder trunk: EfficientNet-Lite0's middle blocks trained end to end to count parts.

Why it exists. The image model's misses are part counts of small, repeated parts (buttons,
handles, drawers; docs/imaging.md). With the ImageNet trunk frozen, a count head over its
7×7 map reads every count of a render right for about half of the val renders however the
map is sampled (448² renders, a pixel CNN beside it), so the frozen features are the limit.
This trainer unfreezes blocks ``freeze``..14 of the trunk (the stem and the first ``freeze``
high-resolution blocks stay ImageNet's, as do the BatchNorm statistics: CPU batches are
small) and trains them, with a count head on the 192 × 7 × 7 map entering block 15, to
classify every label's part count of a rendered view. The image trainer then reads its
features from this trunk (``artformer train image --trunk OUT/trunk.pt``) and stores the
fine-tuned weights in the image checkpoint, so the shipped model stays one file.

    artformer train image-trunk --data data/prepared/v1 --renders data/renders/v1 \
        --extra-train data/prepared/v1x data/renders/v1x --out runs/trunk --steps 1200

writes ``OUT/trunk.pt``::

    {"kind": "image_trunk", "freeze": int, "split": 15, "tag": str,
     "state_dict": {EfficientNet-Lite0 keys of blocks freeze..14: fp16},
     "count_head": {"config": ..., "state_dict": ...},
     "train": {"command", "seed", "config", "data_versions", "history", "chosen", ...}}

The weights stored are the ones of the best val evaluation (exact counts of every label on
the v1 val renders, all views), rounded to fp16 before anything reads them, so feature
caches and the shipped checkpoint see the same numbers.
"""
from __future__ import annotations

import hashlib
import io
import json
import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import torch
from torch.nn import functional as F

from model.core.state import half_state

from .counts import COUNT_SPLIT, CountHead, CountHeadConfig, count_targets, exact_counts

log = logging.getLogger(__name__)

TRUNK_KIND = "image_trunk"


class TrunkError(RuntimeError):
    """A trunk file that is missing, damaged or not a trunk."""


@dataclass
class TrunkTrainConfig:
    steps: int = 1200              # optimiser steps (the schedule depends on steps, not time)
    batch_size: int = 32           # rendered views per step (random object, random view)
    lr: float = 3e-4               # peak learning rate of the trunk blocks
    head_lr_mult: float = 3.0      # the count head's learning rate factor
    weight_decay: float = 0.05
    warmup: int = 40
    freeze: int = 4                # blocks 0..freeze-1 (and the stem) keep ImageNet's weights
    flip: float = 0.5              # share of horizontally mirrored views (counts do not change)
    evals: int = 6                 # val evaluations over the run (the best one is kept)
    seed: int = 0
    threads: int = 2


def trunk_tag(state: dict) -> str:
    """Short content hash of a trunk's weights (names feature caches built with them)."""
    h = hashlib.sha256()
    for k in sorted(state):
        h.update(k.encode())
        h.update(state[k].detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()[:12]


def load_trunk(path) -> dict:
    """Read and check an ``artformer train image-trunk`` file."""
    p = Path(path)
    if p.is_dir():
        p = p / "trunk.pt"
    if not p.exists():
        raise TrunkError(f"no trunk file at {p}; `artformer train image-trunk` writes one")
    try:
        tr = torch.load(p, map_location="cpu", weights_only=False)
    except Exception as e:  # noqa: BLE001 - any damage is reported the same way
        raise TrunkError(f"{p} cannot be read as a trunk file ({e})") from e
    if not isinstance(tr, dict) or tr.get("kind") != TRUNK_KIND or not tr.get("state_dict"):
        raise TrunkError(f"{p} is not an `artformer train image-trunk` file")
    if trunk_tag(tr["state_dict"]) != tr.get("tag"):
        raise TrunkError(f"{p}: the weights do not match their recorded hash (damaged file)")
    return tr


def trunk_keys(net, freeze: int, split: int = COUNT_SPLIT) -> list[str]:
    keep = tuple(f"_blocks.{i}." for i in range(freeze, split))
    return [k for k in net.state_dict() if k.startswith(keep)]


class _Views:
    """(data, renders) sets → view paths and count targets."""

    def __init__(self, sets, labels, max_count):
        from model.data import format as fmt
        from .renders import rendered_ids, view_paths
        self.paths, ys, self.versions = [], [], []
        for root, rroot, splits in sets:
            ids = rendered_ids(rroot, [i for s in splits for i in fmt.split_ids(root, s)])
            self.paths += [[str(p) for p in view_paths(rroot, i)] for i in ids]
            ys.append(count_targets([fmt.load_record(root, i) for i in ids], labels, max_count))
            self.versions.append(fmt.load_manifest(root).get("data_version", "?"))
        self.Y = torch.cat(ys) if ys else torch.zeros(0, len(labels), dtype=torch.long)
        if self.paths and len({len(p) for p in self.paths}) != 1:
            raise ValueError("render sets differ in their number of views")

    def __len__(self):
        return len(self.paths)


def _trunk_forward(enc, x, freeze: int, split: int = COUNT_SPLIT):
    """Frozen stem + blocks 0..freeze-1 (``features_at``, no grad), then the trained blocks."""
    h = enc.features_at(x, freeze)
    for block in enc.net._blocks[freeze:split]:
        h = block(h)
    return h


def _exact_counts(enc, head, views: _Views, freeze: int, batch: int = 50) -> dict:
    """``counts.exact_counts`` on the val views encoded by the current trunk."""
    from model.encoders.image import preprocess
    K = len(views.paths[0])
    with torch.no_grad():
        X = torch.stack([torch.cat([
            _trunk_forward(enc, preprocess([v[k] for v in views.paths[s:s + batch]]), freeze)
            for s in range(0, len(views), batch)]) for k in range(K)], 1)      # (N, K, C, 7, 7)
    return exact_counts(head, X, views.Y)


def train_trunk(data_root: str, render_root: str, out: str, *, extra: Optional[list] = None,
                tc: Optional[TrunkTrainConfig] = None, labels: Optional[list] = None,
                max_count: int = 20, command: str = "") -> Path:
    """Fine-tune trunk blocks ``tc.freeze``..14 + a count head on the rendered train objects of
    ``data_root`` (+ every split of each ``extra`` (data, renders) pair); keep the best of
    ``tc.evals`` val evaluations; write OUT/trunk.pt."""
    from model.encoders.image import ImageEncoder, ImageEncoderConfig, preprocess
    tc = tc or TrunkTrainConfig()
    if not 0 <= tc.freeze < COUNT_SPLIT:
        raise ValueError(f"freeze must be in [0, {COUNT_SPLIT - 1}], got {tc.freeze}")
    torch.set_num_threads(max(1, tc.threads))
    torch.manual_seed(tc.seed)
    rng = np.random.default_rng(tc.seed)
    if labels is None:
        from model.articulation.checkpoint import read_checkpoint
        from .model import SHIPPED
        labels = list(read_checkpoint(SHIPPED)["config"]["count_labels"])
    t0 = time.time()
    train = _Views([(data_root, render_root, ("train",))]
                   + [(d, r, ("train", "val", "test")) for d, r in extra or []], labels, max_count)
    if len(set(train.versions)) < len(train.versions):
        raise ValueError(f"training sets share a data version {train.versions}; extra objects need their own")
    val = _Views([(data_root, render_root, ("val",))], labels, max_count)
    if not len(train) or not len(val):
        raise ValueError(f"{render_root}: no rendered train or val objects")
    K = len(train.paths[0])
    log.info("trunk: %d train objects x %d views, %d val objects", len(train), K, len(val))

    enc = ImageEncoder(ImageEncoderConfig())
    net = enc.net
    net.eval()                       # BatchNorm statistics stay ImageNet's
    keys = trunk_keys(net, tc.freeze)
    params = [p for b in net._blocks[tc.freeze:COUNT_SPLIT] for p in b.parameters()]
    for p in params:
        p.requires_grad_(True)
    head = CountHead(CountHeadConfig(labels=list(labels), max_count=max_count))
    opt = torch.optim.AdamW([{"params": params, "lr": tc.lr, "base": tc.lr},
                             {"params": head.parameters(), "lr": tc.lr * tc.head_lr_mult,
                              "base": tc.lr * tc.head_lr_mult}], weight_decay=tc.weight_decay)
    every = max(1, tc.steps // max(1, tc.evals))
    best, history = None, []
    t_loop = time.time()
    head.train()
    for step in range(1, tc.steps + 1):
        warm = min(1.0, step / max(1, tc.warmup))
        cos = 0.5 * (1 + np.cos(np.pi * (step - 1) / max(1, tc.steps)))
        for g in opt.param_groups:
            g["lr"] = g["base"] * warm * cos
        b = rng.integers(0, len(train), tc.batch_size)
        v = rng.integers(0, K, tc.batch_size)
        x = preprocess([train.paths[i][j] for i, j in zip(b, v)])
        flip = torch.from_numpy(rng.random(tc.batch_size) < tc.flip)
        x[flip] = x[flip].flip(-1)
        loss = F.cross_entropy(head(_trunk_forward(enc, x, tc.freeze)).transpose(1, 2),
                               train.Y[torch.from_numpy(b)])
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        if step % every == 0 or step == tc.steps:
            ev = _exact_counts(enc, head, val, tc.freeze)
            rec = {"step": step, "train_loss": round(loss.item(), 4), "val_exact": ev["exact"],
                   "val_per_label": dict(zip(labels, ev["per_label"])),
                   "minutes": round((time.time() - t_loop) / 60, 2)}
            history.append(rec)
            log.info("trunk step %d/%d loss %.4f val exact %.4f (%.1f min)", step, tc.steps,
                     rec["train_loss"], ev["exact"], rec["minutes"])
            if best is None or ev["exact"] > best[0]["val_exact"]:
                sd = net.state_dict()
                best = (rec, half_state({k: sd[k] for k in keys}), half_state(head.state_dict()))
    rec, state, head_state = best
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    trunk = {"kind": TRUNK_KIND, "freeze": tc.freeze, "split": COUNT_SPLIT, "tag": trunk_tag(state),
             "state_dict": state,
             "count_head": {"config": asdict(head.cfg), "state_dict": head_state},
             "train": {"command": command, "seed": tc.seed, "config": asdict(tc),
                       "data_versions": train.versions, "train_objects": len(train), "views": K,
                       "val_objects": len(val), "chosen": rec, "history": history,
                       "minutes": round((time.time() - t0) / 60, 2)}}
    buf = io.BytesIO()
    torch.save(trunk, buf)
    from model.data.format import atomic_write_bytes
    atomic_write_bytes(out_dir / "trunk.pt", buf.getvalue())
    (out_dir / "trunk_history.json").write_text(json.dumps(trunk["train"], indent=1))
    log.info("trunk: chose step %d (val exact %.4f); wrote %s", rec["step"], rec["val_exact"],
             out_dir / "trunk.pt")
    return out_dir / "trunk.pt"


def _parser():
    import argparse
    d = TrunkTrainConfig()
    ap = argparse.ArgumentParser(
        prog="artformer train image-trunk",
        description="Fine-tune the image encoder's trunk (EfficientNet-Lite0 blocks FREEZE..14) "
                    "end to end to count parts; `artformer train image --trunk OUT/trunk.pt` "
                    "then trains the image model on its features.")
    ap.add_argument("--data", default="data/prepared/v1")
    ap.add_argument("--renders", default="data/renders/v1")
    ap.add_argument("--extra-train", nargs=2, action="append", default=[],
                    metavar=("DATA", "RENDERS"),
                    help="more training objects (all splits), as for `artformer train image`")
    ap.add_argument("--image", default=None,
                    help="image checkpoint whose plan labels are counted (default: the shipped one)")
    ap.add_argument("--out", default="runs/image_trunk")
    ap.add_argument("--steps", type=int, default=d.steps)
    ap.add_argument("--batch-size", type=int, default=d.batch_size)
    ap.add_argument("--lr", type=float, default=d.lr)
    ap.add_argument("--freeze", type=int, default=d.freeze,
                    help=f"leading blocks kept at ImageNet weights (default {d.freeze})")
    ap.add_argument("--evals", type=int, default=d.evals)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    return ap


def cli_main(argv: list[str]) -> int:
    import shlex
    args = _parser().parse_args(argv)
    labels = None
    if args.image:
        from model.articulation.checkpoint import read_checkpoint
        if not Path(args.image).exists():
            print(f"artformer train image-trunk: --image {args.image} does not exist", flush=True)
            return 2
        labels = list(read_checkpoint(args.image)["config"].get("count_labels") or []) or None
    tc = TrunkTrainConfig(steps=args.steps, batch_size=args.batch_size, lr=args.lr,
                          freeze=args.freeze, evals=args.evals, seed=args.seed, threads=args.threads)
    command = "artformer train image-trunk " + " ".join(shlex.quote(a) for a in argv)
    try:
        path = train_trunk(args.data, args.renders, args.out, extra=[tuple(x) for x in args.extra_train],
                           tc=tc, labels=labels, command=command)
    except (ValueError, FileNotFoundError) as e:
        print(f"artformer train image-trunk: {e}", flush=True)
        return 2
    print(f"trunk: {path}")
    return 0
