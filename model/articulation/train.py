"""Training of the articulation transformer (DESIGN §5).

    prepare_data(data_root, targets, cache_dir)  -> PreparedData (items, stats, label table)
    train(run_cfg)                               -> path of the final checkpoint

Samples are decoding rounds of the ground-truth trees (see ``data``); every step draws a
batch of (object, round) pairs, one description per object from a random length, and drops
the text condition per sample with probability ``cond_dropout``.
"""
from __future__ import annotations

import json
import logging
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Optional

import numpy as np
import torch

from model.core.files import atomic_write_bytes
from model.data import format as fmt
from model.data.vocab import semantic_text

from .checkpoint import read_checkpoint, save_checkpoint
from .config import ArticulationConfig, TrainConfig
from .frames import check_frame, to_frame
from .data import (TextCache, TreeItem, collate, group_rounds, make_item, pick_texts,
                   round_sample)
from .network import ArticulationTransformer

log = logging.getLogger(__name__)


@dataclass
class PreparedData:
    items: dict[str, list[TreeItem]]           # split -> items
    stats: dict                                # tok_mean/tok_std (16,), z_mean/z_std or None
    label_table: dict                          # categories, labels, cs (T, 64)
    geo_shape: tuple[int, ...]                 # (C, N) or (Z,)
    data_version: str
    records: dict[str, list[fmt.ObjectRecord]] = field(default_factory=dict)


def _part_targets(root: Path, recs: list[fmt.ObjectRecord], targets, predict_z: bool,
                  cache_path: Optional[Path], progress: bool = True) -> dict[str, np.ndarray]:
    """Per object: geometry target of every part (P_gt (K,C,N) or raw z (K,Z)), cached."""
    # the codebook layout is part of the key: the one_codebook ablation's view of the same
    # prior gives (K, 1, C*N) targets, which a (K, C, N) cache must not stand in for
    layout = getattr(getattr(targets, "cfg", None), "num_codebooks", "")
    key = f"{getattr(targets, 'name', 'targets')}:{getattr(targets, 'prior_path', '')}:" \
          f"{getattr(targets, 'sdf_path', '')}:{'z' if predict_z else f'P{layout}'}"
    cache = {}
    if cache_path is not None and cache_path.exists():
        from model.core.checkpoint import load_weights_only
        try:
            d = load_weights_only(cache_path)
        except Exception as e:  # noqa: BLE001 - a damaged cache is rebuilt
            log.warning("part-target cache %s unreadable (%s); rebuilding it", cache_path, e)
            d = {}
        if d.get("key") == key:
            cache = d["geo"]
    todo = [r for r in recs if r.id not in cache]
    if todo:
        from tqdm import tqdm
        for r in tqdm(todo, desc="part targets", unit="obj", disable=not progress or len(todo) < 50):
            arr = fmt.load_part_arrays(root, r.id)
            z = targets.part_latents(arr["points"].astype(np.float32))          # (K, Z)
            if predict_z:
                cache[r.id] = np.asarray(z, np.float32)
            else:
                cache[r.id] = targets.code_distribution(torch.as_tensor(z)).numpy().astype(np.float32)
        if cache_path is not None:
            cache_path.parent.mkdir(parents=True, exist_ok=True)
            import io
            buf = io.BytesIO()
            torch.save({"key": key, "geo": cache}, buf)
            atomic_write_bytes(cache_path, buf.getvalue())
    return cache


def prepare_data(data_root: str, targets, *, predict_z: bool = False,
                 splits: tuple[str, ...] = ("train", "val"),
                 cache_dir: Optional[str] = None, stats: Optional[dict] = None,
                 label_table: Optional[dict] = None, progress: bool = True,
                 frame: str = "absolute") -> PreparedData:
    """Read a prepared dataset and build training items. ``stats`` / ``label_table`` from a
    checkpoint are reused when given (evaluation), else computed on the train split; the
    token frame (model.articulation.frames) is the stats' own, else ``frame``."""
    root = Path(data_root)
    manifest = fmt.load_manifest(root)
    version = str(manifest.get("data_version", "unknown"))
    cache = Path(cache_dir) if cache_dir else None
    recs = {s: [fmt.load_record(root, i) for i in manifest["splits"].get(s, [])]
            for s in set(splits) | {"train"}}
    if not recs["train"]:
        raise ValueError(f"{root}: the train split is empty")
    geo = {}
    for s, rs in recs.items():
        if s in splits or stats is None:
            geo.update(_part_targets(root, rs, targets, predict_z,
                                     cache / f"targets_{version}_{s}.pt" if cache else None,
                                     progress))
    if stats is None:
        toks = np.concatenate([to_frame(r.tokens, r.parents, frame) for r in recs["train"]])
        std = toks.std(0)
        stats = {"tok_mean": toks.mean(0).astype(np.float32),
                 "tok_std": np.maximum(std, 1e-3).astype(np.float32),
                 "z_mean": None, "z_std": None, "frame": check_frame(frame)}
        if predict_z:
            zs = np.concatenate([geo[r.id] for r in recs["train"]])
            stats["z_mean"] = zs.mean(0).astype(np.float32)
            stats["z_std"] = np.maximum(zs.std(0), 1e-3).astype(np.float32)
    # c_s of every (category, label) pair; the table decodes labels at generation
    pairs = sorted({(r.category, lab) for s in recs for r in recs[s] for lab in r.labels})
    cs_new = targets.semantic_condition([semantic_text(c, l) for c, l in pairs])
    cs_of = {p: cs_new[i].numpy().astype(np.float32) for i, p in enumerate(pairs)}
    if label_table is None:
        train_pairs = sorted({(r.category, lab) for r in recs["train"] for lab in r.labels})
        label_table = {"categories": [c for c, _ in train_pairs],
                       "labels": [l for _, l in train_pairs],
                       "cs": np.stack([cs_of[p] for p in train_pairs])}
    if "cs_mean" not in stats:
        part_cs = np.stack([cs_of[(r.category, lab)] for r in recs["train"] for lab in r.labels])
        stats["cs_mean"] = part_cs.mean(0).astype(np.float32)
        stats["cs_std"] = np.maximum(part_cs.std(0), 1e-3).astype(np.float32)
    row_of = {p: i for i, p in enumerate(zip(label_table["categories"], label_table["labels"]))}
    items = {}
    for s in splits:
        out = []
        for r in recs[s]:
            g = geo[r.id]
            if predict_z:
                g = (g - stats["z_mean"]) / stats["z_std"]
            cs = np.stack([cs_of[(r.category, lab)] for lab in r.labels])
            cs = (cs - stats["cs_mean"]) / stats["cs_std"]
            lab_idx = np.array([row_of.get((r.category, lab), -1) for lab in r.labels])
            out.append(make_item(r, stats["tok_mean"], stats["tok_std"], cs, g, lab_idx,
                                 stats.get("frame", "absolute")))
        items[s] = out
    geo_shape = tuple(next(iter(geo.values())).shape[1:])
    return PreparedData(items, stats, label_table, geo_shape, version,
                        {s: recs[s] for s in splits})


def extra_training_items(data: PreparedData, root: str, prefix: str, targets, *,
                         predict_z: bool = False, cache_dir: Optional[str] = None,
                         progress: bool = True, wordings: int = 0) -> tuple[list[TreeItem], str]:
    """Every object of another prepared dataset (all three splits) as training items, its
    ids prefixed with ``prefix`` and its tokens normalised with ``data``'s stats and label
    table, so the network trained on ``data`` reads them the same way. Its data version
    must differ from ``data``'s (the same objects twice would leak validation objects into
    training). ``wordings`` > 0 keeps only the first that many wordings of every description
    length (fewer text-encoder states to cache; 0 = all). -> (items, its data version)."""
    if wordings < 0:
        raise ValueError(f"wordings must be >= 0 (0 = all), got {wordings}")
    xd = prepare_data(root, targets, predict_z=predict_z, splits=("train", "val", "test"),
                      cache_dir=cache_dir, stats=data.stats, label_table=data.label_table,
                      progress=progress)
    if xd.data_version == data.data_version:
        raise ValueError(f"extra data {root} has the main data's version "
                         f"{data.data_version!r}; extra objects need their own version")
    items = [replace(it, id=prefix + it.id,
                     texts=[g[:wordings] for g in it.texts] if wordings else it.texts)
             for s in ("train", "val", "test") for it in xd.items[s]]
    return items, xd.data_version


def all_samples(items: list[TreeItem]) -> list[tuple[int, int]]:
    return [(i, k) for i, it in enumerate(items) for k in range(it.num_rounds)]


def label_cs_normalised(data: "PreparedData") -> torch.Tensor:
    st = data.stats
    return torch.as_tensor((np.asarray(data.label_table["cs"]) - st["cs_mean"]) / st["cs_std"],
                           dtype=torch.float32)


def make_batch(items: list[TreeItem], groups: list[tuple[int, list[int]]], geo_shape,
               text_cache: TextCache, rng: np.random.Generator,
               label_cs: Optional[torch.Tensor] = None, count_labels: Optional[list] = None):
    """groups: (item index, rounds). One description per object, shared by its rounds.
    -> batch, targets, cond tokens (U, L, D), cond mask (U, L), cond_index (B,)."""
    samples, index = [], []
    for u, (i, rounds) in enumerate(groups):
        for k in rounds:
            samples.append(round_sample(items[i], k))
            index.append(u)
    batch, targets = collate(samples, geo_shape, label_cs, count_labels)
    texts = pick_texts([items[i] for i, _ in groups], rng)
    cond, cmask = text_cache.batch(texts)
    return batch, targets, cond, cmask, torch.tensor(index)


@torch.no_grad()
def own_input_tokens(net: ArticulationTransformer, items: list[TreeItem], groups, batch,
                     cond: torch.Tensor, cmask: torch.Tensor, modality: str, share: float,
                     rng: np.random.Generator, geo_shape) -> int:
    """Scheduled sampling against exposure bias. Iterative decoding feeds the network's own
    articulation predictions back as node tokens, training feeds the ground truth; the END
    decisions learnt on exact geometry then drift on predicted geometry (the shipped model made
    1.4x more teacher-forced END errors on test prompts with its own tokens as inputs).

    For a random ``share`` of the objects of a batch (``groups`` as in ``make_batch``), every
    existing node's tokens in ``batch`` (B, N, 16) are replaced, in place, by what the network
    (eval mode, no gradient) predicts for that node from its parent in the round that adds it,
    with the ground-truth tree before that round. Labels, joint types and targets stay
    ground truth. Returns the number of objects rewritten."""
    pick = [u for u in range(len(groups)) if rng.random() < share]
    samples, index, spans = [], [], {}
    for u in pick:
        i, rounds = groups[u]
        first = len(samples)
        for k in range(max(rounds)):       # inputs of round k were added in rounds < k
            samples.append(round_sample(items[i], k))
            index.append(u)
        spans[u] = (first, len(samples))
    if not samples:
        return 0
    ref, _ = collate(samples, geo_shape, None, net.cfg.count_labels)
    was = net.training
    net.eval()
    out, _ = net(ref, cond, cmask, modality, cond_index=torch.tensor(index))
    net.train(was)
    own = {}
    for u, (a, b) in spans.items():
        it = items[groups[u][0]]
        pred = torch.as_tensor(it.tokens).clone()                         # (K, 16) normalised
        for r in range(a, b):
            t = samples[r]["target"]
            sel = np.nonzero(t >= 0)[0]
            pred[t[sel]] = out["art"][r, sel]
        own[u] = pred
    row = 0
    for u, (i, rounds) in enumerate(groups):
        for k in rounds:
            if u in own:
                present = np.nonzero(items[i].rounds < k)[0]
                batch.tokens[row, 1:1 + len(present)] = own[u][present]
            row += 1
    return len(own)


def loop_config(tc: TrainConfig, desc: str, progress: bool, out=None,
                chunk_minutes: float = 0.0) -> "LoopConfig":
    """The shared loop's settings of a transformer run (text or image): warm-up, then cosine
    to 10 % by max_steps or by the wall-clock budget, whichever comes first."""
    from model.core.training import LoopConfig
    return LoopConfig(steps=tc.max_steps, lr=tc.lr, warmup=tc.warmup_steps, floor=0.1,
                      minutes=tc.max_minutes, val_every=tc.val_every, ckpt_every=tc.ckpt_every,
                      grad_clip=tc.grad_clip, progress=progress, desc=desc,
                      log_dir=None if out is None else str(out), chunk_minutes=chunk_minutes)


@dataclass
class RunConfig:
    data: str
    out: str
    net: ArticulationConfig
    train: TrainConfig
    targets: object = None            # a targets provider (PriorTargets / StandInTargets)
    resume: bool = False
    init: Optional[str] = None       # start from this checkpoint's weights (fine-tuning)
    ablation: str = "none"
    command: str = ""
    progress: bool = True
    extra: list = field(default_factory=list)   # more prepared datasets, all splits to train
    extra_wordings: int = 0          # wordings per description length kept for them (0 = all)
    chunk_minutes: float = 0.0       # stop this process after M minutes (resume continues)


@torch.no_grad()
def mean_losses(net: ArticulationTransformer, items, tc: TrainConfig, n_batches: int, seed: int,
                modality: str, make_batch_fn) -> dict:
    """Mean loss terms over a fixed random subset of decoding rounds (no dropout).

    ``make_batch_fn(groups, rng) -> (batch, targets, cond, cmask, cond_index)`` builds one
    batch for the condition modality (text or image)."""
    was = net.training
    net.eval()
    rng = np.random.default_rng(seed)
    batches = group_rounds(items, rng.permutation(len(items)), tc.batch_size,
                           tc.rounds_per_object, rng)
    sums: dict[str, float] = {}
    nb = 0
    for groups in batches[:n_batches]:
        batch, targets, cond, cmask, idx = make_batch_fn(groups, rng)
        _, L = net(batch, cond, cmask, modality, cond_index=idx, targets=targets,
                   weights=asdict(tc))
        for k, v in L.items():
            sums[k] = sums.get(k, 0.0) + float(v)
        nb += 1
    net.train(was)
    return {k: v / max(nb, 1) for k, v in sums.items()}


def evaluate_loss(net: ArticulationTransformer, items, geo_shape, text_cache, tc: TrainConfig,
                  n_batches: int, seed: int = 1234, label_cs: Optional[torch.Tensor] = None) -> dict:
    """Mean loss terms of the text-conditioned network (see ``mean_losses``)."""
    return mean_losses(net, items, tc, n_batches, seed, "text",
                       lambda groups, rng: make_batch(items, groups, geo_shape, text_cache, rng,
                                                      label_cs, net.cfg.count_labels))


def _configure(cfg: ArticulationConfig, tg) -> None:
    """The network's target dimensions from the targets provider."""
    cfg.cs_dim = int(tg.cs_dim)
    if cfg.predict_z:
        cfg.z_dim = int(tg.z_dim)
    elif cfg.num_codebooks != 1:
        cfg.num_codebooks, cfg.codebook_size = int(tg.num_codebooks), int(tg.codebook_size)
    else:   # one_codebook ablation: see _CodebookView
        cfg.codebook_size = int(tg.num_codebooks) * int(tg.codebook_size)


def _text_data(rc: RunConfig, cfg: ArticulationConfig, out: Path):
    """Items (train, val), the extra-data record and the text cache of a run; caches under
    OUT/cache. -> data, train items, val items, extra info, text cache."""
    tc = rc.train
    view = _CodebookView(rc.targets, cfg)
    data = prepare_data(rc.data, view, predict_z=cfg.predict_z,
                        cache_dir=str(out / "cache"), progress=rc.progress,
                        frame=tc.token_frame)
    tr, va = data.items["train"], data.items.get("val") or []
    extra_info = []
    for j, root in enumerate(rc.extra):
        items, version = extra_training_items(data, root, f"x{j}:", view,
                                              predict_z=cfg.predict_z,
                                              cache_dir=str(out / "cache"),
                                              progress=rc.progress, wordings=rc.extra_wordings)
        tr = tr + items
        extra_info.append({"data": str(root), "data_version": version, "objects": len(items),
                           "wordings": rc.extra_wordings or "all"})
    log.info("data %s: %d train / %d val objects, %d train rounds, %d labels%s",
             data.data_version, len(tr), len(va), len(all_samples(tr)),
             len(data.label_table["labels"]),
             "".join(f"; + {x['data_version']}: {x['objects']}" for x in extra_info))
    text_cache = TextCache.load(out / "cache" / "texts.pt", tc.text_encoder)
    n_before = len(text_cache.index)
    text_cache.add([t for it in tr + va for g in it.texts for t in g], tc.max_text_tokens,
                   progress=rc.progress)
    if len(text_cache.index) != n_before:
        text_cache.save(out / "cache" / "texts.pt")
    return data, tr, va, extra_info, text_cache


def _start_state(rc: RunConfig, net: ArticulationTransformer, opt, last: Path, extra_info,
                 prior: str):
    """Weights of --init, or where --resume continues (None: a fresh run)."""
    from model.core.training import LoopState
    if rc.init and not (rc.resume and last.exists()):
        src = read_checkpoint(rc.init)
        own = net.state_dict()
        same = {k: v.float() if v.is_floating_point() else v
                for k, v in src["state_dict"].items() if k in own and own[k].shape == v.shape}
        net.load_state_dict(same, strict=False)
        skipped = sorted(set(own) - set(same))
        log.info("initialised from %s (%d tensors; not taken: %s)", rc.init, len(same),
                 skipped[:8] or "none")
    if not (rc.resume and last.exists()):
        return None
    ck = read_checkpoint(last, prior=prior)
    if ArticulationConfig.from_dict(ck["config"]) != net.cfg:   # older fields defaulted
        raise ValueError(f"{last} was trained with another config; drop --resume or use "
                         f"another --out")
    had = [(x["data_version"], x.get("wordings", "all")) for x in ck.get("extra_train", [])]
    if had != [(x["data_version"], x["wordings"]) for x in extra_info]:
        raise ValueError(f"{last} was trained with extra data {had or 'none'} (data "
                         f"version, wordings); resume it with the same --extra-train "
                         f"folders, in the same order, and the same --extra-wordings")
    net.load_state_dict(ck["state_dict"])
    opt.load_state_dict(ck["optimizer"])
    log.info("resumed %s at step %d", last, ck["step"])
    return LoopState.of(ck)


def train(rc: RunConfig) -> Path:
    """Train (or resume) a run in ``rc.out``; writes last.pt (resumable) and transformer.pt.
    Under torchrun every process trains on its share of each epoch's batches (DDP)."""
    from model.core.training import Dist, seed_all, train_loop
    tc, cfg, tg = rc.train, rc.net, rc.targets
    torch.set_num_threads(max(1, tc.threads))
    dist = Dist()
    out = Path(rc.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.time()
    _configure(cfg, tg)
    if not dist.main:
        dist.barrier()                       # rank 0 builds the caches first
    data, tr, va, extra_info, text_cache = _text_data(rc, cfg, out)
    if dist.main:
        dist.barrier()
    if text_cache.dim != cfg.cond_dims.get("text"):
        cfg.cond_dims["text"] = text_cache.dim
    if cfg.child_counts:
        cfg.count_labels = sorted(set(data.label_table["labels"]))
    rng = seed_all(tc.seed)
    net = ArticulationTransformer(cfg)
    opt = torch.optim.AdamW(net.parameters(), lr=tc.lr, weight_decay=tc.weight_decay,
                            betas=(0.9, 0.98))
    prior = getattr(tg, "fingerprint", "")
    state = _start_state(rc, net, opt, out / "last.pt", extra_info, prior)
    if cfg.place_bins:
        net.set_token_norm(data.stats["tok_mean"], data.stats["tok_std"])
    if state is not None:
        rng = np.random.default_rng(tc.seed + state.step)
    order = rng                                  # one stream for one process (as before DDP)
    if dist.active:                              # same epoch order everywhere, own sampling
        rng = np.random.default_rng([tc.seed, dist.rank, 0 if state is None else state.step])
    common = dict(stats=data.stats, label_table=data.label_table, text_encoder=tc.text_encoder,
                  data_version=data.data_version, seed=tc.seed, command=rc.command,
                  train_config=asdict(tc), prior=prior)
    meta = {"ablation": rc.ablation, "targets": getattr(tg, "name", "?"), "init": rc.init or "",
            "extra_train": extra_info}

    def save(st, final: bool) -> None:
        run = {**meta, **st.entries()}
        save_checkpoint(out / "last.pt", net, extra={**run, "optimizer": opt.state_dict()},
                        **{**common, "step": st.step})
        if final:
            save_checkpoint(out / "transformer.pt", net, extra=run, **{**common, "step": st.step})
            (out / "history.json").write_text(json.dumps(st.history, indent=1))

    label_cs = label_cs_normalised(data)
    epoch: list = []

    def step_fn(model, step):
        nonlocal epoch
        if not epoch:
            epoch = dist.shard(group_rounds(tr, order.permutation(len(tr)), tc.batch_size,
                                            tc.rounds_per_object, order))
        groups = epoch.pop()
        batch, targets, cond, cmask, idx = make_batch(tr, groups, data.geo_shape, text_cache,
                                                      rng, label_cs, cfg.count_labels)
        drop = torch.from_numpy(rng.random(len(groups)) < tc.cond_dropout)[idx]
        if tc.own_inputs > 0:
            own_input_tokens(net, tr, groups, batch, cond, cmask, "text", tc.own_inputs, rng,
                             data.geo_shape)
        _, L = model(batch, cond, cmask, "text", drop=drop, cond_index=idx, targets=targets,
                     weights=asdict(tc))
        return L["total"], {k: float(v.detach()) for k, v in L.items()
                            if k in ("end", "art", "jt", "cs")}

    def val_fn():
        return evaluate_loss(net, va, data.geo_shape, text_cache, tc, tc.val_batches,
                             label_cs=label_cs) if va else None

    lc = loop_config(tc, "train transformer", rc.progress, out, rc.chunk_minutes)
    st = train_loop(net, opt, lc, step_fn,
                    val_fn=val_fn, save_fn=save, state=state, dist=dist, unused_params=True)
    dist.close()
    log.info("done: %d steps in %.1f min", st.step, (time.time() - t_start) / 60)
    return out / "transformer.pt"


class _CodebookView:
    """Targets seen through the network's codebook layout. For the one_codebook ablation
    with a prior of C > 1 codebooks, P_gt becomes one categorical over all C*N codes (the
    C distributions concatenated and renormalised); a prior trained with a single codebook
    is used as it is."""

    def __init__(self, targets, cfg: ArticulationConfig):
        self.t, self.cfg = targets, cfg
        self.name = getattr(targets, "name", "targets")
        self.prior_path = getattr(targets, "prior_path", "")
        self.sdf_path = getattr(targets, "sdf_path", "")
        self.cs_dim = targets.cs_dim

    def part_latents(self, points):
        return self.t.part_latents(points)

    def code_distribution(self, z):
        P = self.t.code_distribution(z)                       # (K, C, N)
        if self.cfg.num_codebooks == 1 and P.shape[1] != 1:
            K = P.shape[0]
            P = (P / P.shape[1]).reshape(K, 1, -1)            # (K, 1, C*N)
        return P

    def semantic_condition(self, texts):
        return self.t.semantic_condition(texts)
