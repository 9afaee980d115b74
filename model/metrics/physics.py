"""The audit's MuJoCo check moved to model.export.physics (below the data layer, whose
procedural generator gates its objects with the sim-ready verdict); importable from here too."""
from model.export.physics import (FIXED_CLEARANCE, FLOOR, PhysicsConfig,  # noqa: F401
                                  PhysicsResult, PhysicsRun, physics_check)

__all__ = ["PhysicsConfig", "PhysicsResult", "PhysicsRun", "physics_check"]
