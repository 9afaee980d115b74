"""Training renders of articulated objects: viewpoints, openness, lighting, colours (issue 8).

``sample_views(obj_id, k, seed)`` draws ``k`` deterministic view specs per object (a function
of the seed and the object id only, so renders are reproducible and resumable); ``render_view``
poses the object at the view's openness and rasterises it (model.imaging.raster) at 224×224
with 2× supersampling.

View distribution (front = +x, z up):
* openness cycles 0, 1, 0.5, then uniform in [0, 1];
* azimuth uniform in ±65° around the front, elevation 5°–40°, the object's posed bounding
  sphere filling 80–100 % of the frame, field of view 30°–45°;
* a key light within ±70° of the camera azimuth, elevation 15°–80°, ambient 0.25–0.5;
* part colours: a body colour from a palette of materials (white, greys, black, woods,
  metal, pastel, saturated) with jitter; moving panels share it or take a second colour;
  small parts (handles, knobs, buttons, dials) are dark, metallic or contrasting;
* background: a uniform colour or a vertical gradient, light, mid or dark.
"""
from __future__ import annotations

import colorsys
import zlib
from dataclasses import asdict, dataclass

import numpy as np

from model.core import ArticulatedObject

from .raster import Camera, downsample, project, rasterise, shade_faces

RENDER_SIZE = 224

PALETTE = {   # name -> RGB in [0, 1]
    "white": (0.92, 0.92, 0.90), "light_grey": (0.72, 0.73, 0.74), "grey": (0.48, 0.49, 0.50),
    "dark_grey": (0.25, 0.26, 0.27), "black": (0.10, 0.10, 0.11), "oak": (0.72, 0.55, 0.35),
    "walnut": (0.42, 0.28, 0.18), "pine": (0.85, 0.72, 0.50), "steel": (0.66, 0.68, 0.70),
    "cream": (0.93, 0.88, 0.76), "red": (0.75, 0.15, 0.12), "blue": (0.18, 0.32, 0.65),
    "green": (0.25, 0.52, 0.30), "yellow": (0.90, 0.75, 0.20), "teal": (0.20, 0.55, 0.58),
    "pastel_blue": (0.65, 0.78, 0.90), "pastel_pink": (0.92, 0.72, 0.75),
}
SMALL_PARTS = ("handle", "knob", "button", "dial")
PANEL_PARTS = ("door", "drawer", "lid", "tray")


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
    colours: dict            # part label -> RGB (also "body", and "_default")
    background: tuple        # (top RGB, bottom RGB); equal for a uniform background

    def to_json(self) -> dict:
        return asdict(self)


def _jitter(rgb, rng, amount: float) -> tuple[float, float, float]:
    h, s, v = colorsys.rgb_to_hsv(*rgb)
    h = (h + rng.uniform(-0.03, 0.03)) % 1.0
    s = float(np.clip(s + rng.uniform(-amount, amount), 0, 1))
    v = float(np.clip(v * (1 + rng.uniform(-amount, amount)), 0.03, 1))
    return tuple(round(float(c), 4) for c in colorsys.hsv_to_rgb(h, s, v))


def _colours(labels: list[str], rng: np.random.Generator) -> dict:
    names = list(PALETTE)
    body = _jitter(PALETTE[names[rng.integers(len(names))]], rng, 0.15)
    second = _jitter(PALETTE[names[rng.integers(len(names))]], rng, 0.15)
    small_choices = ("black", "dark_grey", "steel", "white", "red", "walnut")
    small = _jitter(PALETTE[small_choices[rng.integers(len(small_choices))]], rng, 0.1)
    out = {"_default": body, "body": body}
    panel = body if rng.random() < 0.5 else second
    for lab in sorted(set(labels)):
        if lab in PANEL_PARTS:
            out[lab] = panel
        elif lab in SMALL_PARTS:
            out[lab] = small if rng.random() < 0.8 else body
        elif lab == "cap":
            out[lab] = second if rng.random() < 0.7 else body
        elif lab != "body":
            out[lab] = second
    return out


def _background(rng: np.random.Generator) -> tuple:
    u = rng.random()
    if u < 0.55:
        base = rng.uniform(0.78, 1.0)
    elif u < 0.85:
        base = rng.uniform(0.45, 0.78)
    else:
        base = rng.uniform(0.05, 0.3)
    tint = rng.uniform(-0.06, 0.06, 3)
    top = np.clip(base + tint, 0, 1)
    if rng.random() < 0.4:
        bottom = np.clip(top * rng.uniform(0.7, 1.15), 0, 1)
    else:
        bottom = top
    return (tuple(round(float(c), 4) for c in top), tuple(round(float(c), 4) for c in bottom))


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
            colours=_colours(labels, rng), background=_background(rng)))
    return views


def _direction(az_deg: float, el_deg: float) -> np.ndarray:
    a, e = np.radians(az_deg), np.radians(el_deg)
    return np.array([np.cos(a) * np.cos(e), np.sin(a) * np.cos(e), np.sin(e)])


def scene_arrays(obj: ArticulatedObject, openness: float, colours: dict
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Posed meshes of all parts → (vertices (V, 3), faces (F, 3), face colours (F, 3))."""
    posed = obj.posed_meshes(ratio=float(openness))
    verts, faces, cols, off = [], [], [], 0
    for p in obj.parts:
        m = posed.get(p.name)
        if m is None or len(m.faces) == 0:
            continue
        v = np.asarray(m.vertices, np.float64)
        f = np.asarray(m.faces, np.int64)
        verts.append(v)
        faces.append(f + off)
        c = colours.get(p.label, colours.get("_default", (0.7, 0.7, 0.7)))
        cols.append(np.broadcast_to(np.asarray(c, np.float64), (len(f), 3)))
        off += len(v)
    if not verts:
        raise ValueError(f"object {obj.name!r} has no part meshes to render")
    return np.concatenate(verts), np.concatenate(faces), np.concatenate(cols)


def render_view(obj: ArticulatedObject, view: ViewSpec, size: int = RENDER_SIZE,
                supersample: int = 2) -> np.ndarray:
    """One view → (size, size, 3) uint8."""
    V, F, C = scene_arrays(obj, view.openness, view.colours)
    lo, hi = V.min(0), V.max(0)
    centre = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-4)
    half = np.radians(view.fov) / 2.0
    dist = radius / np.sin(half) / view.fill
    cam = Camera(eye=centre + dist * _direction(view.azimuth, view.elevation), target=centre,
                 fov_deg=view.fov)
    S = size * supersample
    colours = shade_faces(V, F, C, cam, _direction(view.light_azimuth, view.light_elevation),
                          view.ambient, view.diffuse, view.specular)
    top, bottom = (np.asarray(c, np.float32) for c in view.background)
    t = np.linspace(0.0, 1.0, S, dtype=np.float32)[:, None, None]
    bg = top * (1 - t) + bottom * t                                  # (S, 1, 3)
    img, depth = rasterise(project(V, cam, S), F, colours, S)
    empty = ~np.isfinite(depth)
    img = np.where(empty[..., None], np.broadcast_to(bg, img.shape), img)
    img = downsample(img, supersample)
    return np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)
