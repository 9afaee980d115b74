"""Training of the image-conditioned articulation transformer (`artformer train image`).

The network is the articulation transformer itself (model.articulation) with the image
modality of its condition interface. For every training sample (object, decoding round) the
condition is one random rendered view through the EfficientNet-Lite0 tail over cached trunk
features (model.imaging.features): with a frozen encoder (``trainable_blocks = 0``) every
view's tokens are computed once at start; with ``trainable_blocks = 1`` the last block + head
conv train too (learning rate × ``tail_lr_mult``). By default a run starts from the trained
text model (same config, normalisation and label table; only the image projection is new).
It runs on the shared loop (model.core.training): resumable, wall-clock budget, DDP.

A checkpoint is an articulation checkpoint with ``condition = "image"``, ``image_encoder``
(config, fine-tuned tail and trunk), ``renders`` (render-set manifest) and ``init``.
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
from model.encoders.image import NUM_TOKENS

from .counts import count_token_shape, count_tokens_for
from .trunk import trunk_entry, trunk_for_run

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
    resume: bool = False           # continue from OUT/last.pt
    chunk_minutes: float = 0.0     # stop this process after M minutes (resume continues)


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


def _network_config(rc: ImageRunConfig, init: Optional[dict]):
    """The network config of a run: the init checkpoint's (its heads follow this run's targets
    when it was trained on others) or ``rc.net``. -> (config, same targets as init)."""
    from model.articulation.config import ArticulationConfig
    tc, tg = rc.train, rc.targets
    if init is None:
        cfg, same = rc.net, False
    else:
        cfg = ArticulationConfig.from_dict(init["config"])
        tc.text_encoder = init.get("text_encoder") or tc.text_encoder
        # a start checkpoint trained on other targets (stand-ins, or another shape prior: see
        # model.core.checkpoint.check_prior) keeps its trunk; c_s / codebook heads and the
        # label table follow the new targets
        same = init.get("prior") == getattr(tg, "fingerprint", None) and \
            int(tg.cs_dim) == cfg.cs_dim and int(tg.num_codebooks) == cfg.num_codebooks and \
            int(tg.codebook_size) == cfg.codebook_size
        if not same:
            log.warning("init %s was trained on other targets (prior %r) than this run's (%r): "
                        "its label table is rebuilt and mismatched heads are re-initialised",
                        rc.image.init, init.get("prior"), getattr(tg, "fingerprint", None))
    if not same:
        cfg.cs_dim = int(tg.cs_dim)
        cfg.num_codebooks, cfg.codebook_size = int(tg.num_codebooks), int(tg.codebook_size)
    return cfg, same


def _encoder_for(ic: ImageTrainConfig, init: Optional[dict], cfg):
    """The image encoder of a run, with its fine-tuned trunk; sets the config's image entries."""
    from model.encoders.image import GRID, ImageEncoder, ImageEncoderConfig
    encoder = ImageEncoder(ImageEncoderConfig(trainable_blocks=ic.trainable_blocks,
                                              multiscale=ic.multiscale, image_size=ic.image_size))
    trunk = trunk_for_run(ic, init)
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
    return encoder, trunk


def _rendered_items(rc: ImageRunConfig, cfg, init: Optional[dict], same: bool, out: Path):
    """Prepared items of the rendered objects. -> data, train items, val items, extra sets,
    their record."""
    from model.articulation.train import _CodebookView, prepare_data
    from .renders import rendered_ids
    view = _CodebookView(rc.targets, cfg)
    data = prepare_data(rc.data, view, predict_z=cfg.predict_z, cache_dir=str(out / "cache"),
                        stats=None if init is None else init["stats"],
                        label_table=None if init is None or not same else init["label_table"],
                        frame=rc.train.token_frame)
    tr_all, va_all = data.items["train"], data.items.get("val") or []
    have = set(rendered_ids(rc.renders, [it.id for it in tr_all + va_all]))
    tr = [it for it in tr_all if it.id in have]
    va = [it for it in va_all if it.id in have]
    if not tr:
        raise ValueError(f"no training object of {rc.data} has renders in {rc.renders}; "
                         f"run `artformer data render` first")
    if len(tr) < len(tr_all):
        log.warning("%d of %d train objects have no renders and are skipped",
                    len(tr_all) - len(tr), len(tr_all))
    extra, extra_info = _extra_items(rc, data, view, cfg.predict_z, out / "cache")
    return data, tr, va, extra, extra_info


def _view_features(rc: ImageRunConfig, encoder, trunk, tr: list, va: list, extra: list):
    """Cached trunk features of every view (merged over the extra render sets; extra items
    join ``tr``). -> train items, features, fine features or None."""
    from model.encoders.image import FINE_SPLIT
    from .features import IMAGENET, ViewFeatures, build_feature_cache, encoder_cache_args
    ic = rc.image
    enc_kw = encoder_cache_args(encoder, IMAGENET if trunk is None else trunk["tag"])

    def features(root, ids, split=None):
        kw = {} if split is None else {"split": split}
        return ViewFeatures(build_feature_cache(root, ids, progress=rc.progress, **kw, **enc_kw))

    feats = features(rc.renders, [it.id for it in tr + va])
    fine = features(rc.renders, list(feats.index), FINE_SPLIT) if ic.multiscale else None
    if not extra:
        return tr, feats, fine
    fparts, gparts = [("", feats)], [("", fine)]
    for prefix, rroot, items in extra:
        xf = features(rroot, [it.id[len(prefix):] for it in items])
        fparts.append((prefix, xf))
        if ic.multiscale:
            gparts.append((prefix, features(rroot, list(xf.ids), FINE_SPLIT)))
        tr = tr + items
    feats = merge_view_features(fparts)
    fine = merge_view_features(gparts) if ic.multiscale else None
    return tr, feats, fine


def _image_network(cfg, init: Optional[dict], encoder, seed: int):
    """The network, from the init checkpoint's weights where they fit."""
    from model.articulation.network import ArticulationTransformer
    torch.manual_seed(seed)
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
    return net


def _prepare(rc: ImageRunConfig, out: Path):
    """Everything a run trains on. -> dict of config, init, encoder, trunk, data, items,
    features, conditions, count head and records."""
    from model.articulation.checkpoint import read_checkpoint
    from .renders import load_render_manifest
    ic = rc.image
    init = read_checkpoint(ic.init) if ic.init and ic.init.lower() != "none" else None
    cfg, same = _network_config(rc, init)
    encoder, trunk = _encoder_for(ic, init, cfg)
    data, tr, va, extra, extra_info = _rendered_items(rc, cfg, init, same, out)
    t0 = time.time()
    tr, feats, fine = _view_features(rc, encoder, trunk, tr, va, extra)
    t_feats = time.time() - t0
    if cfg.child_counts and not cfg.count_labels:
        cfg.count_labels = sorted(set(data.label_table["labels"]))
    counter, counter_entry = count_tokens_for(ic, init, trunk, cfg, feats.split)
    if counter is not None:
        cfg.count_tokens = {**cfg.count_tokens, "image": list(count_token_shape(counter))}
    conds = ImageConditions(feats, encoder, precompute=ic.trainable_blocks == 0, fine=fine,
                            counter=counter)
    log.info("data %s: %d train / %d val objects x %d views; features %.0f s",
             data.data_version, len(tr), len(va), feats.views, t_feats)
    rman = load_render_manifest(rc.renders)
    render_info = {k: rman.get(k) for k in ("render_version", "views", "size", "seed",
                                            "data_version")}
    render_info["path"] = str(rc.renders)
    return dict(cfg=cfg, init=init, encoder=encoder, trunk=trunk, data=data, tr=tr, va=va,
                views=feats.views, conds=conds, counter=counter, counter_entry=counter_entry,
                extra_info=extra_info, render_info=render_info, t_feats=t_feats)


def _resume_image(last: Path, net, encoder, opt, prior: str):
    from model.articulation.checkpoint import read_checkpoint
    from model.articulation.config import ArticulationConfig
    from model.core.training import LoopState
    ck = read_checkpoint(last, prior=prior)
    if ArticulationConfig.from_dict(ck["config"]) != net.cfg:   # older fields defaulted
        raise ValueError(f"{last} was trained with another config; drop --resume or use "
                         f"another --out")
    net.load_state_dict(ck["state_dict"])
    if ck.get("image_encoder", {}).get("tail"):
        encoder.load_tail_state_dict(ck["image_encoder"]["tail"])
    opt.load_state_dict(ck["optimizer"])
    log.info("resumed %s at step %d", last, ck["step"])
    return LoopState.of(ck)


def train_image(rc: ImageRunConfig) -> Path:
    """Train (or resume) an image-conditioned model in ``rc.out``; returns image.pt. Under
    torchrun every process trains on its share of each epoch's batches (DDP; frozen encoder)."""
    from model.articulation.data import group_rounds
    from model.articulation.train import label_cs_normalised, loop_config, own_input_tokens
    from model.core.training import Dist, train_loop
    tc, ic = rc.train, rc.image
    if ic.trainable_blocks not in (0, 1):
        raise ValueError("the feature cache serves trainable_blocks 0 or 1")
    dist = Dist()
    if dist.active and ic.trainable_blocks:
        raise ValueError("DDP (torchrun) trains the image model with a frozen encoder only; "
                         "use --trainable-blocks 0 or one process")
    torch.set_num_threads(max(1, tc.threads))
    out = Path(rc.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.time()
    if not dist.main:
        dist.barrier()                       # rank 0 builds the caches first
    p = _prepare(rc, out)
    if dist.main:
        dist.barrier()
    cfg, encoder, data, tr, conds = p["cfg"], p["encoder"], p["data"], p["tr"], p["conds"]
    net = _image_network(cfg, p["init"], encoder, tc.seed)
    if cfg.place_bins:
        net.set_token_norm(data.stats["tok_mean"], data.stats["tok_std"])
    groups = [{"params": list(net.parameters()), "lr_mult": 1.0}]
    tail = encoder.tail_parameters()
    if tail:
        groups.append({"params": tail, "lr_mult": ic.tail_lr_mult})
    opt = torch.optim.AdamW(groups, lr=tc.lr, weight_decay=tc.weight_decay, betas=(0.9, 0.98))
    prior = getattr(rc.targets, "fingerprint", "")
    state = None
    if rc.resume and (out / "last.pt").exists():
        state = _resume_image(out / "last.pt", net, encoder, opt, prior)
    seed = tc.seed if state is None else tc.seed + state.step
    order = np.random.default_rng(seed)
    rng = np.random.default_rng([seed, dist.rank]) if dist.active else order
    save = _saver(rc, p, net, opt, out, prior)
    label_cs = label_cs_normalised(data)
    counter, epoch = p["counter"], []

    def step_fn(model, step):
        nonlocal epoch
        if not epoch:
            epoch = dist.shard(group_rounds(tr, order.permutation(len(tr)), tc.batch_size,
                                            tc.rounds_per_object, order))
        groups = epoch.pop()
        views = rng.integers(0, p["views"], len(groups)).tolist()
        batch, targets, cond, cmask, idx = _image_batch(tr, groups, views, data.geo_shape, conds,
                                                        label_cs, cfg.count_labels)
        if counter is not None and ic.count_truth > 0:
            _true_count_tokens(cond, [tr[i] for i, _ in groups], cfg.count_labels,
                               count_token_shape(counter)[1], rng.random(len(groups)) < ic.count_truth)
        drop = torch.from_numpy(rng.random(len(groups)) < tc.cond_dropout)[idx]
        if tc.own_inputs > 0:   # scheduled sampling, as in text training
            own_input_tokens(net, tr, groups, batch, cond, cmask, "image", tc.own_inputs, rng,
                             data.geo_shape)
        _, L = model(batch, cond, cmask, "image", drop=drop, cond_index=idx, targets=targets,
                     weights=asdict(tc))
        return L["total"], {k: float(v.detach()) for k, v in L.items() if k in ("end", "art", "jt")}

    def val_fn():
        return evaluate_image_loss(net, p["va"], data.geo_shape, conds, tc, tc.val_batches,
                                   label_cs=label_cs) if p["va"] else None

    encoder.train()
    st = train_loop(net, opt, loop_config(tc, "train image", rc.progress, out, rc.chunk_minutes),
                    step_fn, val_fn=val_fn, save_fn=save, state=state, dist=dist, unused_params=True)
    if dist.main:
        summary = {"steps": st.step, "train_minutes": st.elapsed / 60,
                   "total_minutes": (time.time() - t_start) / 60, "feature_seconds": p["t_feats"],
                   "train_objects": len(tr), "val_objects": len(p["va"]), "views": p["views"],
                   "extra_train": p["extra_info"], "trainable_blocks": ic.trainable_blocks,
                   "final": st.history[-1] if st.history else {}}
        (out / "summary.json").write_text(json.dumps(summary, indent=1, default=float))
    dist.close()
    log.info("done: %d steps in %.1f min", st.step, (time.time() - t_start) / 60)
    return out / "image.pt"


def _saver(rc: ImageRunConfig, p: dict, net, opt, out: Path, prior: str):
    """save_fn of the loop: OUT/last.pt (resumable) and, at the end, OUT/image.pt."""
    from model.articulation.checkpoint import save_checkpoint
    from .model import ImageExtras
    tc, ic, encoder, data = rc.train, rc.image, p["encoder"], p["data"]

    def save(st, final: bool) -> None:
        ex = ImageExtras(encoder=asdict(encoder.config), tail=encoder.tail_state_dict(),
                         **trunk_entry(p["trunk"]), renders=p["render_info"],
                         init=ic.init if p["init"] is not None else "none",
                         image_train_config=asdict(ic), extra_train=p["extra_info"],
                         count_tokens=p["counter_entry"])
        extra = {**ex.entries(), "targets": getattr(rc.targets, "name", "?"), "ablation": "none",
                 **st.entries()}
        common = dict(stats=data.stats, label_table=data.label_table,
                      text_encoder=tc.text_encoder, data_version=data.data_version, seed=tc.seed,
                      command=rc.command, step=st.step, train_config=asdict(tc), prior=prior)
        save_checkpoint(out / "last.pt", net, extra={**extra, "optimizer": opt.state_dict()},
                        **common)
        if final:
            save_checkpoint(out / "image.pt", net, extra=extra, **common)
            (out / "history.json").write_text(json.dumps(st.history, indent=1, default=float))
    return save


def write_half(src: Path, dst: Path) -> None:
    """fp16 copy of an image checkpoint (network and fine-tuned encoder tail), no optimizer."""
    from model.articulation.checkpoint import read_checkpoint, save_dict
    ck = read_checkpoint(src)
    ck["state_dict"] = half_state(ck["state_dict"])
    enc = ck.get("image_encoder", {})
    enc["tail"] = half_state(enc.get("tail", {}))
    ck.pop("optimizer", None)
    save_dict(dst, ck)


def cli_main(argv: list[str]) -> int:
    """`artformer train image` (model.imaging.commands)."""
    from .commands import train_image_main
    return train_image_main(argv)
