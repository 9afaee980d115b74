"""Requests a Generator refuses before any work: a bad prompt or a bad GenerationConfig
(each with a GenerationError that names what is wrong)."""
from __future__ import annotations

from model.pipeline.api import GenerationConfig, GenerationError

MAX_PROMPT_CHARS = 2000


def check_prompt(text) -> str:
    """Return the cleaned prompt or raise GenerationError saying what is wrong with it."""
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as e:
            raise GenerationError(f"prompt is not valid UTF-8 ({e.reason} at byte {e.start})") from None
    if not isinstance(text, str):
        raise GenerationError(f"prompt must be a string, got {type(text).__name__}")
    clean = " ".join(text.split())
    if not clean:
        raise GenerationError("prompt is empty")
    if len(clean) > MAX_PROMPT_CHARS:
        raise GenerationError(f"prompt has {len(clean)} characters; the limit is {MAX_PROMPT_CHARS}")
    return clean


def validate_config(cfg: GenerationConfig) -> None:
    """Raise GenerationError naming the first bad field of a GenerationConfig."""
    checks = [
        (8 <= cfg.resolution <= 256, f"resolution must be in [8, 256], got {cfg.resolution}"),
        (1 <= cfg.steps <= 1000, f"steps must be in [1, 1000], got {cfg.steps}"),
        (cfg.guidance >= 0, f"guidance must be >= 0, got {cfg.guidance}"),
        (cfg.temperature > 0, f"temperature must be > 0, got {cfg.temperature}"),
        (0 <= cfg.structure_temperature <= 10,
         f"structure_temperature must be in [0, 10], got {cfg.structure_temperature}"),
        (cfg.layout_sampling in ("never", "structure", "always"),
         f"layout_sampling must be never|structure|always, got {cfg.layout_sampling!r}"),
        (set(cfg.follow_plan) <= {"text", "image"},
         f"follow_plan lists modalities 'text' / 'image', got {cfg.follow_plan!r}"),
        (cfg.geometry in ("generate", "retrieve"), f"geometry must be generate|retrieve, got {cfg.geometry!r}"),
        (cfg.mesh_format in ("obj", "stl", "glb"), f"mesh_format must be obj|stl|glb, got {cfg.mesh_format!r}"),
        (cfg.collision in ("auto", "cells", "vhacd", "hull", "none"),
         f"collision must be auto|cells|vhacd|hull|none, got {cfg.collision!r}"),
        (cfg.device == "cpu", f"device {cfg.device!r} is not supported; this build runs on the CPU"),
        (1 <= cfg.threads <= 64, f"threads must be in [1, 64], got {cfg.threads}"),
        (-1 <= cfg.mesh_workers <= 64,
         f"mesh_workers must be -1 (one per core beyond the first) or 0..64, got {cfg.mesh_workers}"),
        (1 <= cfg.token_threads <= 64, f"token_threads must be in [1, 64], got {cfg.token_threads}"),
        (1 <= cfg.max_nodes <= 64, f"max_nodes must be in [1, 64], got {cfg.max_nodes}"),
        (cfg.face_budget >= 0, f"face_budget must be >= 0, got {cfg.face_budget}"),
        (cfg.mesh_cell >= 0, f"mesh_cell must be >= 0, got {cfg.mesh_cell}"),
        (0 <= cfg.max_depth <= 16, f"max_depth must be in [0, 16], got {cfg.max_depth}"),
        (0 <= cfg.max_children <= 64, f"max_children must be in [0, 64], got {cfg.max_children}"),
    ]
    for ok, msg in checks:
        if not ok:
            raise GenerationError(msg)
