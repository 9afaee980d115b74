"""Core object model: parts, joints, articulated objects, kinematics, tokens."""
from .objects import (TOKEN_DIM, ArticulatedObject, Joint, JointType, ObjectValidationError,
                      Part, rotation_matrix)

__all__ = ["TOKEN_DIM", "ArticulatedObject", "Joint", "JointType", "ObjectValidationError",
           "Part", "rotation_matrix"]
