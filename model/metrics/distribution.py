"""MMD / COV / 1-NNA between a generated set G and a reference set R (DESIGN §7).

Orientation (the standard one of PointFlow / NAP; the ArtFormer reference code transposes its
matrices — not here). With ``D_gr[g, r]`` the distance between generated g and reference r:

* **MMD** = mean over *reference* objects r of min_g D_gr[g, r]  (lower is better)
* **COV** = |{argmin_r D_gr[g, r] : g ∈ G}| / |R|  — the share of reference objects that are
  the nearest neighbour of some generated object (higher is better)
* **1-NNA**: leave-one-out 1-NN classification on G ∪ R with labels "generated"/"reference";
  the accuracy (best 0.5: the two sets are indistinguishable; 1.0: fully separated).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass
class SetMetrics:
    mmd: float
    cov: float
    nna: float         # 1-NNA accuracy
    n_generated: int
    n_reference: int

    def to_json(self) -> dict:
        return asdict(self)


def mmd(D_gr: np.ndarray) -> float:
    """Mean over reference objects (columns) of the distance to the nearest generated one."""
    D_gr = np.asarray(D_gr, dtype=np.float64)
    return float(D_gr.min(axis=0).mean())


def coverage(D_gr: np.ndarray) -> float:
    """Share of reference objects (columns) that are some generated object's nearest."""
    D_gr = np.asarray(D_gr, dtype=np.float64)
    nearest = D_gr.argmin(axis=1)                   # (|G|,) reference index per generated
    return float(len(np.unique(nearest)) / D_gr.shape[1])


def one_nna(D_gg: np.ndarray, D_gr: np.ndarray, D_rr: np.ndarray) -> float:
    """Leave-one-out 1-NN accuracy on G ∪ R (0.5 ideal). Ties go to the other set's object,
    so an exact copy of R scores 0 rather than an arbitrary value."""
    D_gg, D_gr, D_rr = (np.asarray(x, dtype=np.float64) for x in (D_gg, D_gr, D_rr))
    ng, nr = D_gr.shape
    if D_gg.shape != (ng, ng) or D_rr.shape != (nr, nr):
        raise ValueError(f"shapes do not agree: D_gg {D_gg.shape}, D_gr {D_gr.shape}, "
                         f"D_rr {D_rr.shape}")
    if ng + nr < 2:
        raise ValueError("1-NNA needs at least two objects")
    full = np.block([[D_gg, D_gr], [D_gr.T, D_rr]])  # (ng+nr, ng+nr)
    np.fill_diagonal(full, np.inf)
    labels = np.r_[np.zeros(ng, bool), np.ones(nr, bool)]   # True = reference
    correct = 0
    for i in range(ng + nr):
        same = labels == labels[i]
        d_same = full[i, same].min() if same.sum() > 1 else np.inf
        d_other = full[i, ~same].min() if (~same).any() else np.inf
        correct += int(d_same < d_other)            # a tie is counted as misclassified
    return float(correct / (ng + nr))


def set_metrics(D_gg: np.ndarray, D_gr: np.ndarray, D_rr: np.ndarray) -> SetMetrics:
    D_gr = np.asarray(D_gr, dtype=np.float64)
    return SetMetrics(mmd(D_gr), coverage(D_gr), one_nna(D_gg, D_gr, D_rr),
                      int(D_gr.shape[0]), int(D_gr.shape[1]))
