"""Text/image → articulated object → URDF: the end-to-end pipeline."""
from model.pipeline.api import (ExportResult, GeneratedObject, GenerationConfig,
                                GenerationError)

__all__ = ["ExportResult", "GeneratedObject", "GenerationConfig", "GenerationError"]


def __getattr__(name):
    if name in ("Generator", "default_generator", "generate_to_folder", "find_checkpoints"):
        from model.pipeline import generator
        return getattr(generator, name)
    raise AttributeError(name)
