"""Contact sheets of the shape prior's evaluation: the worst reconstructions beside their
true parts, and prior samples per part label (PNG, matplotlib)."""
from __future__ import annotations

import numpy as np


def render_mesh(mesh, size: int = 160, azimuth: float = 35.0, elevation: float = 22.0,
                frame=None) -> np.ndarray:
    """(size, size, 3) uint8 image of one mesh; the largest component grey-blue, every other
    component red (so shredded parts show). ``frame``: bounds (lo, hi) to frame on."""
    from model.export.render import RenderOptions, _direction, _rasterise
    import math
    from .meshing import components
    opt = RenderOptions(azimuth=azimuth, elevation=elevation)
    img = np.ones((size, size, 3))
    if mesh is not None and len(mesh.faces):
        v, f = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
        lo, hi = frame if frame is not None else (v.min(0), v.max(0))
        centre = (np.asarray(lo) + np.asarray(hi)) / 2
        radius = max(float(np.linalg.norm(np.asarray(hi) - np.asarray(lo))) / 2, 1e-6) * 1.05
        eye = centre + radius / math.sin(math.radians(opt.fov) / 2) * _direction(azimuth, elevation)
        n, lab = components(mesh)
        cols = np.tile(np.array([0.55, 0.65, 0.85]), (len(f), 1))
        if n > 1:
            big = np.argmax(np.bincount(lab, weights=np.asarray(mesh.area_faces)))
            cols[lab != big] = (0.9, 0.25, 0.2)
        img = _rasterise(v[f], cols, np.zeros(len(f), dtype=bool), eye, centre, opt.fov,
                         size, size, opt)
    return np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)


def contact_sheet(path, tiles: list[list[np.ndarray]], row_titles: list[str],
                  title: str = "", tile_inches: float = 1.6) -> None:
    """Grid of images (rows of tiles), a title line above each row, written as a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows, cols = len(tiles), max(len(r) for r in tiles)
    head = 0.35 if title else 0.0
    fig = plt.figure(figsize=(tile_inches * cols, (tile_inches + 0.22) * rows + head))
    H = fig.get_figheight()
    for a in range(rows):
        top = 1 - (head + a * (tile_inches + 0.22)) / H
        fig.text(0.005, top - 0.02 / H, row_titles[a], fontsize=7, va="top", ha="left")
        for b, im in enumerate(tiles[a]):
            ax = fig.add_axes([b / cols, top - (0.22 + tile_inches) / H, 1 / cols,
                               tile_inches / H])
            ax.imshow(im)
            ax.axis("off")
    if title:
        fig.text(0.5, 1 - 0.05 / H, title, fontsize=9, ha="center", va="top")
    fig.savefig(path, dpi=100)
    plt.close(fig)


def worst_sheet(path, rows: list[dict], k: int = 12, size: int = 150) -> None:
    """True part | reconstruction for the ``k`` reconstructions with the lowest F-score,
    two pairs per sheet row."""
    worst = sorted(rows, key=lambda r: (r["fscore"], -r["components"]))[:k]
    tiles, titles = [], []
    for a in range(0, len(worst), 2):
        line, t = [], []
        for r in worst[a:a + 2]:
            tp = r["true"]
            fr = tp.mesh.bounds
            line += [render_mesh(tp.mesh, size, frame=fr), render_mesh(r["mesh"], size, frame=fr)]
            t.append(f"{r['text']} ({r['object']}): F {r['fscore']:.2f}, "
                     f"{r['components']} comp (true {r['true_components']})")
        tiles.append(line)
        titles.append(" | ".join(t))
    contact_sheet(path, tiles, titles,
                  title="worst reconstructions: true | reconstructed (red: extra components)")


def samples_sheet(path, rows: list[dict], per_row: int = 6, size: int = 130) -> None:
    """Prior samples, one sheet row per part label (box-frame meshes; a label with several
    category texts shows samples of each in turn)."""
    groups: dict[str, dict[str, list[dict]]] = {}
    for r in rows:
        groups.setdefault(r["label"], {}).setdefault(r["text"], []).append(r)
    tiles, titles = [], []
    for lab, by_text in sorted(groups.items()):
        seq = [r for k in range(max(len(v) for v in by_text.values()))
               for v in by_text.values() if k < len(v) for r in [v[k]]][:per_row]
        tiles.append([render_mesh(r.get("box_mesh", r["mesh"]), size) for r in seq])
        f = np.mean([r["fscore"] for r in seq])
        titles.append(f"{lab} ({', '.join(sorted({r['text'].split(', ')[0] for r in seq}))}): "
                      f"F {f:.2f} vs nearest true part, "
                      f"{np.mean([r['components'] for r in seq]):.1f} components on average")
    contact_sheet(path, tiles, titles,
                  title="prior samples per label (box frame; red: extra components)")
