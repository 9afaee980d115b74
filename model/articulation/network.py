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
from .frames import LOG_RANGE, PLACE_CLASSES, place_values

MODE_EPS = 0.05   # art_modes > 1: share of the articulation loss spread over every mode


@dataclass
class TreeBatch:
    """A padded batch of partial trees. Position 0 of every row is START.

    tokens  (B, N, 16) float   normalised articulation tokens (0 at START / padding)
    jtypes  (B, N)     long    joint type of each node (0 at START / padding)
    cs      (B, N, 64) float   semantic condition of each node
    parents (B, N)     long    parent position for the TPE (-1 for START, root and padding)
    depth   (B, N)     long    root = 0; START and padding = -1
    mask    (B, N)     bool    True = real token (START included)
    labels  (B, N)     long    index of each node's label in ``cfg.count_labels`` (-1 = none);
                               only read by the child-count features (None = all -1)
    """
    tokens: torch.Tensor
    jtypes: torch.Tensor
    cs: torch.Tensor
    parents: torch.Tensor
    depth: torch.Tensor
    mask: torch.Tensor
    labels: Optional[torch.Tensor] = None

    def to(self, device) -> "TreeBatch":
        return TreeBatch(*(getattr(self, k).to(device) for k in
                           ("tokens", "jtypes", "cs", "parents", "depth", "mask")),
                         labels=None if self.labels is None else self.labels.to(device))


@dataclass
class Targets:
    """Per-token targets: the token's next child, or END.

    has_child (B, N) float; child_tokens (B, N, 16); child_jtypes (B, N) long;
    child_cs (B, N, 64); child_P (B, N, C, K) probabilities (or None);
    child_z (B, N, Z) normalised latents (no_shape_prior ablation, else None);
    child_label / label_cs: optional auxiliary target — labels are decoded as the nearest
    c_s of the table, so a cross-entropy over negative distances to the table trains exactly
    that decision.
    """
    has_child: torch.Tensor
    child_tokens: torch.Tensor
    child_jtypes: torch.Tensor
    child_cs: torch.Tensor
    child_P: Optional[torch.Tensor] = None
    child_z: Optional[torch.Tensor] = None
    child_label: Optional[torch.Tensor] = None   # (B, N) long: row of label_cs, -1 = none
    label_cs: Optional[torch.Tensor] = None      # (T, 64) c_s of every training label
    plan_counts: Optional[torch.Tensor] = None   # (B, len(count_labels)) parts per label in
                                                 # the whole object (auxiliary plan head)
    child_place: Optional[torch.Tensor] = None   # (B, N, 6) long: place classes, 3 of the
                                                 # origin, 3 of the centre (place_bins)


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


class Attention(nn.Module):
    """Multi-head attention whose keys/values may be computed once per condition and shared
    by many query rows (``kv_index``): all decoding rounds of one object read one text."""

    def __init__(self, d: int, heads: int, dropout: float):
        super().__init__()
        if d % heads:
            raise ValueError(f"d_model {d} is not divisible by n_heads {heads}")
        self.h, self.dropout = heads, dropout
        self.q = nn.Linear(d, d)
        self.kv = nn.Linear(d, 2 * d)
        self.out = nn.Linear(d, d)

    def forward(self, x: torch.Tensor, mem: torch.Tensor, mem_mask: torch.Tensor,
                kv_index: Optional[torch.Tensor] = None) -> torch.Tensor:
        """x (B, N, d) queries; mem (U, L, d), mem_mask (B, L) True = attend; kv_index (B,)
        rows of mem per query row (None: U == B)."""
        B, N, d = x.shape
        U, L, _ = mem.shape
        dh = d // self.h
        q = self.q(x).view(B, N, self.h, dh).transpose(1, 2)               # (B, h, N, dh)
        k, v = self.kv(mem).view(U, L, 2, self.h, dh).permute(2, 0, 3, 1, 4)  # (U, h, L, dh) x2
        if kv_index is not None:
            k, v = k[kv_index], v[kv_index]                                # (B, h, L, dh)
        o = F.scaled_dot_product_attention(q, k, v, attn_mask=mem_mask[:, None, None, :],
                                           dropout_p=self.dropout if self.training else 0.0)
        return self.out(o.transpose(1, 2).reshape(B, N, d))


class Block(nn.Module):
    """Post-LN transformer block: self-attention (non-causal, key padding masked), optional
    cross-attention to the condition, feed-forward."""

    def __init__(self, d: int, heads: int, ffn_mult: int, dropout: float, cross: bool):
        super().__init__()
        self.self_attn = Attention(d, heads, dropout)
        self.cross_attn = Attention(d, heads, dropout) if cross else None
        self.ffn = nn.Sequential(nn.Linear(d, d * ffn_mult), nn.GELU(), nn.Linear(d * ffn_mult, d))
        self.norms = nn.ModuleList([nn.LayerNorm(d) for _ in range(3 if cross else 2)])
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor, mask: torch.Tensor, mem: Optional[torch.Tensor] = None,
                mem_mask: Optional[torch.Tensor] = None,
                kv_index: Optional[torch.Tensor] = None) -> torch.Tensor:
        """x (B, N, d), mask (B, N) True = real token; mem (U, L, d), mem_mask (B, L)."""
        x = self.norms[0](x + self.drop(self.self_attn(x, x, mask)))
        if self.cross_attn is not None:
            x = self.norms[1](x + self.drop(self.cross_attn(x, mem, mem_mask, kv_index)))
        return self.norms[-1](x + self.drop(self.ffn(x)))


def grid_sincos(rows: int, cols: int, d: int) -> torch.Tensor:
    """(1, rows*cols, d) 2-D sin-cos code, row-major like a flattened feature map: the first
    half of the channels encodes the row, the second half the column."""
    if d % 4:
        raise ValueError(f"a 2-D sin-cos position code needs d % 4 == 0, got d = {d}")
    q = d // 4
    freq = 1.0 / (100.0 ** (torch.arange(q, dtype=torch.float32) / q))

    def code(n: int) -> torch.Tensor:
        a = torch.arange(n, dtype=torch.float32).unsqueeze(1) * freq      # (n, q)
        return torch.cat([a.sin(), a.cos()], 1)                            # (n, d/2)

    r, c = code(rows), code(cols)
    grid = torch.cat([r.unsqueeze(1).expand(-1, cols, -1), c.unsqueeze(0).expand(rows, -1, -1)], -1)
    return grid.reshape(1, rows * cols, d)


class ConditionEncoder(nn.Module):
    """Per-modality input projection + a small post-encoder over the condition tokens, then a
    learned NULL token in front. NULL is never masked: it is what a dropped condition
    (classifier-free training) leaves, and it keeps attention defined for any mask. It is
    added after the encoder so that it carries no information about the text."""

    def __init__(self, cfg: ArticulationConfig):
        super().__init__()
        d = cfg.d_model
        self.cfg_count = {m: tuple(v) for m, v in cfg.count_tokens.items()}
        self.proj = nn.ModuleDict({m: nn.Sequential(nn.Linear(dim, d), nn.LayerNorm(d))
                                   for m, dim in cfg.cond_dims.items()})
        self.pos = nn.ParameterDict({m: nn.Parameter(grid_sincos(int(h), int(w), d))
                                     for m, (h, w) in cfg.cond_grid.items()})
        # count tokens (cfg.count_tokens): a label's count distribution -> one token, plus a
        # learned embedding of which label it counts
        self.count_in = nn.ModuleDict({m: nn.Sequential(nn.Linear(int(c), d), nn.LayerNorm(d))
                                       for m, (n, c) in cfg.count_tokens.items()})
        self.count_pos = nn.ParameterDict({m: nn.Parameter(torch.randn(1, int(n), d) * 0.02)
                                           for m, (n, c) in cfg.count_tokens.items()})
        self.null = nn.Parameter(torch.randn(1, 1, d) * 0.02)
        self.layers = nn.ModuleList([Block(d, cfg.n_heads, cfg.ffn_mult, cfg.dropout, False)
                                     for _ in range(cfg.cond_layers)])

    def forward(self, tokens: torch.Tensor, mask: torch.Tensor, modality: str
                ) -> tuple[torch.Tensor, torch.Tensor]:
        """tokens (U, L, D_cond), mask (U, L) True = real -> memory (U, 1+L, d), mask (U, 1+L)."""
        if modality not in self.proj:
            raise KeyError(f"no input projection for condition modality {modality!r}; "
                           f"this model knows {sorted(self.proj)}")
        U = tokens.shape[0]
        mask = mask.bool()
        counts = None
        if modality in self.count_in:        # the last n tokens carry count distributions
            n, c = (int(v) for v in self.cfg_count[modality])
            if tokens.shape[1] <= n:
                raise ValueError(f"{modality} condition has {tokens.shape[1]} tokens; this model "
                                 f"expects its features followed by {n} count tokens")
            tokens, counts = tokens[:, :-n], tokens[:, -n:, :c]
        x = self.proj[modality](tokens.float())                          # (U, L, d)
        if modality in self.pos:
            pe = self.pos[modality]
            if pe.shape[1] != x.shape[1]:
                raise ValueError(f"{modality} condition has {x.shape[1]} tokens, this model's "
                                 f"position grid has {pe.shape[1]}")
            x = x + pe
        if counts is not None:
            x = torch.cat([x, self.count_in[modality](counts.float()) + self.count_pos[modality]], 1)
        enc_mask = mask.clone()
        enc_mask[:, 0] |= ~mask.any(1)        # an all-masked row: attend to something finite
        for layer in self.layers:
            x = layer(x, enc_mask)
        x = torch.cat([self.null.expand(U, -1, -1), x], 1)               # (U, 1+L, d)
        return x, torch.cat([mask.new_ones(U, 1), mask], 1)


class ArticulationTransformer(nn.Module):
    def __init__(self, cfg: ArticulationConfig):
        super().__init__()
        self.cfg = cfg
        d = cfg.d_model
        self.jt_embed = nn.Embedding(NUM_JOINT_TYPES, cfg.jt_embed_dim)
        d_node = cfg.token_dim + cfg.jt_embed_dim + cfg.cs_dim
        n_counts = 1 + len(cfg.count_labels) if cfg.child_counts else 0
        self.embed = _mlp(d_node + n_counts, d, d)
        self.start = nn.Parameter(torch.randn(d) * 0.02)
        self.tpe = TreePositionEmbedding(d_node, cfg.tpe_hidden, cfg.tpe_code_dim, cfg.tpe_levels)
        self.combine = nn.Linear(d + cfg.tpe_dim, d)
        self.cond = ConditionEncoder(cfg)
        self.layers = nn.ModuleList([Block(d, cfg.n_heads, cfg.ffn_mult, cfg.dropout, True)
                                     for _ in range(cfg.n_layers)])
        self.head_end = nn.Linear(d, 1)
        K = max(int(cfg.art_modes), 1)
        self.head_art = _mlp(d, d, cfg.token_dim * K + (K if K > 1 else 0))
        self.head_jt = nn.Linear(d, NUM_JOINT_TYPES)
        self.head_cs = _mlp(d, d, cfg.cs_dim)
        out_geo = cfg.z_dim if cfg.predict_z else cfg.num_codebooks * cfg.codebook_size
        self.head_geo = _mlp(d, d, out_geo)
        # auxiliary "plan" head on START: how many parts of each label the whole object has
        # (trains the cross-attention to read counts from the condition; not used to decode)
        self.head_plan = (nn.Linear(d, len(cfg.count_labels) * (cfg.plan_max_count + 1))
                          if cfg.plan_head and cfg.count_labels else None)
        # place_bins: per axis, is the child's joint origin on a face / the centre line of its
        # box, and its box touching / flush with a face of its parent's or centred in it?
        # (a regressed hinge averages the left and the right edge into the middle)
        self.head_place = nn.Linear(d, 3 * sum(PLACE_CLASSES)) if cfg.place_bins else None
        # the token statistics (mean, std), to place in the normalised space (set_token_norm)
        self.register_buffer("tok_norm", torch.zeros(2, cfg.token_dim) if cfg.place_bins
                             else None)

    def set_token_norm(self, tok_mean, tok_std) -> None:
        """Store the run's token statistics (place_bins snaps in normalised token space)."""
        self.tok_norm.copy_(torch.stack([torch.as_tensor(tok_mean, dtype=torch.float32),
                                         torch.as_tensor(tok_std, dtype=torch.float32)]))

    def place_logits(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, N, d) -> origin (B, N, 3, 4) and centre (B, N, 3, 6) class logits."""
        origin, centre = self.head_place(x).split([3 * n for n in PLACE_CLASSES], -1)
        return (origin.unflatten(-1, (3, PLACE_CLASSES[0])),
                centre.unflatten(-1, (3, PLACE_CLASSES[1])))

    def snap(self, art: torch.Tensor, classes: torch.Tensor) -> torch.Tensor:
        """art (..., 16) normalised tokens (parent frame) with each origin and centre
        coordinate whose class (..., 6) names a place put exactly there; the last class of a
        coordinate ("elsewhere") keeps the regressed value."""
        mean, std = self.tok_norm[0], self.tok_norm[1]
        raw = art.float() * std + mean
        half = torch.exp(raw[..., 0:3].clamp(*LOG_RANGE)).unsqueeze(-1) / 2        # (..., 3, 1)
        origin, centre = place_values(half, raw.new_tensor)
        out = raw.clone()
        for cls, sl, vals in ((classes[..., :3], slice(6, 9), origin),
                              (classes[..., 3:], slice(3, 6), centre)):
            n = vals.shape[-1]
            val = vals.gather(-1, cls.clamp_max(n - 1).unsqueeze(-1)).squeeze(-1)
            out[..., sl] = torch.where(cls < n, val, raw[..., sl])
        return ((out - mean) / std).to(art.dtype)

    def place_classes(self, out: dict, pick) -> torch.Tensor:
        """(B, N, 6) place classes from a forward's logits; ``pick`` maps (..., C) logits to
        (...) indices (argmax, or a draw)."""
        return torch.cat([pick(out["origin_logits"]), pick(out["centre_logits"])], -1)

    def child_counts(self, batch: TreeBatch) -> torch.Tensor:
        """How many children each token already has, in total and per label: (B, N, 1+T)/4.
        START counts the root as its child."""
        B, N = batch.mask.shape
        T = len(self.cfg.count_labels)
        par = torch.where(batch.depth == 0, torch.zeros_like(batch.parents), batch.parents)
        valid = (par >= 0) & batch.mask                                   # (B, N) has a parent
        lab = batch.labels if batch.labels is not None else torch.full_like(par, -1)
        onehot = torch.zeros(B, N, 1 + T)
        onehot[..., 0] = 1.0
        if T:
            onehot[..., 1:] = F.one_hot(lab.clamp_min(0), T).float() * (lab >= 0).unsqueeze(-1)
        onehot = onehot * valid.unsqueeze(-1)
        counts = torch.zeros(B, N, 1 + T).scatter_add_(
            1, par.clamp_min(0).unsqueeze(-1).expand(-1, -1, 1 + T), onehot)
        return counts / 4.0

    def encode_nodes(self, batch: TreeBatch) -> torch.Tensor:
        """Node features + TPE -> (B, N, d)."""
        feat = torch.cat([batch.tokens, self.jt_embed(batch.jtypes), batch.cs], -1)  # (B, N, d_node)
        if self.cfg.child_counts:
            emb = self.embed(torch.cat([feat, self.child_counts(batch)], -1))         # (B, N, d)
        else:
            emb = self.embed(feat)
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
                cond_index: Optional[torch.Tensor] = None,
                targets: Optional[Targets] = None, weights: Optional[dict] = None,
                memory: Optional[tuple[torch.Tensor, torch.Tensor]] = None):
        """Returns (outputs, losses); losses is None without targets.

        cond_tokens (U, L, D_cond), cond_mask (U, L); cond_index (B,) picks the condition row
        of every tree (None: U == B); drop (B,) bool drops a tree's condition (NULL only).
        outputs: end (B, N) logits, art (B, N, 16), jt (B, N, 5), cs (B, N, 64),
        geo (B, N, C, K) codebook logits or (B, N, Z) latents.
        ``memory``: the output of ``self.cond`` computed once (decoding reuses it every round);
        cond_tokens / cond_mask are then ignored.
        """
        if memory is None:
            memory = self.cond(cond_tokens, cond_mask, modality)
        mem, mem_mask = memory                                           # (U, 1+L, d), (U, 1+L)
        if cond_index is not None:
            mem_mask = mem_mask[cond_index]                              # (B, 1+L)
        if drop is not None:
            keep = torch.ones_like(mem_mask)
            keep[:, 1:] = ~drop.view(-1, 1)
            mem_mask = mem_mask & keep
        x = self.encode_nodes(batch)
        for layer in self.layers:
            x = layer(x, batch.mask, mem, mem_mask, cond_index)
        geo = self.head_geo(x)
        if not self.cfg.predict_z:
            geo = geo.view(*x.shape[:2], self.cfg.num_codebooks, self.cfg.codebook_size)
        out = {"end": self.head_end(x).squeeze(-1), "jt": self.head_jt(x),
               "cs": self.head_cs(x), "geo": geo, **self.articulation(x)}
        if self.head_plan is not None:
            out["plan"] = self.head_plan(x[:, 0]).view(x.shape[0], len(self.cfg.count_labels),
                                                       self.cfg.plan_max_count + 1)
        if self.head_place is not None:
            out["origin_logits"], out["centre_logits"] = self.place_logits(x)
        losses = None if targets is None else self.losses(out, batch.mask, targets,
                                                          weights or {})
        if self.head_place is not None:      # after the losses: they train the raw regression
            out["art_raw"] = out["art"]
            out["art"] = self.snap(out["art"], self.place_classes(out, lambda l: l.argmax(-1)))
        return out, losses

    def articulation(self, x: torch.Tensor) -> dict:
        """art (B, N, 16); with art_modes K > 1 also art_modes (B, N, K, 16) and art_logits
        (B, N, K), ``art`` being the most probable mode."""
        a = self.head_art(x)
        K = self.cfg.art_modes
        if K <= 1:
            return {"art": a}
        modes = a[..., : K * self.cfg.token_dim].unflatten(-1, (K, self.cfg.token_dim))
        logits = a[..., K * self.cfg.token_dim:]
        best = logits.argmax(-1, keepdim=True).unsqueeze(-1).expand(*logits.shape[:-1], 1,
                                                                    self.cfg.token_dim)
        return {"art": modes.gather(-2, best).squeeze(-2), "art_modes": modes,
                "art_logits": logits}

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
        if "art_modes" in out:
            # winner takes all (relaxed: the other modes get MODE_EPS of the gradient so none
            # dies), and the mode logits learn which mode fits
            err = ((out["art_modes"] - t.child_tokens.unsqueeze(-2)) ** 2).mean(-1)  # (B, N, K)
            best = err.detach().argmin(-1)
            fit = err.gather(-1, best.unsqueeze(-1)).squeeze(-1)
            mix = (1 - MODE_EPS) * fit + MODE_EPS * err.mean(-1)
            L["art"] = (mix * mc).sum() / nc
            ce = F.cross_entropy(out["art_logits"].transpose(1, 2), best, reduction="none")
            L["mode"] = (ce * mc).sum() / nc
        if t.child_place is not None and "origin_logits" in out:
            ce = [F.cross_entropy(out[k].permute(0, 3, 1, 2), cls, reduction="none")
                  for k, cls in (("origin_logits", t.child_place[..., :3]),
                                 ("centre_logits", t.child_place[..., 3:]))]
            L["place"] = ((torch.cat(ce, -1).mean(-1)) * mc).sum() / nc
        if t.plan_counts is not None and "plan" in out:
            L["plan"] = F.cross_entropy(out["plan"].transpose(1, 2),
                                        t.plan_counts.clamp(0, self.cfg.plan_max_count))
        if t.child_label is not None and t.label_cs is not None:
            d2 = ((out["cs"].unsqueeze(-2) - t.label_cs) ** 2).mean(-1)     # (B, N, T)
            ml = mc * (t.child_label >= 0)
            ce = F.cross_entropy((-d2 / 0.1).transpose(1, 2), t.child_label.clamp_min(0),
                                 reduction="none")
            L["label"] = (ce * ml).sum() / ml.sum().clamp_min(1.0)
        if self.cfg.predict_z:
            L["z"] = (((out["geo"] - t.child_z) ** 2).mean(-1) * mc).sum() / nc
        else:
            logq = F.log_softmax(out["geo"], -1)                          # (B, N, C, K)
            p = t.child_P
            kl = (p * (torch.log(p.clamp_min(1e-12)) - logq)).sum(-1).mean(-1)  # (B, N)
            L["P"] = (kl * mc).sum() / nc
        weights = {"end": w.get("w_end", 1.0), "art": w.get("w_art", 10.0),
                   "jt": w.get("w_jt", 1.0), "cs": w.get("w_cs", 5.0),
                   "P": w.get("w_p", 2.0), "z": w.get("w_z", 1.0),
                   "label": w.get("w_label", 1.0), "plan": w.get("w_plan", 1.0),
                   "mode": w.get("w_mode", 1.0), "place": w.get("w_place", 1.0)}
        L["total"] = sum(weights[k] * v for k, v in L.items())
        return L
