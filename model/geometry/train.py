"""Training of the SDF auto-encoder and of the diffusion prior.

``train_prior`` with ``codes_from`` trains a prior for a new auto-encoder in another prior's
code space (its codebooks and semantic encoder, frozen): the transformers trained for that
prior run with the new one unchanged.

Both run on the shared loop (model.core.training): single process by default; under
``torchrun --nproc_per_node N`` DDP over gloo (CPU), every rank draws its own random batches,
rank 0 validates, logs (OUT/log.jsonl) and writes checkpoints. Resumable from ``OUT/ckpt.pt``.
"""
from __future__ import annotations

import logging
import math
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Optional

import torch

from model.core.checkpoint import CODE_SPACE_FIELDS
from model.core.training import Dist, LoopConfig, LoopState, resolve_device, train_loop

from .checkpoint import CheckpointError, load_checkpoint, read_checkpoint, save_checkpoint
from .config import TrainConfig, get_preset

log = logging.getLogger(__name__)


@dataclass
class RunArgs:
    data: str
    out: str
    preset: str = "small"
    steps: Optional[int] = None
    epochs: Optional[float] = None
    batch_size: Optional[int] = None
    lr: Optional[float] = None
    seed: int = 0
    resume: bool = False
    threads: Optional[int] = None
    progress: bool = True
    sdf: Optional[str] = None            # prior only: the trained auto-encoder
    n_codebooks: Optional[int] = None    # prior only: codebook layout override (the
    codebook_size: Optional[int] = None  # one_codebook ablation: 1 x 512)
    argv: tuple[str, ...] = ()
    minutes: float = 0.0                 # wall-clock budget over resumes (0 = none)
    chunk_minutes: float = 0.0           # stop this process after M minutes (resume continues)
    device: str = "cpu"                  # sdf only: cpu | cuda | auto (the prior runs on cpu)
    codes_from: Optional[str] = None     # prior only: adopt this prior's code space ...
    codes_sdf: Optional[str] = None      # ... whose latents come from this auto-encoder
    distill_weight: float = 1.0          # prior only, with codes_from: weight of KL(codes)


def _train_cfg(base: TrainConfig, args: RunArgs, n_items: int, world: int) -> TrainConfig:
    t = replace(base)
    if args.batch_size:
        t.batch_size = args.batch_size
    if args.lr:
        t.lr = args.lr
    if args.epochs:
        t.steps = max(1, math.ceil(args.epochs * n_items / (t.batch_size * world)))
    if args.steps:
        t.steps = args.steps
    t.warmup = min(t.warmup, max(1, t.steps // 10))
    if args.threads:
        t.threads = args.threads
    return t


def _resume(path: Path, kind: str, model, opt, dist: Dist):
    """Where a resumed run stands (None without OUT/ckpt.pt)."""
    if not path.exists():
        return None
    src, ckpt = load_checkpoint(path, kind, expect_config=model.cfg)
    model.load_state_dict(src.state_dict())
    if "optimizer" in ckpt:
        opt.load_state_dict(ckpt["optimizer"])
    if dist.main:
        log.info("resumed %s from %s at step %d", kind, path, ckpt["step"])
    return LoopState.of(ckpt)


def _loop(kind: str, args: RunArgs, model, tcfg: TrainConfig, batch_fn, val_fn, dist: Dist,
          out: Path, save_fn) -> dict:
    """Both stages on the shared loop (model.core.training). batch_fn(net, gen) -> loss,
    stats; val_fn() -> float; save_fn(path, step, opt, run) writes OUT/ckpt.pt."""
    opt = torch.optim.AdamW(model.parameters(), lr=tcfg.lr, weight_decay=tcfg.weight_decay)
    state = _resume(out / "ckpt.pt", kind, model, opt, dist) if args.resume else None
    start = state.step if state is not None else 0
    gen = torch.Generator().manual_seed(args.seed * 1_000_003 + dist.rank * 7919 + start)
    cfg = LoopConfig(steps=tcfg.steps, lr=tcfg.lr, warmup=tcfg.warmup, floor=0.05,
                     minutes=args.minutes, chunk_minutes=args.chunk_minutes,
                     val_every=tcfg.val_every, ckpt_every=tcfg.ckpt_every,
                     grad_clip=tcfg.grad_clip, progress=args.progress, desc=f"train {kind}",
                     log_dir=str(out))
    t0 = time.time()
    st = train_loop(model, opt, cfg, lambda net, step: batch_fn(net, gen), val_fn=val_fn,
                    save_fn=lambda st, final: save_fn(out / "ckpt.pt", st.step, opt, st.entries()),
                    state=state, dist=dist)
    last = st.history[-1].get("val", float("nan")) if st.history else float("nan")
    return {"steps": st.step, "start": start, "val": last, "seconds": round(time.time() - t0, 1)}


# -- stage 1: the auto-encoder ------------------------------------------------------------

def _device_name(dev: torch.device) -> str:
    """What made the weights, for the checkpoint header: ``cpu`` or ``cuda (<GPU name>)``."""
    return f"cuda ({torch.cuda.get_device_name(dev)})" if dev.type == "cuda" else dev.type


def train_sdf(args: RunArgs) -> dict:
    from .autoencoder import SDFAutoEncoder
    from .data import load_parts, sample_batch
    dist = Dist()
    dev = resolve_device(args.device)
    if dist.active and dev.type != "cpu":
        raise ValueError("torchrun training runs DDP over gloo on CPU: use --device cpu")
    preset = get_preset(args.preset)
    cfg = preset.sdf
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    max_sdf = preset.sdf_train.max_sdf
    cache = out / "cache"
    workers = max(1, (args.threads or preset.sdf_train.threads) // dist.world)
    if not dist.main:
        dist.barrier()   # rank 0 builds the part caches first: ranks sharing one shard
                         # folder would remove it under each other
    train = load_parts(args.data, "train", progress=dist.main and args.progress, max_sdf=max_sdf,
                       seed=args.seed, cache_dir=cache, workers=workers)
    try:
        val = load_parts(args.data, "val", max_sdf=max_sdf, seed=args.seed, cache_dir=cache,
                         workers=workers)
    except (KeyError, ValueError):
        val = train
    if dist.main:
        dist.barrier()
    tcfg = _train_cfg(preset.sdf_train, args, len(train), dist.world)
    torch.set_num_threads(max(1, tcfg.threads // dist.world))
    torch.manual_seed(args.seed)
    model = SDFAutoEncoder(cfg).to(dev)   # batches are drawn on the CPU and moved

    vgen = torch.Generator().manual_seed(12345)
    vidx = torch.randperm(len(val), generator=vgen)[:tcfg.val_parts]
    vbatches = [tuple(t.to(dev) for t in sample_batch(val, vidx[i:i + tcfg.batch_size],
                                                      tcfg.n_points, tcfg.n_queries, vgen))
                for i in range(0, len(vidx), tcfg.batch_size)]

    def batch_fn(net, gen):
        idx = torch.randint(0, len(train), (tcfg.batch_size,), generator=gen)
        pts, q, s = sample_batch(train, idx, tcfg.n_points, tcfg.n_queries, gen)
        return net(pts.to(dev), q.to(dev), s.to(dev))

    def val_fn():
        from .autoencoder import clamped_l1
        tot = n = 0.0
        for pts, q, s in vbatches:
            pred = model.query(model.decode_planes(model.encode(pts)), q)
            tot += float(clamped_l1(pred, s, cfg.sdf_clamp)) * s.numel()
            n += s.numel()
        return tot / max(n, 1)

    def save_fn(path, step, opt, run):
        save_checkpoint(path, "sdf", model, data_version=train.data_version, seed=args.seed,
                        argv=list(args.argv), step=step, optimizer=opt, train_cfg=tcfg, run=run,
                        extra={"data": str(args.data), "train_parts": len(train)},
                        device=_device_name(dev))

    res = _loop("sdf", args, model, tcfg, batch_fn, val_fn, dist, out, save_fn)
    dist.close()
    return {**res, "out": str(out / "ckpt.pt"), "train_parts": len(train)}


# -- stage 2: the prior -------------------------------------------------------------------

@torch.inference_mode()
def encode_parts(ae, parts, n_points: int, batch: int = 64, seed: int = 0) -> torch.Tensor:
    """Posterior-mean latents of every part (M, Z), from a fixed random subset of its points."""
    gen = torch.Generator().manual_seed(seed)
    zs = []
    P = parts.points.shape[1]
    for i in range(0, len(parts), batch):
        pts = parts.points[i:i + batch]
        sel = torch.randint(0, P, (pts.shape[0], min(n_points, P)), generator=gen)
        zs.append(ae.encode(pts[torch.arange(pts.shape[0]).unsqueeze(1), sel].float()))
    return torch.cat(zs)


def pooled_text(texts: list[str], encoder_name: str, expect_dim: int) -> torch.Tensor:
    from model.encoders.text import get_text_encoder
    enc = get_text_encoder(encoder_name)
    if enc.dim != expect_dim:
        raise ValueError(f"text encoder {encoder_name!r} gives {enc.dim}-d states but the prior "
                         f"config expects text_dim={expect_dim}")
    return enc.encode(texts).pooled.float()                   # (T, text_dim)


@dataclass
class _Teacher:
    """The prior whose code space a new prior adopts, with the auto-encoder of its latents."""
    ae: object
    prior: object
    n_points: int
    record: dict          # checkpoint entry "code_space": {"accepts": [...], "hash": ...}

    @torch.inference_mode()
    def code_logits(self, z: torch.Tensor) -> torch.Tensor:
        """Its latents (M, Z) -> its code logits (M, K, N), in batches."""
        return torch.cat([self.prior.code_logits(self.prior.normalise(z[i:i + 4096]))
                          for i in range(0, len(z), 4096)])


def _code_space_teacher(args: RunArgs) -> _Teacher:
    from model.core.checkpoint import accepted_priors, code_space_hash
    if not args.codes_sdf:
        raise ValueError("--codes-from needs --codes-sdf: the auto-encoder that prior was "
                         "trained on (its latents of the parts give the codes to learn)")
    ae, ae_ck = load_checkpoint(args.codes_sdf, "sdf")
    pr, pr_ck = load_checkpoint(args.codes_from, "prior")
    if pr.cfg.z_dim != ae.cfg.z_dim:
        raise CheckpointError(f"{args.codes_from} was trained on {pr.cfg.z_dim}-d latents but "
                              f"{args.codes_sdf} makes {ae.cfg.z_dim}-d ones")
    n_pts = int(ae_ck.get("train_config", {}).get("n_points", 1024))
    record = {"accepts": accepted_priors(ae_ck, pr_ck, args.codes_from),
              "hash": code_space_hash(pr_ck), "prior": str(args.codes_from),
              "sdf": str(args.codes_sdf)}
    return _Teacher(ae.eval(), pr.eval(), n_pts, record)


def train_prior(args: RunArgs) -> dict:
    from .data import load_parts
    from .prior import ShapePrior
    dist = Dist()
    if not args.sdf:
        raise ValueError("train prior needs --sdf PATH of a trained auto-encoder checkpoint")
    preset = get_preset(args.preset)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    ae, ae_ckpt = load_checkpoint(args.sdf, "sdf")
    cfg = replace(preset.prior, z_dim=ae.cfg.z_dim)
    if args.n_codebooks is not None:
        cfg = replace(cfg, n_codebooks=int(args.n_codebooks))
    if args.codebook_size is not None:
        cfg = replace(cfg, codebook_size=int(args.codebook_size))
    teacher = _code_space_teacher(args) if args.codes_from else None
    if teacher is not None:
        if args.n_codebooks is not None or args.codebook_size is not None:
            raise ValueError("--codes-from takes the codebook layout of that prior: drop "
                             "--codebooks / --codebook-size")
        cfg = replace(cfg, **{k: getattr(teacher.prior.cfg, k) for k in CODE_SPACE_FIELDS})
    train = load_parts(args.data, "train", progress=dist.main and args.progress, with_sdf=False)
    try:
        val = load_parts(args.data, "val", with_sdf=False)
    except (KeyError, ValueError):
        val = train
    tcfg = _train_cfg(preset.prior_train, args, len(train), dist.world)
    torch.set_num_threads(max(1, tcfg.threads // dist.world))
    n_pts = int(ae_ckpt.get("train_config", {}).get("n_points", 1024))
    t0 = time.time()
    z_train = encode_parts(ae, train, n_pts, seed=args.seed)          # (M, Z)
    z_val = encode_parts(ae, val, n_pts, seed=args.seed + 1)
    vocab = sorted(set(train.text_vocab) | set(val.text_vocab))
    emb = pooled_text(vocab, cfg.text_encoder, cfg.text_dim)           # (T, text_dim)
    lookup = {t: i for i, t in enumerate(vocab)}
    tid_train = torch.tensor([lookup[t] for t in train.texts])
    tid_val = torch.tensor([lookup[t] for t in val.texts])
    if teacher is not None:     # the code space's own latents of the same parts
        d_train = teacher.code_logits(encode_parts(teacher.ae, train, teacher.n_points,
                                                   seed=args.seed))
        d_val = teacher.code_logits(encode_parts(teacher.ae, val, teacher.n_points,
                                                 seed=args.seed + 1))
    if dist.main:
        log.info("encoded %d train / %d val parts in %.1fs", len(train), len(val), time.time() - t0)

    torch.manual_seed(args.seed)
    model = ShapePrior(cfg)
    model.set_latent_stats(z_train)
    extra = {"data": str(args.data), "sdf_checkpoint": str(args.sdf),
             "sdf_config": ae_ckpt["config"]}
    if teacher is not None:
        model.adopt_code_space(teacher.prior)
        extra["code_space"] = teacher.record

    vgen_seed = 4242
    vsel = torch.randperm(len(val), generator=torch.Generator().manual_seed(vgen_seed))[:tcfg.val_parts]

    def batch_fn(net, gen):
        idx = torch.randint(0, len(train), (tcfg.batch_size,), generator=gen)
        if teacher is None:
            return net(z_train[idx], emb[tid_train[idx]], gen)
        return net(z_train[idx], emb[tid_train[idx]], gen, teacher_logits=d_train[idx],
                   distill_weight=args.distill_weight)

    def val_fn():
        g = torch.Generator().manual_seed(vgen_seed)
        with torch.no_grad():
            loss, stats = model(z_val[vsel], emb[tid_val[vsel]], g,
                                teacher_logits=None if teacher is None else d_val[vsel])
        return stats["diffusion"]

    bank = {"latents": z_train.half(), "text_ids": torch.tensor([train.text_vocab.index(t)
                                                                 for t in train.texts]),
            "texts": list(train.text_vocab), "object_ids": list(train.object_ids),
            "part_index": list(train.part_index)}

    def save_fn(path, step, opt, run):
        save_checkpoint(path, "prior", model, data_version=train.data_version, seed=args.seed,
                        argv=list(args.argv), step=step, optimizer=opt, train_cfg=tcfg, run=run,
                        extra={**extra, "bank": bank})

    res = _loop("prior", args, model, tcfg, batch_fn, val_fn, dist, out, save_fn)
    dist.close()
    return {**res, "out": str(out / "ckpt.pt"), "train_parts": len(train)}


def thin_bank(prior, bank: dict, per_text: int, seed: int = 0) -> dict:
    """The retrieval bank cut to at most ``per_text`` latents of each label text (a seeded
    random draw, so retrieval sees the label's spread as sampled), with every label's empirical
    code logits computed first from the whole bank (``label_logits``, (T, K, N) log P) so that
    sampling by label is unchanged. ``prior``: the ShapePrior the bank was encoded for."""
    lat, tid = bank["latents"], bank["text_ids"]
    gen = torch.Generator().manual_seed(seed)
    logits, keep = [], []
    for t in range(len(bank["texts"])):
        idx = (tid == t).nonzero()[:, 0]
        logits.append(prior.mean_code_logits(lat[idx]))
        keep.append(idx[torch.randperm(len(idx), generator=gen)[:per_text]])
    keep = torch.cat(keep).sort().values
    out = {**bank, "latents": lat[keep], "text_ids": tid[keep],
           "label_logits": torch.stack(logits), "full_size": len(lat), "per_text": per_text}
    for k in ("object_ids", "part_index"):
        if k in bank:
            out[k] = [bank[k][i] for i in keep.tolist()]
    return out


def export_weights(src: str | os.PathLike, dst: str | os.PathLike, kind: str,
                   bank_per_text: int = 0, seed: int = 0) -> int:
    """Strip a training checkpoint (no optimizer) and store fp16 weights; a prior's retrieval
    bank is thinned to ``bank_per_text`` latents per label (0 = all). -> bytes written."""
    model, ckpt = load_checkpoint(src, kind)
    extra = dict(ckpt.get("extra") or {})
    if kind == "prior" and bank_per_text > 0 and extra.get("bank"):
        extra["bank"] = thin_bank(model, extra["bank"], bank_per_text, seed)
    save_checkpoint(dst, kind, model, data_version=ckpt["data_version"], seed=ckpt["seed"],
                    command=ckpt["command"], step=ckpt["step"], extra=extra,
                    device=ckpt.get("device", "cpu"), half=True)
    return os.path.getsize(dst)


__all__ = ["RunArgs", "train_sdf", "train_prior", "encode_parts", "export_weights", "thin_bank",
           "CheckpointError", "read_checkpoint"]
