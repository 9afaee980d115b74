"""Training data of the articulation transformer: decoding rounds of ground-truth trees.

Children of every node are put in a fixed canonical order (label, then top to bottom, then
left to right, then back to front). With that order the round in which node i is added by
iterative decoding is closed-form: round(root) = 0 and the j-th child of p is added in round
round(p) + 1 + j. Training sample (object, k) holds the nodes of rounds < k; every token's
target is the child it adds in round k, or END. START (position 0) adds the root in round 0.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
import torch

from model.core.objects import TOKEN_DIM
from model.data import format as fmt

from .frames import PLACE_CLASSES, place_classes, to_frame
from .network import Targets, TreeBatch

log = logging.getLogger(__name__)


def canonical_order(labels: list[str], parents: list[int], tokens: np.ndarray
                    ) -> tuple[list[int], dict[int, int], dict[int, list[int]]]:
    """(node indices in decoding order, round of each node, ordered children of each node)."""
    kids: dict[int, list[int]] = {}
    for i, p in enumerate(parents):
        kids.setdefault(int(p), []).append(i)
    for p in kids:
        kids[p].sort(key=lambda i: (labels[i], -round(float(tokens[i][5]), 3),
                                    -round(float(tokens[i][4]), 3), -round(float(tokens[i][3]), 3)))
    roots = kids.get(-1, [])
    if len(roots) != 1:
        raise ValueError(f"a tree needs exactly one root, found {len(roots)}")
    rounds = {roots[0]: 0}
    stack = [roots[0]]
    while stack:
        p = stack.pop()
        for j, c in enumerate(kids.get(p, [])):
            rounds[c] = rounds[p] + 1 + j
            stack.append(c)
    return sorted(rounds, key=lambda i: (rounds[i], i)), rounds, kids


@dataclass
class TreeItem:
    """One object in decoding order; arrays indexed by node (order position)."""
    id: str
    category: str
    tokens: np.ndarray         # (K, 16) normalised
    jtypes: np.ndarray         # (K,)
    parents: np.ndarray        # (K,) parent position, -1 for the root
    depth: np.ndarray          # (K,)
    rounds: np.ndarray         # (K,) round in which the node is added
    cs: np.ndarray             # (K, 64) normalised c_s
    label_idx: np.ndarray      # (K,) row of the label table (-1 if the pair is not in it)
    geo: np.ndarray            # (K, C, N) P_gt or (K, Z) normalised z
    labels: list[str]
    texts: list[list[str]]     # texts per description length (lengths that exist)
    place: Optional[np.ndarray] = None    # (K, 6) place classes (parent frame only;
                                          # model.articulation.frames.place_classes)

    @property
    def num_rounds(self) -> int:
        """Rounds with at least one target (the last one is all-END)."""
        return int(self.rounds.max()) + 2


def make_item(rec: fmt.ObjectRecord, tok_mean: np.ndarray, tok_std: np.ndarray,
              cs: np.ndarray, geo: np.ndarray, label_idx: np.ndarray,
              frame: str = "absolute") -> TreeItem:
    """cs (K, 64) normalised, geo (K, ...) and label_idx (K,) in the record's node order;
    tokens in ``frame`` (model.articulation.frames), then normalised."""
    toks = np.asarray(rec.tokens, dtype=np.float64)
    order, rounds, _ = canonical_order(rec.labels, rec.parents, toks)
    pos = {old: new for new, old in enumerate(order)}
    parents = np.array([pos[rec.parents[i]] if rec.parents[i] >= 0 else -1 for i in order])
    depth = np.zeros(len(order), dtype=np.int64)
    for n, p in enumerate(parents):
        depth[n] = 0 if p < 0 else depth[p] + 1
    texts = [list(rec.descriptions[k]) for k in fmt.DESCRIPTION_LENGTHS
             if rec.descriptions.get(k)]
    rel = to_frame(toks[order], parents, frame)
    return TreeItem(
        id=rec.id, category=rec.category,
        tokens=((rel - tok_mean) / tok_std).astype(np.float32),
        jtypes=np.asarray(rec.joint_types, dtype=np.int64)[order],
        parents=parents.astype(np.int64), depth=depth,
        rounds=np.array([rounds[i] for i in order], dtype=np.int64),
        cs=np.asarray(cs, dtype=np.float32)[order], geo=np.asarray(geo, dtype=np.float32)[order],
        label_idx=np.asarray(label_idx, dtype=np.int64)[order],
        labels=[rec.labels[i] for i in order], texts=texts,
        place=place_classes(rel) if frame == "parent" else None)


def round_sample(item: TreeItem, k: int) -> dict:
    """The partial tree before round k and every token's target (START at position 0)."""
    present = np.nonzero(item.rounds < k)[0]        # decoding order = sorted by round
    n = len(present) + 1
    parents = np.full(n, -1, dtype=np.int64)
    parents[1:] = np.where(item.parents[present] >= 0, item.parents[present] + 1, -1)
    depth = np.full(n, -1, dtype=np.int64)
    depth[1:] = item.depth[present]
    # target of each token: child added in round k (START's child = the root)
    target = np.full(n, -1, dtype=np.int64)
    new = np.nonzero(item.rounds == k)[0]
    for c in new:
        target[item.parents[c] + 1 if item.parents[c] >= 0 else 0] = c
    return {"item": item, "present": present, "parents": parents, "depth": depth,
            "target": target}


def collate(samples: list[dict], geo_shape: tuple[int, ...],
            label_cs: Optional[torch.Tensor] = None,
            count_labels: Optional[list[str]] = None) -> tuple[TreeBatch, Targets]:
    B = len(samples)
    N = max(len(s["parents"]) for s in samples)
    cs_dim = samples[0]["item"].cs.shape[1]
    tok = np.zeros((B, N, TOKEN_DIM), np.float32)
    jt = np.zeros((B, N), np.int64)
    cs = np.zeros((B, N, cs_dim), np.float32)
    par = np.full((B, N), -1, np.int64)
    dep = np.full((B, N), -1, np.int64)
    mask = np.zeros((B, N), bool)
    labs = np.full((B, N), -1, np.int64)
    cidx = {l: i for i, l in enumerate(count_labels or [])}
    has = np.zeros((B, N), np.float32)
    ctok = np.zeros((B, N, TOKEN_DIM), np.float32)
    cjt = np.zeros((B, N), np.int64)
    clab = np.full((B, N), -1, np.int64)
    cplace = np.repeat(np.array(PLACE_CLASSES) - 1, 3)[None, None].repeat(B, 0).repeat(N, 1)
    plan = np.zeros((B, max(len(count_labels or []), 1)), np.int64)
    ccs = np.zeros((B, N, cs_dim), np.float32)
    cgeo = np.zeros((B, N) + tuple(geo_shape), np.float32)
    if len(geo_shape) == 2:
        cgeo += 1.0 / geo_shape[1]   # a valid distribution where there is no child
    for b, s in enumerate(samples):
        it, pr = s["item"], s["present"]
        n = len(s["parents"])
        tok[b, 1:n] = it.tokens[pr]
        jt[b, 1:n] = it.jtypes[pr]
        cs[b, 1:n] = it.cs[pr]
        par[b, :n] = s["parents"]
        dep[b, :n] = s["depth"]
        mask[b, :n] = True
        labs[b, 1:n] = [cidx.get(it.labels[j], -1) for j in pr]
        for lab in it.labels:
            if lab in cidx:
                plan[b, cidx[lab]] += 1
        t = s["target"]
        sel = np.nonzero(t >= 0)[0]
        has[b, sel] = 1.0
        ctok[b, sel] = it.tokens[t[sel]]
        cjt[b, sel] = it.jtypes[t[sel]]
        clab[b, sel] = it.label_idx[t[sel]]
        if it.place is not None:
            cplace[b, sel] = it.place[t[sel]]
        ccs[b, sel] = it.cs[t[sel]]
        cgeo[b, sel] = it.geo[t[sel]]
    T = torch.from_numpy
    batch = TreeBatch(T(tok), T(jt), T(cs), T(par), T(dep), T(mask), labels=T(labs))
    is_z = len(geo_shape) == 1
    targets = Targets(T(has), T(ctok), T(cjt), T(ccs),
                      child_P=None if is_z else T(cgeo), child_z=T(cgeo) if is_z else None,
                      child_label=T(clab) if label_cs is not None else None, label_cs=label_cs,
                      plan_counts=T(plan) if count_labels else None,
                      child_place=T(cplace) if samples[0]["item"].place is not None else None)
    return batch, targets


# --- text condition cache --------------------------------------------------------------------
@dataclass
class TextCache:
    """Frozen text-encoder states of every description, fp16, variable length."""
    encoder: str
    index: dict[str, int] = field(default_factory=dict)
    states: list[torch.Tensor] = field(default_factory=list)   # each (L, D) fp16

    @property
    def dim(self) -> int:
        return int(self.states[0].shape[1]) if self.states else 0

    def add(self, texts: list[str], max_length: int = 128, batch_size: int = 64,
            progress: bool = False) -> None:
        from model.encoders.text import get_text_encoder
        todo = sorted({t for t in texts if t not in self.index}, key=len)
        if not todo:
            return
        enc = get_text_encoder(self.encoder, max_length)
        rng = range(0, len(todo), batch_size)
        if progress:
            from tqdm import tqdm
            rng = tqdm(rng, desc="encode texts", unit="batch")
        for s in rng:
            chunk = todo[s:s + batch_size]
            out = enc.encode(chunk)
            for j, t in enumerate(chunk):
                L = int(out.mask[j].sum())
                self.index[t] = len(self.states)
                self.states.append(out.states[j, :L].to(torch.float16).clone())

    def batch(self, texts: list[str]) -> tuple[torch.Tensor, torch.Tensor]:
        """-> tokens (B, L, D) float32, mask (B, L) bool."""
        st = [self.states[self.index[t]] for t in texts]
        L = max(s.shape[0] for s in st)
        out = torch.zeros(len(st), L, self.dim)
        mask = torch.zeros(len(st), L, dtype=torch.bool)
        for i, s in enumerate(st):
            out[i, : s.shape[0]] = s.float()
            mask[i, : s.shape[0]] = True
        return out, mask

    def save(self, path: Path) -> None:
        torch.save({"encoder": self.encoder, "index": self.index, "states": self.states}, path)

    @classmethod
    def load(cls, path: Path, encoder: str) -> "TextCache":
        if Path(path).exists():
            from model.core.checkpoint import load_weights_only
            try:
                d = load_weights_only(path)
            except Exception as e:  # noqa: BLE001 - a cache is rebuilt, never trusted
                log.warning("text-state cache %s unreadable (%s); rebuilding it", path, e)
                return cls(encoder)
            if isinstance(d, dict) and d.get("encoder") == encoder:
                return cls(encoder, d["index"], d["states"])
        return cls(encoder)


def group_rounds(items: list[TreeItem], order: np.ndarray, batch_size: int, per_object: int,
                 rng: np.random.Generator, chunk_batches: int = 16) -> list[list[tuple[int, list[int]]]]:
    """An epoch of batches. A batch holds whole objects, each with some of its decoding
    rounds (``max(per_object, ceil(rounds / 3))``, all if fewer) until ``batch_size``
    rounds are reached; objects of similar size share batches (less padding)."""
    groups = []
    for i in order:
        R = items[i].num_rounds
        k = min(R, max(per_object, -(-R // 3)))
        groups.append((int(i), sorted(rng.choice(R, size=k, replace=False).tolist())))
    batches: list[list[tuple[int, list[int]]]] = []
    span = chunk_batches * max(1, batch_size // max(per_object, 1))
    for c in range(0, len(groups), span):
        chunk = sorted(groups[c:c + span], key=lambda g: len(items[g[0]].labels))
        cur, n = [], 0
        for g in chunk:
            cur.append(g)
            n += len(g[1])
            if n >= batch_size:
                batches.append(cur)
                cur, n = [], 0
        if cur:
            batches.append(cur)
    perm = rng.permutation(len(batches))
    return [batches[j] for j in perm]


def pick_texts(items: list[TreeItem], rng: np.random.Generator) -> list[str]:
    """One description per item: a random length, then a random wording of that length."""
    out = []
    for it in items:
        group = it.texts[rng.integers(len(it.texts))]
        out.append(group[rng.integers(len(group))])
    return out
