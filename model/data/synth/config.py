"""Generator version, configuration and the rejection error of the procedural generator."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

log = logging.getLogger(__name__)

CATEGORY_WEIGHTS: dict[str, float] = {"StorageFurniture": 0.34, "Safe": 0.12, "Oven": 0.14,
                                      "WashingMachine": 0.14, "Bottle": 0.13, "USB": 0.13}
# synth-2: strict overlap test (≤ 1 mm³ and ≤ 0.2 mm thick); synth-3: legs and top overhangs on
# storage furniture, shaker (recessed-panel) doors, side-hinged oven doors; synth-4: every
# object also passes the geometric checks of the sim-ready audit (model.export.simready:
# interpenetration over the per-joint sweeps, hinges, drawer axes, mesh health) or is redrawn;
# synth-5: objects of at most three parts (bottles, USB sticks) also pass the audit's MuJoCo
# check (a swivel cap resting on the floor could spin its free stick around); synth-6: so do
# objects with a door or lid on a horizontal hinge (a drop-down oven door with its tray
# pulled out could walk the free base 4 cm); synth-7: a storage band of drawers 45 cm or
# taller is split into rows, and no drawer front is taller than 1.2 x its width; synth-8: bottle
# bodies are solid with an open mouth (the neck bore) instead of a 1.5-3 mm hollow shell.
GENERATOR_VERSION = "synth-8"


@dataclass
class SynthConfig:
    seed: int = 0
    categories: dict[str, float] = field(default_factory=lambda: dict(CATEGORY_WEIGHTS))
    states: int = 10                 # openness states of the collision check
    max_shrinks: int = 4             # joint-range shrink rounds before redrawing an object
    max_redraws: int = 30
    attach_distance: float = 0.004  # a moving part must stay within this of its parent (m)
    collision_abs_tol: float = 1e-9  # m³ (1 mm³) of intersection tolerated between two parts...
    collision_depth_tol: float = 2e-4  # ... and if its mean thickness 2V/A is below this (m)
    audit: bool = True               # redraw objects the audit's geometric checks fail (synth-4)
    audit_physics: bool = False      # ... and its MuJoCo check for every draw (slow: export)
    audit_physics_parts: int = 3     # ... objects with at most this many parts always get the
                                     # MuJoCo check (about 0.5 s each; synth-5); 0: none
    audit_physics_swing: bool = True  # ... and objects with a door or lid hinged about a
                                     # horizontal axis: its weight swings fore and aft
                                     # (about 1 s each, a third of the objects; synth-6)


class GenerationRejected(RuntimeError):
    """No valid object could be drawn for a seed (should not happen in practice)."""
