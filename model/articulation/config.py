"""Configuration dataclasses and presets of the articulation transformer (DESIGN §5).

``ArticulationConfig`` describes the network (saved as ``asdict`` in every checkpoint so a
checkpoint alone rebuilds it); ``TrainConfig`` the optimisation. Presets:

* ``tiny``  — tests, a forward pass in milliseconds.
* ``small`` — the shipped CPU model (trains in ~20–25 min on 2 cores).
* ``paper`` — the published sizes: 8 layers, width 1024, 8 heads, TPE 16 levels × 64.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace

from model.core.objects import TOKEN_DIM

ABLATIONS = ("none", "no_tpe", "one_codebook", "no_shape_prior")
NUM_JOINT_TYPES = 5  # model.core.JointType


@dataclass
class ArticulationConfig:
    d_model: int = 256            # token width
    n_layers: int = 4             # decoder layers (self-attn + cross-attn + FFN, post-LN)
    n_heads: int = 4
    ffn_mult: int = 4
    dropout: float = 0.1
    token_dim: int = TOKEN_DIM    # articulation floats per node
    cs_dim: int = 64              # semantic condition c_s of a part
    jt_embed_dim: int = 16        # joint-type embedding width (node input)
    tpe_code_dim: int = 64        # c_i per tree level
    tpe_levels: int = 8           # TPE length = tpe_levels * tpe_code_dim
    tpe_hidden: int = 128         # GRU cell state
    use_tpe: bool = True          # False = ablation no_tpe
    child_counts: bool = True     # node input also gets its number of children so far, in
                                  # total and per label (a decision beyond the paper: exact
                                  # counts are the hardest part of the structure)
    count_labels: list = field(default_factory=list)   # label vocabulary of those counts
    plan_head: bool = True        # auxiliary head on START: parts per label of the object
    plan_max_count: int = 20
    cond_dims: dict = field(default_factory=lambda: {"text": 384, "image": 1280})
    cond_layers: int = 1          # post-encoder layers over the condition tokens
    cond_grid: dict = field(default_factory=dict)   # modality -> [rows, cols]: its tokens
                                  # lie on that grid (the image's 7x7 feature map) and get a
                                  # learned 2-D position embedding (sin-cos initialised);
                                  # text states carry their positions already
    count_tokens: dict = field(default_factory=dict)   # modality -> [labels, classes]: its
                                  # condition ends with that many count tokens, one per label,
                                  # whose first ``classes`` channels hold a count head's
                                  # probabilities of 0..classes-1 parts (model.imaging.counts)
    num_codebooks: int = 4        # codebook logits P: (num_codebooks, codebook_size)
    codebook_size: int = 128
    art_modes: int = 1            # > 1: the articulation head proposes this many
                                  # candidate tokens and their probabilities (trained winner-
                                  # takes-all); decoding draws one, so a part whose place is
                                  # ambiguous (next drawer right or below) takes one place
                                  # instead of the average of both
    place_bins: bool = False      # parent frame only: a head classifies each coordinate of
                                  # the joint origin (on a face / the centre line of the
                                  # part's box) and of the box centre (touching or flush with
                                  # a face of the parent's box, centred) or "elsewhere", and
                                  # decoding puts it exactly there: a door hinges on an edge,
                                  # not between two; a handle touches its drawer's front
    predict_z: bool = False       # True = ablation no_shape_prior: regress z directly
    z_dim: int = 768              # only used when predict_z

    @property
    def tpe_dim(self) -> int:
        return self.tpe_levels * self.tpe_code_dim

    @classmethod
    def from_dict(cls, d: dict) -> "ArticulationConfig":
        names = {f.name for f in fields(cls)}
        unknown = set(d) - names
        if unknown:
            raise ValueError(f"unknown ArticulationConfig fields {sorted(unknown)}: the "
                             f"checkpoint was written by a different code version")
        d = dict(d)
        d.setdefault("plan_head", False)   # checkpoints from before the plan head
        d.setdefault("cond_grid", {})      # ... and before grid position embeddings
        d.setdefault("count_tokens", {})   # ... and before count tokens
        d.setdefault("place_bins", False)  # ... and before place classes
        return cls(**d)


@dataclass
class TrainConfig:
    batch_size: int = 64          # decoding-round samples per step
    lr: float = 3e-4
    weight_decay: float = 0.01
    warmup_steps: int = 200
    max_steps: int = 6000
    max_minutes: float = 0.0      # wall-clock budget (0 = none); stops cleanly and saves
    grad_clip: float = 1.0
    cond_dropout: float = 0.1     # per-sample probability of dropping the text condition
    val_every: int = 250
    val_batches: int = 8
    ckpt_every: int = 250
    seed: int = 0
    threads: int = 2
    text_encoder: str = "all-minilm-l6-v2"
    max_text_tokens: int = 128
    # loss weights (DESIGN §5, reference values) + joint-type CE
    w_art: float = 10.0
    w_end: float = 1.0
    w_jt: float = 1.0
    w_cs: float = 5.0
    w_p: float = 2.0
    w_z: float = 1.0              # ablation no_shape_prior: MSE on (normalised) z
    w_label: float = 1.0          # auxiliary: CE of the nearest-c_s label decision
    w_plan: float = 1.0           # auxiliary: CE of the START plan head (parts per label)
    w_mode: float = 1.0           # art_modes > 1: CE of the articulation mode that fits best
    w_place: float = 1.0          # place_bins: CE of the origin and centre place classes
    rounds_per_object: int = 4    # decoding rounds drawn per object per step (they share
                                  # one encoded description)
    own_inputs: float = 0.0       # scheduled sampling: share of the objects of a batch whose
                                  # existing nodes carry the network's own (teacher-forced)
                                  # articulation predictions instead of the ground truth, as
                                  # iterative decoding feeds them back (exposure bias)
    token_frame: str = "absolute" # part tokens in the object frame or relative to the
                                  # parent's box (model.articulation.frames)


PRESETS: dict[str, tuple[ArticulationConfig, TrainConfig]] = {
    "tiny": (ArticulationConfig(d_model=32, n_layers=2, n_heads=2, ffn_mult=2, dropout=0.0,
                                tpe_levels=4, tpe_code_dim=8, tpe_hidden=16, jt_embed_dim=4,
                                codebook_size=16, z_dim=32),
             TrainConfig(batch_size=16, lr=2e-3, warmup_steps=5, max_steps=60, val_every=20,
                         val_batches=2, ckpt_every=20, threads=1)),
    "small": (ArticulationConfig(d_model=256, n_layers=4, n_heads=4, dropout=0.1,
                                 tpe_levels=8, tpe_code_dim=64, tpe_hidden=128),
              TrainConfig(batch_size=64, lr=4e-4, warmup_steps=200, max_steps=8000,
                          max_minutes=24.0)),
    "paper": (ArticulationConfig(d_model=1024, n_layers=8, n_heads=8, dropout=0.1,
                                 tpe_levels=16, tpe_code_dim=64, tpe_hidden=256, cond_layers=2),
              TrainConfig(batch_size=128, lr=1e-4, warmup_steps=1000, max_steps=200000)),
}


def preset(name: str, ablation: str = "none", **overrides) -> tuple[ArticulationConfig, TrainConfig]:
    """Copies of a preset's configs with an ablation applied and field overrides."""
    if name not in PRESETS:
        raise KeyError(f"unknown preset {name!r}; choose one of {sorted(PRESETS)}")
    if ablation not in ABLATIONS:
        raise ValueError(f"unknown ablation {ablation!r}; choose one of {ABLATIONS}")
    net, train = PRESETS[name]
    net = replace(net, cond_dims=dict(net.cond_dims), count_labels=list(net.count_labels),
                  cond_grid=dict(net.cond_grid), count_tokens=dict(net.count_tokens))
    train = replace(train)
    if ablation == "no_tpe":
        net.use_tpe = False
    elif ablation == "one_codebook":
        net.num_codebooks = 1
    elif ablation == "no_shape_prior":
        net.predict_z = True
    for k, v in overrides.items():
        if hasattr(net, k):
            setattr(net, k, v)
        elif hasattr(train, k):
            setattr(train, k, v)
        else:
            raise KeyError(f"unknown config field {k!r}")
    if net.place_bins and train.token_frame != "parent":
        raise ValueError("place_bins places parts relative to their parent's box: it needs "
                         "token_frame 'parent'")
    return net, train


__all__ = ["ABLATIONS", "NUM_JOINT_TYPES", "ArticulationConfig", "TrainConfig", "PRESETS",
           "preset", "asdict"]
