"""Loading and using an image-conditioned transformer checkpoint (the pipeline's entry point).

    im = load_image_model("model/weights/image_small.pt")   # or None = the shipped file
    tokens, mask = im.encode("photo.png")                    # (1, 49, D), (1, 49); D = 1280 (1728 multiscale)
    tokens, mask, plan = im.condition("photo.png")           # + (1, labels) count-head counts or None
    trees = im.decode_image("photo.png", samples=2, seed=0)  # list[DecodedTree]
    obj = trees[0].to_object()

With a count head (model.imaging.counts, ``artformer train image-counts``) ``decode_image``
holds the END decisions to its per-label counts (``count_plan=False`` turns that off).

``im.am`` is a ``model.articulation.ArticulationModel`` (decoding, label table, editing), so
everything downstream (shape prior, export) is the same as for text.
"""
from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence, Union

import torch

from model.core.checkpoint import CheckpointError
from model.encoders.image import ENCODE_BATCH, ImageEncoder, ImageEncoderConfig, ImageLike, preprocess

log = logging.getLogger(__name__)

SHIPPED = Path(__file__).resolve().parent.parent / "weights" / "image_small.pt"


# the file is not an image-conditioned checkpoint (or is missing); the one CheckpointError,
# kept under this name for one release
ImageModelError = CheckpointError


@dataclass
class ImageExtras:
    """What an image checkpoint holds beyond a text transformer checkpoint (its entries
    ``condition = "image"``, ``image_encoder``, ``renders``, ``init``, ``image_train_config``,
    ``extra_train`` and the optional count heads), typed."""
    encoder: dict                                   # ImageEncoderConfig fields
    tail: dict = field(default_factory=dict)        # fine-tuned last block + head conv
    trunk: dict = field(default_factory=dict)       # blocks of `artformer train image-trunk`
    trunk_info: dict = field(default_factory=dict)  # where the trunk came from
    renders: dict = field(default_factory=dict)     # the render set's manifest
    init: str = "none"                              # the checkpoint the run started from
    image_train_config: dict = field(default_factory=dict)
    extra_train: list = field(default_factory=list)
    count_head: Optional[dict] = None               # END-plan count head
    count_tokens: Optional[dict] = None             # count-token head

    @classmethod
    def of(cls, ckpt: dict, path="checkpoint") -> "ImageExtras":
        if ckpt.get("condition") != "image":
            raise CheckpointError(f"{path} is a text-conditioned transformer checkpoint, not an "
                                  f"image model; pass an `artformer train image` checkpoint")
        enc = ckpt.get("image_encoder") or {}
        return cls(encoder=dict(enc.get("config") or {}), tail=enc.get("tail") or {},
                   trunk=enc.get("trunk") or {}, trunk_info=enc.get("trunk_info") or {},
                   renders=ckpt.get("renders") or {}, init=ckpt.get("init") or "none",
                   image_train_config=ckpt.get("image_train_config") or {},
                   extra_train=list(ckpt.get("extra_train") or []),
                   count_head=ckpt.get("count_head"), count_tokens=ckpt.get("count_tokens"))

    def entries(self) -> dict:
        """The checkpoint entries (the inverse of ``of``)."""
        enc = {"config": self.encoder, "tail": self.tail}
        if self.trunk:
            enc.update(trunk=self.trunk, trunk_info=self.trunk_info)
        heads = {k: v for k, v in (("count_head", self.count_head),
                                   ("count_tokens", self.count_tokens)) if v}
        return {"condition": "image", "image_encoder": enc, "renders": self.renders,
                "init": self.init, "image_train_config": self.image_train_config,
                "extra_train": self.extra_train, **heads}

    def encoder_config(self) -> ImageEncoderConfig:
        return ImageEncoderConfig(**{k: (tuple(v) if k == "background" else v)
                                     for k, v in self.encoder.items()})


class ImageArticulationModel:
    """An articulation model whose condition is an image (EfficientNet-Lite0 tokens)."""

    def __init__(self, am, encoder: ImageEncoder, ckpt: dict, counter=None, token_counter=None):
        self.am = am
        self.encoder = encoder.eval()
        self.counter = counter                    # CountHead (END plan) or None
        self.token_counter = token_counter        # CountHead (count tokens) or None
        self.meta = {k: ckpt.get(k) for k in ("data_version", "seed", "command", "step",
                                              "renders", "init", "image_train_config")}
        if counter is not None:
            self.meta["count_head"] = (ckpt["count_head"].get("train") or {}).get("command")

    @torch.inference_mode()
    def condition(self, images: Union[ImageLike, list], frame: bool = False
                  ) -> tuple[torch.Tensor, torch.Tensor, Optional[torch.Tensor]]:
        """One image or a list → tokens (B, 49, D), mask (B, 49) bool and the count head's
        per-label counts (B, len(count_labels)), or None without a count head. A model with
        count tokens gets one more token per label (``pack_count_tokens``): (B, 49 + labels, D).
        ``frame``: crop pictures with a plain background around their object first (as the
        renders frame it; model.encoders.framing)."""
        x = preprocess(images, self.encoder.config.image_size, self.encoder.config.background,
                       frame=frame)
        chunks = [x[s:s + ENCODE_BATCH] for s in range(0, len(x), ENCODE_BATCH)]
        heads = [h for h in (self.counter, self.token_counter) if h is not None]
        plan = None
        if not heads:
            tokens = torch.cat([self.encoder(c) for c in chunks])                 # (B, 49, D)
        else:               # both heads read the map entering the same block (checked on load)
            outs = [self.encoder.tokens_and_features(c, heads[0].cfg.split) for c in chunks]
            tokens = torch.cat([t for t, _ in outs])
            h = torch.cat([h for _, h in outs])
            if self.counter is not None:
                plan = self.counter.predict(h)
            if self.token_counter is not None:
                from .counts import count_distributions, pack_count_tokens
                tokens = pack_count_tokens(tokens, count_distributions(self.token_counter, h))
        return tokens, torch.ones(tokens.shape[:2], dtype=torch.bool), plan

    def encode(self, images: Union[ImageLike, list], frame: bool = False
               ) -> tuple[torch.Tensor, torch.Tensor]:
        """One image or a list → tokens (B, 49, D), mask (B, 49) bool."""
        tokens, mask, _ = self.condition(images, frame)
        return tokens, mask

    @torch.inference_mode()
    def decode_image(self, image: ImageLike, *, samples: int = 1, seed: int = 0,
                     count_plan: bool = True, frame: bool = False, **kwargs):
        """One image → ``samples`` decoded trees (kwargs go to ArticulationModel.decode);
        with a count head (and ``count_plan``) END decisions follow its counts."""
        tokens, mask, plan = self.condition(image, frame)
        if plan is not None and count_plan:
            kwargs["plan"] = plan.expand(samples, -1)
        return self.am.decode(tokens.expand(samples, -1, -1), mask.expand(samples, -1),
                              seed=seed, modality="image", **kwargs)


def load_image_model(path: Union[str, os.PathLike, None] = None,
                     prior: Union[str, Sequence[str], None] = None) -> ImageArticulationModel:
    """The one loader of image checkpoints (``None`` = the shipped model/weights/image_small.pt).
    ``prior``: fingerprint of the shape prior it will run with, or the list it accepts
    (model.core.checkpoint); a model trained against another prior is refused."""
    from model.articulation.checkpoint import build_network, read_checkpoint
    from model.articulation.decode import ArticulationModel
    p = Path(path) if path is not None else SHIPPED
    if p.is_dir() and (p / "image.pt").exists():
        p = p / "image.pt"
    if not p.exists():
        raise ImageModelError(f"no image checkpoint at {p}; train one with `artformer train image` "
                              f"(the shipped one is model/weights/image_small.pt)")
    ckpt = read_checkpoint(p, prior=prior)
    extras = ImageExtras.of(ckpt, p)
    try:
        net = build_network(ckpt)
    except CheckpointError as e:
        raise ImageModelError(f"{p}: {e}") from e
    am = ArticulationModel(net, ckpt)
    encoder = ImageEncoder(extras.encoder_config())
    if extras.trunk:                 # blocks fine-tuned by `artformer train image-trunk`
        encoder.load_tail_state_dict(extras.trunk)
    if extras.tail:
        encoder.load_tail_state_dict(extras.tail)
    encoder.requires_grad_(False)
    counter = _checkpoint_count_head(p, ckpt, "count_head", am, encoder)
    token_counter = _checkpoint_count_head(p, ckpt, "count_tokens", am, encoder)
    if token_counter is not None:
        want = list((am.cfg.count_tokens or {}).get("image") or [])
        from .counts import count_token_shape
        have = list(count_token_shape(token_counter))
        if want != have:
            raise ImageModelError(f"{p}: the network expects count tokens {want} (labels, "
                                  f"classes), its count head gives {have}")
        if counter is not None and counter.cfg.split != token_counter.cfg.split:
            raise ImageModelError(f"{p}: its two count heads read different encoder blocks")
    elif (am.cfg.count_tokens or {}).get("image"):
        raise ImageModelError(f"{p}: the network expects count tokens but the checkpoint has "
                              f"no count_tokens head")
    return ImageArticulationModel(am, encoder, ckpt, counter, token_counter)


def _checkpoint_count_head(p: Path, ckpt: dict, key: str, am, encoder: ImageEncoder):
    """The count head stored under ``key`` ("count_head": END plan; "count_tokens": condition
    tokens), or None; ImageModelError if it is damaged, counts other labels than the
    transformer or reads a block the checkpoint's encoder fine-tuned."""
    if ckpt.get(key) is None:
        return None
    from .counts import CountHeadError, load_count_head
    what, prefix = ("count head", "") if key == "count_head" else ("count-token head", "count tokens: ")
    try:
        head = load_count_head(ckpt[key], list(am.cfg.count_labels or []))
    except CountHeadError as e:
        raise ImageModelError(f"{p}: {prefix}{e}") from e
    if encoder.split < head.cfg.split:
        raise ImageModelError(f"{p}: the {what} reads block {head.cfg.split}, which this "
                              f"checkpoint's encoder fine-tuned")
    return head
