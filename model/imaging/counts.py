"""Image count head: how many parts of each label an image shows, read from the encoder's 7×7 map.

Why it exists. Almost every miss of the image model is a part count (doors, drawers, handles,
buttons; docs/imaging.md): the articulation transformer reads the 49 image tokens through
softmax cross-attention, which averages over tokens, and its START plan head and END
decisions under-read counts of many similar parts. A small convolutional head over the same
frozen encoder map adds the evidence of every cell instead (convolutions, then a linear
layer over the flattened 7×7 grid) and is trained directly on per-label counts. Its counts
become the decoder's plan (``ArticulationModel.decode(plan=...)``): END decisions are held
to them, everything else (which parts, joints, geometry) still comes from the transformer.

The head reads the frozen features entering EfficientNet-Lite0's last block (192 × 7 × 7,
``COUNT_SPLIT``), the map the image trainer already caches (model.imaging.features), so it
trains in minutes on a CPU and costs one extra small forward at inference.

    artformer train image-counts --image model/weights/image_small.pt \
        --data data/prepared/v1 --renders data/renders/v1 \
        --extra-train data/prepared/v1x data/renders/v1x --out runs/counts

writes ``OUT/image.pt``: the image checkpoint with a ``count_head`` entry (config, weights,
training record). ``model.imaging.model.load_image_model`` picks it up.
"""
from __future__ import annotations

import json
import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional

import torch
from torch import nn
from torch.nn import functional as F

from model.core.checkpoint import CheckpointError
from model.core.state import half_state

from .features import CACHE_SPLIT

log = logging.getLogger(__name__)

COUNT_SPLIT = CACHE_SPLIT      # the head reads the features entering block 15 (192 x 7 x 7)


# a count head that does not fit its image checkpoint (or is damaged); the one
# CheckpointError, kept under this name for one release
CountHeadError = CheckpointError


@dataclass
class CountHeadConfig:
    labels: list = field(default_factory=list)   # the transformer's count_labels, in order
    max_count: int = 20                          # classes 0..max_count per label
    in_channels: int = 192
    grid: tuple = (7, 7)
    width: int = 128
    hidden: int = 256
    dropout: float = 0.2
    split: int = COUNT_SPLIT                      # encoder blocks before the map it reads

    @classmethod
    def from_dict(cls, d: dict) -> "CountHeadConfig":
        d = dict(d)
        d["grid"] = tuple(d.get("grid", (7, 7)))
        return cls(**d)


class CountHead(nn.Module):
    """(B, C, 7, 7) encoder map → (B, labels, max_count + 1) count logits."""

    def __init__(self, cfg: CountHeadConfig):
        super().__init__()
        if not cfg.labels:
            raise ValueError("a count head needs the labels it counts")
        self.cfg = cfg
        w, cells = cfg.width, cfg.grid[0] * cfg.grid[1]
        self.body = nn.Sequential(
            nn.Conv2d(cfg.in_channels, w, 3, padding=1), nn.GELU(),
            nn.Conv2d(w, w, 3, padding=1), nn.GELU(),
            nn.Conv2d(w, w // 2, 1), nn.GELU(), nn.Flatten(),
            nn.Dropout(cfg.dropout), nn.Linear(w // 2 * cells, cfg.hidden), nn.GELU(),
            nn.Linear(cfg.hidden, len(cfg.labels) * (cfg.max_count + 1)))

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        return self.body(h.float()).view(h.shape[0], len(self.cfg.labels), self.cfg.max_count + 1)

    @torch.inference_mode()
    def predict(self, h: torch.Tensor) -> torch.Tensor:
        """→ (B, labels) most likely count of every label."""
        return self.forward(h).argmax(-1)


def count_targets(records, labels: list[str], max_count: int) -> torch.Tensor:
    """Per-label part counts of object records → (N, labels) long, clipped to max_count."""
    from model.articulation.evaluate import record_structure
    rows = []
    for rec in records:
        c = record_structure(rec)["counts"]
        rows.append([min(int(c.get(lab, 0)), max_count) for lab in labels])
    return torch.tensor(rows, dtype=torch.long)


def load_count_head(entry: dict, labels: list[str]) -> CountHead:
    """The ``count_head`` entry of an image checkpoint → CountHead (eval mode, fp32)."""
    try:
        cfg = CountHeadConfig.from_dict(entry["config"])
        head = CountHead(cfg)
        head.load_state_dict({k: v.float() for k, v in entry["state_dict"].items()})
    except Exception as e:  # noqa: BLE001 - any damage is reported the same way
        raise CountHeadError(f"the checkpoint's count head cannot be loaded ({e})") from e
    if list(cfg.labels) != list(labels):
        raise CountHeadError(f"the count head counts {cfg.labels}, the transformer's plan "
                             f"labels are {labels}")
    return head.eval()


def count_token_entry(trunk: dict, path: str = "") -> dict:
    """What an image checkpoint keeps of the count head whose distributions become its count
    tokens (``ArticulationConfig.count_tokens``): the head of a trunk file of
    ``artformer train image-trunk`` (config, fp16 weights) and the trunk it reads."""
    if not trunk.get("count_head"):
        raise CountHeadError(f"{path or 'the trunk'} has no count head")
    return {"config": dict(trunk["count_head"]["config"]),
            "state_dict": half_state(trunk["count_head"]["state_dict"]),
            "trunk_tag": trunk.get("tag"), "source": str(path)}


def count_tokens_for(ic, init: Optional[dict], trunk: Optional[dict], cfg, split: int):
    """The count head whose distributions a run adds as count tokens, and its checkpoint entry:
    ``--count-tokens TRUNK_PT``'s head (it must read this run's trunk), else the init image
    checkpoint's; (None, None) without either."""
    entry = None
    if ic.count_tokens:
        from .trunk import load_trunk
        src = load_trunk(ic.count_tokens)
        if trunk is None or src.get("tag") != trunk.get("tag"):
            raise ValueError(f"--count-tokens {ic.count_tokens}: its count head reads trunk "
                             f"{src.get('tag')}, this run's features are those of "
                             f"{None if trunk is None else trunk.get('tag')}")
        entry = count_token_entry(src, ic.count_tokens)
    elif init is not None and init.get("count_tokens"):
        entry = init["count_tokens"]
    if entry is None:
        return None, None
    try:
        head = load_count_head(entry, list(cfg.count_labels or []))
    except CountHeadError as e:
        raise ValueError(f"count tokens: {e}") from e
    if head.cfg.split != split:
        raise ValueError(f"count tokens: the head reads block {head.cfg.split}, the feature cache "
                         f"holds block {split}")
    return head, entry


def count_token_shape(head: CountHead) -> tuple[int, int]:
    """(labels, classes) of a count head's distributions: the shape of its count tokens'
    entry in ``ArticulationConfig.count_tokens``."""
    return len(head.cfg.labels), head.cfg.max_count + 1


def count_distributions(head: CountHead, h: torch.Tensor) -> torch.Tensor:
    """(B, C, 7, 7) encoder map -> (B, labels, max_count + 1) count probabilities."""
    with torch.no_grad():
        return F.softmax(head(h), -1)


def pack_count_tokens(tokens: torch.Tensor, probs: torch.Tensor) -> torch.Tensor:
    """Image tokens (B, L, D) and count probabilities (B, labels, classes) -> (B, L + labels, D):
    one more token per label whose first ``classes`` channels are its distribution (the layout
    ``ConditionEncoder`` reads for ``ArticulationConfig.count_tokens``); the rest are 0."""
    B, n, c = probs.shape
    if c > tokens.shape[2]:
        raise ValueError(f"{c} count classes do not fit in {tokens.shape[2]}-channel tokens")
    extra = tokens.new_zeros(B, n, tokens.shape[2])
    extra[..., :c] = probs.to(tokens.dtype)
    return torch.cat([tokens, extra], 1)


# ---------------------------------------------------------------------------------------------
# training
# ---------------------------------------------------------------------------------------------
@dataclass
class CountTrainConfig:
    epochs: int = 100              # passes over the training objects (one random view each)
    minutes: float = 0.0           # wall-clock cap (0 = none)
    batch_size: int = 64
    lr: float = 1e-3
    weight_decay: float = 0.05
    seed: int = 0
    threads: int = 2
    evals: int = 10                # val evaluations over the run (the best one is kept)


def _split_features(render_root, ids: list[str]):
    """Cached block-15 features of the rendered ``ids`` → (kept ids, (N, K, C, 7, 7) fp16)."""
    from .features import ViewFeatures, build_feature_cache
    from .renders import rendered_ids
    ids = rendered_ids(render_root, ids)
    vf = ViewFeatures(build_feature_cache(render_root, ids, progress=False, split=COUNT_SPLIT))
    rows = torch.tensor([vf.index[i] for i in ids], dtype=torch.long)
    return ids, vf.feats[rows]


def exact_counts(head: CountHead, X: torch.Tensor, Y: torch.Tensor, batch: int = 256) -> dict:
    """Share of (object, view) pairs whose every label count is right; X (N, K, C, 7, 7)."""
    head.eval()
    ok, per_label, loss = [], [], 0.0
    with torch.no_grad():
        for k in range(X.shape[1]):
            for s in range(0, X.shape[0], batch):
                logits = head(X[s:s + batch, k])
                y = Y[s:s + batch]
                loss += float(F.cross_entropy(logits.transpose(1, 2), y, reduction="sum"))
                hit = logits.argmax(-1) == y
                ok.append(hit.all(1))
                per_label.append(hit)
    head.train()
    n = X.shape[0] * X.shape[1]
    return {"exact": float(torch.cat(ok).float().mean()),
            "per_label": torch.cat(per_label).float().mean(0).tolist(),
            "loss": loss / (n * Y.shape[1])}


def _count_sets(data_root, render_root, extra, labels: list, max_count: int):
    """Cached features and count targets: train (+ every split of the extra sets) and val.
    -> X train (N, K, C, 7, 7), Y train, X val, Y val, data versions."""
    from model.data import format as fmt

    def load(root, rroot, splits):
        ids = [i for s in splits for i in fmt.split_ids(root, s)]
        ids, X = _split_features(rroot, ids)
        Y = count_targets([fmt.load_record(root, i) for i in ids], labels, max_count)
        return X, Y, fmt.load_manifest(root).get("data_version", "?")

    sets = [load(data_root, render_root, ("train",))]
    for droot, rroot in extra or []:
        sets.append(load(droot, rroot, ("train", "val", "test")))
        if sets[-1][0].shape[1:] != sets[0][0].shape[1:]:
            raise ValueError(f"{rroot}: features {tuple(sets[-1][0].shape[1:])} differ from "
                             f"{render_root}'s {tuple(sets[0][0].shape[1:])}")
    Xs, Ys, versions = (list(col) for col in zip(*sets))
    if len(set(versions)) < len(versions):
        raise ValueError(f"training sets share a data version {versions}; extra objects need their own")
    Xva, Yva, _ = load(data_root, render_root, ("val",))
    return torch.cat(Xs), torch.cat(Ys), Xva, Yva, versions


def train_count_head(image_ckpt: str, data_root: str, render_root: str, out: str, *,
                     extra: Optional[list] = None, tc: Optional[CountTrainConfig] = None,
                     command: str = "", half: bool = True, progress: bool = True) -> Path:
    """Train a count head for ``image_ckpt`` on the rendered train objects of ``data_root``
    (+ every split of each ``extra`` (data, renders) pair); pick the best of ``tc.evals``
    evaluations on the val renders; write OUT/image.pt (the image checkpoint + the head)."""
    from model.articulation.checkpoint import read_checkpoint, save_dict
    from model.core.training import seed_all

    tc = tc or CountTrainConfig()
    torch.set_num_threads(max(1, tc.threads))
    rng = seed_all(tc.seed)
    ck = read_checkpoint(image_ckpt)
    if ck.get("condition") != "image":
        raise CountHeadError(f"{image_ckpt} is not an image checkpoint (`artformer train image`)")
    if (ck.get("image_encoder") or {}).get("trunk"):
        raise CountHeadError(f"{image_ckpt} reads a fine-tuned trunk; this head trains on the "
                             f"ImageNet trunk's features (`artformer train image-trunk` trains "
                             f"a count head with its trunk)")
    labels = list(ck["config"].get("count_labels") or [])
    if not labels:
        raise CountHeadError(f"{image_ckpt} has no plan labels (count_labels) to count")
    cfg = CountHeadConfig(labels=labels, max_count=int(ck["config"].get("plan_max_count", 20)))
    t0 = time.time()

    Xtr, Ytr, Xva, Yva, versions = _count_sets(data_root, render_root, extra, labels,
                                               cfg.max_count)
    cfg.in_channels = int(Xtr.shape[2])
    cfg.grid = (int(Xtr.shape[3]), int(Xtr.shape[4]))
    N, K = Xtr.shape[:2]
    log.info("count head: %d train objects x %d views, %d val objects; features %.0f s",
             N, K, len(Xva), time.time() - t0)

    head = CountHead(cfg)
    opt = torch.optim.AdamW(head.parameters(), lr=tc.lr, weight_decay=tc.weight_decay)
    steps = max(1, tc.epochs * N // tc.batch_size)
    best, history, last = None, [], {}

    def step_fn(net, step):
        b = torch.from_numpy(rng.integers(0, N, tc.batch_size))
        v = torch.from_numpy(rng.integers(0, K, tc.batch_size))
        loss = F.cross_entropy(net(Xtr[b, v]).transpose(1, 2), Ytr[b])
        last.update(step=step + 1, loss=loss.item())
        return loss, {}

    def val_fn():
        nonlocal best
        ev = exact_counts(head, Xva, Yva) if len(Xva) else {"exact": float("nan"), "loss": float("nan")}
        rec = {"step": last["step"], "train_loss": last["loss"], "val_exact": ev["exact"],
               "val_loss": ev["loss"], "minutes": (time.time() - t0) / 60}
        history.append(rec)
        if best is None or (ev["exact"], -ev["loss"]) > (best[0]["val_exact"], -best[0]["val_loss"]):
            best = (rec, {k: v.detach().clone() for k, v in head.state_dict().items()},
                    ev.get("per_label"))
        return {"exact": ev["exact"], "loss": ev["loss"]}

    from model.core.training import LoopConfig, train_loop
    train_loop(head, opt, LoopConfig(steps=steps, lr=tc.lr, warmup=max(1, steps // 10), floor=0.0,
                                     minutes=tc.minutes, val_every=max(1, steps // max(1, tc.evals)),
                                     progress=progress, desc="train image-counts"),
               step_fn, val_fn=val_fn)
    rec, state, per_label = best
    if half:
        state = half_state(state)
    ck["count_head"] = {
        "config": asdict(cfg), "state_dict": state,
        "train": {"command": command, "seed": tc.seed, "config": asdict(tc),
                  "data_versions": versions, "train_objects": int(N), "views": int(K),
                  "val_objects": int(len(Xva)), "chosen": rec,
                  "val_per_label": dict(zip(labels, per_label or [])),
                  "history": history, "minutes": (time.time() - t0) / 60,
                  "image_checkpoint": str(image_ckpt)}}
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    save_dict(out_dir / "image.pt", ck)
    (out_dir / "count_history.json").write_text(json.dumps(ck["count_head"]["train"], indent=1))
    log.info("count head: chose step %d (val exact %.4f); wrote %s", rec["step"], rec["val_exact"],
             out_dir / "image.pt")
    return out_dir / "image.pt"


# ---------------------------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------------------------
def _parser():
    import argparse
    ap = argparse.ArgumentParser(
        prog="artformer train image-counts",
        description="Train the image count head (per-label part counts from the encoder's 7x7 "
                    "map) of an image checkpoint; the decoder then follows its counts.")
    ap.add_argument("--image", default="model/weights/image_small.pt",
                    help="image checkpoint to add the head to")
    ap.add_argument("--data", default="data/prepared/v1")
    ap.add_argument("--renders", default="data/renders/v1")
    ap.add_argument("--extra-train", nargs=2, action="append", default=[],
                    metavar=("DATA", "RENDERS"),
                    help="more training objects (all splits), as for `artformer train image`")
    ap.add_argument("--out", default="runs/image_counts")
    ap.add_argument("--epochs", type=int, default=CountTrainConfig.epochs)
    ap.add_argument("--minutes", type=float, default=0.0)
    ap.add_argument("--batch-size", type=int, default=CountTrainConfig.batch_size)
    ap.add_argument("--lr", type=float, default=CountTrainConfig.lr)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--fp32", action="store_true", help="store the head in fp32 (default fp16)")
    return ap


def cli_main(argv: list[str]) -> int:
    import shlex
    args = _parser().parse_args(argv)
    if not Path(args.image).exists():
        print(f"artformer train image-counts: --image {args.image} does not exist", flush=True)
        return 2
    tc = CountTrainConfig(epochs=args.epochs, minutes=args.minutes, batch_size=args.batch_size,
                          lr=args.lr, seed=args.seed, threads=args.threads)
    command = "artformer train image-counts " + " ".join(shlex.quote(a) for a in argv)
    try:
        path = train_count_head(args.image, args.data, args.renders, args.out,
                                extra=[tuple(x) for x in args.extra_train], tc=tc, command=command,
                                half=not args.fp32, progress=not args.no_progress)
    except CountHeadError as e:
        print(f"artformer train image-counts: {e}", flush=True)
        return 2
    print(f"checkpoint: {path}")
    return 0
