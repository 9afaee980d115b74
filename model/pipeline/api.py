"""Public generation API (contract shared by the CLI, the ROS node, eval and bench).

    gen = Generator.load(GenerationConfig(checkpoint=None))   # None = shipped model
    results = gen.generate("a cabinet with two drawers", seed=3, samples=1)
    exported = gen.export(results[0], "out/cabinet")            # URDF + meshes + preview
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from model.core import ArticulatedObject


class GenerationError(RuntimeError):
    """A request could not produce a valid object; the message says why."""


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
    follow_plan: tuple = ("text",)     # modalities whose END decisions are held to a plan:
                                       # text to the START plan head (decode.py), an image to
                                       # its model's count head if it has one (counts.py).
                                       # Chosen on val: it helps text (0.8125 -> 0.8425), not
                                       # images (START head 0.35 -> 0.335; count head
                                       # 0.425 -> 0.4175), so images decode freely
    frame_images: bool = True          # crop a photo with a plain background around its
                                       # object, as the training renders frame it
                                       # (model.encoders.framing; docs/imaging.md)
    geometry: str = "generate"         # generate | retrieve
    mesh_format: str = "obj"           # obj | stl | glb
    collision: str = "auto"            # auto | cells | vhacd | hull | none (model.export.collision)
    device: str = "cpu"
    threads: int = 2                   # torch threads for SDF meshing and image encoding
    token_threads: int = 1             # ... for the token-sized networks (text, decoding, DDIM);
                                       # one thread is ~3x faster there on 2 cores (core.runtime)
    max_nodes: int = 32
    max_depth: int = 4
    max_children: int = 16
    refine: bool = True                # layout + mesh refinement before export (model.refine)
    face_budget: int = 30000           # visual faces per object after refinement (0: all)


@dataclass
class GeneratedObject:
    obj: ArticulatedObject
    prompt: str
    seed: int
    timings: dict[str, float] = field(default_factory=dict)   # stage -> seconds


@dataclass
class ExportResult:
    out_dir: str
    urdf_path: str
    mesh_paths: dict[str, str]          # link name -> mesh file
    metadata_path: str
    preview_path: Optional[str] = None
