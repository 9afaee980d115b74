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
from model.core.structure import hinge_side

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
    hinges: Optional[list] = None      # per node: the hinge side a structure asked for, or None

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
LABEL_TAU = 0.1         # the label head's softmax scale: training's label cross-entropy reads
                        # -mean((c_s - c_s(label))^2) / 0.1 as logits (network.losses)

# What the training data's generator builds (docs/data.md, "The generator"), per category and
# part label: the labels a part can be attached to, its joint types, the most parts of the
# label one object has, and (doors) the hinge sides a structure may ask for. Structure control
# (decode(structure=...)) holds decoding to it; checked against model.data.synth by
# test/test_structure_control.py.
_BODY = ("body",)
STRUCTURE_GRAMMAR: dict[str, dict[str, tuple]] = {
    "StorageFurniture": {"body": ((), ("fixed",), 1),
                         "door": (_BODY, ("revolute",), 18),
                         "drawer": (_BODY, ("prismatic",), 20),
                         "handle": (("door", "drawer"), ("fixed",), 40)},
    "Safe": {"body": ((), ("fixed",), 1),
             "door": (_BODY, ("revolute",), 2),
             "button": (("door",), ("prismatic",), 24),
             "dial": (("door",), ("continuous",), 2),
             "handle": (("door",), ("fixed", "revolute"), 2)},
    "Oven": {"body": ((), ("fixed",), 1),
             "door": (_BODY, ("revolute",), 1),
             "drawer": (_BODY, ("prismatic",), 1),
             "knob": (_BODY, ("revolute", "continuous"), 6),
             "button": (_BODY, ("prismatic",), 3),
             "tray": (_BODY, ("prismatic",), 2),
             "handle": (("door", "drawer"), ("fixed",), 2)},
    "WashingMachine": {"body": ((), ("fixed",), 1),
                       "door": (_BODY, ("revolute",), 1),
                       "lid": (_BODY, ("revolute",), 1),
                       "drawer": (_BODY, ("prismatic",), 1),
                       "dial": (_BODY, ("continuous",), 2),
                       "button": (_BODY, ("prismatic",), 5),
                       "handle": (("door", "drawer", "lid"), ("fixed",), 3)},
    "Bottle": {"body": ((), ("fixed",), 1),
               "cap": (_BODY, ("screw",), 1),
               "lid": (_BODY, ("revolute",), 1)},
    "USB": {"body": ((), ("fixed",), 1),
            "cap": (_BODY, ("revolute", "prismatic"), 1)},
}
# labels one object never has together (a bottle has a screw cap or a flip lid; a washing
# machine is a front loader with a door and maybe a drawer, or a top loader with a lid)
STRUCTURE_EXCLUSIVE = {"Bottle": [("cap", "lid")],
                       "WashingMachine": [("door", "lid"), ("drawer", "lid")]}
HINGED_LABELS = ("door",)   # labels a structure may give hinge sides


@dataclass
class StructurePlan:
    """A structure checked against the model (``ArticulationModel.resolve_structure``):
    ``categories`` the object may be (decoding picks among them by the root's c_s);
    ``counts`` label -> exact count (labels not in it and not in ``auto`` are not produced);
    ``auto`` labels whose count the model decides; ``joints`` label -> joint type;
    ``hinges`` label -> hinge side per part (in decoding order)."""
    categories: list[str]
    counts: dict[str, int]
    auto: frozenset
    joints: dict[str, str]
    hinges: dict[str, tuple]

    def allowed(self, label: str) -> bool:
        return label in self.auto or self.counts.get(label, 0) > 0


def set_hinge(token: np.ndarray, side: str) -> np.ndarray:
    """A copy of a revolute part's token whose joint is hinged on ``side`` of the part's box
    and opens towards the front (+x), as the training data's doors do. The predicted joint is
    kept when it already is on that side, mirrored through the box centre when it is on the
    opposite edge (left <-> right, top <-> bottom), and rebuilt on that edge of the box at the
    predicted origin's depth otherwise; the joint limits stay the predicted ones."""
    tok = np.array(token, dtype=np.float64)
    have = hinge_side(tok)
    if have == side:
        return tok
    c, s = tok[3:6], tok[0:3]
    opposite = {"left": "right", "right": "left", "top": "bottom", "bottom": "top"}
    if have == opposite[side]:
        k = 1 if side in ("left", "right") else 2
        tok[6 + k] = 2 * c[k] - tok[6 + k]
        m = np.ones(3)
        m[k] = -1
        tok[9:12] = -m * tok[9:12]          # an axis is a pseudovector under reflection
        return tok
    x = tok[6]
    if side == "left":
        tok[6:9], tok[9:12] = (x, c[1] - s[1] / 2, c[2]), (0.0, 0.0, -1.0)
    elif side == "right":
        tok[6:9], tok[9:12] = (x, c[1] + s[1] / 2, c[2]), (0.0, 0.0, 1.0)
    elif side == "bottom":
        tok[6:9], tok[9:12] = (x, c[1], c[2] - s[2] / 2), (0.0, 1.0, 0.0)
    else:
        tok[6:9], tok[9:12] = (x, c[1], c[2] + s[2] / 2), (0.0, -1.0, 0.0)
    return tok


class ArticulationModel:
    """A trained network with everything decoding needs (normalisation, label table, text
    encoder name). Build with ``ArticulationModel.load(path)``."""

    def __init__(self, net: ArticulationTransformer, ckpt: dict):
        self.net = net.eval()
        self.cfg = net.cfg
        self.meta = {k: ckpt.get(k) for k in ("data_version", "seed", "command", "step",
                                              "text_encoder", "ablation", "targets", "prior")}
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
    def load(cls, path: Union[str, os.PathLike], prior: Optional[str] = None
             ) -> "ArticulationModel":
        """``prior``: the fingerprint of the shape prior it will run with; a checkpoint
        trained against another is refused (model.core.checkpoint.check_prior)."""
        ckpt = read_checkpoint(path, prior=prior)
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

    # -- structure control ----------------------------------------------------------------------
    def resolve_structure(self, spec, *, max_nodes: int = 32,
                          max_children: int = 16) -> StructurePlan:
        """A structure (``model.pipeline.api.parse_structure`` form: dict, JSON text or
        StructureSpec) -> StructurePlan, or ValueError saying why this model cannot produce it
        (unknown label or category, a label the category does not have, a count above what
        the training data had or the node caps allow, a joint type or hinge the label does
        not take, labels that exclude each other, a part with nothing to attach to).

        Labels the structure does not name are not produced, except ``handle`` (attached to
        doors / drawers / lids), whose count the model decides unless the structure names it.
        """
        from model.core.structure import GenerationError, parse_structure
        try:
            spec = parse_structure(spec)
        except GenerationError as e:
            raise ValueError(str(e)) from None
        known = set(self.table_labels)
        unknown = sorted(set(spec.parts) - known)
        if unknown:
            raise ValueError(f"structure: unknown part label(s) {unknown}; this model knows "
                             f"{sorted(known)}")
        cats = sorted(set(self.table_categories) & set(STRUCTURE_GRAMMAR))
        if spec.category is not None:
            match = [c for c in cats if c.lower() == spec.category.lower()]
            if not match:
                raise ValueError(f"structure: unknown category {spec.category!r}; this model "
                                 f"knows {cats}")
            cats = match
        plans, why = [], {}
        for cat in cats:
            try:
                plans.append(self._plan_for(cat, spec, max_nodes, max_children))
            except ValueError as e:
                why[cat] = str(e)
        if not plans:
            if len(why) == 1:
                raise ValueError(f"structure: {next(iter(why.values()))}")
            reasons = "; ".join(f"{c}: {m}" for c, m in why.items())
            raise ValueError(f"structure: no category of this model can have these parts "
                             f"({reasons})")
        first = plans[0]
        return StructurePlan(categories=[c for c in cats if c not in why], counts=first.counts,
                             auto=first.auto, joints=first.joints, hinges=first.hinges)

    def _plan_for(self, cat: str, spec, max_nodes: int, max_children: int) -> StructurePlan:
        """Check a parsed structure against one category (ValueError says why not)."""
        grammar = STRUCTURE_GRAMMAR[cat]
        have = {lab for c, lab in zip(self.table_categories, self.table_labels) if c == cat}
        counts: dict[str, int] = {"body": 1}
        auto, joints, hinges = set(), {}, {}
        cap = int(self.cfg.plan_max_count or 20)
        for lab, req in spec.parts.items():
            if lab not in grammar or lab not in have:
                if req.count == 0:
                    continue
                raise ValueError(f"a {cat} has no {lab!r} parts (it has "
                                 f"{sorted(set(grammar) & have)})")
            hosts, jts, most = grammar[lab]
            if lab == "body":
                if req.count not in (None, 1) or (req.joint not in (None, "fixed")) or req.hinge:
                    raise ValueError("the body is the one fixed root part: body must be 1 "
                                     "(fixed, no hinge)")
                continue
            if req.count is None:
                auto.add(lab)
            else:
                most = min(most, cap)
                if req.count > most:
                    raise ValueError(f"{req.count} {lab} parts: at most {most} per {cat} are "
                                     f"supported (the training data's range)")
                counts[lab] = req.count
            if req.hinge:
                if lab not in HINGED_LABELS:
                    raise ValueError(f"hinge sides are supported for {list(HINGED_LABELS)}, "
                                     f"not {lab!r}")
                hinges[lab] = tuple(req.hinge)
            if req.joint is not None:
                if req.joint not in jts:
                    raise ValueError(f"a {cat} {lab} moves with a {' or '.join(jts)} joint, not "
                                     f"{req.joint}")
                joints[lab] = req.joint
        if "handle" in grammar and "handle" in have and "handle" not in spec.parts:
            auto.add("handle")          # handles come with their doors / drawers by default
        for a, b in STRUCTURE_EXCLUSIVE.get(cat, []):
            if counts.get(a, 0) > 0 and counts.get(b, 0) > 0:
                raise ValueError(f"a {cat} has either {a} or {b} parts, not both")
        for lab, n in counts.items():
            hosts = grammar[lab][0]
            if n > 0 and hosts and not any(counts.get(h, 0) > 0 for h in hosts):
                raise ValueError(f"{lab} parts attach to a {' or '.join(hosts)}; ask for at "
                                 f"least one with an exact count")
            only_body = hosts == _BODY
            if only_body and n > max_children:
                raise ValueError(f"{n} {lab} parts on the body: at most max_children="
                                 f"{max_children} children per part")
        on_body = sum(n for lab, n in counts.items() if grammar[lab][0] == _BODY)
        if on_body > max_children:
            raise ValueError(f"{on_body} parts on the body: at most max_children={max_children} "
                             f"children per part")
        total = sum(counts.values())
        if total > max_nodes:
            raise ValueError(f"{total} parts (body included): at most max_nodes={max_nodes}")
        return StructurePlan([cat], counts, frozenset(auto), joints, hinges)

    # -- decoding -----------------------------------------------------------------------------
    @torch.inference_mode()
    def decode(self, cond_tokens: torch.Tensor, cond_mask: torch.Tensor, *, seed: int = 0,
               max_nodes: int = 32, max_depth: int = 4, max_children: int = 16,
               temperature: float = 1.0, modality: str = "text",
               keep: Union[ArticulatedObject, DecodedTree, None] = None,
               follow_plan: bool = False, plan=None,
               structure=None, sample_choices: bool = False,
               dropout_sampling: bool = False) -> list[DecodedTree]:
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

        ``structure`` (a dict / JSON text / StructureSpec, or a StructurePlan from
        ``resolve_structure``) constrains every row to exactly those parts: the root is the
        body of an allowed category, a node only gets children of labels it can carry that
        the structure still lacks (or leaves to the model), a node that the END head stops
        keeps growing only while no other part could carry a missing label, labels are drawn
        from the label head's distribution over the allowed labels, joint types from the
        joint-type head over the joint types the label takes (or the asked one), and an asked
        hinge side is set on the predicted joint (``set_hinge``) before the node is fed back.
        Replaces ``plan`` / ``follow_plan``; not combined with ``keep``.

        ``sample_choices`` (with temperature > 0): the row's seed also draws the discrete
        choices that are otherwise taken as the most likely ones: each new part's label from
        the label head's distribution (softmax of -distance / LABEL_TAU to the table's c_s,
        tempered) and, with ``follow_plan``, each label's planned count from the START plan
        head's distribution (tempered). False (default): the nearest label and the plan's
        most likely counts. The boxes and joints of a part are regressed, so without
        ``dropout_sampling`` they vary with the seed only through these choices and the END /
        joint-type draws (docs/articulation.md).

        ``dropout_sampling``: every round runs the network a second time with its training
        dropout on, masks drawn from the row's seed, and takes the new parts' articulation
        (boxes, joint origins and axes, limits) from that pass; every decision (END, labels,
        joint types, plan) and the c_s / P outputs still come from the deterministic pass.
        The seed thus picks one of the thinned networks dropout trained (Monte-Carlo
        dropout): it samples the network's uncertainty about the layout, not a learned
        distribution of layouts. Rows are then decoded one at a time (seed + i each).
        """
        if max_nodes < 1 or max_depth < 0 or max_children < 0:
            raise ValueError("max_nodes must be >= 1, max_depth and max_children >= 0")
        S = cond_tokens.shape[0]
        cond_tokens = cond_tokens.float()
        if dropout_sampling and S > 1:    # a row's masks must not depend on the other rows
            plan_t = None if plan is None else torch.as_tensor(plan)
            return [tree for i in range(S) for tree in self.decode(
                cond_tokens[i:i + 1], cond_mask[i:i + 1], seed=int(seed) + i,
                max_nodes=max_nodes, max_depth=max_depth, max_children=max_children,
                temperature=temperature, modality=modality, keep=keep, follow_plan=follow_plan,
                plan=None if plan_t is None else plan_t[i:i + 1], structure=structure,
                sample_choices=sample_choices, dropout_sampling=True)]
        if structure is not None:
            if keep is not None:
                raise ValueError("structure control does not combine with editing (keep)")
            if not isinstance(structure, StructurePlan):
                structure = self.resolve_structure(structure, max_nodes=max_nodes,
                                                   max_children=max_children)
            follow_plan, plan = False, None
        gens = [torch.Generator().manual_seed(int(seed) + i) for i in range(S)]
        rows = [self._initial_row(keep, max_nodes) for _ in range(S)]
        if structure is not None:
            for r in rows:
                r["struct"] = {"plan": structure, "cat": None, "names": [],
                               "need": dict(structure.counts), "hinge_i": {}, "sides": []}
        if plan is not None:
            plan = torch.as_tensor(plan, dtype=torch.long)
            want = (S, len(self.cfg.count_labels or []))
            if tuple(plan.shape) != want or want[1] == 0:
                raise ValueError(f"plan must be (rows, count labels) = {want}, got {tuple(plan.shape)}")
            for r, p in zip(rows, plan.tolist()):
                r["plan"] = p
        memory = self.net.cond(cond_tokens, cond_mask, modality)   # encoded once, every round
        max_rounds = max_nodes + 2
        with torch.random.fork_rng(devices=[], enabled=dropout_sampling):
            if dropout_sampling:
                torch.manual_seed(int(seed))   # the dropout masks (the global generator)
            self._rounds(rows, gens, memory, modality, max_rounds, max_nodes, max_depth,
                         max_children, temperature, follow_plan, structure, sample_choices,
                         dropout_sampling)
        trees = [self._finish(r) for r in rows]
        if structure is not None:
            for i, (r, tree) in enumerate(zip(rows, trees)):
                short = {k: v for k, v in r["struct"]["need"].items() if v}
                if short:   # resolve_structure's checks should make this unreachable
                    raise RuntimeError(f"row {i}: decoding ended {short} parts short of the "
                                       f"structure")
                tree.category = r["struct"]["cat"]
                tree.hinges = r["struct"]["sides"]
        return trees

    def _rounds(self, rows, gens, memory, modality, max_rounds, max_nodes, max_depth,
                max_children, temperature, follow_plan, structure, sample_choices,
                dropout_sampling) -> None:
        """The decoding rounds of ``decode`` (every unfinished node may get one child)."""
        for _ in range(max_rounds):
            active = [i for i, r in enumerate(rows) if not all(r["done"])]
            if not active:
                break
            batch = self._batch([rows[i] for i in active])
            out, _ = self.net(batch, None, None, modality, memory=memory,
                              cond_index=torch.tensor(active))
            if dropout_sampling:
                self.net.train()
                try:
                    sampled, _ = self.net(batch, None, None, modality, memory=memory,
                                          cond_index=torch.tensor(active))
                finally:
                    self.net.eval()
                out["art"] = sampled["art"]
            for b, i in enumerate(active):
                if "plan" in out and rows[i]["plan_logits"] is None:
                    rows[i]["plan_logits"] = out["plan"][b].float().numpy().copy()
                if follow_plan and "plan" in out and rows[i].get("plan") is None:
                    pl = out["plan"][b].float()                              # (labels, counts)
                    if sample_choices and temperature > 0:
                        rows[i]["plan"] = torch.multinomial(torch.softmax(pl / temperature, -1),
                                                            1, generator=gens[i])[:, 0].tolist()
                    else:
                        rows[i]["plan"] = pl.argmax(-1).tolist()
                grow = self._grow_structured if structure is not None else self._grow
                grow(rows[i], {k: v[b] for k, v in out.items()}, gens[i],
                     max_nodes, max_depth, max_children, temperature,
                     temperature if sample_choices else 0.0)

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
              max_depth: int, max_children: int, temperature: float,
              label_temperature: float = 0.0) -> None:
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
            li = self._sample_label(cs_raw, None, self.table_labels, gen, label_temperature,
                                    self.table_categories)
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
            self._push(row, out, t, li, jt, depth_child)

    def _sample_label(self, cs_raw: torch.Tensor, cat: Optional[str], labels: list[str],
                      gen: torch.Generator, temperature: float,
                      categories: Optional[list[str]] = None) -> int:
        """Index into the label table of the label drawn for a predicted c_s (normalised)
        among ``labels`` of category ``cat`` (or the ``categories``' entries): the label
        head's softmax over -distance / LABEL_TAU, tempered (0 = the nearest)."""
        cats = [cat] if cat is not None else list(categories or [])
        idx = [i for i, (c, lab) in enumerate(zip(self.table_categories, self.table_labels))
               if c in cats and lab in labels]
        d2 = ((self.table_cs_n[idx] - cs_raw) ** 2).mean(-1)                  # (n,)
        if temperature > 0:
            probs = torch.softmax(-d2 / (LABEL_TAU * temperature), -1)
            return idx[int(torch.multinomial(probs, 1, generator=gen))]
        return idx[int(d2.argmin())]

    def _grow_structured(self, row: dict, out: dict, gen: torch.Generator, max_nodes: int,
                         max_depth: int, max_children: int, temperature: float,
                         label_temperature: float) -> None:
        """_grow held to a StructurePlan (see ``decode``'s ``structure``)."""
        st = row["struct"]
        sp: StructurePlan = st["plan"]
        names, need = st["names"], st["need"]
        n_tokens = len(row["done"])

        def host_ok(u: int) -> bool:      # token u can still take a child
            d = 0 if u == 0 else row["depth"][u - 1] + 1
            return d <= max_depth and (u == 0 or row["nkids"][u] < max_children)

        def hosts(lab: str) -> tuple:
            return STRUCTURE_GRAMMAR[st["cat"]][lab][0]

        def deferrable(t: int, lab: str) -> bool:
            """Another part (or one still to be made) can carry the missing ``lab``."""
            if any(need.get(h, 0) > 0 for h in hosts(lab)):
                return True
            return any(u != t and not row["done"][u] and names[u - 1] in hosts(lab)
                       and host_ok(u) for u in range(1, len(row["done"])))

        for t in range(n_tokens):
            if row["done"][t]:
                continue
            cs_raw = out["cs"][t].float()
            if t == 0:
                if row["tok"]:
                    row["done"][0] = True
                    continue
                li = self._sample_label(cs_raw, None, ["body"], gen, label_temperature,
                                        sp.categories)
                st["cat"] = self.table_categories[li]
                self._add_node(row, out, t, li, int(JointType.FIXED), 0, names, need)
                st["sides"].append(None)
                continue
            parent = names[t - 1]
            free = len(row["tok"]) + sum(need.values()) < max_nodes   # room for an auto part
            can = [lab for lab in STRUCTURE_GRAMMAR[st["cat"]]
                   if parent in hosts(lab) and (need.get(lab, 0) > 0 or (lab in sp.auto and free))]
            missing = [lab for lab in can if need.get(lab, 0) > 0]
            if not can or not host_ok(t) or len(row["tok"]) >= max_nodes:
                row["done"][t] = True
                continue
            logit = out["end"][t]
            if temperature > 0:
                wants = bool(torch.rand((), generator=gen) < torch.sigmoid(logit / temperature))
            else:
                wants = bool(logit > 0)
            forced = [lab for lab in missing if not deferrable(t, lab)]
            if not forced:
                row["logp"] += float(F.logsigmoid(logit if wants else -logit))
            if not wants and not forced:
                row["done"][t] = True
                continue
            li = self._sample_label(cs_raw, st["cat"], forced or can, gen, label_temperature)
            lab = self.table_labels[li]
            allowed = [int(JointType.parse(j)) for j in
                       ([sp.joints[lab]] if lab in sp.joints
                        else STRUCTURE_GRAMMAR[st["cat"]][lab][1])]
            logits = out["jt"][t].float()
            if len(allowed) == 1:
                jt = allowed[0]
            else:
                masked = torch.full_like(logits, float("-inf"))
                masked[allowed] = logits[allowed]
                if temperature > 0:
                    jt = int(torch.multinomial(torch.softmax(masked / temperature, -1), 1,
                                               generator=gen))
                else:
                    jt = int(masked.argmax())
                row["logp"] += float(torch.log_softmax(logits, -1)[jt])
            self._add_node(row, out, t, li, jt, row["depth"][t - 1] + 1, names, need)
            st["sides"].append(None)
            if lab in sp.hinges:
                k = st["hinge_i"].get(lab, 0)
                st["hinge_i"][lab] = k + 1
                st["sides"][-1] = sp.hinges[lab][k]
                tok = row["tok"][-1] * self.tok_std + self.tok_mean
                tok = set_hinge(tok.double().numpy(), sp.hinges[lab][k])
                row["tok"][-1] = (torch.as_tensor(tok, dtype=torch.float32)
                                  - self.tok_mean) / self.tok_std

    def _add_node(self, row: dict, out: dict, t: int, li: int, jt: int, depth: int,
                  names: list, need: dict) -> None:
        """Append the child predicted at token t with label-table entry li (structure path)."""
        lab = self.table_labels[li]
        names.append(lab)
        if need.get(lab, 0) > 0:
            need[lab] -= 1
        self._push(row, out, t, li, jt, depth)

    def _push(self, row: dict, out: dict, t: int, li: int, jt: int, depth: int) -> None:
        """Append to ``row`` the child predicted at token t, label-table entry li."""
        row["lab"].append(self._count_index.get(self.table_labels[li], -1))
        row["tok"].append(out["art"][t].float().clone())
        row["jt"].append(jt)
        row["cs"].append(self.table_cs_n[li])
        row["cs_raw"].append(out["cs"][t].float().clone())
        row["geo"].append(out["geo"][t].float().clone())
        row["par"].append(t - 1)
        row["depth"].append(depth)
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
