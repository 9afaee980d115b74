"""Old home of the prompt parser, kept one release: it lives in ``model.data.prompt_parse``
(generation reads prompts with it too, below the metrics layer)."""
from model.data.expected_structure import (SPATIAL_KEYS, SPATIAL_KINDS,  # noqa: F401
                                           ExpectedStructure, read_annotated_prompts)
from model.data.prompt_parse import parse_prompt  # noqa: F401
