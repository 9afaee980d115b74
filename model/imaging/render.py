"""Training renders of articulated objects: viewpoints, openness, lighting, colours (issue 8).

``sample_views(obj_id, labels, k, seed)`` draws ``k`` deterministic view specs per object (a
function of the seed and the object id only, so renders are reproducible and resumable);
``render_view`` poses the object at the view's openness and rasterises it at 224×224 with the
project's offscreen renderer (``model.export.render.render_views``, numpy z-buffer, 2×
supersampling).

View distribution (front = +x, z up):
* openness cycles 0, 1, 0.5, then uniform in [0, 1];
* azimuth uniform in ±65° around the front, elevation 5°–40°, the object's posed bounding
  sphere filling 80–100 % of the frame, field of view 30°–45°;
* a key light within ±70° of the camera azimuth, elevation 15°–80°, ambient 0.25–0.5,
  diffuse 0.55–0.85, specular 0–0.25;
* part colours drawn per view (random hue / saturation / value per part, seeded);
* a uniform background: light (55 %), mid grey (30 %) or dark (15 %), slightly tinted.
"""
from __future__ import annotations

import zlib
from dataclasses import asdict, dataclass

import numpy as np

from model.core import ArticulatedObject

RENDER_SIZE = 224


@dataclass
class ViewSpec:
    openness: float
    azimuth: float           # degrees, 0 = looking at the front (+x) face
    elevation: float         # degrees above the horizon
    fill: float              # share of the frame the bounding sphere spans
    fov: float               # degrees
    light_azimuth: float
    light_elevation: float
    ambient: float
    diffuse: float
    specular: float
    colour_seed: int         # seeds the per-part colours of the renderer
    background: tuple        # RGB in [0, 1]

    def to_json(self) -> dict:
        return asdict(self)


def _background(rng: np.random.Generator) -> tuple:
    u = rng.random()
    if u < 0.55:
        base = rng.uniform(0.78, 1.0)
    elif u < 0.85:
        base = rng.uniform(0.45, 0.78)
    else:
        base = rng.uniform(0.05, 0.3)
    tint = rng.uniform(-0.06, 0.06, 3)
    return tuple(round(float(c), 4) for c in np.clip(base + tint, 0, 1))


def object_rng(obj_id: str, seed: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), zlib.crc32(obj_id.encode())])


def sample_views(obj_id: str, labels: list[str], k: int, seed: int = 0) -> list[ViewSpec]:
    """``k`` view specs for one object; deterministic in (obj_id, seed)."""
    rng = object_rng(obj_id, seed)
    fixed = (0.0, 1.0, 0.5)
    views = []
    for i in range(k):
        r = fixed[i] if i < len(fixed) else float(rng.uniform(0, 1))
        az = float(rng.uniform(-65, 65))
        views.append(ViewSpec(
            openness=round(r, 4), azimuth=round(az, 3), elevation=round(float(rng.uniform(5, 40)), 3),
            fill=round(float(rng.uniform(0.8, 1.0)), 4), fov=round(float(rng.uniform(30, 45)), 3),
            light_azimuth=round(az + float(rng.uniform(-70, 70)), 3),
            light_elevation=round(float(rng.uniform(15, 80)), 3),
            ambient=round(float(rng.uniform(0.25, 0.5)), 4),
            diffuse=round(float(rng.uniform(0.55, 0.85)), 4),
            specular=round(float(rng.uniform(0.0, 0.25)), 4),
            colour_seed=int(rng.integers(0, 2**31 - 1)), background=_background(rng)))
    return views


def render_options(view: ViewSpec):
    """The renderer's options for one view."""
    from model.export.render import RenderOptions
    return RenderOptions(azimuth=view.azimuth, elevation=view.elevation, fov=view.fov,
                         margin=1.0 / view.fill, light_azimuth=view.light_azimuth,
                         light_elevation=view.light_elevation, ambient=view.ambient,
                         diffuse=view.diffuse, specular=view.specular,
                         background=tuple(float(c) for c in view.background),
                         colour_mode="random", supersample=2)


def render_view(obj: ArticulatedObject, view: ViewSpec, size: int = RENDER_SIZE) -> np.ndarray:
    """One view → (size, size, 3) uint8."""
    from model.export.render import render_views
    if not any(p.mesh is not None and len(p.mesh.faces) for p in obj.parts):
        raise ValueError(f"object {obj.name!r} has no part meshes to render")
    return render_views(obj, (float(view.openness),), size, options=render_options(view),
                        seed=int(view.colour_seed))[0]


def part_ids(obj: ArticulatedObject, view: ViewSpec, size: int = RENDER_SIZE) -> np.ndarray:
    """The part seen at every pixel of ``view`` (one z-buffer sample per pixel, the camera of
    ``render_view``): (size, size) int, -1 = background."""
    from model.export.render import render_part_ids
    return render_part_ids(obj, float(view.openness), size, options=render_options(view))


def part_pixels(obj: ArticulatedObject, view: ViewSpec, size: int = RENDER_SIZE) -> np.ndarray:
    """Visible pixels of every part of ``obj`` in ``view`` at ``size``:
    (len(obj.parts),) int; 0 = hidden."""
    ids = part_ids(obj, view, size)
    return np.bincount(ids[ids >= 0].ravel(), minlength=len(obj.parts))[:len(obj.parts)]
