"""Public API of the shape prior (what the transformer, the pipeline and eval call).

    from model.geometry import ShapeModel, fit_to_bbox
    shape = ShapeModel.load()                        # shipped model/weights/{sdf,prior}_small.pt
    c_s = shape.semantic_condition(["storage furniture, drawer"])      # (B, 64)
    P_gt = shape.code_distribution(z)                                  # (B, 4, N) targets
    z = shape.sample_from_logits(P, c_s, steps=50, tau=0.5, guidance=1.0, generator=g)
    meshes = shape.decode_meshes(z, resolution=64)   # unit-cube trimeshes (empty = no surface)
    part_mesh = fit_to_bbox(meshes[0], center, size)
    z_ret, idx = shape.retrieve(z, texts)            # nearest training latent (DESIGN §4.4)
"""
from __future__ import annotations

import functools
import logging
import os
from pathlib import Path
from typing import Optional, Sequence

import numpy as np
import torch

from .checkpoint import CheckpointError, load_checkpoint
from .meshing import MIN_ISLAND, MeshResult, SdfGrid, evaluate_grids, fit_to_bbox, mesh_grid

log = logging.getLogger(__name__)

WEIGHTS_DIR = Path(__file__).resolve().parent.parent / "weights"
DEFAULT_SDF = WEIGHTS_DIR / "sdf_small.pt"
DEFAULT_PRIOR = WEIGHTS_DIR / "prior_small.pt"


class ShapeModel:
    """The auto-encoder's decoder side + the diffusion prior + the retrieval bank."""

    def __init__(self, ae, prior=None, bank: Optional[dict] = None, info: Optional[dict] = None):
        self.ae = ae.eval()
        self.prior = prior.eval() if prior is not None else None
        self.bank = bank or {}
        self.info = info or {}
        self._label_logits: dict[str, torch.Tensor] = {}

    @classmethod
    def load(cls, sdf: Optional[str | os.PathLike] = None,
             prior: Optional[str | os.PathLike] = None, *, need_prior: bool = True) -> "ShapeModel":
        """Load the two checkpoints (None = the shipped small weights)."""
        sdf_path = Path(sdf) if sdf else DEFAULT_SDF
        ae, ae_ck = load_checkpoint(sdf_path, "sdf")
        pr = bank = None
        info = {"sdf": str(sdf_path), "sdf_data_version": ae_ck["data_version"]}
        if need_prior or prior:
            prior_path = Path(prior) if prior else DEFAULT_PRIOR
            pr, pr_ck = load_checkpoint(prior_path, "prior")
            if pr.cfg.z_dim != ae.cfg.z_dim:
                raise CheckpointError(f"{prior_path} was trained on {pr.cfg.z_dim}-d latents but "
                                      f"{sdf_path} makes {ae.cfg.z_dim}-d ones; pass the matching "
                                      f"pair (--sdf/--prior)")
            stored = pr_ck.get("extra", {}).get("sdf_config")
            if stored is not None and stored != ae_ck["config"]:
                log.warning("prior %s was trained on an auto-encoder with a different config "
                            "than %s", prior_path, sdf_path)
            bank = pr_ck.get("extra", {}).get("bank")
            from model.core.checkpoint import accepted_priors
            accepts = accepted_priors(ae_ck, pr_ck, prior_path)
            info.update(prior=str(prior_path), prior_data_version=pr_ck["data_version"],
                        fingerprint=accepts[0], accepts=accepts)
        return cls(ae, pr, bank, info)

    def _need_prior(self):
        if self.prior is None:
            raise RuntimeError("this ShapeModel was loaded without a prior checkpoint")
        return self.prior

    @torch.inference_mode()
    def encode(self, points: torch.Tensor) -> torch.Tensor:
        """Surface points (B, P, 3) of parts in the iso unit cube (the prepared-data frame)
        -> z (B, Z). The points are box-normalised first (model.geometry.data.box_frame)."""
        return self.ae.encode(points.float())

    # -- conditions -----------------------------------------------------------------------
    @torch.inference_mode()
    def code_distribution(self, z: torch.Tensor) -> torch.Tensor:
        """z (B, Z) -> P_gt (B, 4, N): softmax of negative code distances (transformer targets)."""
        return self._need_prior().code_distribution(z.float())

    @torch.inference_mode()
    def semantic_condition(self, texts: Sequence[str]) -> torch.Tensor:
        """Label texts such as 'storage furniture, drawer' -> c_s (B, 64)."""
        from .train import pooled_text
        pr = self._need_prior()
        return pr.semantic(pooled_text(list(texts), pr.cfg.text_encoder, pr.cfg.text_dim))

    @torch.inference_mode()
    def label_logits(self, texts: Sequence[str]) -> torch.Tensor:
        """Empirical code logits of each label text: log of the mean P_gt over the training
        parts with that text (uniform for an unseen text). -> (B, 4, N)."""
        pr = self._need_prior()
        out = []
        for t in texts:
            if t not in self._label_logits:
                lat = self.bank.get("latents")
                stored = self.bank.get("label_logits")      # a thinned bank keeps them
                known = t in self.bank.get("texts", ())
                if known and stored is not None:
                    self._label_logits[t] = stored[self.bank["texts"].index(t)].float()
                elif known and lat is not None:
                    sel = self.bank["text_ids"] == self.bank["texts"].index(t)
                    self._label_logits[t] = pr.mean_code_logits(lat[sel])
                else:
                    self._label_logits[t] = pr.mean_code_logits(torch.zeros(0, pr.cfg.z_dim))
            out.append(self._label_logits[t])
        return torch.stack(out)

    # -- sampling -------------------------------------------------------------------------
    @torch.inference_mode()
    def sample_from_logits(self, P: torch.Tensor, c_s: torch.Tensor, steps: int = 50,
                           tau: Optional[float] = None, guidance: float = 1.0,
                           generator: Optional[torch.Generator] = None) -> torch.Tensor:
        """Codebook logits P (B, 4, N) + c_s (B, 64) -> z (B, Z). Batch all parts of an object."""
        return self._need_prior().sample_from_logits(P, c_s, steps=steps, tau=tau,
                                                     guidance=guidance, generator=generator)

    @torch.inference_mode()
    def sample_for_labels(self, texts: Sequence[str], steps: int = 50, tau: Optional[float] = None,
                          guidance: float = 1.0, generator: Optional[torch.Generator] = None
                          ) -> torch.Tensor:
        """Sample z for label texts alone (codes drawn from the label's empirical logits)."""
        return self.sample_from_logits(self.label_logits(texts), self.semantic_condition(texts),
                                       steps=steps, tau=tau, guidance=guidance, generator=generator)

    # -- retrieval (DESIGN §4.4) ----------------------------------------------------------
    @torch.inference_mode()
    def retrieve(self, z: torch.Tensor, texts: Optional[Sequence[str]] = None
                 ) -> tuple[torch.Tensor, torch.Tensor]:
        """Nearest training latent to each z (B, Z), restricted to the same label text when the
        text is known. -> (latents (B, Z), bank indices (B,))."""
        lat = self.bank.get("latents")
        if lat is None:
            raise RuntimeError("the prior checkpoint has no retrieval bank")
        lat = lat.float()
        d = torch.cdist(z.float(), lat)                                  # (B, M)
        if texts is not None:
            for b, t in enumerate(texts):
                if t in self.bank["texts"]:
                    other = self.bank["text_ids"] != self.bank["texts"].index(t)
                    d[b, other] = float("inf")
        idx = d.argmin(1)
        return lat[idx], idx

    # -- meshing --------------------------------------------------------------------------
    @torch.inference_mode()
    def decode(self, z: torch.Tensor, resolution=64, part_batch: int = 1,
               min_island: int = MIN_ISLAND, **kw) -> list[MeshResult]:
        """z (B, Z) -> one MeshResult per part (mesh in the unit cube, status, evaluations).

        ``resolution``: cells per side for every part, or a sequence of one per part (then
        parts are meshed one at a time). The planes of all parts are decoded in one call;
        the SDF grids are evaluated ``part_batch`` parts per network call (parts need very
        different numbers of evaluations, and padding them to one batch measured 2x slower
        per part than one part at a time).
        """
        return [mesh_grid(g, min_island) for g in self.decode_grids(z, resolution, part_batch, **kw)]

    @torch.inference_mode()
    def decode_grids(self, z: torch.Tensor, resolution=64, part_batch: int = 1,
                     **kw) -> list[SdfGrid]:
        """The network's half of :meth:`decode`: each part's SDF on its vertex grid, for
        meshing elsewhere (``model.geometry.surface.mesh_grid``, in any process)."""
        planes = self.ae.decode_planes(z.float())                        # (B, 3, C, R, R)
        per_part = np.ndim(resolution) > 0
        if per_part:
            part_batch = 1
        out: list[SdfGrid] = []
        for i in range(0, z.shape[0], part_batch):
            pl = planes[i:i + part_batch]
            res = int(resolution[i]) if per_part else int(resolution)
            out += evaluate_grids(lambda xyz, pl=pl: self.ae.query(pl, xyz), pl.shape[0],
                                  res, **kw)
        return out

    def decode_meshes(self, z: torch.Tensor, resolution: int = 64) -> list:
        """z (B, Z) -> list of trimesh.Trimesh in the unit cube. A part without a surface
        comes back as an empty mesh (``mesh.is_empty``) with ``mesh.metadata['surface']`` set
        to 'empty' or 'full'; fall back to its bbox."""
        out = []
        for r in self.decode(z, resolution):
            r.mesh.metadata["surface"] = r.status
            out.append(r.mesh)
        return out


@functools.lru_cache(maxsize=2)
def load_shape_model(sdf: Optional[str] = None, prior: Optional[str] = None) -> ShapeModel:
    """Process-wide cached ShapeModel (None = shipped weights)."""
    return ShapeModel.load(sdf, prior)


__all__ = ["ShapeModel", "load_shape_model", "fit_to_bbox", "MeshResult", "DEFAULT_SDF",
           "DEFAULT_PRIOR"]
