"""Configs of the shape-prior networks and their training, with a preset registry.

One dataclass per network (`SDFConfig` for the tri-plane SDF auto-encoder, `PriorConfig` for
the codebook diffusion prior) plus one per training run (`TrainConfig`). `PRESETS` maps a name
to all four: ``tiny`` (tests, seconds), ``small`` (the CPU model we ship), ``paper`` (the
published sizes, DESIGN §4 / paper supplementary). Checkpoints store ``asdict(config)`` so a
checkpoint alone rebuilds its network.
"""
from __future__ import annotations

from dataclasses import dataclass, fields


@dataclass
class SDFConfig:
    """Tri-plane SDF auto-encoder (DESIGN §4.1)."""
    bound: float = 1.05            # planes cover [-bound, bound]^2: the WHOLE part cube (+ margin)
    plane_res: int = 32            # R: each plane is C x R x R
    plane_channels: int = 16       # C
    pointnet_hidden: int = 32      # width of the local-pooling PointNet
    pointnet_blocks: int = 2       # ResNet blocks; all but the first follow a local pooling
    plane_net_channels: int = 16   # width of the small per-plane conv net after scattering
    vae_channels: tuple[int, ...] = (32, 64, 64)   # conv widths; each halves the resolution
    z_dim: int = 256               # the latent z (a flat vector)
    mlp_hidden: int = 64           # SDF decoder width (meshing cost ~ width^2)
    mlp_layers: int = 3            # SDF decoder hidden layers
    mlp_skip: int = 1              # the input is concatenated again before this hidden layer
    prior_std: float = 0.25        # KL against N(0, prior_std^2) (ref)
    kl_weight: float = 1e-5        # (ref)
    posterior_std_max: float = 0.05  # cap on the posterior std: with Adam the tiny KL term
                                     # otherwise drives the encoder to the prior (collapse)
    sdf_clamp: float = 0.2         # L1 on SDF values clamped to +-sdf_clamp

    @property
    def latent_res(self) -> int:
        return self.plane_res // (2 ** len(self.vae_channels))

    def validate(self) -> "SDFConfig":
        if self.plane_res % (2 ** len(self.vae_channels)) or self.latent_res < 1:
            raise ValueError(f"plane_res {self.plane_res} must be divisible by "
                             f"2**len(vae_channels) = {2 ** len(self.vae_channels)}")
        if not 0 < self.mlp_skip < self.mlp_layers:
            raise ValueError("mlp_skip must be between 1 and mlp_layers - 1")
        return self


@dataclass
class PriorConfig:
    """Codebook-conditioned diffusion prior over z (DESIGN §4.2)."""
    z_dim: int = 256               # must equal the auto-encoder's z_dim
    width: int = 128               # transformer token width (DDIM cost ~ width^2 x steps)
    depth: int = 4                 # transformer blocks (paper: 4)
    heads: int = 4
    ffn_mult: int = 2              # feed-forward hidden = ffn_mult x width
    n_codebooks: int = 4
    codebook_size: int = 128       # N
    code_dim: int = 32             # d
    text_dim: int = 384            # pooled text-encoder width (all-MiniLM-L6-v2: 384)
    cs_dim: int = 64               # semantic condition c_s
    cs_tokens: int = 4             # c_s is lifted to this many cross-attention tokens
    encoder_hidden: int = 256      # mini encoders (4-layer MLPs, paper supp.)
    timesteps: int = 1000          # training diffusion steps (ref)
    tau_train: float = 0.2         # Gumbel-softmax temperature in training (ref)
    tau_sample: float = 0.5        # ... and at generation (ref)
    p_drop_both: float = 0.2       # per-sample condition dropout (ref)
    p_drop_geo: float = 0.2
    usage_weight: float = 0.01     # KL(code usage || uniform)
    text_encoder: str = "all-minilm-l6-v2"


@dataclass
class TrainConfig:
    """Optimisation of one stage (the same dataclass serves both)."""
    steps: int = 1000
    batch_size: int = 32
    lr: float = 1e-3
    weight_decay: float = 0.0
    warmup: int = 100
    grad_clip: float = 1.0
    n_points: int = 1024           # input surface points per part (AE)
    n_queries: int = 2048          # SDF samples per part per step (AE)
    max_sdf: int = 8192            # SDF samples kept in memory per part (AE)
    val_every: int = 250
    val_parts: int = 64
    ckpt_every: int = 500
    threads: int = 2


@dataclass
class Preset:
    sdf: SDFConfig
    prior: PriorConfig
    sdf_train: TrainConfig
    prior_train: TrainConfig


def _presets() -> dict[str, Preset]:
    tiny = Preset(
        sdf=SDFConfig(plane_res=16, plane_channels=8, pointnet_hidden=16, pointnet_blocks=2,
                      plane_net_channels=8, vae_channels=(16, 16), z_dim=32, mlp_hidden=32,
                      mlp_layers=3, mlp_skip=1),
        prior=PriorConfig(z_dim=32, width=32, depth=1, heads=2, codebook_size=8, code_dim=8,
                          cs_dim=16, cs_tokens=2, encoder_hidden=32, timesteps=100),
        sdf_train=TrainConfig(steps=60, batch_size=4, lr=3e-3, warmup=5, n_points=256,
                              n_queries=512, val_every=30, val_parts=4, ckpt_every=30, threads=1),
        prior_train=TrainConfig(steps=60, batch_size=8, lr=2e-3, warmup=5, val_every=30,
                                val_parts=8, ckpt_every=30, threads=1),
    )
    small = Preset(
        sdf=SDFConfig(),
        prior=PriorConfig(),
        sdf_train=TrainConfig(steps=3600, batch_size=16, lr=2e-3, warmup=100, n_points=512,
                              n_queries=2048, val_every=200, val_parts=96, ckpt_every=200),
        prior_train=TrainConfig(steps=4000, batch_size=128, lr=1e-3, warmup=200,
                                val_every=500, val_parts=512, ckpt_every=500),
    )
    paper = Preset(
        sdf=SDFConfig(plane_res=64, plane_channels=256, pointnet_hidden=256, pointnet_blocks=5,
                      plane_net_channels=256, vae_channels=(256, 256, 256, 256), z_dim=768,
                      mlp_hidden=512, mlp_layers=9, mlp_skip=4, sdf_clamp=0.1),
        prior=PriorConfig(z_dim=768, width=768, depth=4, heads=8, ffn_mult=4, n_codebooks=4,
                          codebook_size=128, code_dim=32, text_dim=1024, cs_dim=64,
                          encoder_hidden=512, text_encoder="t5-large"),
        sdf_train=TrainConfig(steps=200_000, batch_size=32, lr=1e-4, warmup=1000,
                              n_points=4096, n_queries=16000, val_every=2000, val_parts=256,
                              ckpt_every=2000),
        prior_train=TrainConfig(steps=200_000, batch_size=64, lr=1e-4, warmup=1000,
                                val_every=2000, val_parts=1024, ckpt_every=5000),
    )
    # small with a 64 x 64 tri-plane (one more down-sampling block keeps the 4 x 4 latent
    # grid, so z, the prior and the transformer's code layout stay as in small): thin walls
    # decode broken at 32 x 32 (docs/geometry.md, "How good it is, and why walls break")
    small_fine = Preset(
        sdf=SDFConfig(plane_res=64, vae_channels=(32, 64, 64, 64)),
        prior=PriorConfig(),
        sdf_train=small.sdf_train,
        prior_train=small.prior_train,
    )
    # small-fine with an 8 x 8 latent grid (one down-sampling block fewer; z stays 256-d, so
    # the prior and the transformer's code layout do too): fitted freely, the 4 x 4 grids of
    # small-fine hold 21 of 24 validation bodies whole and 8 x 8 grids 23 (docs/geometry.md)
    small_grid8 = Preset(
        sdf=SDFConfig(plane_res=64, vae_channels=(32, 64, 64)),
        prior=PriorConfig(),
        sdf_train=small.sdf_train,
        prior_train=small.prior_train,
    )
    return {"tiny": tiny, "small": small, "small-fine": small_fine, "small-grid8": small_grid8,
            "paper": paper}


PRESETS: dict[str, Preset] = _presets()


def get_preset(name: str) -> Preset:
    if name not in PRESETS:
        raise KeyError(f"unknown preset {name!r}; choose one of {sorted(PRESETS)}")
    p = PRESETS[name]
    return Preset(**{f.name: type(getattr(p, f.name))(**_asdict_shallow(getattr(p, f.name)))
                     for f in fields(Preset)})


def _asdict_shallow(cfg) -> dict:
    return {f.name: getattr(cfg, f.name) for f in fields(cfg)}


def config_from_dict(cls, d: dict):
    """Rebuild a config dataclass from ``asdict`` output; unknown keys are an error."""
    names = {f.name for f in fields(cls)}
    unknown = set(d) - names
    if unknown:
        raise ValueError(f"{cls.__name__}: unknown config keys {sorted(unknown)} "
                         f"(checkpoint from a newer version?)")
    kw = dict(d)
    for f in fields(cls):
        if f.name in kw and isinstance(kw[f.name], list):
            kw[f.name] = tuple(kw[f.name])
    return cls(**kw)
