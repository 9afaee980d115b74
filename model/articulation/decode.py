"""Iterative decoding and editing with a trained articulation transformer (paper
"Iterative Decoding", supplementary "Editing").

    am = ArticulationModel.load("model/weights/transformer_small.pt")
    tokens, mask = am.encode_text(["a cabinet with two drawers"] * 3)
    trees = am.decode(tokens, mask, seed=0)          # three samples (seeds 0, 1, 2)
    obj = trees[0].to_object()                       # ArticulatedObject (no meshes yet)

Each round every node that has not emitted END gets one new child; a node that emits END
is finished. START (the root's virtual parent) adds exactly the single root. Caps: total
nodes, depth (root = 0) and children per node force END. Row i of a batch draws its random
numbers from ``torch.Generator().manual_seed(seed + i)``, so a row's result does not depend
on the other rows.
"""
from __future__ import annotations

import logging
import os
from collections import Counter
from dataclasses import dataclass, field
from typing import Optional, Union

import numpy as np
import torch
from torch.nn import functional as F

from model.core.objects import TOKEN_DIM, ArticulatedObject, JointType

from .checkpoint import build_network, read_checkpoint
from .network import ArticulationTransformer, TreeBatch

log = logging.getLogger(__name__)


@dataclass
class DecodedTree:
    """One decoded object, nodes in decoding order (every parent before its children).

    tokens (K, 16) denormalised articulation (metres / radians, object frame);
    joint_types (K,) model.core.JointType values; parents (K,) (-1 = root);
    labels: part label per node, category: object category (both read from c_s);
    cs (K, 64): c_s snapped to the nearest training label (what the shape prior expects);
    cs_raw (K, 64): the network's c_s; P_logits (K, C, N) codebook logits (None for the
    no_shape_prior ablation, which gives z (K, Z) instead); kept (K,) True for nodes given by
    ``keep``; source_index (K,): index of a kept node in the ``keep`` object's parts (-1 new).
    log_prob: the untempered network's log-probability of the tree's END and joint-type
    decisions (labels and continuous outputs are regressed, not sampled); plan_logits
    (labels, max_count + 1) the START plan head's per-label count logits (None without it).
    """
    tokens: np.ndarray
    joint_types: np.ndarray
    parents: np.ndarray
    labels: list[str]
    category: str
    cs: np.ndarray
    cs_raw: np.ndarray
    P_logits: Optional[np.ndarray]
    z: Optional[np.ndarray] = None
    kept: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    source_index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    log_prob: float = 0.0
    plan_logits: Optional[np.ndarray] = None

    @property
    def num_nodes(self) -> int:
        return len(self.labels)

    def depth(self) -> np.ndarray:
        d = np.zeros(self.num_nodes, np.int64)
        for i, p in enumerate(self.parents):
            d[i] = 0 if p < 0 else d[p] + 1
        return d

    def to_object(self, name: str = "object") -> ArticulatedObject:
        return ArticulatedObject.from_tokens(self.tokens, self.joint_types, self.parents,
                                             self.labels, category=self.category, name=name)

    def summary(self) -> dict:
        """Category, count per label and joint types per label (like ArticulatedObject.summary)."""
        counts: dict[str, int] = {}
        joints: dict[str, set] = {}
        for lab, jt in zip(self.labels, self.joint_types):
            counts[lab] = counts.get(lab, 0) + 1
            joints.setdefault(lab, set()).add(JointType(int(jt)).name.lower())
        return {"category": self.category, "counts": counts,
                "joint_types": {k: sorted(v) for k, v in joints.items()},
                "num_parts": self.num_nodes}


PLAN_ADD_MARGIN = 3.0   # follow_plan adds a child the END head gave p > sigmoid(-3) ~ 5 %


class ArticulationModel:
    """A trained network with everything decoding needs (normalisation, label table, text
    encoder name). Build with ``ArticulationModel.load(path)``."""

    def __init__(self, net: ArticulationTransformer, ckpt: dict):
        self.net = net.eval()
        self.cfg = net.cfg
        self.meta = {k: ckpt.get(k) for k in ("data_version", "seed", "command", "step",
                                              "text_encoder", "ablation", "targets")}
        st = ckpt["stats"]
        self.tok_mean = torch.as_tensor(st["tok_mean"], dtype=torch.float32)   # (16,)
        self.tok_std = torch.as_tensor(st["tok_std"], dtype=torch.float32)     # (16,)
        self.z_mean = None if st.get("z_mean") is None else torch.as_tensor(st["z_mean"]).float()
        self.z_std = None if st.get("z_std") is None else torch.as_tensor(st["z_std"]).float()
        lt = ckpt["label_table"]
        self.table_categories: list[str] = list(lt["categories"])
        self.table_labels: list[str] = list(lt["labels"])
        self.table_cs = torch.as_tensor(lt["cs"], dtype=torch.float32)          # (T, 64) raw
        self.cs_mean = torch.as_tensor(st["cs_mean"], dtype=torch.float32)     # (64,)
        self.cs_std = torch.as_tensor(st["cs_std"], dtype=torch.float32)
        self.table_cs_n = (self.table_cs - self.cs_mean) / self.cs_std          # network space
        self._count_index = {l: i for i, l in enumerate(self.cfg.count_labels)}
        self.text_encoder_name: str = ckpt.get("text_encoder") or "all-minilm-l6-v2"
        self.text_max_length: int = int(ckpt.get("train_config", {}).get("max_text_tokens", 128))

    @classmethod
    def load(cls, path: Union[str, os.PathLike]) -> "ArticulationModel":
        ckpt = read_checkpoint(path)
        return cls(build_network(ckpt), ckpt)

    # -- conditions ---------------------------------------------------------------------------
    def encode_text(self, texts: list[str]) -> tuple[torch.Tensor, torch.Tensor]:
        """texts -> condition tokens (B, L, D_text), mask (B, L) with the training encoder."""
        from model.encoders.text import get_text_encoder
        enc = get_text_encoder(self.text_encoder_name, self.text_max_length).encode(list(texts))
        return enc.states.float(), enc.mask

    # -- labels -------------------------------------------------------------------------------
    def nearest_label(self, cs_n: torch.Tensor) -> torch.Tensor:
        """Normalised cs (K, 64) -> index into the label table (K,)."""
        return torch.cdist(cs_n.float(), self.table_cs_n).argmin(-1)

    def label_cs(self, category: str, label: str) -> torch.Tensor:
        """Normalised c_s of a (category, label) pair from the table (the mean over the
        categories that have the label, if that pair was never seen)."""
        pairs = list(zip(self.table_categories, self.table_labels))
        if (category, label) in pairs:
            return self.table_cs_n[pairs.index((category, label))]
        same = [i for i, lab in enumerate(self.table_labels) if lab == label]
        if same:
            return self.table_cs_n[same].mean(0)
        raise ValueError(f"part label {label!r} is not known to this model; known labels: "
                         f"{sorted(set(self.table_labels))}")

    # -- decoding -----------------------------------------------------------------------------
    @torch.inference_mode()
    def decode(self, cond_tokens: torch.Tensor, cond_mask: torch.Tensor, *, seed: int = 0,
               max_nodes: int = 32, max_depth: int = 4, max_children: int = 16,
               temperature: float = 1.0, modality: str = "text",
               keep: Union[ArticulatedObject, DecodedTree, None] = None,
               follow_plan: bool = False, plan=None) -> list[DecodedTree]:
        """cond_tokens (S, L, D_cond), cond_mask (S, L) -> S decoded trees.

        ``temperature`` scales the END logits and the joint-type logits before sampling
        (0 = greedy: END when p < 0.5, most likely joint type). ``keep`` (editing) starts
        every row from that partial tree: its nodes are kept unchanged and may get new
        children (missing subtrees are regenerated).

        ``follow_plan`` (a deviation from the paper, off by default): the END decision of a
        node is overridden where it contradicts the network's own START plan head (parts per
        label of the whole object, read from the condition in the first round): a child whose
        predicted label has already reached its planned count is not added, and a node that
        would stop while its predicted child's label is still short of the plan adds it.
        Needs a checkpoint trained with the plan head; ignored otherwise.

        ``plan`` (S, len(count_labels)) integer counts from elsewhere (the image count head,
        model.imaging.counts) replaces the START plan head's and is always followed; a
        negative count leaves that label's END decisions to the network.
        """
        if max_nodes < 1 or max_depth < 0 or max_children < 0:
            raise ValueError("max_nodes must be >= 1, max_depth and max_children >= 0")
        S = cond_tokens.shape[0]
        cond_tokens = cond_tokens.float()
        gens = [torch.Generator().manual_seed(int(seed) + i) for i in range(S)]
        rows = [self._initial_row(keep, max_nodes) for _ in range(S)]
        if plan is not None:
            plan = torch.as_tensor(plan, dtype=torch.long)
            want = (S, len(self.cfg.count_labels or []))
            if tuple(plan.shape) != want or want[1] == 0:
                raise ValueError(f"plan must be (rows, count labels) = {want}, got {tuple(plan.shape)}")
            for r, p in zip(rows, plan.tolist()):
                r["plan"] = p
        memory = self.net.cond(cond_tokens, cond_mask, modality)   # encoded once, every round
        max_rounds = max_nodes + 2
        for _ in range(max_rounds):
            active = [i for i, r in enumerate(rows) if not all(r["done"])]
            if not active:
                break
            batch = self._batch([rows[i] for i in active])
            out, _ = self.net(batch, None, None, modality, memory=memory,
                              cond_index=torch.tensor(active))
            for b, i in enumerate(active):
                if "plan" in out and rows[i]["plan_logits"] is None:
                    rows[i]["plan_logits"] = out["plan"][b].float().numpy().copy()
                if follow_plan and "plan" in out and rows[i].get("plan") is None:
                    rows[i]["plan"] = out["plan"][b].argmax(-1).tolist()   # (labels,)
                self._grow(rows[i], {k: v[b] for k, v in out.items()}, gens[i],
                           max_nodes, max_depth, max_children, temperature)
        return [self._finish(r) for r in rows]

    def _initial_row(self, keep, max_nodes: int) -> dict:
        row = {"tok": [], "jt": [], "cs": [], "cs_raw": [], "geo": [], "par": [], "depth": [],
               "lab": [],
               "nkids": [0], "done": [False], "kept": [], "src": [], "logp": 0.0,
               "plan_logits": None}   # index 0 = START
        if keep is None:
            return row
        if isinstance(keep, DecodedTree):
            toks, jts, pars, labs = keep.tokens, keep.joint_types, keep.parents, keep.labels
            cs_list = [(torch.as_tensor(c, dtype=torch.float32) - self.cs_mean) / self.cs_std
                       for c in keep.cs]
            src = list(range(keep.num_nodes))
        else:
            order = keep.topological_order()
            toks, jts, pars, labs = keep.tokens()
            cs_list = [self.label_cs(keep.category, lab) for lab in labs]
            src = order
        if len(labs) > max_nodes:
            raise ValueError(f"the kept tree has {len(labs)} nodes, more than max_nodes={max_nodes}")
        if len(labs) == 0 or sum(int(p) < 0 for p in pars) != 1:
            raise ValueError("the kept tree must be non-empty with a single root")
        row["done"][0] = True   # the root exists: START adds nothing
        for n, (tok, jt, p, c) in enumerate(zip(toks, jts, pars, cs_list)):
            row["tok"].append((torch.as_tensor(np.asarray(tok), dtype=torch.float32)
                               - self.tok_mean) / self.tok_std)
            row["jt"].append(int(jt))
            row["lab"].append(self._count_index.get(labs[n], -1))
            row["cs"].append(c)
            row["cs_raw"].append(c)
            row["geo"].append(None)
            row["par"].append(int(p))
            row["depth"].append(0 if p < 0 else row["depth"][int(p)] + 1)
            row["nkids"].append(0)
            row["done"].append(False)
            row["kept"].append(True)
            row["src"].append(int(src[n]))
            if p >= 0:
                row["nkids"][int(p) + 1] += 1
        if isinstance(keep, DecodedTree) and keep.P_logits is not None:
            row["geo"] = [torch.as_tensor(g) for g in keep.P_logits]
        elif isinstance(keep, DecodedTree) and keep.z is not None:
            row["geo"] = [(torch.as_tensor(g) - self.z_mean) / self.z_std for g in keep.z]
        return row

    def _batch(self, rows: list[dict]) -> TreeBatch:
        B = len(rows)
        N = 1 + max(len(r["tok"]) for r in rows)
        tok = torch.zeros(B, N, TOKEN_DIM)
        jt = torch.zeros(B, N, dtype=torch.long)
        lab = torch.full((B, N), -1, dtype=torch.long)
        cs = torch.zeros(B, N, self.cfg.cs_dim)
        par = torch.full((B, N), -1, dtype=torch.long)
        dep = torch.full((B, N), -1, dtype=torch.long)
        mask = torch.zeros(B, N, dtype=torch.bool)
        for b, r in enumerate(rows):
            n = len(r["tok"])
            mask[b, : n + 1] = True
            if n:
                tok[b, 1: n + 1] = torch.stack(r["tok"])
                jt[b, 1: n + 1] = torch.tensor(r["jt"])
                lab[b, 1: n + 1] = torch.tensor(r["lab"])
                cs[b, 1: n + 1] = torch.stack(r["cs"])
                p = torch.tensor(r["par"])
                par[b, 1: n + 1] = torch.where(p >= 0, p + 1, p)
                dep[b, 1: n + 1] = torch.tensor(r["depth"])
        return TreeBatch(tok, jt, cs, par, dep, mask, labels=lab)

    def _grow(self, row: dict, out: dict, gen: torch.Generator, max_nodes: int,
              max_depth: int, max_children: int, temperature: float) -> None:
        """Add at most one child to every unfinished token of one row (in token order)."""
        n_tokens = len(row["done"])
        for t in range(n_tokens):
            if row["done"][t]:
                continue
            depth_child = 0 if t == 0 else row["depth"][t - 1] + 1
            capped = (len(row["tok"]) >= max_nodes or depth_child > max_depth
                      or (t > 0 and row["nkids"][t] >= max_children)
                      or (t == 0 and row["nkids"][0] >= 1))
            logit = out["end"][t]
            if temperature > 0:
                p_child = torch.sigmoid(logit / temperature)
                wants = bool(torch.rand((), generator=gen) < p_child)
            else:
                wants = bool(logit > 0)
            cs_raw = out["cs"][t].float()
            li = int(self.nearest_label(cs_raw[None])[0])
            count_i = self._count_index.get(self.table_labels[li], -1)
            plan = row.get("plan")
            if plan is not None and t > 0 and count_i >= 0 and plan[count_i] >= 0:
                # the plan overrides END for a label it counts (see decode); it only adds a
                # child the END head finds plausible: a leaf's child head is untrained
                short = row["lab"].count(count_i) < plan[count_i]
                wants = short and (wants or float(logit) > -PLAN_ADD_MARGIN)
            if t == 0 and not row["tok"]:
                wants = True   # an object has at least its root
            if not capped and not (t == 0 and not row["tok"]):
                # the untempered network's log-probability of this END decision
                row["logp"] += float(F.logsigmoid(logit if wants else -logit))
            if capped or not wants:
                row["done"][t] = True
                continue
            if t == 0:
                jt = int(JointType.FIXED)   # the single root is fixed to the world
            else:
                if temperature > 0:
                    probs = torch.softmax(out["jt"][t] / temperature, -1)
                    jt = int(torch.multinomial(probs, 1, generator=gen))
                else:
                    jt = int(out["jt"][t].argmax())
                row["logp"] += float(torch.log_softmax(out["jt"][t].float(), -1)[jt])
            cs = self.table_cs_n[li]
            row["lab"].append(count_i)
            row["tok"].append(out["art"][t].float().clone())
            row["jt"].append(jt)
            row["cs"].append(cs)
            row["cs_raw"].append(cs_raw.clone())
            row["geo"].append(out["geo"][t].float().clone())
            row["par"].append(t - 1)
            row["depth"].append(depth_child)
            row["nkids"][t] += 1
            row["nkids"].append(0)
            row["done"].append(False)
            row["kept"].append(False)
            row["src"].append(-1)

    def _finish(self, row: dict) -> DecodedTree:
        K = len(row["tok"])
        tok = torch.stack(row["tok"]) * self.tok_std + self.tok_mean if K else torch.zeros(0, TOKEN_DIM)
        cs_n = torch.stack(row["cs"]) if K else torch.zeros(0, self.cfg.cs_dim)
        idx = self.nearest_label(cs_n) if K else torch.zeros(0, dtype=torch.long)
        cs = cs_n * self.cs_std + self.cs_mean
        cs_raw = torch.stack(row["cs_raw"]) * self.cs_std + self.cs_mean if K else cs
        labels = [self.table_labels[i] for i in idx.tolist()]
        cats = [self.table_categories[i] for i in idx.tolist()]
        category = ""
        if cats:
            votes = Counter(cats).most_common()
            top = [c for c, n in votes if n == votes[0][1]]
            category = cats[0] if cats[0] in top else top[0]
        P = z = None
        if self.cfg.predict_z:
            z = np.stack([(g * self.z_std + self.z_mean).numpy() if g is not None
                          else np.zeros(self.cfg.z_dim, np.float32) for g in row["geo"]]) \
                if K else np.zeros((0, self.cfg.z_dim), np.float32)
        else:
            shape = (self.cfg.num_codebooks, self.cfg.codebook_size)
            P = np.stack([g.numpy() if g is not None else np.zeros(shape, np.float32)
                          for g in row["geo"]]) if K else np.zeros((0,) + shape, np.float32)
        return DecodedTree(
            tokens=tok.double().numpy(), joint_types=np.asarray(row["jt"], np.int64),
            parents=np.asarray(row["par"], np.int64), labels=labels, category=category,
            cs=cs.numpy(), cs_raw=cs_raw.numpy(),
            P_logits=P, z=z, kept=np.asarray(row["kept"], bool),
            source_index=np.asarray(row["src"], np.int64), log_prob=row["logp"],
            plan_logits=row["plan_logits"])
