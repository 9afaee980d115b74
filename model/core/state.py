"""State-dict storage helper shared by every checkpoint writer."""
from __future__ import annotations

import torch


def half_state(state: dict) -> dict:
    """Detached copy of a state dict with floating tensors in fp16 (how shipped weights are
    stored); other tensors (step counters, indices) are cloned unchanged."""
    return {k: v.detach().to(torch.float16, copy=True) if v.is_floating_point() else v.detach().clone()
            for k, v in state.items()}
