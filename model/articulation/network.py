"""The articulation transformer network (DESIGN §5; paper "Articulation Transformer").

Every existing node of the tree is a token; position 0 of each sequence is the START token,
a learned embedding that stands for the root's (virtual) parent. For every token the network
predicts: does this node get another child (END logit), and if so that child's articulation
(16 normalised floats), joint type (5-way), semantic condition c_s (64) and codebook logits
P (num_codebooks × codebook_size) — or the latent z directly for the no_shape_prior ablation.

Self-attention is NOT causal: every node sees every other existing node (padding masked);
cross-attention in every layer reads the condition tokens after a small post-encoder.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import torch
import torch.nn as nn
import torch.nn.functional as F

from .config import NUM_JOINT_TYPES, ArticulationConfig


@dataclass
class TreeBatch:
    """A padded batch of partial trees. Position 0 of every row is START.

    tokens  (B, N, 16) float   normalised articulation tokens (0 at START / padding)
    jtypes  (B, N)     long    joint type of each node (0 at START / padding)
    cs      (B, N, 64) float   semantic condition of each node
    parents (B, N)     long    parent position for the TPE (-1 for START, root and padding)
    depth   (B, N)     long    root = 0; START and padding = -1
    mask    (B, N)     bool    True = real token (START included)
    """
    tokens: torch.Tensor
    jtypes: torch.Tensor
    cs: torch.Tensor
    parents: torch.Tensor
    depth: torch.Tensor
    mask: torch.Tensor

    def to(self, device) -> "TreeBatch":
        return TreeBatch(*(getattr(self, k).to(device) for k in
                           ("tokens", "jtypes", "cs", "parents", "depth", "mask")))


@dataclass
class Targets:
    """Per-token targets: the token's next child, or END.

    has_child (B, N) float; child_tokens (B, N, 16); child_jtypes (B, N) long;
    child_cs (B, N, 64); child_P (B, N, C, K) probabilities (or None);
    child_z (B, N, Z) normalised latents (no_shape_prior ablation, else None).
    """
    has_child: torch.Tensor
    child_tokens: torch.Tensor
    child_jtypes: torch.Tensor
    child_cs: torch.Tensor
    child_P: Optional[torch.Tensor] = None
    child_z: Optional[torch.Tensor] = None


def _mlp(d_in: int, d_hidden: int, d_out: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(d_in, d_hidden), nn.GELU(), nn.Linear(d_hidden, d_out))


class TreePositionEmbedding(nn.Module):
    """h_i = GRUCell(x_i, h_parent) (root's parent state 0); c_i = MLP(h_i) ∈ R^code;
    e_i = concat(c_i, c_parent, c_grandparent, ...) truncated / zero-padded to
    ``levels * code`` floats (equivalently concat(c_i, e_parent) truncated)."""

    def __init__(self, d_in: int, hidden: int, code: int, levels: int):
        super().__init__()
        self.levels, self.code = levels, code
        self.gru = nn.GRUCell(d_in, hidden)
        self.to_code = _mlp(hidden, hidden, code)

    def forward(self, x: torch.Tensor, parents: torch.Tensor, depth: torch.Tensor) -> torch.Tensor:
        """x (B, N, d_in), parents (B, N), depth (B, N) -> e (B, N, levels*code); 0 where depth < 0."""
        B, N, _ = x.shape
        h = x.new_zeros(B, N, self.gru.hidden_size)                      # (B, N, H)
        par = parents.clamp_min(0)                                       # (B, N)
        has_par = (parents >= 0).unsqueeze(-1)                           # (B, N, 1)
        max_depth = int(depth.max().item()) if depth.numel() else -1
        x_flat = x.reshape(B * N, -1)
        for d in range(max_depth + 1):  # a node's state needs its parent's: level by level
            h_par = torch.gather(h, 1, par.unsqueeze(-1).expand_as(h)) * has_par  # (B, N, H)
            h_new = self.gru(x_flat, h_par.reshape(B * N, -1)).view(B, N, -1)
            h = torch.where((depth == d).unsqueeze(-1), h_new, h)
        c = self.to_code(h) * (depth >= 0).unsqueeze(-1)                 # (B, N, code)
        # ancestor positions: anc[..., k] = k-th ancestor (0 = self), -1 past the root
        anc = [torch.where(depth >= 0, torch.arange(N, device=x.device).expand(B, N),
                           torch.full_like(depth, -1))]
        for _ in range(self.levels - 1):
            prev = anc[-1]
            nxt = torch.gather(parents, 1, prev.clamp_min(0))
            anc.append(torch.where(prev >= 0, nxt, torch.full_like(nxt, -1)))
        anc_t = torch.stack(anc, -1)                                     # (B, N, L)
        idx = anc_t.clamp_min(0).reshape(B, N * self.levels, 1).expand(-1, -1, self.code)
        e = torch.gather(c, 1, idx).view(B, N, self.levels, self.code)   # (B, N, L, code)
        e = e * (anc_t >= 0).unsqueeze(-1)
        return e.reshape(B, N, self.levels * self.code)


class ConditionEncoder(nn.Module):
    """Per-modality input projection + post-encoder over [NULL, condition tokens].

    A learned NULL token is always present (never masked): it carries the unconditional
    case (condition dropout) and keeps attention defined when every token is masked.
    """

    def __init__(self, cfg: ArticulationConfig):
        super().__init__()
        d = cfg.d_model
        self.proj = nn.ModuleDict({m: nn.Sequential(nn.Linear(dim, d), nn.LayerNorm(d))
                                   for m, dim in cfg.cond_dims.items()})
        self.null = nn.Parameter(torch.randn(1, 1, d) * 0.02)
        layer = nn.TransformerEncoderLayer(d, cfg.n_heads, d * cfg.ffn_mult, cfg.dropout,
                                           activation="gelu", batch_first=True, norm_first=False)
        self.encoder = nn.TransformerEncoder(layer, cfg.cond_layers, enable_nested_tensor=False) \
            if cfg.cond_layers > 0 else None

    def forward(self, tokens: torch.Tensor, mask: torch.Tensor, modality: str,
                drop: Optional[torch.Tensor] = None) -> tuple[torch.Tensor, torch.Tensor]:
        """tokens (B, L, D_cond), mask (B, L) True = real, drop (B,) bool ->
        memory (B, 1+L, d), memory mask (B, 1+L)."""
        if modality not in self.proj:
            raise KeyError(f"no input projection for condition modality {modality!r}; "
                           f"this model knows {sorted(self.proj)}")
        B = tokens.shape[0]
        x = self.proj[modality](tokens)                                  # (B, L, d)
        mask = mask.bool()
        if drop is not None:
            mask = mask & ~drop.view(B, 1)
        x = torch.cat([self.null.expand(B, -1, -1), x], 1)               # (B, 1+L, d)
        mask = torch.cat([mask.new_ones(B, 1), mask], 1)                 # (B, 1+L)
        if self.encoder is not None:
            x = self.encoder(x, src_key_padding_mask=~mask)
        return x, mask


class ArticulationTransformer(nn.Module):
    def __init__(self, cfg: ArticulationConfig):
        super().__init__()
        self.cfg = cfg
        d = cfg.d_model
        self.jt_embed = nn.Embedding(NUM_JOINT_TYPES, cfg.jt_embed_dim)
        d_node = cfg.token_dim + cfg.jt_embed_dim + cfg.cs_dim
        self.embed = _mlp(d_node, d, d)
        self.start = nn.Parameter(torch.randn(d) * 0.02)
        self.tpe = TreePositionEmbedding(d_node, cfg.tpe_hidden, cfg.tpe_code_dim, cfg.tpe_levels)
        self.combine = nn.Linear(d + cfg.tpe_dim, d)
        self.cond = ConditionEncoder(cfg)
        self.layers = nn.ModuleList([
            nn.TransformerDecoderLayer(d, cfg.n_heads, d * cfg.ffn_mult, cfg.dropout,
                                       activation="gelu", batch_first=True, norm_first=False)
            for _ in range(cfg.n_layers)])
        self.head_end = nn.Linear(d, 1)
        self.head_art = _mlp(d, d, cfg.token_dim)
        self.head_jt = nn.Linear(d, NUM_JOINT_TYPES)
        self.head_cs = _mlp(d, d, cfg.cs_dim)
        out_geo = cfg.z_dim if cfg.predict_z else cfg.num_codebooks * cfg.codebook_size
        self.head_geo = _mlp(d, d, out_geo)

    def num_params(self) -> int:
        return sum(p.numel() for p in self.parameters())

    def encode_nodes(self, batch: TreeBatch) -> torch.Tensor:
        """Node features + TPE -> (B, N, d)."""
        feat = torch.cat([batch.tokens, self.jt_embed(batch.jtypes), batch.cs], -1)  # (B, N, d_node)
        emb = self.embed(feat)                                                        # (B, N, d)
        is_start = torch.zeros_like(batch.mask)
        is_start[:, 0] = True
        emb = torch.where(is_start.unsqueeze(-1), self.start.expand_as(emb), emb)
        if self.cfg.use_tpe:
            e = self.tpe(feat, batch.parents, batch.depth)                            # (B, N, tpe)
        else:
            e = emb.new_zeros(*emb.shape[:2], self.cfg.tpe_dim)
        return self.combine(torch.cat([emb, e], -1))                                  # (B, N, d)

    def forward(self, batch: TreeBatch, cond_tokens: torch.Tensor, cond_mask: torch.Tensor,
                modality: str = "text", drop: Optional[torch.Tensor] = None,
                targets: Optional[Targets] = None, weights: Optional[dict] = None):
        """Returns (outputs, losses); losses is None without targets.

        outputs: end (B, N) logits, art (B, N, 16), jt (B, N, 5), cs (B, N, 64),
        geo (B, N, C, K) codebook logits or (B, N, Z) latents.
        """
        mem, mem_mask = self.cond(cond_tokens, cond_mask, modality, drop)
        x = self.encode_nodes(batch)
        pad = ~batch.mask
        for layer in self.layers:
            x = layer(x, mem, tgt_key_padding_mask=pad, memory_key_padding_mask=~mem_mask)
        geo = self.head_geo(x)
        if not self.cfg.predict_z:
            geo = geo.view(*x.shape[:2], self.cfg.num_codebooks, self.cfg.codebook_size)
        out = {"end": self.head_end(x).squeeze(-1), "art": self.head_art(x),
               "jt": self.head_jt(x), "cs": self.head_cs(x), "geo": geo}
        if targets is None:
            return out, None
        return out, self.losses(out, batch.mask, targets, weights or {})

    def losses(self, out: dict, mask: torch.Tensor, t: Targets, w: dict) -> dict:
        """Weighted loss terms; child terms only where a child exists. 'total' is the sum."""
        m = mask.float()                                                  # (B, N)
        mc = m * t.has_child                                              # (B, N)
        n, nc = m.sum().clamp_min(1.0), mc.sum().clamp_min(1.0)
        bce = F.binary_cross_entropy_with_logits(out["end"], t.has_child, reduction="none")
        L = {"end": (bce * m).sum() / n,
             "art": (((out["art"] - t.child_tokens) ** 2).mean(-1) * mc).sum() / nc,
             "jt": (F.cross_entropy(out["jt"].transpose(1, 2), t.child_jtypes,
                                    reduction="none") * mc).sum() / nc,
             "cs": (((out["cs"] - t.child_cs) ** 2).mean(-1) * mc).sum() / nc}
        if self.cfg.predict_z:
            L["z"] = (((out["geo"] - t.child_z) ** 2).mean(-1) * mc).sum() / nc
        else:
            logq = F.log_softmax(out["geo"], -1)                          # (B, N, C, K)
            p = t.child_P
            kl = (p * (torch.log(p.clamp_min(1e-12)) - logq)).sum(-1).mean(-1)  # (B, N)
            L["P"] = (kl * mc).sum() / nc
        weights = {"end": w.get("w_end", 1.0), "art": w.get("w_art", 10.0),
                   "jt": w.get("w_jt", 1.0), "cs": w.get("w_cs", 5.0),
                   "P": w.get("w_p", 2.0), "z": w.get("w_z", 1.0)}
        L["total"] = sum(weights[k] * v for k, v in L.items())
        return L
