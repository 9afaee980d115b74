"""Editing support: cut parts (with their subtrees) out of an articulated object."""
from __future__ import annotations

from typing import Iterable

from model.core import ArticulatedObject


def remove_parts(obj: ArticulatedObject, names: Iterable[str]) -> ArticulatedObject:
    """A copy of ``obj`` without the named parts and everything below them.

    Names are part names (= URDF link names). The root cannot be removed (there would be
    nothing to continue from).
    """
    names = list(names)
    index = {p.name: i for i, p in enumerate(obj.parts)}
    drop: set[int] = set()
    for n in names:
        if n not in index:
            raise KeyError(f"no part named {n!r}; parts are {sorted(index)}")
        i = index[n]
        if obj.parts[i].parent < 0:
            raise ValueError(f"{n!r} is the root; it cannot be removed (edit keeps the root)")
        stack = [i]
        while stack:
            j = stack.pop()
            drop.add(j)
            stack.extend(obj.children(j))
    kept = [i for i in range(len(obj.parts)) if i not in drop]
    remap = {old: new for new, old in enumerate(kept)}
    out = obj.copy()
    parts = []
    for old in kept:
        p = out.parts[old]
        p.parent = remap[p.parent] if p.parent >= 0 else -1
        parts.append(p)
    out.parts = parts
    return out.validate()
