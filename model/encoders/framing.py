"""Frame the object of a photo the way the training renders frame it.

The image model learnt from renders whose object fills most of the frame (the posed bounding
sphere spans 80-100 % of it). A photo taken from further away shows the same object on
fewer pixels once the whole picture is resized to 224², and its small parts vanish. When the
picture has a plain background (a wall, a table top, a studio sweep), the object can be
found as what differs from the border colour; ``frame_object`` then crops a square around it
so that it fills the frame as in training (its larger side ``fill`` of the crop side),
padding with the border colour where the square leaves the picture. An object that already
fills that much is only padded to a square with the border colour (instead of the fixed
background the plain resize pads with); a cluttered border or no object leaves the picture
unchanged.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

# the larger side of the object's box over the frame side in the training renders: the median
# over 2,000 random v1 train renders is 0.714 (10th-90th percentile 0.567-0.826; session 14,
# `python scripts/render_fill.py`)
FRAME_FILL = 0.71
BORDER = 0.03            # share of the picture's smaller side read as its border ring
COLOUR_TOL = 0.10        # a pixel this far (max over channels, in [0, 1]) from the border colour is object
BORDER_SPREAD = 0.06     # ... and a border whose 90th-percentile deviation exceeds this is not plain
MIN_LINE = 0.005         # rows / columns with fewer object pixels than this share are noise
DETECT_SIDE = 512        # the object is looked for on a copy strided down to about this side


@dataclass
class Framing:
    box: Optional[tuple]     # (y0, x0, y1, x1) of the object, None when none was found
    background: np.ndarray   # (3,) the border colour
    reason: str              # "object", "cluttered border", "no object"


def border_ring(rgb: np.ndarray, width: int = 1) -> np.ndarray:
    """The pixels of the outer ``width`` rows and columns of ``rgb`` → (n, 3)."""
    b = int(width)
    return np.concatenate([rgb[:b].reshape(-1, 3), rgb[-b:].reshape(-1, 3),
                           rgb[:, :b].reshape(-1, 3), rgb[:, -b:].reshape(-1, 3)])


def find_object(rgb: np.ndarray) -> Framing:
    """(H, W, 3) float in [0, 1] → the box of what differs from a plain border colour."""
    h, w = rgb.shape[:2]
    ring = border_ring(rgb, max(1, int(round(BORDER * min(h, w)))))
    bg = np.median(ring, axis=0).astype(np.float32)
    if np.percentile(np.abs(ring - bg).max(-1), 90) > BORDER_SPREAD:
        return Framing(None, bg, "cluttered border")
    diff = np.abs(rgb - bg).max(-1) > COLOUR_TOL
    rows = np.flatnonzero(diff.sum(1) >= max(2, MIN_LINE * w))
    cols = np.flatnonzero(diff.sum(0) >= max(2, MIN_LINE * h))
    if not rows.size or not cols.size:
        return Framing(None, bg, "no object")
    return Framing((int(rows[0]), int(cols[0]), int(rows[-1]) + 1, int(cols[-1]) + 1), bg, "object")


def frame_object(rgb: np.ndarray, fill: float = FRAME_FILL) -> np.ndarray:
    """Crop (and pad) ``rgb`` to a square in which the object's larger side is ``fill`` of
    the side (at most the picture's larger side: then the picture padded to a square with
    the border colour); the input itself when no object stands out from a plain border."""
    if not 0 < fill <= 1:
        raise ValueError(f"fill must be in (0, 1], got {fill}")
    h, w = rgb.shape[:2]
    k = max(1, int(np.ceil(max(h, w) / DETECT_SIDE)))   # a 12-MP photo: 0.7 s → ~0.03 s
    f = find_object(rgb[::k, ::k] if k > 1 else rgb)
    if f.box is None:
        return rgb
    y0, x0, y1, x1 = (v * k for v in f.box)
    y1, x1 = min(h, y1), min(w, x1)
    side = int(np.ceil(max(y1 - y0, x1 - x0) / fill))
    if side >= max(h, w):
        if h == w:
            return rgb
        side, (y0, x0, y1, x1) = max(h, w), (0, 0, h, w)      # pad to a square, centred
    cy, cx = (y0 + y1) / 2.0, (x0 + x1) / 2.0
    top, left = int(round(cy - side / 2.0)), int(round(cx - side / 2.0))
    out = np.empty((side, side, 3), np.float32)
    out[:] = f.background
    sy0, sx0 = max(0, top), max(0, left)
    sy1, sx1 = min(h, top + side), min(w, left + side)
    out[sy0 - top:sy1 - top, sx0 - left:sx1 - left] = rgb[sy0:sy1, sx0:sx1]
    return out
