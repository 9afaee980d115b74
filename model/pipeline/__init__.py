"""Text/image → articulated object → URDF: the end-to-end pipeline."""
from model.pipeline.api import (ExportResult, GeneratedObject, GenerationConfig,
                                GenerationError)

__all__ = ["ExportResult", "GeneratedObject", "GenerationConfig", "GenerationError"]
