"""The node's parameters: one table (name, default, description, range, read-only), the
validation of values, and the conversion into the core ``GenerationConfig`` (once, at start).

Kept apart from the node so that validation is tested without rclpy; the node turns each
``ParamSpec`` into a ``ParameterDescriptor`` with the same description and range.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Optional

BACKENDS = ("model", "example")
MESH_FORMATS = ("obj", "stl", "glb")


@dataclass(frozen=True)
class ParamSpec:
    name: str
    default: Any
    description: str
    read_only: bool = False
    int_range: Optional[tuple[int, int]] = None
    float_range: Optional[tuple[float, float]] = None
    choices: Optional[tuple[str, ...]] = None


PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("backend", "model",
              "'model': the generation pipeline (model.pipeline); 'example': exports the built-in "
              "example object for every request (plumbing demos, no model)",
              read_only=True, choices=BACKENDS),
    ParamSpec("checkpoint", "",
              "folder of the stage checkpoints; empty = the shipped model", read_only=True),
    ParamSpec("output_dir", "~/.ros/artformer_ros/output",
              "one folder per request is written here (URDF, meshes, metadata)", read_only=True),
    ParamSpec("resolution", 64, "marching-cubes cells per side of the largest parts (smaller parts "
              "get 16 or 32 when their cells stay under GenerationConfig.mesh_cell)",
              read_only=True, int_range=(8, 256)),
    ParamSpec("steps", 50, "DDIM sampling steps of the shape prior",
              read_only=True, int_range=(1, 1000)),
    ParamSpec("guidance", 1.0, "classifier-free guidance scale of the shape prior (1 = off)",
              read_only=True, float_range=(0.0, 20.0)),
    ParamSpec("mesh_format", "obj", "mesh file format of the exported parts",
              read_only=True, choices=MESH_FORMATS),
    ParamSpec("preview", True, "write preview.png (openness 0 / 0.5 / 1) beside each URDF; "
              "false saves its rendering time (the example backend never writes one)"),
    ParamSpec("mesh_uri", "file", "mesh references in the URDF: 'file' (absolute file:// "
              "paths) or a 'package://<pkg>/<path>' prefix that replaces the output folder"),
    ParamSpec("refine", True, "layout + mesh refinement of each generated object before "
              "export (GenerationConfig.refine)", read_only=True),
    ParamSpec("prompt_structure", True, "hold a text request's decoding to the part counts, "
              "joint types and hinge sides its text states outright (GenerationConfig."
              "prompt_structure); false = the network's own reading", read_only=True),
    ParamSpec("hold_plan", True, "decode a text again with the counts its START plan head "
              "read held as a structure (GenerationConfig.hold_plan)", read_only=True),
    ParamSpec("sibling_room", True, "redraw a part's candidate box that covers a sibling decoded "
              "before it (GenerationConfig.sibling_room)", read_only=True),
    ParamSpec("frame_images", True, "crop an image request with a plain background around its "
              "object first, as the training renders frame it", read_only=True),
    ParamSpec("device", "cpu", "torch device; this build runs on the CPU only ('cpu')",
              read_only=True, choices=("cpu",)),
    ParamSpec("threads", 2, "torch CPU threads used by generation",
              read_only=True, int_range=(1, 64)),
    ParamSpec("mesh_workers", -1, "helper processes that finish the parts' meshes beside the "
              "node (GenerationConfig.mesh_workers); -1 = one per core beyond the first, at "
              "most 3; 0 = none", read_only=True, int_range=(-1, 64)),
    ParamSpec("seed", -1, "seed of requests that do not give one; -1 = a fresh random seed "
              "per request", int_range=(-1, 2**31 - 1)),
    ParamSpec("samples", 1, "objects generated per request (the first is published on "
              "robot_description)", int_range=(1, 16)),
    ParamSpec("queue_size", 4, "requests waiting behind the running one; when full a request "
              "is answered 'rejected'", int_range=(1, 1000)),
    ParamSpec("retention", 20, "output folders kept under output_dir (oldest deleted first)",
              int_range=(1, 100000)),
    ParamSpec("max_text_length", 1000, "longest accepted text request (characters)",
              int_range=(1, 100000)),
    ParamSpec("max_image_pixels", 4096 * 4096, "largest accepted image request (height*width)",
              int_range=(1, 100_000_000)),
    ParamSpec("shutdown_timeout", 10.0, "seconds a SIGINT/SIGTERM waits for a running "
              "generation before abandoning it", float_range=(0.0, 3600.0)),
    ParamSpec("frame_id", "world", "fixed frame of the markers (the object's root link sits "
              "at its origin); set RViz's Fixed Frame to it"),
    ParamSpec("openness", 0.0, "pose of markers and joint_states: every joint at "
              "lower + openness * (upper - lower)", float_range=(0.0, 1.0)),
    ParamSpec("animate", False, "sweep the openness 0 -> 1 -> 0 over and over (markers and "
              "joint_states follow); false = hold `openness`"),
    ParamSpec("animate_period", 4.0, "seconds of one back-and-forth sweep of `animate`",
              float_range=(0.5, 3600.0)),
    ParamSpec("publish_rate", 10.0, "joint_states messages per second (and marker updates "
              "while animating)", float_range=(0.1, 100.0)),
)

SPECS = {p.name: p for p in PARAMS}


def _type_ok(default: Any, value: Any) -> bool:
    if isinstance(default, bool) or isinstance(value, bool):
        return isinstance(default, bool) and isinstance(value, bool)
    if isinstance(default, float):
        return isinstance(value, (int, float))   # an integer is a fine float
    return isinstance(value, type(default))


def validate(name: str, value: Any) -> Optional[str]:
    """Reason why ``value`` is not acceptable for parameter ``name`` (None if it is)."""
    spec = SPECS.get(name)
    if spec is None:
        return None  # not ours (e.g. use_sim_time)
    if not _type_ok(spec.default, value):
        return f"{name} must be of type {type(spec.default).__name__}, got {value!r}"
    if spec.int_range and not spec.int_range[0] <= value <= spec.int_range[1]:
        return f"{name} must be in [{spec.int_range[0]}, {spec.int_range[1]}], got {value}"
    if spec.float_range and not spec.float_range[0] <= value <= spec.float_range[1]:
        return f"{name} must be in [{spec.float_range[0]}, {spec.float_range[1]}], got {value}"
    if spec.choices and value not in spec.choices:
        return f"{name} must be one of {list(spec.choices)}, got {value!r}"
    if name == "mesh_uri" and value != "file" and not (
            value.startswith("package://") and len(value.rstrip("/")) > len("package://")):
        return f"mesh_uri must be 'file' or start with 'package://<package>', got {value!r}"
    if name == "output_dir" and not str(value).strip():
        return "output_dir must not be empty"
    if name == "frame_id" and (not value or value != value.strip() or value.startswith("/")
                               or not value.isprintable()):
        return f"frame_id must be a non-empty frame name without '/' prefix, got {value!r}"
    return None


@dataclass
class NodeSettings:
    """The parameter values the node and its worker read (live ones change at run time)."""
    backend: str = "model"
    checkpoint: str = ""
    output_dir: str = "~/.ros/artformer_ros/output"
    resolution: int = 64
    steps: int = 50
    guidance: float = 1.0
    mesh_format: str = "obj"
    preview: bool = True
    mesh_uri: str = "file"
    refine: bool = True
    prompt_structure: bool = True
    sibling_room: bool = True
    hold_plan: bool = True
    frame_images: bool = True
    device: str = "cpu"
    threads: int = 2
    mesh_workers: int = -1
    seed: int = -1
    samples: int = 1
    queue_size: int = 4
    retention: int = 20
    max_text_length: int = 1000
    max_image_pixels: int = 4096 * 4096
    shutdown_timeout: float = 10.0
    frame_id: str = "world"
    openness: float = 0.0
    animate: bool = False
    animate_period: float = 4.0
    publish_rate: float = 10.0

    @classmethod
    def from_values(cls, values: dict[str, Any]) -> "NodeSettings":
        for name, value in values.items():
            reason = validate(name, value)
            if reason:
                raise ValueError(reason)
        known = {k: (float(v) if isinstance(SPECS[k].default, float) else v)
                 for k, v in values.items() if k in SPECS}
        return cls(**known)

    @property
    def output_path(self) -> str:
        return os.path.abspath(os.path.expanduser(self.output_dir))

    def generation_config(self):
        """The core config (converted once, when the model is loaded)."""
        from model.pipeline.api import GenerationConfig

        return GenerationConfig(checkpoint=self.checkpoint or None, resolution=self.resolution,
                                steps=self.steps, guidance=self.guidance,
                                mesh_format=self.mesh_format, device=self.device,
                                threads=self.threads, mesh_workers=self.mesh_workers,
                                frame_images=self.frame_images,
                                refine=self.refine, prompt_structure=self.prompt_structure,
                                sibling_room=self.sibling_room, hold_plan=self.hold_plan)
