"""Training of the image-conditioned articulation transformer (`artformer train image`).

The network is the articulation transformer itself (model.articulation): its condition
interface takes any tokens (B, L, D) + mask with a per-modality input projection, and the
image modality (D = 1280) is already part of every config. This module supplies the
condition: for every training sample (object, decoding round) one random rendered view of the
object, through the EfficientNet-Lite0 tail over cached trunk features (model.imaging.features).

* frozen encoder (``trainable_blocks = 0``): the 49 × 1280 tokens of every view are computed
  once at start (fp16, in memory), a step costs what a text step costs;
* light fine-tuning (``trainable_blocks = 1``): the last MBConv block + head conv train with
  the transformer (learning rate × ``tail_lr_mult``), the tail runs every step.

By default the run starts from the trained text model (same config, normalisation and label
table; only the image projection is new), which shortens training a lot on a CPU.

A checkpoint is an articulation checkpoint (model.articulation.checkpoint) with extra keys:
``condition = "image"``, ``image_encoder = {"config": ..., "tail": fine-tuned weights}``,
``renders`` (render-set manifest), ``init`` (the text checkpoint it started from).
"""
from __future__ import annotations

import json
import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
import torch

from model.core.state import half_state
from model.encoders.image import NUM_TOKENS, check_image_size

from .counts import count_token_shape

log = logging.getLogger(__name__)


@dataclass
class ImageTrainConfig:
    trainable_blocks: int = 0      # 0 = frozen encoder; 1 = fine-tune the last block + head conv
    tail_lr_mult: float = 0.1      # learning-rate factor of the fine-tuned encoder tail
    init: str = "model/weights/transformer_small.pt"   # text checkpoint to start from, or "none"
    eval_views: int = 0            # val loss: views per object (0 = all)
    positions: bool = True         # 2-D position embedding of the 7x7 image tokens (without it
                                   # cross-attention sees an unordered set of 49 features)
    multiscale: bool = False       # tokens also carry the folded 14x14 block-10 map (1728-d)
    trunk: str = ""                # fine-tuned trunk (`artformer train image-trunk`); "" = the
                                   # init image checkpoint's, else ImageNet's
    image_size: int = 224          # encoder input side (448: 2x-upsampled renders, the finer
                                   # map pooled to the 7x7 token grid before the last block)
    count_tokens: str = ""         # trunk file whose count head's per-label distributions
                                   # join the condition as count tokens; "" = the init image
                                   # checkpoint's count tokens if it has them, else none
    count_truth: float = 0.0       # share of training views whose count tokens carry the
                                   # object's true counts (one-hot) instead of the head's
                                   # readings; validation always reads the head


@dataclass
class ImageRunConfig:
    data: str
    renders: str
    out: str
    net: object                    # ArticulationConfig (replaced by the init checkpoint's)
    train: object                  # TrainConfig
    image: ImageTrainConfig = field(default_factory=ImageTrainConfig)
    targets: object = None         # PriorTargets / StandInTargets (model.articulation.targets)
    command: str = ""
    progress: bool = True
    # more training objects: (prepared data, its render set) pairs; every split of them is
    # used for training (validation and the held-out test stay those of ``data``)
    extra: list = field(default_factory=list)


class ImageConditions:
    """Condition tokens of rendered views, from cached trunk features (and, for multiscale
    tokens, the cached 14x14 block-10 features ``fine``, same ids and views)."""

    def __init__(self, feats, encoder, precompute: bool, chunk: int = 256, fine=None,
                 counter=None):
        self.feats, self.encoder, self.fine = feats, encoder, fine
        if encoder.config.multiscale and (fine is None or any(i not in fine for i in feats.ids)):
            raise ValueError("multiscale tokens need the block-10 feature cache of every object")
        self.tokens = None
        N, K = feats.feats.shape[:2]
        flat = feats.feats.reshape(N * K, *feats.feats.shape[2:])              # (N*K, C, 7, 7)
        if precompute:   # frozen encoder: every view's tokens once, fp16
            out = torch.empty(N * K, NUM_TOKENS, encoder.dim, dtype=torch.float16)
            with torch.no_grad():
                for s in range(0, N * K, chunk):
                    f = None
                    if fine is not None:   # the same views' fine maps, chunk by chunk (GBs)
                        at = range(s, min(s + chunk, N * K))
                        f = fine.batch([feats.ids[n // K] for n in at], [n % K for n in at])
                    out[s:s + chunk] = encoder.tail(flat[s:s + chunk].float(), feats.split,
                                                    fine=f).half()
            self.tokens = out.view(N, K, NUM_TOKENS, encoder.dim)              # (N, K, 49, D)
            self.fine = None          # read into the tokens
        self.counts = None
        if counter is not None:   # the count head reads the cached map itself: every view once
            from .counts import count_distributions
            self.counts = torch.cat([count_distributions(counter, flat[s:s + chunk].float())
                                     for s in range(0, N * K, chunk)]
                                    ).view(N, K, *count_token_shape(counter))

    @property
    def views(self) -> int:
        return self.feats.views

    def batch(self, ids: list[str], views: list[int]) -> tuple[torch.Tensor, torch.Tensor]:
        """-> tokens (B, 49 [+ count labels], D) float32, mask (B, same) bool."""
        rows = torch.tensor([self.feats.index[i] for i in ids])
        if self.tokens is not None:
            tok = self.tokens[rows, torch.as_tensor(views)].float()
        else:
            fine = None if self.fine is None else self.fine.batch(ids, views)
            tok = self.encoder.tail(self.feats.batch(ids, views), self.feats.split, fine=fine)
        if self.counts is not None:
            from .counts import pack_count_tokens
            tok = pack_count_tokens(tok, self.counts[rows, torch.as_tensor(views)])
        return tok, torch.ones(tok.shape[:2], dtype=torch.bool)


def _true_count_tokens(cond: torch.Tensor, items: list, labels: list, classes: int, rows) -> None:
    """Put the true per-label counts of ``items`` (one-hot over ``classes``, clipped) into the
    count tokens at the end of the selected ``rows`` of ``cond`` (U, 49 + labels, D), in place."""
    n = len(labels)
    for u, (it, pick) in enumerate(zip(items, rows)):
        if pick:
            cond[u, -n:] = 0
            for j, lab in enumerate(labels):
                cond[u, -n + j, min(it.labels.count(lab), classes - 1)] = 1.0


def _image_batch(items, groups, views, geo_shape, conds: ImageConditions, label_cs=None,
                 count_labels=None):
    """groups: (item index, rounds), one view per group shared by its rounds.
    -> batch, targets, cond tokens (U, 49, 1280), cond mask (U, 49), cond_index (B,)."""
    from model.articulation.data import collate, round_sample
    samples, index = [], []
    for u, (i, rounds) in enumerate(groups):
        for k in rounds:
            samples.append(round_sample(items[i], k))
            index.append(u)
    batch, targets = collate(samples, geo_shape, label_cs, count_labels)
    cond, cmask = conds.batch([items[i].id for i, _ in groups], views)
    return batch, targets, cond, cmask, torch.tensor(index)


def evaluate_image_loss(net, items, geo_shape, conds: ImageConditions, tc, n_batches: int,
                        seed: int = 1234, label_cs=None) -> dict:
    """Mean loss terms over a fixed subset of (object, rounds, view) samples (no dropout)."""
    from model.articulation.train import mean_losses

    def batch_fn(groups, rng):
        views = [int(i) % conds.views for i, _ in groups]
        return _image_batch(items, groups, views, geo_shape, conds, label_cs, net.cfg.count_labels)

    return mean_losses(net, items, tc, n_batches, seed, "image", batch_fn)


def merge_view_features(parts: list) -> "ViewFeatures":
    """One ViewFeatures of several render sets: ``parts`` are (id prefix, ViewFeatures) with
    the same views and cache split; ids become prefix + id."""
    from .features import ViewFeatures
    if len({(f.views, f.split, tuple(f.feats.shape[2:])) for _, f in parts}) != 1:
        raise ValueError("render sets to merge differ in views or feature shape: " + ", ".join(
            f"{p or 'main'}: {f.views} views, split {f.split}" for p, f in parts))
    ids = [p + i for p, f in parts for i in f.ids]
    if len(set(ids)) != len(ids):
        raise ValueError("merged render sets share object ids; give each a distinct prefix")
    return ViewFeatures({"ids": ids, "feats": torch.cat([f.feats for _, f in parts], 0),
                         "split": parts[0][1].split})


def _extra_items(rc: "ImageRunConfig", data, targets, predict_z: bool, cache_dir: Path):
    """Training items of every extra (data, renders) pair, all splits, ids prefixed 'x<j>:'
    and normalised with the main data's stats and label table; -> (items per pair, info)."""
    from model.articulation.train import extra_training_items
    from .renders import load_render_manifest, rendered_ids
    main_manifest = load_render_manifest(rc.renders)
    out, info = [], []
    for j, (droot, rroot) in enumerate(rc.extra):
        rman = load_render_manifest(rroot)
        for k in ("render_version", "views", "size"):
            if rman.get(k) != main_manifest.get(k):
                raise ValueError(f"extra render set {rroot}: {k} {rman.get(k)!r} differs from "
                                 f"{rc.renders}'s {main_manifest.get(k)!r}")
        prefix = f"x{j}:"
        items, version = extra_training_items(data, droot, prefix, targets, predict_z=predict_z,
                                              cache_dir=str(cache_dir), progress=rc.progress)
        have = set(rendered_ids(rroot, [it.id[len(prefix):] for it in items]))
        kept = [it for it in items if it.id[len(prefix):] in have]
        if len(kept) < len(items):
            log.warning("extra %s: %d of %d objects have no renders and are skipped", droot,
                        len(items) - len(kept), len(items))
        out.append((prefix, rroot, kept))
        info.append({"data": str(droot), "renders": str(rroot), "data_version": version,
                     "objects": len(kept)})
    return out, info


def _init_from(path: str):
    from model.articulation.checkpoint import read_checkpoint
    ck = read_checkpoint(path)
    if ck.get("condition") == "image":
        log.info("initialising from image checkpoint %s", path)
    return ck


def widen_image_projection(sd: dict, own: dict, key: str = "cond.proj.image.0.weight") -> bool:
    """A start checkpoint with 1280-d image tokens, a multiscale network with wider ones: keep
    the learned columns and add zero columns for the new channels, so the network starts
    as the checkpoint was and learns what to read from the fine features. In place."""
    if key not in sd or key not in own:
        return False
    w, target = sd[key], own[key]
    if w.shape == target.shape or w.shape[0] != target.shape[0] or w.shape[1] > target.shape[1]:
        return False
    sd[key] = torch.cat([w, w.new_zeros(w.shape[0], target.shape[1] - w.shape[1])], 1)
    log.info("init: image projection widened %d -> %d input channels (new ones start at 0)",
             w.shape[1], target.shape[1])
    return True


def train_image(rc: ImageRunConfig) -> Path:
    """Train an image-conditioned model in ``rc.out``; returns the path of image.pt."""
    from model.articulation.checkpoint import save_checkpoint
    from model.articulation.config import ArticulationConfig
    from model.articulation.network import ArticulationTransformer
    from model.articulation.data import group_rounds
    from model.articulation.train import (_CodebookView, label_cs_normalised, lr_at,
                                          own_input_tokens, prepare_data)
    from model.encoders.image import FINE_SPLIT, GRID, ImageEncoder, ImageEncoderConfig

    from .features import IMAGENET, ViewFeatures, build_feature_cache, encoder_cache_args
    from .renders import load_render_manifest, rendered_ids

    tc, ic = rc.train, rc.image
    if ic.trainable_blocks not in (0, 1):
        raise ValueError("the feature cache serves trainable_blocks 0 or 1")
    torch.set_num_threads(max(1, tc.threads))
    out = Path(rc.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.time()
    init = None
    tg = rc.targets
    same_targets = True
    if ic.init and ic.init.lower() != "none":
        init = _init_from(ic.init)
        cfg = ArticulationConfig.from_dict(init["config"])
        tc.text_encoder = init.get("text_encoder") or tc.text_encoder
        # a start checkpoint trained on other targets (e.g. stand-ins before the prior existed)
        # keeps its trunk; c_s / codebook heads and the label table follow the new targets
        same_targets = init.get("targets") == getattr(tg, "name", None) and \
            int(tg.cs_dim) == cfg.cs_dim and int(tg.num_codebooks) == cfg.num_codebooks and \
            int(tg.codebook_size) == cfg.codebook_size
        if not same_targets:
            log.warning("init %s was trained on %r targets, this run uses %r: its label table "
                        "is rebuilt and mismatched heads are re-initialised", ic.init,
                        init.get("targets"), getattr(tg, "name", None))
    else:
        cfg = rc.net
    if init is None or not same_targets:
        cfg.cs_dim = int(tg.cs_dim)
        cfg.num_codebooks, cfg.codebook_size = int(tg.num_codebooks), int(tg.codebook_size)
    encoder = ImageEncoder(ImageEncoderConfig(trainable_blocks=ic.trainable_blocks,
                                              multiscale=ic.multiscale, image_size=ic.image_size))
    trunk = _trunk_for(ic, init)
    has_tokens = bool(ic.count_tokens or (init or {}).get("count_tokens"))
    if ic.count_truth and (not has_tokens or not 0 < ic.count_truth <= 1):   # before any loading
        raise ValueError("count_truth needs count tokens (--count-tokens or an init checkpoint "
                         f"with them) and a share in (0, 1], got {ic.count_truth}")
    if trunk is not None:
        encoder.load_tail_state_dict(trunk["state_dict"])
        log.info("encoder trunk: %s (blocks %d-%d fine-tuned, tag %s)", ic.trunk or ic.init,
                 trunk["freeze"], trunk["split"] - 1, trunk["tag"])
    if cfg.cond_dims.get("image") != encoder.dim:
        cfg.cond_dims = {**cfg.cond_dims, "image": encoder.dim}
    grid = {k: v for k, v in cfg.cond_grid.items() if k != "image"}
    cfg.cond_grid = {**grid, "image": list(GRID)} if ic.positions else grid
    view = _CodebookView(rc.targets, cfg)
    data = prepare_data(rc.data, view, predict_z=cfg.predict_z,
                        cache_dir=str(out / "cache"),
                        stats=None if init is None else init["stats"],
                        label_table=None if init is None or not same_targets else init["label_table"])
    rmanifest = load_render_manifest(rc.renders)
    tr_all, va_all = data.items["train"], data.items.get("val") or []
    ids = [it.id for it in tr_all + va_all]
    have = set(rendered_ids(rc.renders, ids))
    tr = [it for it in tr_all if it.id in have]
    va = [it for it in va_all if it.id in have]
    if not tr:
        raise ValueError(f"no training object of {rc.data} has renders in {rc.renders}; "
                         f"run `artformer data render` first")
    if len(tr) < len(tr_all):
        log.warning("%d of %d train objects have no renders and are skipped",
                    len(tr_all) - len(tr), len(tr_all))
    extra, extra_info = _extra_items(rc, data, view, cfg.predict_z, out / "cache")
    t0 = time.time()

    enc_kw = encoder_cache_args(encoder, IMAGENET if trunk is None else trunk["tag"])

    def features(root, ids, split=None):
        kw = {} if split is None else {"split": split}
        return ViewFeatures(build_feature_cache(root, ids, progress=rc.progress, **kw, **enc_kw))

    feats = features(rc.renders, [it.id for it in tr + va])
    fine = features(rc.renders, list(feats.index), FINE_SPLIT) if ic.multiscale else None
    if extra:
        n0 = len(tr)
        fparts, gparts = [("", feats)], [("", fine)]
        for prefix, rroot, items in extra:
            xf = features(rroot, [it.id[len(prefix):] for it in items])
            fparts.append((prefix, xf))
            if ic.multiscale:
                gparts.append((prefix, features(rroot, list(xf.ids), FINE_SPLIT)))
            tr = tr + items
        feats = merge_view_features(fparts)
        fine = merge_view_features(gparts) if ic.multiscale else None
        del fparts, gparts, xf       # the merged copies hold them: free the GBs of the parts
        log.info("extra training objects: %d (%s)", len(tr) - n0,
                 ", ".join(f"{x['data_version']}: {x['objects']}" for x in extra_info))
    t_feats = time.time() - t0
    if cfg.child_counts and not cfg.count_labels:
        cfg.count_labels = sorted(set(data.label_table["labels"]))
    counter, counter_entry = _count_tokens_for(ic, init, trunk, cfg, feats.split)
    if counter is not None:
        cfg.count_tokens = {**cfg.count_tokens, "image": list(count_token_shape(counter))}
    conds = ImageConditions(feats, encoder, precompute=ic.trainable_blocks == 0, fine=fine,
                            counter=counter)
    del fine                         # conds keeps what it still needs (GBs for multiscale)
    log.info("data %s: %d train / %d val objects x %d views; features %.0f s",
             data.data_version, len(tr), len(va), feats.views, t_feats)

    torch.manual_seed(tc.seed)
    net = ArticulationTransformer(cfg)
    if init is not None:
        sd = {k: v.float() if v.is_floating_point() else v for k, v in init["state_dict"].items()}
        own = net.state_dict()
        widen_image_projection(sd, own)
        skip = [k for k, v in sd.items() if k not in own or own[k].shape != v.shape]
        if skip:
            log.warning("init: %d tensors do not fit and stay freshly initialised: %s",
                        len(skip), skip[:6])
        net.load_state_dict({k: v for k, v in sd.items() if k not in skip}, strict=False)
        if init.get("condition") == "image" and init.get("image_encoder", {}).get("tail"):
            encoder.load_tail_state_dict(init["image_encoder"]["tail"])
    groups = [{"params": list(net.parameters()), "lr_mult": 1.0}]
    tail = encoder.tail_parameters()
    if tail:
        groups.append({"params": tail, "lr_mult": ic.tail_lr_mult})
    opt = torch.optim.AdamW(groups, lr=tc.lr, weight_decay=tc.weight_decay, betas=(0.9, 0.98))
    rng = np.random.default_rng(tc.seed)
    history: list[dict] = []
    render_info = {k: rmanifest.get(k) for k in ("render_version", "views", "size", "seed",
                                                   "data_version")}
    render_info["path"] = str(rc.renders)

    def save(path: Path, step: int, half: bool = False) -> None:
        tail_sd = encoder.tail_state_dict()
        if half:
            tail_sd = half_state(tail_sd)
        extra = {"condition": "image", "targets": getattr(rc.targets, "name", "?"),
                 "image_encoder": {"config": asdict(encoder.config), "tail": tail_sd,
                                   **_trunk_entry(trunk)},
                 "image_train_config": asdict(ic), "renders": render_info,
                 **({"count_tokens": counter_entry} if counter_entry else {}),
                 "extra_train": extra_info,
                 "init": ic.init if init is not None else "none",
                 "elapsed": time.time() - t_loop, "history": history, "ablation": "none"}
        save_checkpoint(path, net, stats=data.stats, label_table=data.label_table,
                        text_encoder=tc.text_encoder, data_version=data.data_version,
                        seed=tc.seed, command=rc.command, step=step, train_config=asdict(tc),
                        extra=extra, half=half)

    label_cs = label_cs_normalised(data)
    epoch: list = []
    net.train()
    encoder.train()
    budget = tc.max_minutes * 60.0
    bar = None
    if rc.progress:
        from tqdm import tqdm
        bar = tqdm(total=tc.max_steps, desc="train image", unit="step")
    run: dict[str, float] = {}
    step = 0
    t_loop = time.time()
    val_batches = tc.val_batches
    while step < tc.max_steps:
        elapsed = time.time() - t_loop
        if budget and elapsed > budget:
            log.info("wall-clock budget of %.1f min reached at step %d", tc.max_minutes, step)
            break
        if not epoch:
            epoch = group_rounds(tr, rng.permutation(len(tr)), tc.batch_size,
                                 tc.rounds_per_object, rng)
        groups = epoch.pop()
        views = rng.integers(0, feats.views, len(groups)).tolist()
        batch, targets, cond, cmask, idx = _image_batch(tr, groups, views, data.geo_shape, conds,
                                                        label_cs, cfg.count_labels)
        if counter is not None and ic.count_truth > 0:
            _true_count_tokens(cond, [tr[i] for i, _ in groups], cfg.count_labels,
                               count_token_shape(counter)[1], rng.random(len(groups)) < ic.count_truth)
        drop = torch.from_numpy(rng.random(len(groups)) < tc.cond_dropout)[idx]
        if tc.own_inputs > 0:   # scheduled sampling, as in text training
            own_input_tokens(net, tr, groups, batch, cond, cmask, "image", tc.own_inputs, rng,
                             data.geo_shape)
        for g in opt.param_groups:
            g["lr"] = lr_at(step, tc, elapsed) * g["lr_mult"]
        _, L = net(batch, cond, cmask, "image", drop=drop, cond_index=idx, targets=targets,
                   weights=asdict(tc))
        opt.zero_grad(set_to_none=True)
        L["total"].backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), tc.grad_clip)
        if tail:
            torch.nn.utils.clip_grad_norm_(tail, tc.grad_clip)
        opt.step()
        step += 1
        for k, v in L.items():
            v = float(v.detach())
            run[k] = 0.98 * run.get(k, v) + 0.02 * v
        if bar is not None:
            bar.update(1)
            bar.set_postfix(loss=f"{run['total']:.3f}", end=f"{run['end']:.3f}")
        elif step % 25 == 0:
            log.info("step %d loss %.4f (end %.4f art %.4f jt %.4f cs %.4f)", step, run["total"],
                     run["end"], run["art"], run["jt"], run["cs"])
        if step % tc.val_every == 0:
            rec = {"step": step, "train": dict(run), "time_min": (time.time() - t_loop) / 60}
            if va:
                rec["val"] = evaluate_image_loss(net, va, data.geo_shape, conds, tc, val_batches,
                                                 label_cs=label_cs)
            history.append(rec)
            log.info("step %d train %.4f val %s", step, run["total"],
                     f"{rec['val']['total']:.4f}" if va else "-")
        if step % tc.ckpt_every == 0:
            save(out / "last.pt", step)
    if bar is not None:
        bar.close()
    final = {"step": step, "train": dict(run), "time_min": (time.time() - t_loop) / 60}
    if va:
        final["val"] = evaluate_image_loss(net, va, data.geo_shape, conds, tc, val_batches,
                                           label_cs=label_cs)
    history.append(final)
    save(out / "last.pt", step)
    save(out / "image.pt", step)
    summary = {"steps": step, "train_minutes": (time.time() - t_loop) / 60,
               "total_minutes": (time.time() - t_start) / 60, "feature_seconds": t_feats,
               "train_objects": len(tr), "val_objects": len(va), "views": feats.views,
               "extra_train": extra_info,
               "trainable_blocks": ic.trainable_blocks, "final": final}
    (out / "history.json").write_text(json.dumps(history, indent=1))
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    log.info("done: %d steps in %.1f min", step, (time.time() - t_start) / 60)
    return out / "image.pt"


def _trunk_for(ic: ImageTrainConfig, init: Optional[dict]) -> Optional[dict]:
    """The fine-tuned trunk a run uses: --trunk, else the one of an image init checkpoint."""
    from .trunk import load_trunk
    if ic.trunk:
        return load_trunk(ic.trunk)
    enc = (init or {}).get("image_encoder") or {}
    if init is not None and init.get("condition") == "image" and enc.get("trunk"):
        return {**enc["trunk_info"], "state_dict": enc["trunk"]}
    return None


def _count_tokens_for(ic: ImageTrainConfig, init: Optional[dict], trunk: Optional[dict], cfg,
                      split: int):
    """The count head whose distributions a run adds as count tokens, and its checkpoint entry:
    ``--count-tokens TRUNK_PT``'s head (it must read this run's trunk), else the init image
    checkpoint's; (None, None) without either."""
    from .counts import CountHeadError, count_token_entry, load_count_head
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


def _trunk_entry(trunk: Optional[dict]) -> dict:
    """What an image checkpoint keeps of its fine-tuned trunk: the weights (fp16) and where
    they came from (without the per-evaluation history)."""
    if trunk is None:
        return {}
    train = {k: v for k, v in (trunk.get("train") or {}).items() if k != "history"}
    info = {k: trunk[k] for k in ("kind", "freeze", "split", "tag") if k in trunk}
    return {"trunk": trunk["state_dict"], "trunk_info": {**info, "train": train}}


def write_half(src: Path, dst: Path) -> None:
    """fp16 copy of an image checkpoint (network and fine-tuned encoder tail), no optimizer."""
    from model.articulation.checkpoint import read_checkpoint, save_dict
    ck = read_checkpoint(src)
    ck["state_dict"] = half_state(ck["state_dict"])
    enc = ck.get("image_encoder", {})
    enc["tail"] = half_state(enc.get("tail", {}))
    ck.pop("optimizer", None)
    save_dict(dst, ck)


# ---------------------------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------------------------
def _parser():
    import argparse
    ap = argparse.ArgumentParser(
        prog="artformer train image",
        description="Train the articulation transformer conditioned on rendered images "
                    "(EfficientNet-Lite0 tokens), or --eval an image checkpoint on held-out renders.")
    ap.add_argument("--data", default="data/prepared/v1")
    ap.add_argument("--renders", default="data/renders/v1")
    ap.add_argument("--prior", default="model/weights/prior_small.pt",
                    help="shape-prior checkpoint (P_gt / c_s targets); 'none' = stand-in targets")
    ap.add_argument("--sdf", default="model/weights/sdf_small.pt")
    ap.add_argument("--preset", default="small")
    ap.add_argument("--out", default="runs/image_small")
    ap.add_argument("--init", default="model/weights/transformer_small.pt",
                    help="text transformer checkpoint to start from ('none' = from scratch)")
    ap.add_argument("--trainable-blocks", type=int, default=0, choices=(0, 1),
                    help="0 = frozen encoder (default), 1 = fine-tune its last block + head")
    ap.add_argument("--tail-lr-mult", type=float, default=0.1)
    ap.add_argument("--trunk", metavar="TRUNK_PT",
                    help="read the features of this fine-tuned trunk (`artformer train "
                         "image-trunk`); default: the --init image checkpoint's, else ImageNet's")
    ap.add_argument("--multiscale", action="store_true",
                    help="tokens also carry the 14x14 block-10 features (1728-d); from a "
                         "1280-d image checkpoint the projection is widened with zeros")
    ap.add_argument("--image-size", type=int, default=224, metavar="PX",
                    help="encoder input side, a multiple of 224 (448: the renders upsampled 2x so "
                         "small parts cover 4x the feature-map cells; the map entering the last "
                         "block is pooled back to 7x7); default 224")
    ap.add_argument("--count-tokens", metavar="TRUNK_PT",
                    help="add the count head of this trunk file (the run's own trunk) to the "
                         "condition: one token per label carrying its count distribution")
    ap.add_argument("--count-truth", type=float, default=0.0, metavar="SHARE",
                    help="with count tokens: share of training views whose tokens carry the "
                         "object's true counts instead of the head's (default 0)")
    ap.add_argument("--no-positions", action="store_true",
                    help="no 2-D position embedding of the 7x7 image tokens (the earlier model)")
    ap.add_argument("--extra-train", nargs=2, action="append", default=[],
                    metavar=("DATA", "RENDERS"),
                    help="more training objects: a prepared dataset with its own data version "
                         "and its render set (all its splits train; repeatable)")
    ap.add_argument("--steps", type=int)
    ap.add_argument("--minutes", type=float)
    ap.add_argument("--batch-size", type=int)
    ap.add_argument("--lr", type=float)
    ap.add_argument("--warmup", type=int, help="override warmup_steps")
    ap.add_argument("--own-inputs", type=float, metavar="SHARE",
                    help="scheduled sampling: share of the objects per batch whose nodes carry "
                         "the network's own articulation predictions (default 0)")
    ap.add_argument("--seed", type=int)
    ap.add_argument("--threads", type=int)
    ap.add_argument("--half", metavar="PATH", help="also write an fp16 copy (the shipped file)")
    ap.add_argument("--eval", metavar="CKPT", help="category / structure accuracy of CKPT on --split")
    ap.add_argument("--split", default="test")
    ap.add_argument("--pipeline", type=int, metavar="N", default=0,
                    help="--eval: instead, run N test images through the whole generator "
                         "(the --eval folder or 'shipped') and report POR, validity, structure")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--eval-views", default="all", help="--eval: view indices (comma list) or 'all'")
    ap.add_argument("--eval-seed", type=int, default=0)
    ap.add_argument("--temperature", type=float, default=1.0)
    ap.add_argument("--follow-plan", action="store_true",
                    help="--eval: decode with END decisions held to the START plan head")
    ap.add_argument("--no-count-plan", action="store_true",
                    help="--eval: ignore the checkpoint's count head (decode END freely)")
    ap.add_argument("--oracle-plan", action="store_true",
                    help="--eval diagnostic: hold END decisions to each object's TRUE part "
                         "counts (how far count-guided decoding can go)")
    ap.add_argument("--visibility", action="store_true",
                    help="--eval: also measure every part's visible pixels in each render and "
                         "report structure by visibility (by_visibility)")
    ap.add_argument("--visible-px", type=int, default=16,
                    help="--visibility: pixels a part needs to count as visible (default 16)")
    ap.add_argument("--frame", action="store_true",
                    help="--eval: crop each picture around its object first, as the product "
                         "does for photos (model.encoders.framing)")
    ap.add_argument("--farther", type=float, default=1.0, metavar="S",
                    help="--eval: show each render at S (< 1) of the picture's side, in the "
                         "middle of a larger picture of its background colour: a photo taken "
                         "from further away (default 1: the render as it is)")
    ap.add_argument("--json", metavar="PATH")
    ap.add_argument("--no-progress", action="store_true")
    return ap


def cli_main(argv: list[str]) -> int:
    import shlex
    args = _parser().parse_args(argv)
    if args.eval and args.pipeline:
        from .evaluate import image_pipeline_report
        rep = image_pipeline_report(args.data, args.renders, split=args.split, n=args.pipeline,
                                    checkpoint=None if args.eval == "shipped" else args.eval,
                                    seed=args.eval_seed, progress=not args.no_progress)
        print(json.dumps({k: v for k, v in rep.items() if k != "rows"}, indent=1))
        if args.json:
            Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            Path(args.json).write_text(json.dumps(rep, indent=1))
        return 0
    if args.eval:
        from .evaluate import image_alignment_report
        if not 0 < args.farther <= 1:
            print(f"artformer train image: --farther must be in (0, 1], got {args.farther}", flush=True)
            return 2
        views = None if args.eval_views == "all" else [int(v) for v in args.eval_views.split(",")]
        rep = image_alignment_report(args.eval, args.data, args.renders, split=args.split,
                                     views=views, limit=args.limit, seed=args.eval_seed,
                                     temperature=args.temperature, follow_plan=args.follow_plan,
                                     count_plan=not args.no_count_plan,
                                     oracle_plan=args.oracle_plan, visibility=args.visibility,
                                     visible_px=args.visible_px, frame=args.frame,
                                     farther=args.farther, progress=not args.no_progress)
        print(json.dumps({k: v for k, v in rep.items() if k != "rows"}, indent=1))
        if args.json:
            Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            Path(args.json).write_text(json.dumps(rep, indent=1))
        return 0
    from model.articulation.commands import make_targets
    from model.articulation.config import preset
    overrides = {k: v for k, v in {"max_steps": args.steps, "max_minutes": args.minutes,
                                   "batch_size": args.batch_size, "lr": args.lr,
                                   "warmup_steps": args.warmup, "own_inputs": args.own_inputs,
                                   "seed": args.seed, "threads": args.threads}.items()
                 if v is not None}
    net_cfg, tc = preset(args.preset, **overrides)
    targets = make_targets(args.prior, args.sdf, net_cfg)
    ic = ImageTrainConfig(trainable_blocks=args.trainable_blocks, tail_lr_mult=args.tail_lr_mult,
                          init=args.init, positions=not args.no_positions,
                          multiscale=args.multiscale, trunk=args.trunk or "",
                          image_size=args.image_size, count_tokens=args.count_tokens or "",
                          count_truth=args.count_truth)
    try:
        check_image_size(args.image_size)
    except ValueError as e:
        print(f"artformer train image: --image-size: {e}", flush=True)
        return 2
    if ic.init.lower() != "none" and not Path(ic.init).exists():
        print(f"artformer train image: --init {ic.init} does not exist; train the text model "
              f"first or pass --init none", flush=True)
        return 2
    command = "artformer train image " + " ".join(shlex.quote(a) for a in argv)
    path = train_image(ImageRunConfig(data=args.data, renders=args.renders, out=args.out,
                                      net=net_cfg, train=tc, image=ic, targets=targets,
                                      command=command, progress=not args.no_progress,
                                      extra=[tuple(x) for x in args.extra_train]))
    if args.half:
        write_half(path, Path(args.half))
        print(f"fp16 copy: {args.half}")
    print(f"checkpoint: {path}")
    return 0
