"""Physical audit of articulated objects, as ``artformer audit`` runs it: every URDF of a set
of folders (ours, the dataset's, anyone's), a table, a summary row, JSON and a contact sheet
of the worst objects.

The checks (interpenetration over joint sweeps, attachment, hinge and drawer axes, mesh
health, MuJoCo physics) and the **sim-ready** verdict of one object are in
model.export.simready (``AuditConfig``, ``ObjectAudit``, ``audit_object``), their
measurements in model.export.audit_checks and the MuJoCo check in model.export.physics:
below the data layer, whose procedural generator gates its objects with them. Their names
are importable from here too.

    rep = audit_object(obj)                 # ObjectAudit; rep.sim_ready, rep.failures
    reps = audit_paths(["out/"])           # every URDF folder under out/
    print(audit_table(reps)); write_contact_sheet(reps, "worst.png")
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from model.core.contacts import checked_pairs, pair_overlaps  # noqa: F401  (re-exported)
from model.export.audit_checks import (HINGED_LABELS, SLIDING_LABELS, _manifolds,  # noqa: F401
                                       attachment_gaps, axis_angle_deg, hinge_offset,
                                       mesh_health, opening_normal, overlaps, slide_angle_deg)
from model.export.simready import AuditConfig, ObjectAudit, audit_object


# ---------------------------------------------------------------------------------------------
# folders, tables, pictures
# ---------------------------------------------------------------------------------------------
def find_urdfs(paths: Sequence[str]) -> list[Path]:
    """URDF files named by ``paths``: a file, a folder holding one, or a tree of folders."""
    found: list[Path] = []
    for p in map(Path, paths):
        if p.is_file():
            found.append(p)
        elif p.is_dir():
            found.extend(sorted(p.glob("*.urdf")) or sorted(p.rglob("*.urdf")))
        else:
            raise FileNotFoundError(f"{p} is not a URDF file or a folder")
    return found


def audit_urdf(path: Path, config: Optional[AuditConfig] = None) -> ObjectAudit:
    """Audit a URDF file (meshes resolved beside it); a broken file gets an error row."""
    from model.export.importer import import_urdf

    try:
        obj = import_urdf(path)
    except Exception as e:
        return ObjectAudit(name=Path(path).stem, path=str(path), error=f"cannot import: {e}")
    return audit_object(obj, urdf=str(path), config=config, mesh_bytes=visual_mesh_bytes(path))


def visual_mesh_bytes(urdf: Path) -> int:
    """Bytes of the visual mesh files a URDF names."""
    from lxml import etree

    from model.export.importer import resolve_mesh_path
    total = 0
    for vis in etree.parse(str(urdf)).getroot().iter("visual"):
        for m in vis.iter("mesh"):
            try:
                total += resolve_mesh_path(m.get("filename", ""), Path(urdf).parent).stat().st_size
            except Exception:
                pass
    return total


def audit_paths(paths: Sequence[str], config: Optional[AuditConfig] = None,
                progress: bool = False) -> list[ObjectAudit]:
    urdfs = find_urdfs(paths)
    if progress:
        from tqdm import tqdm
        urdfs = tqdm(urdfs, desc="audit", unit="obj")
    return [audit_urdf(u, config) for u in urdfs]


def summarise(reps: Sequence[ObjectAudit], config: Optional[AuditConfig] = None) -> dict:
    """Shares and medians over a set of audits (the row of a results table), each check
    against ``config``'s thresholds (the defaults when None)."""
    cfg = config or AuditConfig()
    n = len(reps)
    if not n:
        return {"objects": 0}
    ok = lambda f: float(np.mean([f(r) for r in reps]))   # noqa: E731
    phys = [r for r in reps if r.physics is not None]
    return {
        "objects": n,
        "sim_ready": ok(lambda r: r.sim_ready),
        "overlap_ok": ok(lambda r: not r.error and r.max_overlap <= cfg.max_overlap),
        "attached": ok(lambda r: not r.error and r.max_gap <= cfg.max_gap),
        "hinges_ok": ok(lambda r: not r.error and all(h["ok"] for h in r.hinges)),
        "slides_ok": ok(lambda r: not r.error and all(s["ok"] for s in r.slides)),
        "mesh_ok": ok(lambda r: not r.error and r.watertight and r.floater_faces == 0),
        "physics_ok": float(np.mean([r.physics["ok"] for r in phys])) if phys else None,
        "median_max_overlap": float(np.median([r.max_overlap for r in reps])),
        "median_worst_components": float(np.median([r.worst_components for r in reps])),
        "median_faces": float(np.median([r.faces for r in reps])),
        "median_bytes": float(np.median([r.bytes for r in reps if r.bytes is not None]))
        if any(r.bytes is not None for r in reps) else None,
    }


def audit_table(reps: Sequence[ObjectAudit], config: Optional[AuditConfig] = None) -> str:
    """A markdown table, one row per object, then the summary."""
    rows = ["| object | sim-ready | overlap | gap mm | hinges | slides | comps | floaters | faces | physics | first failure |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in reps:
        phys = "-" if r.physics is None else ("ok" if r.physics["ok"] else "fail")
        rows.append(
            f"| {r.name} | {'yes' if r.sim_ready else 'no'} | {r.max_overlap:.1%} | "
            f"{r.max_gap * 1000:.1f} | {sum(h['ok'] for h in r.hinges)}/{len(r.hinges)} | "
            f"{sum(s['ok'] for s in r.slides)}/{len(r.slides)} | {r.worst_components} | "
            f"{r.floater_faces} | {r.faces} | {phys} | "
            f"{(r.error or (r.failures[0] if r.failures else '')).replace('|', '/')} |")
    s = summarise(reps, config)
    if s["objects"]:
        rows.append("")
        rows.append(f"sim-ready: {s['sim_ready']:.1%} of {s['objects']} objects "
                    f"(overlap ok {s['overlap_ok']:.1%}, attached {s['attached']:.1%}, hinges "
                    f"{s['hinges_ok']:.1%}, slides {s['slides_ok']:.1%}, meshes "
                    f"{s['mesh_ok']:.1%}, physics "
                    + ("-" if s["physics_ok"] is None else f"{s['physics_ok']:.1%}")
                    + f"); median faces {s['median_faces']:.0f}")
    return "\n".join(rows)


def _severity(r: ObjectAudit) -> tuple:
    return (bool(r.error), len(r.failures), r.max_overlap)


def write_contact_sheet(reps: Sequence[ObjectAudit], path, objects: Optional[dict] = None,
                        worst: int = 8, size: int = 200) -> Optional[str]:
    """PNG of the ``worst`` objects (most failures first), each at rest and fully open with
    its first failures as caption. ``objects``: name -> ArticulatedObject already in memory
    (else each URDF is imported again)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from model.export.importer import import_urdf
    from model.export.render import render_views

    chosen = sorted(reps, key=_severity, reverse=True)[:worst]
    if not chosen:
        return None
    fig, axes = plt.subplots(len(chosen), 1, figsize=(6, 3.2 * len(chosen)), squeeze=False)
    for ax, r in zip(axes[:, 0], chosen):
        ax.axis("off")
        try:
            obj = (objects or {}).get(r.name) or import_urdf(r.path)
            views = render_views(obj, (0.0, 1.0), size, simplify=True)
            ax.imshow(np.concatenate(list(views), axis=1))
        except Exception as e:
            ax.text(0.5, 0.5, f"cannot render: {e}", ha="center", va="center", fontsize=8)
        caption = "; ".join(([r.error] if r.error else []) + r.failures[:2]) or "sim-ready"
        ax.set_title(f"{r.name}: {caption}"[:110], fontsize=8)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return str(path)


__all__ = ["AuditConfig", "ObjectAudit", "audit_object", "audit_urdf", "audit_paths",
           "audit_table", "summarise", "write_contact_sheet", "find_urdfs", "overlaps",
           "attachment_gaps", "mesh_health", "hinge_offset", "slide_angle_deg",
           "axis_angle_deg", "checked_pairs"]
