"""Procedural articulated objects in the paper's six categories (DESIGN §3.1).

Every part is a closed 2-manifold built from exact manifold3d booleans of boxes and
cylinders: bodies are hollow carcasses with real openings, drawers are open boxes with a
front, doors / lids / caps fit their openings with a clearance gap. Handles are separate
fixed child parts of the drawer / door / lid they belong to (the PartNet-Mobility convention,
where handles are their own segmented parts).

Frames (DESIGN §2): metres, x forward, y left, z up; base on z = 0, centred on the z axis,
front facing +x. Side words ("left", "right") are as seen by a viewer standing in front of
the object, who looks towards -x: the viewer's left is -y, right is +y.

Hinge convention: a door / lid turns about the outer edge of its outer face, and its joint
axis is chosen so that positive angles open it; every joint's rest value is 0 and its range
starts at 0 (closed) and ends fully open.

Every object is verified with :func:`check_object` (exact intersection volumes of all part
pairs at 10 openness states, and the distance of every moving part to its parent); the
generator shrinks offending joint ranges a few times and otherwise draws a new object.

    obj = generate_object(seed=0, index=12)                  # one object
    for obj in generate_objects(n=100, seed=0): ...           # deterministic stream
"""
from .builder import HANDLE_STYLES
from .config import CATEGORY_WEIGHTS, GENERATOR_VERSION, GenerationRejected, SynthConfig
from .dataset import synthesize_dataset
from .generate import (
           GENERATORS,
           generate_object,
           generate_objects,
           object_rng,
           pick_category,
)
from .verify import CheckReport, check_object

__all__ = ["CATEGORY_WEIGHTS", "GENERATOR_VERSION", "GENERATORS", "HANDLE_STYLES", "CheckReport",
           "GenerationRejected", "SynthConfig", "check_object", "generate_object",
           "generate_objects", "object_rng", "pick_category", "synthesize_dataset"]
