"""Part Overlapping Ratio (POR, DESIGN §7; paper eq. "POR").

For an articulated object E and a set of joint states J, MI(E, J) is the mean over every
unordered pair of parts of the exact volume IoU of their posed meshes. POR is the mean of MI
over ``n_states`` openness states r ∈ linspace(0, 1, n_states) (every joint at
``lerp(lower, upper, r)``). The maximum over states is reported too.

Volumes come from manifold3d (exact booleans on closed meshes, ``model.core.meshops``). Each
part mesh is converted once; per state only a rigid transform of the Manifold is applied, so
the volumes are reused and only intersections are computed (skipped when bounding boxes are
apart).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from model.core import ArticulatedObject

log = logging.getLogger(__name__)


@dataclass
class PORResult:
    mean: float                        # POR: mean over states of the mean pairwise IoU
    max: float                         # max over states of the mean pairwise IoU
    per_state: list[float]             # (n_states,) MI at each openness ratio
    ratios: list[float]                # (n_states,) the openness ratios used
    num_pairs: int                     # pairs of parts scored
    nonwatertight_parts: int = 0       # parts replaced by their convex hull (or skipped)
    worst_pair: tuple[str, str] | None = None   # pair with the highest IoU over all states
    worst_iou: float = 0.0
    extra: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"mean": self.mean, "max": self.max, "per_state": self.per_state,
                "ratios": self.ratios, "num_pairs": self.num_pairs,
                "nonwatertight_parts": self.nonwatertight_parts,
                "worst_pair": list(self.worst_pair) if self.worst_pair else None,
                "worst_iou": self.worst_iou}


def _part_manifolds(obj: ArticulatedObject, on_error: str):
    """One Manifold per meshed part (index, manifold), and how many were not watertight."""
    from model.core import meshops
    out, bad = [], 0
    for i, p in enumerate(obj.parts):
        if p.mesh is None or len(p.mesh.faces) == 0:
            continue
        try:
            man = meshops.to_manifold(p.mesh)
        except meshops.NotWatertightError:
            bad += 1
            if on_error == "skip":
                log.warning("POR: part %r is not watertight; skipped", p.name)
                continue
            if on_error == "raise":
                raise
            man = meshops.hull(np.asarray(p.mesh.vertices))
            log.warning("POR: part %r is not watertight; scored by its convex hull", p.name)
        out.append((i, man))
    return out, bad


def _overlap(a, b) -> bool:
    ba, bb = a.bounding_box(), b.bounding_box()
    return all(ba[k] <= bb[k + 3] and bb[k] <= ba[k + 3] for k in range(3))


def part_overlap_ratio(obj: ArticulatedObject, n_states: int = 10, *,
                       on_error: str = "hull") -> PORResult:
    """POR of one object with part meshes (object frame at rest).

    on_error: what to do with a part mesh that is not a closed manifold — ``"hull"`` (score its
    convex hull, an over-estimate; counted in ``nonwatertight_parts``), ``"skip"`` or ``"raise"``.
    Objects with fewer than two meshed parts have no pairs: POR 0.
    """
    if on_error not in ("hull", "skip", "raise"):
        raise ValueError(f"on_error must be hull, skip or raise, got {on_error!r}")
    ratios = np.linspace(0.0, 1.0, n_states) if n_states > 1 else np.array([0.0])
    parts, bad = _part_manifolds(obj, on_error)
    n = len(parts)
    num_pairs = n * (n - 1) // 2
    if num_pairs == 0:
        zeros = [0.0] * len(ratios)
        return PORResult(0.0, 0.0, zeros, ratios.tolist(), 0, bad)
    vol = np.array([float(m.volume()) for _, m in parts])          # (n,) rigid-invariant
    names = [obj.parts[i].name for i, _ in parts]
    per_state = []
    worst, worst_pair = 0.0, None
    for r in ratios:
        T = obj.link_transforms(ratio=float(r))
        posed = [m.transform(np.ascontiguousarray(T[obj.parts[i].name][:3, :]))
                 for i, m in parts]
        total = 0.0
        for a in range(n):
            for b in range(a + 1, n):
                if vol[a] <= 0 or vol[b] <= 0 or not _overlap(posed[a], posed[b]):
                    continue
                inter = max(0.0, float((posed[a] ^ posed[b]).volume()))
                if inter <= 0.0:
                    continue
                iou = inter / (vol[a] + vol[b] - inter)
                total += iou
                if iou > worst:
                    worst, worst_pair = iou, (names[a], names[b])
        per_state.append(total / num_pairs)
    return PORResult(float(np.mean(per_state)), float(np.max(per_state)),
                     [float(x) for x in per_state], ratios.tolist(), num_pairs, bad,
                     worst_pair, float(worst))
