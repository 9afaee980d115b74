"""One verified object per (seed, index): the category generators, redraws and range
shrinks."""
from __future__ import annotations

import logging
from typing import Callable, Iterator, Optional

import numpy as np

from model.core.objects import ArticulatedObject, JointType

from .builder import _Builder
from .cabinets import _gen_oven, _gen_safe, _gen_storage
from .config import GenerationRejected, SynthConfig
from .handheld import _gen_bottle, _gen_usb
from .verify import (
    CheckReport,
    _audit_failures,
    _moving_ancestor,
    _shrink,
    check_object,
)
from .washer import _gen_washer

log = logging.getLogger(__name__)

GENERATORS: dict[str, Callable] = {
    "StorageFurniture": _gen_storage, "Safe": _gen_safe, "Oven": _gen_oven,
    "WashingMachine": _gen_washer, "Bottle": _gen_bottle, "USB": _gen_usb,
}




# =============================================================================================
# public API
# =============================================================================================
def object_rng(seed: int, index: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), int(index)])


def pick_category(rng: np.random.Generator, weights: dict[str, float]) -> str:
    cats = list(weights)
    p = np.array([weights[c] for c in cats], dtype=np.float64)
    return cats[int(rng.choice(len(cats), p=p / p.sum()))]


def generate_object(seed: int = 0, index: int = 0, config: Optional[SynthConfig] = None,
                    category: Optional[str] = None) -> ArticulatedObject:
    """One verified object, a pure function of (seed, index, category)."""
    cfg = config or SynthConfig(seed=seed)
    rng = object_rng(seed, index)
    cat = category or pick_category(rng, cfg.categories)
    if cat not in GENERATORS:
        raise ValueError(f"unknown category {cat!r}; choose from {sorted(GENERATORS)}")
    last: Optional[CheckReport] = None
    for attempt in range(cfg.max_redraws):
        b = _Builder(cat)
        GENERATORS[cat](rng, b)
        obj = b.build(f"{cat.lower()}_{seed}_{index:05d}")
        obj.metadata.update(seed=int(seed), index=int(index), attempt=attempt)
        mans = {p["name"]: p["man"] for p in b.parts}
        for _ in range(cfg.max_shrinks + 1):
            rep = check_object(obj, cfg.states, attach_distance=cfg.attach_distance,
                               abs_tol=cfg.collision_abs_tol, depth_tol=cfg.collision_depth_tol,
                               manifolds=mans, stop_early=True)
            if rep.ok:
                obj.validate()
                physics = (cfg.audit_physics or len(obj.parts) <= cfg.audit_physics_parts
                           or (cfg.audit_physics_swing and swings_fore_and_aft(obj)))
                failures = _audit_failures(obj, physics) if cfg.audit else []
                if not failures:
                    return obj
                log.debug("%s seed %d index %d attempt %d fails the audit: %s", cat, seed,
                          index, attempt, failures)
                break
            last = rep
            if rep.detached:
                break           # shrinking does not re-attach a part: redraw
            a, bn = rep.collisions[0][:2]
            movers = {k for k in (_moving_ancestor(obj, a), _moving_ancestor(obj, bn)) if k is not None}
            if not movers:
                break           # two static parts overlap: a construction fault, redraw
            for k in movers:
                _shrink(obj.parts[k].joint, 0.7)
        log.debug("%s seed %d index %d attempt %d rejected: %s", cat, seed, index, attempt, last)
    raise GenerationRejected(f"no valid {cat} for seed {seed} index {index}: {last}")


def swings_fore_and_aft(obj: ArticulatedObject) -> bool:
    """A door or lid on a revolute joint whose axis is within 60 degrees of horizontal."""
    return any(p.label in ("door", "lid") and p.joint.type == JointType.REVOLUTE
               and abs(float(np.asarray(p.joint.axis, dtype=float)[2])) < 0.5
               for p in obj.parts)


def generate_objects(n: int, seed: int = 0, config: Optional[SynthConfig] = None,
                     start: int = 0) -> Iterator[ArticulatedObject]:
    for i in range(start, start + n):
        yield generate_object(seed, i, config)


