"""The diffusion process of the shape prior, kept apart from the denoiser (STYLE.md #4).

x0 prediction, cosine noise schedule (Nichol & Dhariwal), ``timesteps`` training steps, and a
deterministic DDIM sampler (eta = 0) with optional classifier-free guidance. Every function
takes the denoiser as an argument: ``model(x_t (B, Z), t (B,) long, cond, drop) -> x0 (B, Z)``
where ``drop`` is a (B,) long tensor: 0 = keep both conditions, 1 = drop the geometry
condition, 2 = drop both.
"""
from __future__ import annotations

import math
from typing import Callable, Optional

import torch

DROP_NONE, DROP_GEO, DROP_BOTH = 0, 1, 2


class Diffusion:
    def __init__(self, timesteps: int = 1000, s: float = 0.008):
        self.T = int(timesteps)
        t = torch.arange(self.T + 1, dtype=torch.float64) / self.T
        f = torch.cos((t + s) / (1 + s) * math.pi / 2) ** 2
        abar = f / f[0]
        betas = (1 - abar[1:] / abar[:-1]).clamp(max=0.999)
        self.alpha_bar = torch.cumprod(1 - betas, 0).float()      # (T,) ᾱ_t for t = 0..T-1

    def q_sample(self, x0: torch.Tensor, t: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        """x0 (B, Z), t (B,) -> x_t (B, Z)."""
        ab = self.alpha_bar.to(x0.device)[t].unsqueeze(-1)          # (B, 1)
        return ab.sqrt() * x0 + (1 - ab).sqrt() * noise

    def training_loss(self, model: Callable, x0: torch.Tensor, cond, drop: torch.Tensor,
                      generator: Optional[torch.Generator] = None) -> torch.Tensor:
        """MSE between the predicted and the true x0 at a uniformly random step."""
        B = x0.shape[0]
        t = torch.randint(0, self.T, (B,), generator=generator, device=x0.device)
        noise = torch.randn(x0.shape, generator=generator, device=x0.device)
        pred = model(self.q_sample(x0, t, noise), t, cond, drop)   # (B, Z)
        return (pred - x0).pow(2).mean()

    @torch.inference_mode()
    def ddim_sample(self, model: Callable, shape: tuple[int, int], cond, *, steps: int = 50,
                    guidance: float = 1.0, generator: Optional[torch.Generator] = None,
                    clip: Optional[float] = None) -> torch.Tensor:
        """Deterministic DDIM from pure noise in ``steps`` steps -> x0 (B, Z).

        ``guidance`` != 1 runs the unconditional branch (both conditions dropped) in the same
        batch and extrapolates: x0 = x0_u + guidance * (x0_c - x0_u).
        """
        steps = max(1, min(int(steps), self.T))
        B = shape[0]
        x = torch.randn(shape, generator=generator)
        ts = torch.linspace(self.T - 1, 0, steps).round().long().tolist()
        ab = self.alpha_bar
        keep = torch.full((B,), DROP_NONE, dtype=torch.long)
        use_cfg = guidance != 1.0
        for i, t in enumerate(ts):
            tt = torch.full((B,), t, dtype=torch.long)
            if use_cfg:
                both = model(torch.cat([x, x]), torch.cat([tt, tt]), _repeat_cond(cond),
                             torch.cat([keep, torch.full((B,), DROP_BOTH, dtype=torch.long)]))
                x0c, x0u = both[:B], both[B:]
                x0 = x0u + guidance * (x0c - x0u)
            else:
                x0 = model(x, tt, cond, keep)
            if clip is not None:
                x0 = x0.clamp(-clip, clip)
            a_t = ab[t]
            if i + 1 == len(ts):
                x = x0
                break
            a_n = ab[ts[i + 1]]
            eps = (x - a_t.sqrt() * x0) / (1 - a_t).sqrt()
            x = a_n.sqrt() * x0 + (1 - a_n).sqrt() * eps
        return x


def _repeat_cond(cond):
    """Duplicate a condition (tensor or tuple of tensors) along the batch for CFG."""
    if isinstance(cond, torch.Tensor):
        return torch.cat([cond, cond])
    return type(cond)(torch.cat([c, c]) for c in cond)
