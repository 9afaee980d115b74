"""The trees of decoding (model.articulation.decode): ``DecodedTree``, what decoding gives, and
the row, the tree being decoded, with its conversions: from a kept tree (editing), to the
network's ``TreeBatch``, to the ``DecodedTree`` it gives.

A row is a dict of per-node lists, in decoding order: ``tok`` (16,) normalised articulation,
``jt`` joint type, ``lab`` count-label index (-1: not counted), ``cs`` (64,) c_s snapped to
the label table, ``cs_raw`` the network's c_s, ``geo`` P logits or z (None for a kept node
without them), ``par`` parent (-1 root), ``depth``, ``kept``, ``src``; per token (index 0 =
START, node k at k + 1): ``nkids``, ``done``; and ``logp``, ``plan_logits``, ``plan`` (counts
to follow) and, under structure control, ``struct`` (decode._start_rows).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Optional

import numpy as np
import torch

from model.core.objects import TOKEN_DIM, ArticulatedObject, JointType

from .network import TreeBatch

if TYPE_CHECKING:
    from .model import ArticulationModel


def label_summary(labels, joint_types) -> dict:
    """{"counts": parts per label, "joint_types": sorted joint type names per label}."""
    counts: dict[str, int] = {}
    joints: dict[str, set] = {}
    for lab, jt in zip(labels, joint_types):
        counts[lab] = counts.get(lab, 0) + 1
        joints.setdefault(lab, set()).add(JointType(int(jt)).name.lower())
    return {"counts": counts, "joint_types": {k: sorted(v) for k, v in joints.items()}}


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
    hinges: Optional[list] = None      # per node: the hinge side a structure asked for, or None
    structure: Optional[dict] = None   # the structure decoding was held to (asked for, or
                                       # stated by the prompt: GenerationConfig.prompt_structure)
    spatial: Optional[dict] = None     # arrangements and sides the prompt states (label ->
                                       # facts; model.refine.arrange holds them in the layout)
    size: Optional[dict] = None        # the body's dimensions the prompt states (m;
                                       # model.refine.size gives them to the layout)
    height_said: bool = False          # the prompt gives the body's height (a stated size, a
                                       # size word, an everyday name's usual height)
    width_said: bool = False           # ... its width
    knob_handles: bool = False         # the text calls a cabinet's handles knobs
    front_up: bool = False             # a chest with a lid: decoded as a cabinet with a
                                       # flip-up door, turned front up after meshing
                                       # (model.refine.orient)

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
        return {"category": self.category, **label_summary(self.labels, self.joint_types),
                "num_parts": self.num_nodes}



def initial_row(am: "ArticulationModel", keep, max_nodes: int) -> dict:
    row = {"tok": [], "jt": [], "cs": [], "cs_raw": [], "geo": [], "par": [], "depth": [],
           "lab": [],
           "nkids": [0], "done": [False], "kept": [], "src": [], "logp": 0.0,
           "plan_logits": None}   # index 0 = START
    if keep is None:
        return row
    if isinstance(keep, DecodedTree):
        toks, jts, pars, labs = keep.tokens, keep.joint_types, keep.parents, keep.labels
        cs_list = [(torch.as_tensor(c, dtype=torch.float32) - am.cs_mean) / am.cs_std
                   for c in keep.cs]
        src = list(range(keep.num_nodes))
    else:
        order = keep.topological_order()
        toks, jts, pars, labs = keep.tokens()
        cs_list = [am.label_cs(keep.category, lab) for lab in labs]
        src = order
    if len(labs) > max_nodes:
        raise ValueError(f"the kept tree has {len(labs)} nodes, more than max_nodes={max_nodes}")
    if len(labs) == 0 or sum(int(p) < 0 for p in pars) != 1:
        raise ValueError("the kept tree must be non-empty with a single root")
    row["done"][0] = True   # the root exists: START adds nothing
    net_toks = am.network_tokens(toks, pars)
    for n, (tok, jt, p, c) in enumerate(zip(net_toks, jts, pars, cs_list)):
        row["tok"].append(tok)
        row["jt"].append(int(jt))
        row["lab"].append(am._count_index.get(labs[n], -1))
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
        row["geo"] = [(torch.as_tensor(g) - am.z_mean) / am.z_std for g in keep.z]
    return row


def batch_rows(am: "ArticulationModel", rows: list[dict]) -> TreeBatch:
    B = len(rows)
    N = 1 + max(len(r["tok"]) for r in rows)
    tok = torch.zeros(B, N, TOKEN_DIM)
    jt = torch.zeros(B, N, dtype=torch.long)
    lab = torch.full((B, N), -1, dtype=torch.long)
    cs = torch.zeros(B, N, am.cfg.cs_dim)
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


def finish_row(am: "ArticulationModel", row: dict) -> DecodedTree:
    K = len(row["tok"])
    tok = torch.as_tensor(am.absolute_tokens(row["tok"], row["par"]), dtype=torch.float32
                          ).reshape(-1, TOKEN_DIM)
    cs_n = torch.stack(row["cs"]) if K else torch.zeros(0, am.cfg.cs_dim)
    idx = am.nearest_label(cs_n) if K else torch.zeros(0, dtype=torch.long)
    cs = cs_n * am.cs_std + am.cs_mean
    cs_raw = torch.stack(row["cs_raw"]) * am.cs_std + am.cs_mean if K else cs
    labels = [am.table_labels[i] for i in idx.tolist()]
    cats = [am.table_categories[i] for i in idx.tolist()]
    category = ""
    if cats:
        votes = Counter(cats).most_common()
        top = [c for c, n in votes if n == votes[0][1]]
        category = cats[0] if cats[0] in top else top[0]
    P = z = None
    if am.cfg.predict_z:
        z = np.stack([(g * am.z_std + am.z_mean).numpy() if g is not None
                      else np.zeros(am.cfg.z_dim, np.float32) for g in row["geo"]]) \
            if K else np.zeros((0, am.cfg.z_dim), np.float32)
    else:
        shape = (am.cfg.num_codebooks, am.cfg.codebook_size)
        P = np.stack([g.numpy() if g is not None else np.zeros(shape, np.float32)
                      for g in row["geo"]]) if K else np.zeros((0,) + shape, np.float32)
    return DecodedTree(
        tokens=tok.double().numpy(), joint_types=np.asarray(row["jt"], np.int64),
        parents=np.asarray(row["par"], np.int64), labels=labels, category=category,
        cs=cs.numpy(), cs_raw=cs_raw.numpy(),
        P_logits=P, z=z, kept=np.asarray(row["kept"], bool),
        source_index=np.asarray(row["src"], np.int64), log_prob=row["logp"],
        plan_logits=row["plan_logits"])


def push_child(am: "ArticulationModel", row: dict, out: dict, t: int, li: int, jt: int,
          depth: int) -> None:
    """Append to ``row`` the child predicted at token t, label-table entry li."""
    row["lab"].append(am._count_index.get(am.table_labels[li], -1))
    row["tok"].append(out["art"][t].float().clone())
    row["jt"].append(jt)
    row["cs"].append(am.table_cs_n[li])
    row["cs_raw"].append(out["cs"][t].float().clone())
    row["geo"].append(out["geo"][t].float().clone())
    row["par"].append(t - 1)
    row["depth"].append(depth)
    row["nkids"][t] += 1
    row["nkids"].append(0)
    row["done"].append(False)
    row["kept"].append(False)
    row["src"].append(-1)
