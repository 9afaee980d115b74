"""A trained articulation transformer ready to decode: ``ArticulationModel`` (loading, text
conditions, the label table, structure checks, and ``decode`` — whose rounds are in
model.articulation.decode).

    am = ArticulationModel.load("model/weights/transformer_small.pt")
    tokens, mask = am.encode_text(["a cabinet with two drawers"] * 3)
    trees = am.decode(tokens, mask, seed=0)          # three samples (seeds 0, 1, 2)
    obj = trees[0].to_object()                       # ArticulatedObject (no meshes yet)
"""
from __future__ import annotations

import os
from typing import Optional, Sequence, Union

import numpy as np
import torch

from model.core.objects import ArticulatedObject

from .checkpoint import build_network, read_checkpoint
from .decode import decode_trees
from .frames import check_frame, from_frame, to_frame
from .network import ArticulationTransformer
from .structure_control import StructurePlan, resolve_structure
from .trees import DecodedTree


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
        self.frame: str = check_frame(st.get("frame", "absolute"))   # model.articulation.frames
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
    def load(cls, path: Union[str, os.PathLike], prior: Union[str, Sequence[str], None] = None
             ) -> "ArticulationModel":
        """``prior``: the fingerprint of the shape prior it will run with (or the list it
        accepts, ``ShapeModel.info["accepts"]``); a checkpoint trained against another is
        refused (model.core.checkpoint.check_prior)."""
        ckpt = read_checkpoint(path, prior=prior)
        return cls(build_network(ckpt), ckpt)

    # -- conditions ---------------------------------------------------------------------------
    def encode_text(self, texts: list[str]) -> tuple[torch.Tensor, torch.Tensor]:
        """texts -> condition tokens (B, L, D_text), mask (B, L) with the training encoder."""
        from model.encoders.text import get_text_encoder
        enc = get_text_encoder(self.text_encoder_name, self.text_max_length).encode(list(texts))
        return enc.states.float(), enc.mask

    # -- tokens -------------------------------------------------------------------------------
    def network_tokens(self, tokens, parents) -> list[torch.Tensor]:
        """Absolute (K, 16) tokens of a tree -> the network's normalised tokens (one per node)."""
        rel = to_frame(np.asarray(tokens, dtype=np.float64).reshape(-1, 16), parents, self.frame)
        return list((torch.as_tensor(rel, dtype=torch.float32) - self.tok_mean) / self.tok_std)

    def absolute_tokens(self, tokens: list[torch.Tensor], parents) -> np.ndarray:
        """The network's normalised tokens of a tree (parents first) -> absolute (K, 16)."""
        if not tokens:
            return np.zeros((0, 16))
        rel = (torch.stack(list(tokens)).float() * self.tok_std + self.tok_mean).double().numpy()
        return from_frame(rel, parents, self.frame)

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
        return resolve_structure(spec, self.table_categories, self.table_labels,
                                 self.cfg.plan_max_count, max_nodes=max_nodes,
                                 max_children=max_children)

    # -- decoding -----------------------------------------------------------------------------
    @torch.inference_mode()
    def decode(self, cond_tokens: torch.Tensor, cond_mask: torch.Tensor, *, seed: int = 0,
               max_nodes: int = 32, max_depth: int = 4, max_children: int = 16,
               temperature: float = 1.0, modality: str = "text",
               keep: Union[ArticulatedObject, DecodedTree, None] = None,
               follow_plan: Union[bool, str] = False, plan=None,
               structure=None, sample_choices: bool = False,
               dropout_sampling: bool = False,
               sibling_room: bool = True) -> list[DecodedTree]:
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
        ``follow_plan="hold"`` then decodes every row again with the counts its plan head
        read held as a structure (``decode.plan_structure``, structure control below); a row
        whose plan is no valid structure keeps its first tree.

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

        ``sibling_room`` (default on; a deviation from the paper): a network with articulation
        modes proposes several candidate tokens per new part; where the one drawn puts the
        part's box over a sibling decoded before it (more than SIBLING_OVERLAP of the smaller
        box), the draw is repeated among the candidates that collide with none (decode.py).
        """
        return decode_trees(self, cond_tokens, cond_mask, seed=seed, max_nodes=max_nodes,
                            max_depth=max_depth, max_children=max_children,
                            temperature=temperature, modality=modality, keep=keep,
                            follow_plan=follow_plan, plan=plan, structure=structure,
                            sample_choices=sample_choices, dropout_sampling=dropout_sampling,
                            sibling_room=sibling_room)
