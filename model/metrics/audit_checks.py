"""The audit's measurements moved to model.export.audit_checks (below the data layer, whose
procedural generator gates its objects with the sim-ready verdict); importable from here too."""
from model.export.audit_checks import (HINGED_LABELS, SLIDING_LABELS, _manifolds,  # noqa: F401
                                       attachment_gaps, axis_angle_deg, hinge_offset,
                                       mesh_health, opening_normal, overlaps, slide_angle_deg)
