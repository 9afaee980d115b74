"""Refinement between decoding and export: a generated object made physically plausible
without changing its structure (labels, counts, joint types, parents).

    done = arrange_stated(obj, spatial)  # rows and columns a prompt states (arrange.py)
    done += safe_keypads(obj, spatial)   # ... and a safe's keypad where it states none
    report = refine_layout(obj)          # boxes + joints, before meshing (layout.py)
    done = place_stated_sides(obj, spatial)   # ... and the sides it states (arrange.py)
    report = refine_meshes(obj)          # after meshing (meshes.py)
    report = simplify_meshes(obj, 30000) # raw output: only the face budget

Both work in place and return what they changed; :class:`RefineConfig` switches each step
for ablations (``artformer eval`` measures them, docs/refine.md).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from model.core import ArticulatedObject, meshops

from .arrange import arrange_stated, door_beside_controls, place_stated_sides, safe_keypads
from .hardware import knob_handles, match_handles
from .layout import LayoutConfig, face_of, free_edge_handles, refine_layout
from .revolve import revolve_knobs, revolve_vessels


@dataclass
class RefineConfig:
    layout: LayoutConfig = field(default_factory=LayoutConfig)
    floaters: bool = True          # drop specks and enclosed voids of every part
    carve: bool = True             # parents give way where a moving child passes
    runners: bool = True           # a detached drawer gets a slab of its parent to slide on
    revolve: bool = True           # a bottle's body and screw cap: solids of revolution
    settle: bool = True            # a lid or cap hovering over its parent's mesh comes down
    panels: bool = True            # controls with nothing behind them get a plate of it,
                                   # an oven's front is closed around its doors and drawers
    limits: bool = True            # a range ends where its sweep still collides
    vessels: bool = True           # a bottle stands on the hull of its body below the cap
    foot: bool = True              # the root's box pieces get a slab over its footprint
    face_budget: int = 30000       # visual faces per object (0: keep every face)
    max_overlap: float = 0.01      # what the limit shrink tolerates (the audit's threshold)


def refine_meshes(obj: ArticulatedObject, config: Optional[RefineConfig] = None,
                  frozen: frozenset = frozenset(), prepared: Optional[dict] = None) -> dict:
    """Floaters, simplification, carving, joint limits on ``obj``'s meshes (in place).
    Parts whose index is in ``frozen`` (kept parts of an edit) keep their meshes.
    ``prepared``: part index -> :class:`~model.refine.prepare.PreparedMesh` already made
    from that part's current mesh (the pipeline makes them while meshing); the other parts
    are prepared here."""
    from . import meshes as M

    cfg = config or RefineConfig()
    t0 = time.perf_counter()
    # 15 % headroom: carving adds faces after simplifying
    mans, tol = _within_budget(obj, int(0.85 * cfg.face_budget), cfg.floaters, frozen, prepared)
    report: dict = {"simplify_tolerance": tol}
    if cfg.revolve and not frozen:
        report["revolved"] = revolve_vessels(obj, mans) + revolve_knobs(obj, mans)
    if cfg.settle and not frozen:
        report["settled"] = M.settle_onto_parents(obj, mans)
        report["lids_fitted"] = M.fit_lids_to_necks(obj, mans)
        report["lids_seated"] = M.seat_lids(obj, mans)
        report["caps_fitted"] = M.fit_caps_to_necks(obj, mans)
        report["necks_capped"] = M.cap_necks(obj, mans)
    if cfg.panels and not frozen:
        report["control_panels"] = M.add_control_panels(obj, mans)
        report["fronts_closed"] = M.close_fronts(obj, mans)
        report["swivel_caps_closed"] = M.close_swivel_caps(obj, mans)
        report["slide_caps_closed"] = M.close_slide_caps(obj, mans)
        report["console_controls"] = M.seat_console_controls(obj, mans)
    if cfg.carve:
        carved = M.carve_parents(obj, mans)
        for i, sweep in carved.items():
            if obj.parts[i].collision:
                obj.parts[i].collision = M.carve_collision(obj.parts[i].collision, sweep)
        report["carved"] = sorted(obj.parts[i].name for i in carved)
    if cfg.runners:
        report["runners"] = M.add_runners(obj, mans)
    mans, more = _back_within_budget(mans, cfg.face_budget, tol, cfg.floaters)
    if more:
        report["simplify_tolerance"] = more
    M.store(obj, mans)
    report["hull_collision"] = M.round_collision(obj, mans)
    for i in mans:               # the boxes describe the meshes that get exported
        obj.parts[i].fit_bbox_to_mesh()
    if cfg.vessels:
        report["vessel_collision"] = M.vessel_collision(obj)
    if cfg.foot:
        report["foot_collision"] = M.foot_collision(obj)
    if cfg.limits and not frozen:
        report["limits_shrunk"] = M.shrink_limits(obj, mans, cfg.max_overlap)
    report["faces"] = int(sum(m.num_tri() for m in mans.values()))
    report["seconds"] = time.perf_counter() - t0
    return report


def simplify_meshes(obj: ArticulatedObject, face_budget: int, frozen: frozenset = frozenset(),
                    prepared: Optional[dict] = None) -> dict:
    """The raw model output within ``face_budget`` visual faces (in place): the refinement's
    simplification steps and nothing else -- the model's floaters kept (a part keeps at most
    as many pieces as it had), nothing carved, boxes, joints and collision untouched. A
    budget is an export setting, not a correction of the model, so ``--no-refine`` output
    keeps it too. ``prepared`` as for :func:`refine_meshes` (made without dropping
    floaters)."""
    from .meshes import largest_pieces

    t0 = time.perf_counter()
    mans, tol = _within_budget(obj, face_budget, False, frozen, prepared)
    if tol:
        for i, m in mans.items():
            pieces = len(meshops.edge_pieces(obj.parts[i].mesh)[1])
            obj.parts[i].mesh = largest_pieces(meshops.to_trimesh(m), pieces)
    return {"simplify_tolerance": tol, "faces": int(sum(len(p.mesh.faces) for p in obj.parts
                                                         if p.mesh is not None)),
            "seconds": time.perf_counter() - t0}


def _within_budget(obj: ArticulatedObject, budget: int, floaters: bool, frozen: frozenset,
                   prepared: Optional[dict]) -> tuple[dict, float]:
    """Every part not in ``frozen`` as a Manifold (floaters dropped when ``floaters``),
    simplified until the object has at most ``budget`` faces (0: as it is); and the last
    tolerance used (0: none). The first steps come from ``prepared`` (see prepare.py), the
    rest need every part here."""
    from . import meshes as M
    from .prepare import STEPS_AHEAD, prepare_mesh

    ready = {}
    for k, p in enumerate(obj.parts):
        if k in frozen or p.mesh is None or not len(p.mesh.faces):
            continue
        ready[k] = (prepared or {}).get(k) or prepare_mesh(p.mesh, floaters,
                                                            STEPS_AHEAD if budget > 0 else 0)
    tol = 0.0
    # simplify_to_budget's steps: each taken while the object is over budget
    level, ahead = -1, min((len(r.steps) for r in ready.values()), default=0)
    while budget > 0 and sum(r.faces(level) for r in ready.values()) > budget:
        if level + 1 >= ahead:
            break
        level += 1
        tol = M.SIMPLIFY_STEPS[level]
    mans = {k: r.manifold(level) for k, r in ready.items()}
    if budget > 0 and level + 1 == ahead and level + 1 < len(M.SIMPLIFY_STEPS):
        mans, more = M.simplify_to_budget(mans, budget, M.SIMPLIFY_STEPS[level + 1:],
                                          fine=M.FINE_STEPS if level < 0 else ())
        tol = more or tol
        if level >= 0 and sum(m.num_tri() for m in mans.values()) > budget:
            # the steps made ahead kept parts in place at the budget's cost: every step
            # anew without that check (with it, they would end where these did)
            mans, tol = M.simplify_to_budget({k: r.manifold() for k, r in ready.items()},
                                             budget, check=False)
    if floaters and tol:
        mans = {k: M.drop_floaters(m) for k, m in mans.items()}   # simplifying can split
    return mans, tol


def _back_within_budget(mans: dict, budget: int, tol: float, floaters: bool) -> tuple[dict, float]:
    """``mans`` within ``budget`` faces again after carving and runners added faces beyond the
    15 % headroom (a screw cap's sweep cut into a ribbed bottle body adds ~5k): the
    simplification steps coarser than ``tol``, the one already used. -> the meshes and the
    last tolerance used (0: nothing to do)."""
    from . import meshes as M
    if budget <= 0 or sum(m.num_tri() for m in mans.values()) <= budget:
        return mans, 0.0
    steps = tuple(t for t in M.SIMPLIFY_STEPS if t > tol)
    out, used = M.simplify_to_budget(mans, budget, steps, fine=() if tol else M.FINE_STEPS)
    if floaters and used:
        out = {k: M.drop_floaters(m) for k, m in out.items()}   # simplifying can split
    return out, used


__all__ = ["RefineConfig", "simplify_meshes", "LayoutConfig", "arrange_stated",
           "door_beside_controls", "free_edge_handles", "knob_handles", "match_handles",
           "place_stated_sides", "refine_layout",
           "refine_meshes", "face_of", "safe_keypads"]
