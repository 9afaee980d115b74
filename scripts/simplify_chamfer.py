"""How far simplification moves generated surfaces: for raw generated objects (no
refinement), simplify every part to the face budget as the refinement does, then measure the
symmetric mean point-to-surface distance (Chamfer-L1) between each part before and after,
area-weighted per object, and how far the worst 1 % of each part's unsimplified surface lies
from the simplified one (a fold or a squashed knob that the mean hides). Prints median and
max over the objects, and faces before/after.

    python scripts/simplify_chamfer.py --n 24 --budget 30000
"""
from __future__ import annotations

import argparse

import numpy as np


def chamfer_l1(a, b, n: int = 20000, seed: int = 0) -> tuple[float, float]:
    """Symmetric mean point-to-surface distance (m) between two trimesh meshes, and the 99th
    percentile distance from ``a``'s surface to ``b``'s."""
    import igl
    import trimesh
    pa = np.asarray(trimesh.sample.sample_surface(a, n, seed=seed)[0], dtype=np.float64)
    pb = np.asarray(trimesh.sample.sample_surface(b, n, seed=seed + 1)[0], dtype=np.float64)
    da = igl.point_mesh_squared_distance(pa, np.asarray(b.vertices, float), np.asarray(b.faces, np.int64))[0]
    db = igl.point_mesh_squared_distance(pb, np.asarray(a.vertices, float), np.asarray(a.faces, np.int64))[0]
    return (float((np.sqrt(da).mean() + np.sqrt(db).mean()) / 2),
            float(np.percentile(np.sqrt(da), 99)))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=24, help="objects (free-form prompts, seed 0)")
    p.add_argument("--budget", type=int, default=30000)
    a = p.parse_args()
    from model.core import meshops
    from model.metrics.reference import freeform_prompts
    from model.pipeline import GenerationConfig, Generator
    from model.refine import meshes as M
    gen = Generator.load(GenerationConfig(refine=False, face_budget=0))   # unsimplified
    prompts = freeform_prompts()[: a.n]
    rows = []
    for prompt in prompts:
        [res] = gen.generate(prompt, seed=0)
        mans = {k: M.drop_floaters(m) for k, m in M.manifolds_of(res.obj).items()}
        simple, tol = M.simplify_to_budget(mans, int(0.85 * a.budget))
        before = sum(m.num_tri() for m in mans.values())
        after = sum(m.num_tri() for m in simple.values())
        d, w, far = [], [], []
        for k, m in mans.items():
            x, y = meshops.to_trimesh(m), meshops.to_trimesh(simple[k])
            mean, p99 = chamfer_l1(x, y)
            d.append(mean)
            far.append(p99)
            w.append(float(x.area))
        rows.append((float(np.average(d, weights=w)), max(d), before, after, tol, max(far)))
        print(f"{prompt[:50]:<50} faces {before:>7} -> {after:>6} (tol {tol * 1000:.0f} mm) "
              f"chamfer {rows[-1][0] * 1000:.3f} mm (worst part {rows[-1][1] * 1000:.3f}, "
              f"its worst 1 % {rows[-1][5] * 1000:.1f} mm)")
    c = np.array([r[0] for r in rows]) * 1000
    f = np.array([r[5] for r in rows]) * 1000
    print(f"\n{len(rows)} objects: Chamfer-L1 median {np.median(c):.3f} mm, max {c.max():.3f} mm; "
          f"worst 1 % of a part's surface farther than 3 mm in {int((f > 3).sum())} objects "
          f"(median {np.median(f):.1f} mm, max {f.max():.1f} mm); faces median "
          f"{np.median([r[2] for r in rows]):.0f} -> {np.median([r[3] for r in rows]):.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
