"""Public generation API (contract shared by the CLI, the ROS node, eval and bench).

    gen = Generator.load(GenerationConfig(checkpoint=None))   # None = shipped model
    results = gen.generate("a cabinet with two drawers", seed=3, samples=1)
    exported = gen.export(results[0], "out/cabinet")            # URDF + meshes + preview
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from model.core import ArticulatedObject
from model.core.structure import (AUTO, HINGE_SIDES, GenerationError,  # noqa: F401  (this API)
                                   PartRequest, StructureSpec, hinge_side, parse_size,
                                   parse_structure)
from model.export.urdf import ExportResult  # noqa: F401  (part of this API)


@dataclass
class GenerationConfig:
    checkpoint: Optional[str] = None   # folder of the three stage checkpoints; None = shipped
    resolution: int = 64               # marching-cubes cells per side of the largest parts
    mesh_cell: float = 0.008           # m: smaller parts get 16 or 32 cells when that
                                       # keeps their cells under this (0: all at resolution)
    steps: int = 50                    # DDIM steps of the shape prior
    guidance: float = 1.0              # classifier-free guidance scale (1 = off)
    temperature: float = 0.5           # Gumbel-softmax temperature at generation
    structure_temperature: float = 0.3 # END / joint-type sampling temperature of the tree
                                       # decoding (0 = greedy; 1 = the paper's plain sampling)
    sample_choices: bool = False       # the seed also draws each part's label and the plan's
                                       # counts from their heads' distributions at that
                                       # temperature (decode.py). Off: on the test split it
                                       # lowers alignment (0.815 -> 0.805) and barely varies
                                       # the layouts (docs/structure.md, "Diversity")
    layout_sampling: str = "structure" # never | structure | always: the seed picks dropout
                                       # masks for the parts' boxes and joints (Monte-Carlo
                                       # dropout, decode.py), so seeds give different layouts
                                       # of one structure; "structure" = only when a structure
                                       # is forced (free text: it lowers alignment 0.815 ->
                                       # 0.79; docs/structure.md, "Diversity")
    sibling_room: bool = True          # a new part's candidate box that covers a sibling
                                       # decoded before it is drawn again among the network's
                                       # other candidates (decode.py, docs/articulation.md)
    prompt_structure: bool = True      # hold text decoding to the part counts, joint types
                                       # and hinge sides the prompt states outright, read by
                                       # the rule-based prompt parser (prompt_structure.py;
                                       # docs/structure.md); parts it leaves open stay the
                                       # network's choice
    follow_plan: tuple = ("text",)     # modalities whose END decisions are held to a plan:
                                       # text to the START plan head (decode.py), an image to
                                       # its model's count head if it has one (counts.py).
                                       # Chosen on val: it helps text (0.8125 -> 0.8425), not
                                       # images (START head 0.35 -> 0.335; count head
                                       # 0.425 -> 0.4175), so images decode freely
    hold_plan: bool = True             # text: decoded again with the START plan head's
                                       # counts held as a structure (decode.py,
                                       # follow_plan="hold"; for stated counts, the reading
                                       # that fills the counts left open); chosen on val:
                                       # alignment 0.947 -> 0.964 (docs/articulation.md)
    frame_images: bool = True          # crop a photo with a plain background around its
                                       # object, as the training renders frame it
                                       # (model.encoders.framing; docs/imaging.md)
    geometry: str = "generate"         # generate | retrieve
    mesh_format: str = "obj"           # obj | stl | glb
    collision: str = "auto"            # auto | cells | vhacd | hull | none (model.export.collision)
    device: str = "cpu"
    threads: int = 2                   # torch threads for SDF meshing and image encoding
    mesh_workers: int = -1             # helper processes that finish parts (marching cubes,
                                       # manifolds, simplification) beside this one
                                       # (part_pool.py); -1: one per core beyond the first, at
                                       # most 3; 0: all in this process
    token_threads: int = 1             # ... for the token-sized networks (text, decoding, DDIM);
                                       # one thread is ~3x faster there on 2 cores (core.runtime)
    max_nodes: int = 32
    max_depth: int = 4
    max_children: int = 16
    refine: bool = True                # layout + mesh refinement before export (model.refine)
    instances: bool = True             # parts of one label and the same box (a stack's
                                       # drawers, their handles) share the first one's
                                       # decoded shape: meshed once, moved to each box
    face_budget: int = 30000           # visual faces per object, refined or raw (0: all)


@dataclass
class GeneratedObject:
    obj: ArticulatedObject
    prompt: str
    seed: int
    timings: dict[str, float] = field(default_factory=dict)   # stage -> seconds
