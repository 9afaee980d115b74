"""Per-part training targets that come from the shape prior (DESIGN §5).

The transformer learns to predict, for every child part, its semantic condition c_s (64) and
its codebook distribution P_gt (C × N) = softmax of negative distances of the part's geometry
code z to each codebook entry (or z itself for the no_shape_prior ablation). Two providers:

* ``PriorTargets`` — the real thing: the geometry engineer's SDF auto-encoder (z from the
  prepared part points) and codebook prior (``code_distribution(z)``,
  ``semantic_condition(texts)``), loaded from their checkpoints.
* ``StandInTargets`` — deterministic targets with the same shapes and no trained network
  (hash-seeded c_s per label text, z = a fixed random projection of point statistics, random
  codebooks). For tests and for developing without a prior; never for a shipped model.
"""
from __future__ import annotations

import logging
import zlib

import numpy as np
import torch

log = logging.getLogger(__name__)


class StandInTargets:
    name = "stand-in"
    fingerprint = "stand-in"      # model.core.checkpoint.STAND_IN: no shape prior

    def __init__(self, z_dim: int = 32, num_codebooks: int = 4, codebook_size: int = 16,
                 cs_dim: int = 64, seed: int = 0):
        self.z_dim, self.num_codebooks, self.codebook_size, self.cs_dim = \
            z_dim, num_codebooks, codebook_size, cs_dim
        g = np.random.default_rng(seed)
        self._feat_dim = 3 + 6 + 3
        self._proj = g.normal(size=(self._feat_dim, z_dim)) / np.sqrt(self._feat_dim)
        chunk = z_dim // num_codebooks
        self._codebooks = g.normal(size=(num_codebooks, codebook_size, chunk))

    def part_latents(self, points: np.ndarray) -> np.ndarray:
        """points (K, P, 3) in the part cube -> z (K, z_dim)."""
        p = np.asarray(points, dtype=np.float64)
        mean = p.mean(1)                                               # (K, 3)
        c = p - mean[:, None]
        cov = np.einsum("kpi,kpj->kij", c, c) / p.shape[1]             # (K, 3, 3)
        iu = np.triu_indices(3)
        feat = np.concatenate([mean, cov[:, iu[0], iu[1]] * 4, np.abs(c).max(1)], 1)
        return np.tanh(feat @ self._proj).astype(np.float32)

    def code_distribution(self, z: torch.Tensor) -> torch.Tensor:
        """z (K, z_dim) -> P (K, C, N) probabilities."""
        z = torch.as_tensor(z, dtype=torch.float32)
        K = z.shape[0]
        chunks = z[:, : self.num_codebooks * (self.z_dim // self.num_codebooks)]
        chunks = chunks.view(K, self.num_codebooks, -1)               # (K, C, d)
        cb = torch.as_tensor(self._codebooks, dtype=torch.float32)    # (C, N, d)
        d2 = ((chunks[:, :, None, :] - cb[None]) ** 2).sum(-1)        # (K, C, N)
        return torch.softmax(-d2, -1)

    def semantic_condition(self, texts: list[str]) -> torch.Tensor:
        """texts -> c_s (K, cs_dim): a fixed unit-variance vector per distinct text."""
        out = []
        for t in texts:
            g = np.random.default_rng(zlib.crc32(t.encode()))
            out.append(g.normal(size=self.cs_dim))
        return torch.as_tensor(np.stack(out), dtype=torch.float32)


class PriorTargets:
    """Targets from the trained shape prior and its SDF auto-encoder (model.geometry API)."""
    name = "prior"

    def __init__(self, prior_path: str, sdf_path: str, n_points: int | None = None,
                 seed: int = 0):
        from model.core.checkpoint import prior_fingerprint
        from model.geometry.api import ShapeModel
        from model.geometry.checkpoint import read_checkpoint
        self.prior_path, self.sdf_path = str(prior_path), str(sdf_path)
        self.shape = ShapeModel.load(sdf_path, prior_path)
        sdf_ck = read_checkpoint(sdf_path, "sdf")
        # the identity of this prior, stored in every checkpoint trained on its targets
        self.fingerprint = prior_fingerprint(sdf_ck, read_checkpoint(prior_path, "prior"))
        if n_points is None:   # the auto-encoder's own training input size
            n_points = int(sdf_ck.get("train_config", {}).get("n_points", 1024))
        pc = self.shape.prior.cfg
        self.z_dim, self.num_codebooks = int(pc.z_dim), int(pc.n_codebooks)
        self.codebook_size, self.cs_dim = int(pc.codebook_size), int(pc.cs_dim)
        self.n_points, self.seed = n_points, seed

    @torch.inference_mode()
    def part_latents(self, points: np.ndarray) -> np.ndarray:
        """points (K, P, 3) -> posterior-mean z (K, Z) from a fixed subset of n_points."""
        pts = torch.as_tensor(np.asarray(points, dtype=np.float32))
        P = pts.shape[1]
        g = torch.Generator().manual_seed(self.seed)
        sel = torch.randperm(P, generator=g)[: min(self.n_points, P)]
        return self.shape.ae.encode(pts[:, sel]).float().numpy()

    @torch.inference_mode()
    def code_distribution(self, z: torch.Tensor) -> torch.Tensor:
        return self.shape.code_distribution(torch.as_tensor(z, dtype=torch.float32)).float()

    @torch.inference_mode()
    def semantic_condition(self, texts: list[str]) -> torch.Tensor:
        return self.shape.semantic_condition(list(texts)).float()
