"""One part's mesh made ready for refinement, in whichever process meshes it.

Refinement starts with work that needs no other part: the part's closed manifold, its
floaters dropped, and the first simplification steps. The pipeline runs it right after
marching cubes, in its meshing lanes (``model.pipeline.part_pool``), and hands the result
to :func:`model.refine.refine_meshes` as plain arrays. Every part goes through the same
arrays whichever process made them, so an object does not depend on how many lanes ran.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from model.core import meshops

from .meshes import FINE_STEPS, SIMPLIFY_STEPS, _simplified, drop_floaters, first_step

STEPS_AHEAD = 2      # simplification steps made per part in advance (most objects need two)


@dataclass
class PreparedMesh:
    whole: tuple                    # meshops.pack: the closed part, floaters dropped
    steps: tuple = ()               # after simplification step i (SIMPLIFY_STEPS[i]); None:
                                    # that step leaves the part as the step before left it

    def faces(self, level: int) -> int:
        """Faces after step ``level`` (-1: none taken)."""
        return len(self._at(level)[1])

    def _at(self, level: int) -> tuple:
        for p in reversed(self.steps[:level + 1]):
            if p is not None:
                return p
        return self.whole

    def moved(self, offset) -> "PreparedMesh":
        """The same part translated by ``offset`` (m)."""
        d = np.asarray(offset, dtype=np.float64)
        return PreparedMesh((self.whole[0] + d, self.whole[1]),
                            tuple(None if s is None else (s[0] + d, s[1]) for s in self.steps))

    def turned(self, rotation) -> "PreparedMesh":
        """The same part rotated about the origin by ``rotation`` (3x3, a proper rotation:
        the faces keep their winding)."""
        R = np.asarray(rotation, dtype=np.float64).T
        return PreparedMesh((self.whole[0] @ R, self.whole[1]),
                            tuple(None if s is None else (s[0] @ R, s[1]) for s in self.steps))

    def manifold(self, level: int = -1):
        """The part as a Manifold after simplification step ``level`` (-1: none)."""
        return meshops.unpack(self._at(level))


def prepare_mesh(mesh, floaters: bool = True, steps: int = STEPS_AHEAD) -> PreparedMesh:
    """``mesh`` (trimesh, object frame) -> :class:`PreparedMesh` with the first ``steps``
    simplification steps of ``model.refine.meshes.simplify_to_budget`` made (0: none). A
    mesh that is not a closed manifold becomes its convex hull (as in refinement)."""
    man = meshops.to_manifold(mesh, fallback="hull")
    if floaters:
        man = drop_floaters(man)
    done, cur = [], man
    for i in range(min(steps, len(SIMPLIFY_STEPS))):
        s = first_step(cur, SIMPLIFY_STEPS[0], FINE_STEPS) if i == 0 else \
            _simplified(cur, SIMPLIFY_STEPS[i])
        done.append(None if s is None else meshops.pack(s))
        cur = cur if s is None else s
    return PreparedMesh(meshops.pack(man), tuple(done))


__all__ = ["PreparedMesh", "prepare_mesh", "STEPS_AHEAD"]
