"""The frame the network reads and writes part tokens in.

``absolute``: the 16 floats of ``Part.token`` as they are (object frame, metres): box size,
box centre, joint origin, joint axis, translation and rotation limits.

``parent``: each part's box is given relative to its parent's box, and its joint origin
relative to its own box, so a drawer in a stack, a handle on a drawer or a hinge on a door's
edge is the same few numbers whatever the size of the furniture around it:

* size: ``log(size / parent size)`` per axis;
* centre: ``(centre - parent centre) / parent size``;
* origin: ``(origin - centre) / size`` (a hinge on a box edge is +-0.5);
* axis and limits: unchanged.

The root is taken relative to a virtual parent: a 1 m box centred on the origin. Sizes below
``MIN_SIZE`` are read as ``MIN_SIZE``. Decoding turns a tree back top-down (every parent comes
before its children in decoding order).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

FRAMES = ("absolute", "parent")
MIN_SIZE = 1e-4                       # metres
LOG_RANGE = (-12.0, 4.0)              # log size ratios read back are clipped to this
# place classes (ArticulationConfig.place_bins), per axis of a part in the parent frame:
# its joint origin lies on one face of its own box, on the box's centre line, on the other
# face or elsewhere; its box lies outside the parent's - face touching it, flush inside it,
# centred, flush inside the + face, outside it touching, or elsewhere
ORIGIN_GRID = (-0.5, 0.0, 0.5)        # origin - centre, in the part's box sizes
ORIGIN_TOL = 0.02
CENTRE_FACE = (-0.5, -0.5, 0.0, 0.5, 0.5)   # centre - parent centre, in parent box sizes, is
CENTRE_SIDE = (-1.0, 1.0, 0.0, -1.0, 1.0)   # face + side * half the part's size over the parent's
CENTRE_TOL = 0.005
PLACE_CLASSES = (len(ORIGIN_GRID) + 1, len(CENTRE_FACE) + 1)   # classes per origin / centre
                                                                # axis; the last is "elsewhere"


def check_frame(frame: str) -> str:
    if frame not in FRAMES:
        raise ValueError(f"unknown token frame {frame!r}; choose one of {FRAMES}")
    return frame


def _parent_box(parent_token) -> tuple[np.ndarray, np.ndarray]:
    """(centre, size) of the box a token is relative to; the virtual 1 m box for the root."""
    if parent_token is None:
        return np.zeros(3), np.ones(3)
    pt = np.asarray(parent_token, dtype=np.float64)
    return pt[3:6], np.maximum(np.abs(pt[0:3]), MIN_SIZE)


def token_to_frame(token: np.ndarray, parent_token, frame: str) -> np.ndarray:
    """One absolute token in ``frame``, given its parent's absolute token (None: root)."""
    tok = np.array(token, dtype=np.float64)
    if check_frame(frame) == "absolute":
        return tok
    pc, ps = _parent_box(parent_token)
    size = np.maximum(np.abs(tok[0:3]), MIN_SIZE)
    out = tok.copy()
    out[0:3] = np.log(size / ps)
    out[3:6] = (tok[3:6] - pc) / ps
    out[6:9] = (tok[6:9] - tok[3:6]) / size
    return out


def to_frame(tokens: np.ndarray, parents: Sequence[int], frame: str) -> np.ndarray:
    """(K, 16) absolute tokens -> the same tokens in ``frame`` (parents: index or -1)."""
    toks = np.asarray(tokens, dtype=np.float64)
    if check_frame(frame) == "absolute":
        return toks.copy()
    return np.stack([token_to_frame(toks[i], None if int(p) < 0 else toks[int(p)], frame)
                     for i, p in enumerate(parents)]) if len(toks) else toks.copy()


def token_from_frame(token: np.ndarray, parent_token, frame: str) -> np.ndarray:
    """One token in ``frame`` -> absolute, given its parent's absolute token (None: root)."""
    rel = np.array(token, dtype=np.float64)
    if check_frame(frame) == "absolute":
        return rel
    pc, ps = _parent_box(parent_token)
    out = rel.copy()
    out[0:3] = ps * np.exp(np.clip(rel[0:3], *LOG_RANGE))
    out[3:6] = pc + rel[3:6] * ps
    out[6:9] = out[3:6] + rel[6:9] * np.maximum(out[0:3], MIN_SIZE)
    return out


def from_frame(tokens: np.ndarray, parents: Sequence[int], frame: str) -> np.ndarray:
    """(K, 16) tokens in ``frame`` -> absolute tokens; parents precede their children."""
    rel = np.asarray(tokens, dtype=np.float64)
    if check_frame(frame) == "absolute":
        return rel.copy()
    out = rel.copy()
    for i, p in enumerate(parents):
        p = int(p)
        if p >= i:
            raise ValueError(f"node {i}'s parent {p} does not come before it")
        out[i] = token_from_frame(rel[i], None if p < 0 else out[p], frame)
    return out


def place_values(half, asarray=np.asarray):
    """The places a class names, given ``half`` (..., 3, 1), half the part's size over its
    parent's per axis: origin values (..., 3, 3) in the part's box sizes from its centre,
    centre values (..., 3, 5) in parent box sizes from the parent's centre. ``asarray``
    makes the constants the type of ``half`` (``np.asarray``, or a tensor's ``new_tensor``)."""
    return (asarray(ORIGIN_GRID) + 0 * half,
            asarray(CENTRE_FACE) + asarray(CENTRE_SIDE) * half)


def place_classes(rel: np.ndarray) -> np.ndarray:
    """(..., 16) tokens in the parent frame -> (..., 6) place classes: 3 of the joint origin
    (ORIGIN_GRID index), 3 of the box centre (CENTRE_FACE index); the last class of each
    (PLACE_CLASSES - 1) where no value is within its tolerance."""
    rel = np.asarray(rel, dtype=np.float64)
    origin, centre = place_values(np.exp(np.clip(rel[..., 0:3], *LOG_RANGE))[..., None] / 2)
    out = []
    for vals, x, tol in ((origin, rel[..., 6:9], ORIGIN_TOL), (centre, rel[..., 3:6], CENTRE_TOL)):
        d = np.abs(vals - x[..., None])
        out.append(np.where(d.min(-1) <= tol, d.argmin(-1), vals.shape[-1]))
    return np.concatenate(out, -1).astype(np.int64)


__all__ = ["CENTRE_FACE", "CENTRE_SIDE", "CENTRE_TOL", "FRAMES", "LOG_RANGE", "MIN_SIZE",
           "ORIGIN_GRID", "ORIGIN_TOL", "PLACE_CLASSES", "check_frame", "place_classes",
           "place_values", "token_to_frame", "token_from_frame", "to_frame", "from_frame"]
