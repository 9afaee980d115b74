"""Generation backends of the node, chosen by the ``backend`` parameter.

* ``model``   — the real pipeline: ``model.pipeline.generator.Generator`` loaded once from the
  node's parameters (``NodeSettings.generation_config()``).
* ``example`` — no model: every request exports the built-in example object of
  ``model.core.example`` (the bottle when the prompt mentions a bottle, else the cabinet).
  For plumbing demos and fast tests of the node only; it ignores seeds and images' contents,
  and exports with one convex hull per part as collision and no preview (speed). A request
  with a ``structure`` gets the example object that has exactly those parts, or an error
  naming what the two examples have.

Heavy imports (torch, trimesh, the model) happen inside ``load_backend``, which the node runs
on its loading thread, so the node is up and answering within a second.
"""
from __future__ import annotations

import logging
import time
from typing import Optional

import numpy as np

from artformer_ros.params import NodeSettings

log = logging.getLogger("artformer_ros.backends")


class ModelBackend:
    """Adapter around ``Generator`` (generate + export)."""
    name = "model"

    def __init__(self, generator, settings: NodeSettings):
        self.generator = generator
        self._settings = settings   # live: preview and mesh_uri are read per request

    def generate(self, *, text: Optional[str], image: Optional[np.ndarray], seed: int,
                 samples: int, structure: Optional[dict] = None,
                 size: Optional[dict] = None) -> list:
        if image is not None:
            return self.generator.generate(image=image, seed=seed, samples=samples,
                                           structure=structure, size=size)
        return self.generator.generate(text=text, seed=seed, samples=samples,
                                       structure=structure, size=size)

    def export(self, result, out_dir: str):
        # the node draws preview.png after publishing (GenerationService._write_previews)
        return self.generator.export(result, out_dir, preview=False,
                                     mesh_uri=self._settings.mesh_uri)

    def preview(self, result, exported, interrupt=None):
        return self.generator.write_preview(result, exported, interrupt=interrupt)


class ExampleBackend:
    """Exports ``model.core.example`` objects; no learning involved (see module docstring)."""
    name = "example"

    def __init__(self, settings: NodeSettings):
        from model.core import example   # imports trimesh lazily inside its builders

        self._settings = settings
        self._builders = {"cabinet": example.example_cabinet, "bottle": example.example_bottle}
        self._cache: dict = {}

    def _object(self, key: str):
        if key not in self._cache:   # building uses exact booleans: do it once per kind
            self._cache[key] = self._builders[key]()
        return self._cache[key].copy()

    def generate(self, *, text: Optional[str], image: Optional[np.ndarray], seed: int,
                 samples: int, structure: Optional[dict] = None,
                 size: Optional[dict] = None) -> list:
        from model.core.example import structure_mismatch
        from model.pipeline.api import GeneratedObject, GenerationError

        if size is not None:
            raise GenerationError("the example backend (no model) only has its built-in "
                                  "objects at their own size; run the node with "
                                  "backend:=model for a size")

        key = "bottle" if text and "bottle" in text.lower() else "cabinet"
        if structure is not None:
            why = {k: structure_mismatch(self._object(k), structure) for k in self._builders}
            fits = [k for k in (key, *self._builders) if why[k] is None]
            if not fits:
                raise GenerationError(
                    "the example backend (no model) only has its built-in objects and neither "
                    "has this structure: " + "; ".join(f"the {k}: {m}" for k, m in why.items())
                    + "; run the node with backend:=model for other structures")
            key = fits[0]
        t0 = time.perf_counter()
        objs = [self._object(key) for _ in range(samples)]
        dt = time.perf_counter() - t0
        prompt = text if text is not None else "<image>"
        return [GeneratedObject(obj=o, prompt=prompt, seed=seed, timings={"example": dt})
                for o in objs]

    def export(self, result, out_dir: str):
        from model.export import CollisionConfig, export_object

        # plumbing speed: one convex hull per part and no preview picture
        return export_object(result.obj, out_dir, mesh_format=self._settings.mesh_format,
                             preview=False, collision=CollisionConfig(method="hull"),
                             mesh_uri=self._settings.mesh_uri,
                             provenance={"prompt": result.prompt, "seed": result.seed,
                                         "backend": "example (built-in object, no model)"})


def load_backend(settings: NodeSettings):
    """Build the backend named by ``settings.backend`` (slow for 'model': loads weights)."""
    if settings.backend == "example":
        backend = ExampleBackend(settings)
        backend._object("cabinet")   # warm: the first request should not pay for the booleans
        return backend
    if settings.backend == "model":
        import torch

        torch.set_num_threads(settings.threads)
        from model.core.runtime import settle_after_load
        from model.pipeline.generator import Generator

        backend = ModelBackend(Generator.load(settings.generation_config()), settings)
        settle_after_load()          # cheap per-request garbage collection from now on
        return backend
    raise ValueError(f"unknown backend {settings.backend!r}")
