"""artformer core: articulated-object model, data, networks, export, metrics.

Plain Python (torch / numpy / trimesh); never imports rclpy. Heavy submodules load lazily.
"""
from model.core import (TOKEN_DIM, ArticulatedObject, Joint, JointType, ObjectValidationError,
                        Part)
from model.core.version import __version__

__all__ = ["TOKEN_DIM", "ArticulatedObject", "Joint", "JointType", "ObjectValidationError",
           "Part", "generate", "__version__"]


def generate(text=None, *, image=None, seed=0, samples=1, structure=None, **kwargs):
    """Generate articulated objects from a text (or an image) with the shipped model.

    ``structure`` forces the parts, e.g. ``{"drawer": 3, "door": {"count": 1, "hinge":
    "left"}}`` (labels, counts, joint types, hinge sides; docs/articulation.md); ``size=
    {"width": 0.6}`` gives the body its dimensions in metres (docs/structure.md). Thin
    convenience wrapper over ``model.pipeline.Generator`` (loaded once, cached).
    """
    from model.pipeline import default_generator
    return default_generator().generate(text, image=image, seed=seed, samples=samples,
                                        structure=structure, **kwargs)
