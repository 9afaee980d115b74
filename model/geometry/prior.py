"""Codebook-conditioned diffusion shape prior (DESIGN §4.2, paper "Diverse and Controllable
Shape Prior").

* ``Denoiser`` — the network only: tokens [4 geometry-condition tokens, time embedding, x_t,
  query] with self-attention, cross-attention to the c_s tokens, x0 read off the query token.
* ``ShapePrior`` — the denoiser plus its condition encoders: E_g (z -> 4 chunks, each mixed
  from its own codebook by Gumbel-softmax over negative distances, lifted by 4 linear heads)
  and E_s (pooled label-text embedding -> 64-d c_s). The diffusion process is passed in.

A prior can adopt another's code space (``adopt_code_space``: its codebooks and E_s, frozen)
and learn to generate a new auto-encoder's latents from that prior's codes, so transformers
trained for the other prior run with it unchanged (``train prior --codes-from``).

The prior works on a normalised latent (z - z_mean) / z_std; the statistics are buffers set
from the training latents, so callers always see the auto-encoder's raw z.
"""
from __future__ import annotations

import math
from typing import Optional

import torch
import torch.nn as nn
import torch.nn.functional as F

from model.core.checkpoint import CODE_SPACE_FIELDS

from .config import PriorConfig
from .diffusion import DROP_BOTH, DROP_GEO, DROP_NONE, Diffusion


def mlp(d_in: int, hidden: int, d_out: int, layers: int = 4) -> nn.Sequential:
    dims = [d_in] + [hidden] * (layers - 1) + [d_out]
    mods: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(dims[:-1], dims[1:])):
        mods.append(nn.Linear(a, b))
        if i < len(dims) - 2:
            mods.append(nn.SiLU())
    return nn.Sequential(*mods)


def timestep_embedding(t: torch.Tensor, dim: int) -> torch.Tensor:
    """t (B,) -> (B, dim) sinusoidal."""
    half = dim // 2
    freqs = torch.exp(-math.log(10000.0) * torch.arange(half, dtype=torch.float32) / half)
    args = t.float().unsqueeze(-1) * freqs.unsqueeze(0)
    emb = torch.cat([torch.cos(args), torch.sin(args)], dim=-1)
    return F.pad(emb, (0, dim % 2))


class Block(nn.Module):
    def __init__(self, width: int, heads: int, ffn_mult: int = 4):
        super().__init__()
        self.ln1 = nn.LayerNorm(width)
        self.attn = nn.MultiheadAttention(width, heads, batch_first=True)
        self.ln2 = nn.LayerNorm(width)
        self.cross = nn.MultiheadAttention(width, heads, batch_first=True)
        self.ln3 = nn.LayerNorm(width)
        self.ff = nn.Sequential(nn.Linear(width, ffn_mult * width), nn.GELU(),
                                nn.Linear(ffn_mult * width, width))

    def forward(self, x: torch.Tensor, ctx: torch.Tensor) -> torch.Tensor:
        """x (B, L, W), ctx (B, M, W) -> (B, L, W)."""
        h = self.ln1(x)
        x = x + self.attn(h, h, h, need_weights=False)[0]
        x = x + self.cross(self.ln2(x), ctx, ctx, need_weights=False)[0]
        return x + self.ff(self.ln3(x))


class Denoiser(nn.Module):
    """x0-predicting transformer. cond = (geo_tokens (B, 4, W), c_s (B, cs_dim))."""

    def __init__(self, cfg: PriorConfig):
        super().__init__()
        W, K = cfg.width, cfg.n_codebooks
        self.cfg = cfg
        self.x_in = nn.Linear(cfg.z_dim, W)
        self.t_mlp = nn.Sequential(nn.Linear(W, W), nn.SiLU(), nn.Linear(W, W))
        self.query = nn.Parameter(torch.randn(1, 1, W) * 0.02)
        self.pos = nn.Parameter(torch.randn(1, K + 3, W) * 0.02)
        self.null_geo = nn.Parameter(torch.randn(1, K, W) * 0.02)
        self.null_ctx = nn.Parameter(torch.randn(1, cfg.cs_tokens, W) * 0.02)
        self.ctx_in = nn.Linear(cfg.cs_dim, cfg.cs_tokens * W)
        self.blocks = nn.ModuleList([Block(W, cfg.heads, cfg.ffn_mult) for _ in range(cfg.depth)])
        self.ln_out = nn.LayerNorm(W)
        self.out = nn.Linear(W, cfg.z_dim)

    def forward(self, x_t: torch.Tensor, t: torch.Tensor, cond, drop: torch.Tensor) -> torch.Tensor:
        """x_t (B, Z), t (B,), cond (geo (B, K, W), c_s (B, S)), drop (B,) -> x0 (B, Z)."""
        geo, cs = cond
        B = x_t.shape[0]
        W = self.cfg.width
        d = drop.view(B, 1, 1)
        geo = torch.where(d >= DROP_GEO, self.null_geo.expand(B, -1, -1), geo)   # (B, K, W)
        ctx = self.ctx_in(cs).view(B, self.cfg.cs_tokens, W)                      # (B, M, W)
        ctx = torch.where(d >= DROP_BOTH, self.null_ctx.expand(B, -1, -1), ctx)
        temb = self.t_mlp(timestep_embedding(t, W)).unsqueeze(1)                 # (B, 1, W)
        x = torch.cat([geo, temb, self.x_in(x_t).unsqueeze(1),
                       self.query.expand(B, -1, -1)], dim=1) + self.pos          # (B, K+3, W)
        for blk in self.blocks:
            x = blk(x, ctx)
        return self.out(self.ln_out(x[:, -1]))                                   # (B, Z)


def gumbel_softmax(logits: torch.Tensor, tau: float,
                   generator: Optional[torch.Generator] = None) -> torch.Tensor:
    """Soft Gumbel-softmax sample over the last dim (generator-driven, hence reproducible)."""
    u = torch.rand(logits.shape, generator=generator, device=logits.device)
    g = -torch.log(-torch.log(u.clamp(1e-10, 1.0 - 1e-7)))
    return F.softmax((logits + g) / tau, dim=-1)


class ShapePrior(nn.Module):
    def __init__(self, cfg: PriorConfig):
        super().__init__()
        self.cfg = cfg
        K, N, d = cfg.n_codebooks, cfg.codebook_size, cfg.code_dim
        self.geo_encoder = mlp(cfg.z_dim, cfg.encoder_hidden, K * d)            # E_g
        self.codebooks = nn.Parameter(torch.randn(K, N, d))                     # (K, N, d)
        self.geo_heads = nn.ModuleList([nn.Linear(d, cfg.width) for _ in range(K)])
        self.sem_encoder = mlp(cfg.text_dim, cfg.encoder_hidden, cfg.cs_dim)    # E_s
        self.denoiser = Denoiser(cfg)
        self.register_buffer("z_mean", torch.zeros(cfg.z_dim))
        self.register_buffer("z_std", torch.ones(cfg.z_dim))
        self.diffusion = Diffusion(cfg.timesteps)    # the process: plain object, no weights

    # -- pieces ---------------------------------------------------------------------------
    def set_latent_stats(self, z: torch.Tensor) -> None:
        """Normalisation from the training latents z (M, Z): per-dim mean, one global std."""
        self.z_mean.copy_(z.mean(0))
        self.z_std.fill_(float((z - z.mean(0)).std().clamp_min(1e-6)))

    def normalise(self, z: torch.Tensor) -> torch.Tensor:
        return (z - self.z_mean) / self.z_std

    def denormalise(self, x: torch.Tensor) -> torch.Tensor:
        return x * self.z_std + self.z_mean

    def code_logits(self, z_norm: torch.Tensor) -> torch.Tensor:
        """Normalised z (B, Z) -> negative distances D (B, K, N) of its chunks to each codebook."""
        K, d = self.cfg.n_codebooks, self.cfg.code_dim
        c = self.geo_encoder(z_norm).view(-1, K, 1, d)                  # (B, K, 1, d)
        return -(c - self.codebooks.unsqueeze(0)).pow(2).sum(-1).clamp_min(1e-12).sqrt()

    def geo_tokens(self, weights: torch.Tensor) -> torch.Tensor:
        """Code weights (B, K, N) -> condition tokens (B, K, W)."""
        mixed = torch.einsum("bkn,knd->bkd", weights, self.codebooks)   # (B, K, d)
        return torch.stack([h(mixed[:, k]) for k, h in enumerate(self.geo_heads)], dim=1)

    # -- training -------------------------------------------------------------------------
    def forward(self, z: torch.Tensor, text_emb: torch.Tensor,
                generator: Optional[torch.Generator] = None,
                teacher_logits: Optional[torch.Tensor] = None,
                distill_weight: float = 1.0) -> tuple[torch.Tensor, dict]:
        """z (B, Z) raw latents, text_emb (B, text_dim) pooled label texts -> (loss, stats).

        ``teacher_logits`` (B, K, N): the code logits another prior reads from its own latents
        of these parts (``adopt_code_space``). The denoiser is then conditioned on the
        teacher's codes, as the transformer's predictions for that prior will condition it,
        and the geometry encoder learns to read the same codes from this prior's latents
        (``distill_weight`` x KL(teacher || own), in place of the code-usage term: the
        codebooks are frozen)."""
        cfg = self.cfg
        B = z.shape[0]
        x0 = self.normalise(z)
        D = self.code_logits(x0)                                        # (B, K, N)
        cond = D if teacher_logits is None else teacher_logits.float()
        geo = self.geo_tokens(gumbel_softmax(cond, cfg.tau_train, generator))
        cs = self.sem_encoder(text_emb)                                 # (B, S)
        u = torch.rand(B, generator=generator)
        drop = torch.full((B,), DROP_NONE, dtype=torch.long)
        drop[u < cfg.p_drop_both + cfg.p_drop_geo] = DROP_GEO
        drop[u < cfg.p_drop_both] = DROP_BOTH
        diff = self.diffusion.training_loss(self.denoiser, x0, (geo, cs), drop, generator)
        if teacher_logits is not None:
            kl = F.kl_div(F.log_softmax(D, dim=-1), F.log_softmax(cond, dim=-1),
                          log_target=True, reduction="none").sum(-1).mean()
            return diff + distill_weight * kl, {"diffusion": float(diff.detach()),
                                                "distill_kl": float(kl.detach())}
        usage = F.softmax(D, dim=-1).mean(0)                            # (K, N)
        kl_u = (usage * (usage.clamp_min(1e-12) * cfg.codebook_size).log()).sum(-1).mean()
        loss = diff + cfg.usage_weight * kl_u
        return loss, {"diffusion": float(diff.detach()), "usage_kl": float(kl_u.detach())}

    def adopt_code_space(self, other: "ShapePrior") -> None:
        """Take ``other``'s codebooks and semantic encoder and freeze them, so code logits
        and c_s made for ``other`` (a transformer's predictions) mean the same here; the rest
        trains against ``other``'s codes (``forward(teacher_logits=...)``)."""
        for k in CODE_SPACE_FIELDS:
            if getattr(self.cfg, k) != getattr(other.cfg, k):
                raise ValueError(f"the code space's prior has {k}={getattr(other.cfg, k)!r}, "
                                 f"this one {getattr(self.cfg, k)!r}")
        with torch.no_grad():
            self.codebooks.copy_(other.codebooks)
            self.sem_encoder.load_state_dict(other.sem_encoder.state_dict())
        self.codebooks.requires_grad_(False)
        self.sem_encoder.requires_grad_(False)

    # -- inference ------------------------------------------------------------------------
    @torch.inference_mode()
    def code_distribution(self, z: torch.Tensor) -> torch.Tensor:
        """Raw z (B, Z) -> P_gt (B, K, N): softmax of negative distances (transformer targets)."""
        return F.softmax(self.code_logits(self.normalise(z)), dim=-1)

    @torch.inference_mode()
    def mean_code_logits(self, z: torch.Tensor) -> torch.Tensor:
        """A set of raw latents (M, Z) -> log of their mean P_gt (K, N), the empirical code
        logits of a label; uniform for an empty set."""
        if len(z) == 0:
            return torch.full((self.cfg.n_codebooks, self.cfg.codebook_size),
                              1.0 / self.cfg.codebook_size).log()
        return self.code_distribution(z.float()).mean(0).clamp_min(1e-8).log()

    @torch.inference_mode()
    def semantic(self, text_emb: torch.Tensor) -> torch.Tensor:
        """Pooled label-text embeddings (B, text_dim) -> c_s (B, cs_dim)."""
        return self.sem_encoder(text_emb)

    @torch.inference_mode()
    def sample_from_logits(self, P: torch.Tensor, c_s: torch.Tensor, *, steps: int = 50,
                           tau: Optional[float] = None, guidance: float = 1.0,
                           generator: Optional[torch.Generator] = None) -> torch.Tensor:
        """Codebook logits P (B, K, N) + c_s (B, S) -> raw z (B, Z) by DDIM.

        P is read as logits (log-probabilities or negative distances both work: the softmax is
        shift invariant); each codebook entry is mixed by Gumbel-softmax at temperature tau.
        """
        tau = self.cfg.tau_sample if tau is None else tau
        P = P.float()
        geo = self.geo_tokens(gumbel_softmax(P, tau, generator))        # (B, K, W)
        x = self.diffusion.ddim_sample(self.denoiser, (P.shape[0], self.cfg.z_dim),
                                       (geo, c_s.float()), steps=steps, guidance=guidance,
                                       generator=generator)
        return self.denormalise(x)
