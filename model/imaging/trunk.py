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
     "centre_head": {"labels", "state_dict"}      (with --centre-weight only),
     "train": {"command", "seed", "config", "data_versions", "history", "chosen", ...}}

``--centre-weight W`` adds a second target: a small head (``CentreHead``) on the same map
regresses, per label and cell, the parts centred there (``artformer data partmaps``), so
the blocks are told where each counted part is, not only how many there are (mirrored views
get mirrored maps). ``--init-trunk`` starts the blocks from a trunk file or from the trunk
of an image checkpoint instead of ImageNet's; from a trunk file whose count head has the
same labels and classes, the count head continues too (an image checkpoint stores no count
head for the trunk, so there it starts fresh, as does the centre head always).

The weights stored are the ones of the best val evaluation (exact counts of every label on
the v1 val renders, all views), rounded to fp16 before anything reads them, so feature
caches and the shipped checkpoint see the same numbers.
"""
from __future__ import annotations

import hashlib
import json
import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from model.core.checkpoint import CheckpointError, CheckpointMeta, read_checkpoint, write_checkpoint
from model.core.state import half_state

from .counts import COUNT_SPLIT, CountHead, CountHeadConfig, count_targets, exact_counts

log = logging.getLogger(__name__)

TRUNK_KIND = "image_trunk"


# a trunk file that is missing, damaged or not a trunk (kept as a name for one release)
TrunkError = CheckpointError


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
    centre_weight: float = 0.0     # weight of the part-centre map loss (0 = counts only)
    init: str = ""                 # start from this trunk (trunk.pt or an image checkpoint)
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
    """Read and check an ``artformer train image-trunk`` file, or take the fine-tuned trunk
    of an image checkpoint (the shipped ``image_small.pt``), tagged by its weights as a
    trunk file is (both store fp16: the same blocks share their feature caches)."""
    p = Path(path)
    if p.is_dir():
        p = p / "trunk.pt"
    how = "`artformer train image-trunk` writes one; an image checkpoint also carries one"
    tr = read_checkpoint(p, (TRUNK_KIND, "articulation"), how=how)
    if tr["kind"] != TRUNK_KIND:
        enc = tr.get("image_encoder") or {}
        if tr.get("condition") != "image" or not enc.get("trunk"):
            raise TrunkError(f"{p} is a text checkpoint or an image checkpoint without a "
                             f"fine-tuned trunk; {how}")
        info = {k: v for k, v in (enc.get("trunk_info") or {}).items() if k != "tag"}
        return {**info, "kind": TRUNK_KIND, "state_dict": enc["trunk"],
                "tag": trunk_tag(enc["trunk"]), "source": str(p)}
    if not tr["state_dict"]:
        raise TrunkError(f"{p} is not an `artformer train image-trunk` file (no weights)")
    if trunk_tag(tr["state_dict"]) != tr.get("tag"):
        raise TrunkError(f"{p}: the weights do not match their recorded hash (damaged file)")
    return tr


def count_labels_of(image_ckpt=None) -> list[str]:
    """The count labels of an image checkpoint (default: the shipped one)."""
    from model.articulation.checkpoint import read_checkpoint as read_articulation
    from .model import SHIPPED
    path = SHIPPED if image_ckpt is None else Path(image_ckpt)
    if not Path(path).exists():
        raise FileNotFoundError(f"no image checkpoint at {path}")
    labels = list(read_articulation(path)["config"].get("count_labels") or [])
    if not labels:
        raise ValueError(f"{path} has no count labels")
    return labels


def trunk_for_run(ic, init: Optional[dict]) -> Optional[dict]:
    """The fine-tuned trunk a run uses: --trunk, else the one of an image init checkpoint."""
    if ic.trunk:
        return load_trunk(ic.trunk)
    enc = (init or {}).get("image_encoder") or {}
    if init is not None and init.get("condition") == "image" and enc.get("trunk"):
        return {**enc["trunk_info"], "state_dict": enc["trunk"]}
    return None


def trunk_entry(trunk: Optional[dict]) -> dict:
    """What an image checkpoint keeps of its fine-tuned trunk: the weights (fp16) and where
    they came from (without the per-evaluation history)."""
    if trunk is None:
        return {}
    train = {k: v for k, v in (trunk.get("train") or {}).items() if k != "history"}
    info = {k: trunk[k] for k in ("kind", "freeze", "split", "tag") if k in trunk}
    return {"trunk": trunk["state_dict"], "trunk_info": {**info, "train": train}}


def trunk_keys(net, freeze: int, split: int = COUNT_SPLIT) -> list[str]:
    keep = tuple(f"_blocks.{i}." for i in range(freeze, split))
    return [k for k in net.state_dict() if k.startswith(keep)]


def first_block(state: dict) -> int:
    """The lowest block index among ``_blocks.<i>.`` keys of a trunk state dict."""
    return min(int(k.split(".")[1]) for k in state)


class CentreHead(nn.Module):
    """(B, C, 7, 7) trunk map → (B, labels, 7, 7) non-negative part-centre counts per cell."""

    def __init__(self, in_channels: int, labels: int, width: int = 128):
        super().__init__()
        self.body = nn.Sequential(nn.Conv2d(in_channels, width, 3, padding=1), nn.GELU(),
                                  nn.Conv2d(width, labels, 1))
        nn.init.constant_(self.body[-1].bias, -4.0)   # start near empty cells (softplus 0.018)

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        return F.softplus(self.body(h.float()))


def centre_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Squared error of the per-cell part counts, summed over labels and cells, mean over views."""
    return (pred - target.float()).pow(2).sum((1, 2, 3)).mean()


def initial_trunk(path, freeze: int) -> dict:
    """The fine-tuned blocks of a trunk file or of an image checkpoint, to start from. A trunk
    file may fine-tune fewer blocks than ``freeze``..14 (a continuation that unfreezes more:
    the blocks it lacks start from ImageNet's weights), never more (its blocks before
    ``freeze`` would be dropped)."""
    p = Path(path)
    if p.is_dir() or p.name == "trunk.pt":
        tr = load_trunk(p)
        if tr["freeze"] < freeze:
            raise ValueError(f"{p} fine-tunes blocks {tr['freeze']}..14, more than {freeze}..14")
        return {k: v.float() for k, v in tr["state_dict"].items()}
    if not p.exists():
        raise FileNotFoundError(f"--init-trunk {p} does not exist")
    ck = read_checkpoint(p, "articulation", how="pass a trunk.pt or an image checkpoint")
    state = (ck.get("image_encoder") or {}).get("trunk")
    if not state:
        raise ValueError(f"{p} is neither a trunk file nor an image checkpoint with a fine-tuned trunk")
    first = first_block(state)
    if first < freeze:
        raise ValueError(f"{p} fine-tunes blocks {first}..14, more than {freeze}..14")
    return {k: v.float() for k, v in state.items()}


def initial_count_head(path, cfg) -> Optional[dict]:
    """The count head of a trunk file when it matches ``cfg`` (labels, classes, channels), else None."""
    p = Path(path)
    if not (p.is_dir() or p.name == "trunk.pt"):
        return None
    head = load_trunk(p).get("count_head") or {}
    if head.get("config") != asdict(cfg) or not head.get("state_dict"):
        return None
    return {k: v.float() for k, v in head["state_dict"].items()}


class _Views:
    """(data, renders) sets → view paths, count targets and (optionally) part-centre maps."""

    def __init__(self, sets, labels, max_count, centres: bool = False):
        from model.data import format as fmt
        from .partmaps import load_partmaps
        from .renders import rendered_ids, view_paths
        self.paths, ys, ms, self.versions = [], [], [], []
        for root, rroot, splits in sets:
            ids = rendered_ids(rroot, [i for s in splits for i in fmt.split_ids(root, s)])
            version = fmt.load_manifest(root).get("data_version", "?")
            if centres:
                pm = load_partmaps(rroot, labels)
                if pm is None or pm.get("data_version") != version:
                    raise ValueError(f"{rroot} has no part maps for these labels and data version; "
                                     f"run `artformer data partmaps --data {root} --renders {rroot}`")
                where = {i: k for k, i in enumerate(pm["ids"])}
                ids = [i for i in ids if i in where]
                ms.append(pm["maps"][[where[i] for i in ids]])
            self.paths += [[str(p) for p in view_paths(rroot, i)] for i in ids]
            ys.append(count_targets([fmt.load_record(root, i) for i in ids], labels, max_count))
            self.versions.append(version)
        self.Y = torch.cat(ys) if ys else torch.zeros(0, len(labels), dtype=torch.long)
        self.M = torch.cat(ms) if ms else None      # (N, views, labels, 7, 7) uint8
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


def _trunk_sets(data_root, render_root, extra, labels, max_count: int, centres: bool):
    train = _Views([(data_root, render_root, ("train",))]
                   + [(d, r, ("train", "val", "test")) for d, r in extra or []], labels, max_count,
                   centres=centres)
    if len(set(train.versions)) < len(train.versions):
        raise ValueError(f"training sets share a data version {train.versions}; extra objects need their own")
    val = _Views([(data_root, render_root, ("val",))], labels, max_count)
    if not len(train) or not len(val):
        raise ValueError(f"{render_root}: no rendered train or val objects")
    return train, val


def _trunk_modules(tc: TrunkTrainConfig, labels: list, max_count: int):
    """Encoder (blocks freeze..14 trainable, from ``tc.init`` when given), count head, centre
    head or None, optimizer (the heads at ``head_lr_mult``), whether the head continues."""
    from model.encoders.image import ImageEncoder, ImageEncoderConfig
    enc = ImageEncoder(ImageEncoderConfig())
    net = enc.net
    net.eval()                       # BatchNorm statistics stay ImageNet's
    if tc.init:
        start = initial_trunk(tc.init, tc.freeze)
        first = first_block(start)
        if sorted(start) != sorted(trunk_keys(net, first)):
            raise ValueError(f"{tc.init}: its trunk blocks do not match blocks {first}..14")
        net.load_state_dict(start, strict=False)
        log.info("trunk: starting from the blocks %d..14 of %s%s", first, tc.init,
                 f" (blocks {tc.freeze}..{first - 1}: ImageNet's)" if first > tc.freeze else "")
    params = [p for b in net._blocks[tc.freeze:COUNT_SPLIT] for p in b.parameters()]
    for p in params:
        p.requires_grad_(True)
    head = CountHead(CountHeadConfig(labels=list(labels), max_count=max_count))
    head_start = initial_count_head(tc.init, head.cfg) if tc.init else None
    if head_start is not None:
        head.load_state_dict(head_start)
        log.info("trunk: the count head continues from %s", tc.init)
    heads = list(head.parameters())
    centre_head = None
    if tc.centre_weight > 0:
        centre_head = CentreHead(head.cfg.in_channels, len(labels))
        heads += list(centre_head.parameters())
    opt = torch.optim.AdamW([{"params": params}, {"params": heads, "lr_mult": tc.head_lr_mult}],
                            lr=tc.lr, weight_decay=tc.weight_decay)
    return enc, head, centre_head, opt, head_start is not None


class _TrunkModel(nn.Module):
    """The trained blocks and heads as one module (what the shared loop trains)."""

    def __init__(self, enc, head, centre_head, freeze: int):
        super().__init__()
        self.enc, self.head, self.centre_head, self.freeze = enc, head, centre_head, freeze

    def train(self, mode: bool = True):
        super().train(mode)
        self.enc.net.eval()              # BatchNorm statistics stay ImageNet's
        return self

    def forward(self, x):
        h = _trunk_forward(self.enc, x, self.freeze)
        return self.head(h), (self.centre_head(h) if self.centre_head is not None else None)


def train_trunk(data_root: str, render_root: str, out: str, *, extra: Optional[list] = None,
                tc: Optional[TrunkTrainConfig] = None, labels: Optional[list] = None,
                max_count: int = 20, command: str = "", progress: bool = True) -> Path:
    """Fine-tune trunk blocks ``tc.freeze``..14 + a count head on the rendered train objects of
    ``data_root`` (+ every split of each ``extra`` (data, renders) pair) on the shared loop;
    keep the best of ``tc.evals`` val evaluations; write OUT/trunk.pt."""
    from model.core.training import LoopConfig, seed_all, train_loop
    from model.encoders.image import preprocess
    tc = tc or TrunkTrainConfig()
    if not 0 <= tc.freeze < COUNT_SPLIT:
        raise ValueError(f"freeze must be in [0, {COUNT_SPLIT - 1}], got {tc.freeze}")
    torch.set_num_threads(max(1, tc.threads))
    rng = seed_all(tc.seed)
    labels = count_labels_of() if labels is None else labels
    t0 = time.time()
    train, val = _trunk_sets(data_root, render_root, extra, labels, max_count, tc.centre_weight > 0)
    K = len(train.paths[0])
    log.info("trunk: %d train objects x %d views, %d val objects", len(train), K, len(val))
    enc, head, centre_head, opt, continued = _trunk_modules(tc, labels, max_count)
    model = _TrunkModel(enc, head, centre_head, tc.freeze)
    keys = trunk_keys(enc.net, tc.freeze)
    best, history, last = None, [], {}

    def step_fn(net, step):
        b, v = rng.integers(0, len(train), tc.batch_size), rng.integers(0, K, tc.batch_size)
        x = preprocess([train.paths[i][j] for i, j in zip(b, v)])
        flip = torch.from_numpy(rng.random(tc.batch_size) < tc.flip)
        x[flip] = x[flip].flip(-1)
        logits, centres = net(x)
        loss = F.cross_entropy(logits.transpose(1, 2), train.Y[torch.from_numpy(b)])
        last.update(step=step + 1, count_loss=loss.item())
        if centres is not None:
            target = train.M[torch.from_numpy(b), torch.from_numpy(v)]
            target = torch.where(flip[:, None, None, None], target.flip(-1), target)
            c_loss = centre_loss(centres, target)
            last["centre_loss"] = c_loss.item()
            loss = loss + tc.centre_weight * c_loss
        last["train_loss"] = loss.item()
        return loss, {}

    def val_fn():
        nonlocal best
        ev = _exact_counts(enc, head, val, tc.freeze)
        rec = {"step": last["step"], "train_loss": round(last["train_loss"], 4),
               "val_exact": ev["exact"],
               **({"count_loss": round(last["count_loss"], 4),
                   "centre_loss": round(last["centre_loss"], 4)} if centre_head is not None else {}),
               "val_per_label": dict(zip(labels, ev["per_label"])),
               "minutes": round((time.time() - t0) / 60, 2)}
        history.append(rec)
        if best is None or ev["exact"] > best[0]["val_exact"]:
            sd = enc.net.state_dict()
            best = (rec, half_state({k: sd[k] for k in keys}), half_state(head.state_dict()),
                    half_state(centre_head.state_dict()) if centre_head is not None else None)
        return {"exact": ev["exact"]}

    cfg = LoopConfig(steps=tc.steps, lr=tc.lr, warmup=tc.warmup, floor=0.0,
                     val_every=max(1, tc.steps // max(1, tc.evals)), progress=progress,
                     desc="train image-trunk")
    train_loop(model, opt, cfg, step_fn, val_fn=val_fn)
    info = {"command": command, "seed": tc.seed, "config": asdict(tc),
            "data_versions": train.versions, "train_objects": len(train), "views": K,
            "val_objects": len(val), "head_continued": continued, "history": history,
            "head_config": asdict(head.cfg),
            "minutes": round((time.time() - t0) / 60, 2)}
    return _write_trunk(Path(out), best, labels, tc, info)


def _write_trunk(out_dir: Path, best, labels, tc: TrunkTrainConfig, info: dict) -> Path:
    """OUT/trunk.pt of the chosen evaluation (and OUT/trunk_history.json)."""
    rec, state, head_state, centre_state = best
    out_dir.mkdir(parents=True, exist_ok=True)
    trunk = {"freeze": tc.freeze, "split": COUNT_SPLIT, "tag": trunk_tag(state),
             "state_dict": state,
             "count_head": {"config": info.pop("head_config"), "state_dict": head_state},
             **({"centre_head": {"labels": list(labels), "state_dict": centre_state}}
                if centre_state is not None else {}),
             "train": {**info, "chosen": rec}}
    meta = CheckpointMeta(kind=TRUNK_KIND, data_version=",".join(info["data_versions"]),
                          seed=tc.seed, command=info["command"], step=int(rec["step"]),
                          train_config=asdict(tc))
    write_checkpoint(out_dir / "trunk.pt", meta, trunk)
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
    ap.add_argument("--centre-weight", type=float, default=d.centre_weight,
                    help="also regress the per-cell part-centre maps of `artformer data partmaps` "
                         "with this weight (default 0: counts only)")
    ap.add_argument("--init-trunk", default="",
                    help="start from the blocks of this trunk.pt or image checkpoint "
                         "(default: ImageNet's)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--no-progress", action="store_true")
    return ap


def cli_main(argv: list[str]) -> int:
    import shlex
    args = _parser().parse_args(argv)
    labels = None
    if args.image:
        try:
            labels = count_labels_of(args.image)
        except (FileNotFoundError, ValueError) as e:
            print(f"artformer train image-trunk: --image {e}", flush=True)
            return 2
    tc = TrunkTrainConfig(steps=args.steps, batch_size=args.batch_size, lr=args.lr,
                          freeze=args.freeze, evals=args.evals, seed=args.seed, threads=args.threads,
                          centre_weight=args.centre_weight, init=args.init_trunk)
    command = "artformer train image-trunk " + " ".join(shlex.quote(a) for a in argv)
    try:
        path = train_trunk(args.data, args.renders, args.out, extra=[tuple(x) for x in args.extra_train],
                           tc=tc, labels=labels, command=command, progress=not args.no_progress)
    except (ValueError, FileNotFoundError, TrunkError) as e:
        print(f"artformer train image-trunk: {e}", flush=True)
        return 2
    print(f"trunk: {path}")
    return 0
