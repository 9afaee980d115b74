"""Iterative decoding and editing with a trained articulation transformer (paper
"Iterative Decoding", supplementary "Editing"): the rounds behind ``ArticulationModel.decode``
(model.articulation.model) and the trees they give (``DecodedTree``).

    am = ArticulationModel.load("model/weights/transformer_small.pt")
    tokens, mask = am.encode_text(["a cabinet with two drawers"] * 3)
    trees = am.decode(tokens, mask, seed=0)          # three samples (seeds 0, 1, 2)
    obj = trees[0].to_object()                       # ArticulatedObject (no meshes yet)

Each round every node that has not emitted END gets one new child; a node that emits END
is finished. START (the root's virtual parent) adds exactly the single root. Caps: total
nodes, depth (root = 0) and children per node force END. Row i of a batch draws its random
numbers from ``torch.Generator().manual_seed(seed + i)``, so a row's result does not depend
on the other rows.

The rows (trees being decoded) and ``DecodedTree`` are in model.articulation.trees.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Optional

import torch
from torch.nn import functional as F

from model.core.objects import JointType

from .frames import LOG_RANGE

# structure control and DecodedTree lived in this module before structure_control.py and
# trees.py: the names not used here stay importable from it (re-exported)
from .structure_control import (HINGED_LABELS, STRUCTURE_EXCLUSIVE, STRUCTURE_GRAMMAR,  # noqa: F401
                                StructurePlan, set_hinge)
from .trees import DecodedTree, batch_rows, finish_row, initial_row, push_child

if TYPE_CHECKING:
    from .model import ArticulationModel


def __getattr__(name: str):
    # ArticulationModel lived here until it moved to model.articulation.model; this keeps
    # ``from model.articulation.decode import ArticulationModel`` working for one release.
    # Looked up on first use because model.py imports this module.
    if name == "ArticulationModel":
        from .model import ArticulationModel
        return ArticulationModel
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


PLAN_ADD_MARGIN = 3.0   # follow_plan adds a child the END head gave p > sigmoid(-3) ~ 5 %
SET_ASIDE = 4           # structure control: proposals of a ruled-out label set aside per row
SIBLING_OVERLAP = 0.1   # sibling_room: boxes sharing more than this share of the smaller
                        # box's volume collide (siblings in the data touch at most)
LABEL_TAU = 0.1         # the label head's softmax scale: training's label cross-entropy reads
                        # -mean((c_s - c_s(label))^2) / 0.1 as logits (network.losses)


# -- one decode call ----------------------------------------------------------------------------
def decode_trees(am: "ArticulationModel", cond_tokens: torch.Tensor, cond_mask: torch.Tensor,
                 *, seed: int, max_nodes: int, max_depth: int, max_children: int,
                 temperature: float, modality: str, keep, follow_plan: bool, plan, structure,
                 sample_choices: bool, dropout_sampling: bool,
                 sibling_room: bool = True) -> list[DecodedTree]:
    """``am.decode`` (``ArticulationModel.decode`` documents the arguments)."""
    if max_nodes < 1 or max_depth < 0 or max_children < 0:
        raise ValueError("max_nodes must be >= 1, max_depth and max_children >= 0")
    S = cond_tokens.shape[0]
    cond_tokens = cond_tokens.float()
    if dropout_sampling and S > 1:    # a row's masks must not depend on the other rows
        plan_t = None if plan is None else torch.as_tensor(plan)
        return [tree for i in range(S) for tree in decode_trees(
            am, cond_tokens[i:i + 1], cond_mask[i:i + 1], seed=int(seed) + i,
            max_nodes=max_nodes, max_depth=max_depth, max_children=max_children,
            temperature=temperature, modality=modality, keep=keep, follow_plan=follow_plan,
            plan=None if plan_t is None else plan_t[i:i + 1], structure=structure,
            sample_choices=sample_choices, dropout_sampling=True, sibling_room=sibling_room)]
    if follow_plan == "hold" and structure is None and keep is None and plan is None:
        return _hold_plan(am, cond_tokens, cond_mask, seed=seed, max_nodes=max_nodes,
                          max_depth=max_depth, max_children=max_children,
                          temperature=temperature, modality=modality,
                          sample_choices=sample_choices, dropout_sampling=dropout_sampling,
                          sibling_room=sibling_room)
    if structure is not None:
        if keep is not None:
            raise ValueError("structure control does not combine with editing (keep)")
        if not isinstance(structure, StructurePlan):
            structure = am.resolve_structure(structure, max_nodes=max_nodes,
                                             max_children=max_children)
        follow_plan, plan = False, None
    gens = [torch.Generator().manual_seed(int(seed) + i) for i in range(S)]
    rows = _start_rows(am, S, keep, max_nodes, structure, plan)
    memory = am.net.cond(cond_tokens, cond_mask, modality)   # encoded once, every round
    max_rounds = max_nodes + 2
    with torch.random.fork_rng(devices=[], enabled=dropout_sampling):
        if dropout_sampling:
            torch.manual_seed(int(seed))   # the dropout masks (the global generator)
        _rounds(am, rows, gens, memory, modality, max_rounds, max_nodes, max_depth,
                max_children, temperature, follow_plan, structure, sample_choices,
                dropout_sampling, sibling_room)
    if structure is not None:
        for r in rows:
            _drop_set_aside(r)
    trees = [finish_row(am, r) for r in rows]
    if structure is not None:
        _settle_structure(rows, trees)
    return trees


def plan_structure(am: "ArticulationModel", tree: DecodedTree) -> dict:
    """The structure a decoded tree's START plan head reads from its condition: the tree's
    category and the plan's most likely count of every label it counts (``handle`` always
    named, so its count is held too; the body is the root)."""
    counts = tree.plan_logits.argmax(-1).tolist()
    spec: dict = {"category": tree.category}
    for lab, n in zip(am.cfg.count_labels, counts):
        if lab != "body" and (n > 0 or lab == "handle"):
            spec[lab] = int(n)
    return spec


def _hold_plan(am: "ArticulationModel", cond_tokens, cond_mask, *, seed: int, max_nodes: int,
               max_depth: int, max_children: int, **kw) -> list[DecodedTree]:
    """``follow_plan="hold"``: decode with the plan followed (``follow_plan=True``), then
    decode each row again with the structure its plan head read (:func:`plan_structure`)
    held by structure control; a row whose plan the model cannot produce as a structure
    (a label its category does not have, a count over the caps) keeps its first tree."""
    first = decode_trees(am, cond_tokens, cond_mask, seed=seed, max_nodes=max_nodes,
                         max_depth=max_depth, max_children=max_children, keep=None,
                         follow_plan=True, plan=None, structure=None, **kw)
    out = []
    for i, tree in enumerate(first):
        if tree.plan_logits is None:
            out.append(tree)
            continue
        try:
            splan = am.resolve_structure(plan_structure(am, tree), max_nodes=max_nodes,
                                         max_children=max_children)
        except ValueError:
            out.append(tree)
            continue
        out += decode_trees(am, cond_tokens[i:i + 1], cond_mask[i:i + 1], seed=int(seed) + i,
                            max_nodes=max_nodes, max_depth=max_depth,
                            max_children=max_children, keep=None, follow_plan=False,
                            plan=None, structure=splan, **kw)
    return out


def _start_rows(am: "ArticulationModel", S: int, keep, max_nodes: int,
                structure: Optional[StructurePlan], plan) -> list[dict]:
    """The S rows before the first round: each starts from ``keep`` (or nothing), with the
    structure's bookkeeping and its row of ``plan`` (S, count labels)."""
    rows = [initial_row(am, keep, max_nodes) for _ in range(S)]
    if structure is not None:
        for r in rows:
            # cat: the category the root picked; names: label per node; need: label -> parts
            # still missing; hinge_i: label -> hinge sides used; sides: hinge side per node
            # aside: per node, whether it is a proposal set aside (_set_aside)
            r["struct"] = {"plan": structure, "cat": None, "names": [],
                           "need": dict(structure.counts), "hinge_i": {}, "sides": [],
                           "aside": []}
    if plan is not None:
        plan = torch.as_tensor(plan, dtype=torch.long)
        want = (S, len(am.cfg.count_labels or []))
        if tuple(plan.shape) != want or want[1] == 0:
            raise ValueError(f"plan must be (rows, count labels) = {want}, got {tuple(plan.shape)}")
        for r, p in zip(rows, plan.tolist()):
            r["plan"] = p
    return rows


def _settle_structure(rows: list[dict], trees: list[DecodedTree]) -> None:
    """Give structured trees the category their root picked and the asked hinge sides."""
    for i, (r, tree) in enumerate(zip(rows, trees)):
        short = {k: v for k, v in r["struct"]["need"].items() if v}
        if short:   # resolve_structure's checks should make this unreachable
            raise RuntimeError(f"row {i}: decoding ended {short} parts short of the "
                               f"structure")
        tree.category = r["struct"]["cat"]
        tree.hinges = r["struct"]["sides"]


def _rounds(am: "ArticulationModel", rows, gens, memory, modality, max_rounds, max_nodes,
            max_depth, max_children, temperature, follow_plan, structure, sample_choices,
            dropout_sampling, sibling_room) -> None:
    """The decoding rounds of ``decode`` (every unfinished node may get one child)."""
    for _ in range(max_rounds):
        active = [i for i, r in enumerate(rows) if not all(r["done"])]
        if not active:
            break
        batch = batch_rows(am, [rows[i] for i in active])
        out, _ = am.net(batch, None, None, modality, memory=memory,
                        cond_index=torch.tensor(active))
        if dropout_sampling:
            am.net.train()
            try:
                sampled, _ = am.net(batch, None, None, modality, memory=memory,
                                    cond_index=torch.tensor(active))
            finally:
                am.net.eval()
            out.update({k: sampled[k] for k in ("art", "art_raw", "art_modes", "art_logits")
                        if k in sampled})
        if "art_logits" in out:          # one candidate token per node, drawn by its probability
            out["art"] = torch.stack([
                torch.stack([out["art_modes"][b, t, _draw_choice(out["art_logits"][b, t].float(),
                                                                 temperature, gens[i])]
                             for t in range(out["art_logits"].shape[1])])
                for b, i in enumerate(active)])
        classes = None
        if "origin_logits" in out:       # origins on faces / centre lines, boxes on faces
            raw = out["art"] if "art_logits" in out else out["art_raw"]
            classes = torch.stack([am.net.place_classes(
                {k: out[k][b] for k in ("origin_logits", "centre_logits")},
                lambda l, i=i: _draw_classes(l.float(), temperature, gens[i]))
                for b, i in enumerate(active)])
            out["art"] = am.net.snap(raw, classes)
        if sibling_room and "art_logits" in out:
            _make_room(am, [rows[i] for i in active], [gens[i] for i in active], out, classes,
                       temperature)
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
            grow = _grow_structured if structure is not None else _grow
            grow(am, rows[i], {k: v[b] for k, v in out.items()}, gens[i],
                 max_nodes, max_depth, max_children, temperature,
                 temperature if sample_choices else 0.0)


def box_overlap(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Intersection of boxes (..., 6) = (size, centre) over the smaller one's volume."""
    lo = torch.maximum(a[..., 3:6] - a[..., 0:3] / 2, b[..., 3:6] - b[..., 0:3] / 2)
    hi = torch.minimum(a[..., 3:6] + a[..., 0:3] / 2, b[..., 3:6] + b[..., 0:3] / 2)
    inter = (hi - lo).clamp_min(0).prod(-1)
    small = torch.minimum(a[..., 0:3].prod(-1), b[..., 0:3].prod(-1)).clamp_min(1e-12)
    return inter / small


def _make_room(am: "ArticulationModel", rows: list[dict], gens: list, out: dict,
               classes: Optional[torch.Tensor], temperature: float) -> None:
    """``sibling_room``: where the candidate token drawn for a node's next child puts its box
    over one of that node's children already decoded (SIBLING_OVERLAP), the choice is drawn
    again among the network's other candidates (``art_modes``, snapped to the same place
    classes) that collide with none, by their probabilities; with none free, the least
    colliding one. Tokens of one parent's children share a frame (the parent's box, or the
    object's), so their boxes compare as they are. Changes ``out["art"]`` in place."""
    def boxes(tok: torch.Tensor) -> torch.Tensor:
        raw = tok.float() * am.tok_std + am.tok_mean
        size = (torch.exp(raw[..., 0:3].clamp(*LOG_RANGE)) if am.frame == "parent"
                else raw[..., 0:3].abs())
        return torch.cat([size, raw[..., 3:6]], -1)

    for b, row in enumerate(rows):
        for t in range(1, len(row["done"])):
            kids = [j for j, p in enumerate(row["par"]) if p == t - 1]
            if row["done"][t] or not kids:
                continue
            have = boxes(torch.stack([row["tok"][j] for j in kids]))          # (C, 6)
            if float(box_overlap(boxes(out["art"][b, t]), have).max()) <= SIBLING_OVERLAP:
                continue
            modes = out["art_modes"][b, t]                                    # (K, 16)
            if classes is not None:
                modes = am.net.snap(modes, classes[b, t].expand(len(modes), -1))
            worst = box_overlap(boxes(modes)[:, None], have[None]).amax(-1)   # (K,)
            free = worst <= SIBLING_OVERLAP
            if bool(free.any()):
                logits = out["art_logits"][b, t].float().masked_fill(~free, float("-inf"))
                k = _draw_choice(logits, temperature, gens[b])
            else:
                k = int(worst.argmin())
            out["art"][b, t] = modes[k].to(out["art"].dtype)


# -- one round of one row ---------------------------------------------------------------------------
def _grow(am: "ArticulationModel", row: dict, out: dict, gen: torch.Generator, max_nodes: int,
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
        wants = _draw_end(logit, temperature, gen)
        cs_raw = out["cs"][t].float()
        li = _sample_label(am, cs_raw, None, am.table_labels, gen, label_temperature,
                           am.table_categories)
        count_i = am._count_index.get(am.table_labels[li], -1)
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
            jt = _draw_choice(_grammar_joints(am, li, out["jt"][t]), temperature, gen)
            row["logp"] += float(torch.log_softmax(out["jt"][t].float(), -1)[jt])
        push_child(am, row, out, t, li, jt, depth_child)


def _grammar_joints(am: "ArticulationModel", li: int, logits: torch.Tensor) -> torch.Tensor:
    """Joint-type ``logits`` of a new part with label-table entry ``li``, the types its
    category never gives that label (``STRUCTURE_GRAMMAR``: a cabinet's door only turns, a
    drawer only slides) masked out; the logits as they are for a label the grammar lacks."""
    kinds = STRUCTURE_GRAMMAR.get(am.table_categories[li], {}).get(am.table_labels[li])
    return logits if kinds is None else _only(logits, kinds[1])


def _only(logits: torch.Tensor, kinds) -> torch.Tensor:
    """Joint-type ``logits`` with every type outside ``kinds`` (names) masked out."""
    allowed = [int(JointType.parse(j)) for j in kinds]
    masked = torch.full_like(logits, float("-inf"))
    masked[allowed] = logits[allowed]
    return masked


def _draw_end(logit: torch.Tensor, temperature: float, gen: torch.Generator) -> bool:
    """Whether the END head wants a child: drawn with p = sigmoid(logit / temperature), or
    logit > 0 when greedy (temperature 0)."""
    if temperature > 0:
        return bool(torch.rand((), generator=gen) < torch.sigmoid(logit / temperature))
    return bool(logit > 0)


def _draw_choice(logits: torch.Tensor, temperature: float, gen: torch.Generator) -> int:
    """Index drawn from softmax(logits / temperature), or the largest logit's when greedy."""
    if temperature > 0:
        probs = torch.softmax(logits / temperature, -1)
        return int(torch.multinomial(probs, 1, generator=gen))
    return int(logits.argmax())


def _draw_classes(logits: torch.Tensor, temperature: float, gen: torch.Generator
                  ) -> torch.Tensor:
    """(..., C) logits -> (...) indices, each drawn as ``_draw_choice`` draws one."""
    if temperature <= 0:
        return logits.argmax(-1)
    probs = torch.softmax(logits / temperature, -1).reshape(-1, logits.shape[-1])
    return torch.multinomial(probs, 1, generator=gen).view(logits.shape[:-1])


def _sample_label(am: "ArticulationModel", cs_raw: torch.Tensor, cat: Optional[str],
                  labels: list[str], gen: torch.Generator, temperature: float,
                  categories: Optional[list[str]] = None) -> int:
    """Index into the label table of the label drawn for a predicted c_s (normalised)
    among ``labels`` of category ``cat`` (or the ``categories``' entries): the label
    head's softmax over -distance / LABEL_TAU, tempered (0 = the nearest)."""
    cats = [cat] if cat is not None else list(categories or [])
    idx = [i for i, (c, lab) in enumerate(zip(am.table_categories, am.table_labels))
           if c in cats and lab in labels]
    d2 = ((am.table_cs_n[idx] - cs_raw) ** 2).mean(-1)                  # (n,)
    if temperature > 0:
        probs = torch.softmax(-d2 / (LABEL_TAU * temperature), -1)
        return idx[int(torch.multinomial(probs, 1, generator=gen))]
    return idx[int(d2.argmin())]


# -- one round of one row under a structure ------------------------------------------------------
def _grow_structured(am: "ArticulationModel", row: dict, out: dict, gen: torch.Generator,
                     max_nodes: int, max_depth: int, max_children: int, temperature: float,
                     label_temperature: float) -> None:
    """_grow held to a StructurePlan (see ``decode``'s ``structure``)."""
    for t in range(len(row["done"])):
        if row["done"][t]:
            continue
        if t == 0:
            if row["tok"]:
                row["done"][0] = True
            else:
                _add_body(am, row, out, gen, label_temperature)
            continue
        choices = _child_labels(row, t, max_nodes, max_depth, max_children)
        if choices is None:
            row["done"][t] = True
            continue
        can, forced = choices
        logit = out["end"][t]
        wants = _draw_end(logit, temperature, gen)
        if not forced:
            row["logp"] += float(F.logsigmoid(logit if wants else -logit))
        if not wants and not forced:
            row["done"][t] = True
            continue
        pool = forced or can
        # the proposal's own label: the nearest of all its category's labels
        own = _sample_label(am, out["cs"][t].float(), row["struct"]["cat"], am.table_labels,
                            gen, 0.0)
        if am.table_labels[own] not in pool:
            kin = [lab for lab in pool if _kin(am.table_labels[own], lab)]
            if kin:
                pool = kin          # renamed within its kind (a cap held as a flip lid)
            elif wants and _set_aside(am, row, out, t, own, max_nodes, max_children):
                continue
        li = _sample_label(am, out["cs"][t].float(), row["struct"]["cat"], pool, gen,
                           label_temperature)
        lab = am.table_labels[li]
        jt = _structured_joint(row, lab, out["jt"][t].float(), temperature, gen)
        _add_node(am, row, out, t, li, jt, row["depth"][t - 1] + 1)
        if lab in row["struct"]["plan"].hinges:
            _hinge_last(am, row, lab)


# labels of one kind: parts of one size and place, so that a proposal of one is renamed
# to another the structure needs (a bottle's cap held as its flip lid). Fronts are not one
# kind (a washer's 5 cm soap drawer held as its door is no door), nor are controls (a
# button renamed to the washer's one dial took it from the network's own dial proposal)
KINDS = (("cap", "lid"),)


def _kin(a: str, b: str) -> bool:
    return any(a in kind and b in kind for kind in KINDS)


def _set_aside(am: "ArticulationModel", row: dict, out: dict, t: int, li: int,
               max_nodes: int, max_children: int) -> bool:
    """A proposal whose own label ``li`` the structure rules out here, with no label of its
    kind to take instead (a button where the prompt says "no buttons" while a door is still
    needed) is not renamed: a door held on a button's 2 cm box is no door. It is added as a
    leaf that decoding sees (so the node's next proposal is the part after it, as the
    network would go on) and that the tree drops at the end (:func:`_drop_set_aside`). At
    most SET_ASIDE per row, and only while the node caps leave room for every part still
    needed. -> whether it was set aside."""
    st = row["struct"]
    if sum(st["aside"]) >= SET_ASIDE:
        return False
    need = sum(st["need"].values())
    if len(row["tok"]) + 1 + need > max_nodes or row["nkids"][t] + 1 + need > max_children:
        return False
    _push_structured(am, row, out, t, li, int(out["jt"][t].argmax()),
                     row["depth"][t - 1] + 1, aside=True)
    row["done"][-1] = True            # a leaf: nothing hangs on a part that is dropped
    return True


def _drop_set_aside(row: dict) -> None:
    """Remove the leaves :func:`_set_aside` added from a finished row (in place)."""
    aside = row["struct"]["aside"]
    if not any(aside):
        return
    keep = [n for n, a in enumerate(aside) if not a]
    new = {old: k for k, old in enumerate(keep)}
    for key in ("tok", "jt", "cs", "cs_raw", "geo", "depth", "lab", "kept", "src"):
        row[key] = [row[key][n] for n in keep]
    row["par"] = [new[row["par"][n]] if row["par"][n] >= 0 else -1 for n in keep]
    row["nkids"] = [row["nkids"][0]] + [sum(p == k for p in row["par"]) for k in range(len(keep))]
    row["done"] = [row["done"][0]] + [row["done"][n + 1] for n in keep]
    st = row["struct"]
    st["names"] = [st["names"][n] for n in keep]
    st["sides"] = [st["sides"][n] for n in keep]
    st["aside"] = [False] * len(keep)


def _add_body(am: "ArticulationModel", row: dict, out: dict, gen: torch.Generator,
              label_temperature: float) -> None:
    """The root of a structured row: the body of the allowed category the START token's
    c_s picks, which fixes the row's category."""
    st = row["struct"]
    li = _sample_label(am, out["cs"][0].float(), None, ["body"], gen, label_temperature,
                       st["plan"].categories)
    st["cat"] = am.table_categories[li]
    _add_node(am, row, out, 0, li, int(JointType.FIXED), 0)


def _hosts(st: dict, lab: str) -> tuple:
    """The labels a ``lab`` part attaches to in the row's category."""
    return STRUCTURE_GRAMMAR[st["cat"]][lab][0]


def _can_host(row: dict, u: int, max_depth: int, max_children: int) -> bool:
    """Token u can still take a child (depth and children caps)."""
    d = 0 if u == 0 else row["depth"][u - 1] + 1
    return d <= max_depth and (u == 0 or row["nkids"][u] < max_children)


def _deferrable(row: dict, t: int, lab: str, max_depth: int, max_children: int) -> bool:
    """Another part (or one still to be made) can carry the missing ``lab``."""
    st = row["struct"]
    if any(st["need"].get(h, 0) > 0 for h in _hosts(st, lab)):
        return True
    return any(u != t and not row["done"][u] and st["names"][u - 1] in _hosts(st, lab)
               and _can_host(row, u, max_depth, max_children) for u in range(1, len(row["done"])))


def _child_labels(row: dict, t: int, max_nodes: int, max_depth: int,
                  max_children: int) -> Optional[tuple[list, list]]:
    """(labels token t's child may have, the missing ones no other part can carry: the child
    must be one of them) under the row's structure; None when token t can take no child."""
    st = row["struct"]
    sp: StructurePlan = st["plan"]
    need = st["need"]
    parent = st["names"][t - 1]
    free = len(row["tok"]) + sum(need.values()) < max_nodes   # room for an auto part
    can = [lab for lab in STRUCTURE_GRAMMAR[st["cat"]]
           if parent in _hosts(st, lab) and (need.get(lab, 0) > 0 or (lab in sp.auto and free))]
    if not can or not _can_host(row, t, max_depth, max_children) or len(row["tok"]) >= max_nodes:
        return None
    forced = [lab for lab in can if need.get(lab, 0) > 0
              and not _deferrable(row, t, lab, max_depth, max_children)]
    return can, forced


def _structured_joint(row: dict, lab: str, logits: torch.Tensor, temperature: float,
                      gen: torch.Generator) -> int:
    """Joint type of a new ``lab`` part: the asked one, or the joint-type head's (``logits``)
    draw among the types the label takes (its log-probability added to the row's)."""
    st = row["struct"]
    sp: StructurePlan = st["plan"]
    kinds = [sp.joints[lab]] if lab in sp.joints else STRUCTURE_GRAMMAR[st["cat"]][lab][1]
    if len(kinds) == 1:
        return int(JointType.parse(kinds[0]))
    jt = _draw_choice(_only(logits, kinds), temperature, gen)
    row["logp"] += float(torch.log_softmax(logits, -1)[jt])
    return jt


def _add_node(am: "ArticulationModel", row: dict, out: dict, t: int, li: int, jt: int,
              depth: int) -> None:
    """Append the child predicted at token t with label-table entry li (structure path)."""
    need = row["struct"]["need"]
    lab = am.table_labels[li]
    if need.get(lab, 0) > 0:
        need[lab] -= 1
    _push_structured(am, row, out, t, li, jt, depth, aside=False)


def _push_structured(am: "ArticulationModel", row: dict, out: dict, t: int, li: int, jt: int,
                     depth: int, aside: bool) -> None:
    """push_child, and the structure's per-node label, hinge side (none yet) and set-aside
    flag."""
    st = row["struct"]
    push_child(am, row, out, t, li, jt, depth)
    st["names"].append(am.table_labels[li])
    st["sides"].append(None)
    st["aside"].append(aside)


def _hinge_last(am: "ArticulationModel", row: dict, lab: str) -> None:
    """Hinge the ``lab`` part just added on the structure's next side for that label
    (``set_hinge`` on its denormalised token)."""
    st = row["struct"]
    k = st["hinge_i"].get(lab, 0)
    st["hinge_i"][lab] = k + 1
    side = st["plan"].hinges[lab][k]
    st["sides"][-1] = side
    toks = am.absolute_tokens(row["tok"], row["par"])
    toks[-1] = set_hinge(toks[-1], side)
    row["tok"][-1] = am.network_tokens(toks, row["par"])[-1]
