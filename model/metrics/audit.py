"""Physical audit of articulated objects: would a roboticist accept this object in a sim?

For one object (in memory or a URDF folder, ours or anyone's) it measures

* **interpenetration** — exact intersection volume / the smaller part's volume (manifold3d)
  for every pair of parts except a parent and a child rigidly fixed together, at rest, at
  ``states`` openness ratios of all joints together, and with each joint alone swept over
  ``states`` ratios while the others stay at rest (a part behind a closed door or lid is
  not required to pass through it or its handle: those pairs count in the all-joints sweep
  only);
* **attachment** — a sliding part's gap to its parent at rest and fully open; a turning
  part's axis line to the part, and to its parent less the part's thickness (a hinge
  bridges a door's thickness);
* **hinges** — a door's or lid's revolute axis lies along an edge of its box (angle to the
  nearest principal axis, distance to the nearest parallel edge / the panel's width);
* **drawers** — a drawer's (or tray's) opening direction against the outward normal of the
  parent-box face it leaves through (the face its open box crosses furthest);
* **mesh health** — connected components, floater faces (components under 1 % of the part's
  surface), watertightness, faces and bytes;
* **physics** — MuJoCo on a floor with every joint driven (``model.metrics.physics``).

Each object gets a **sim-ready** verdict: every check within the thresholds of
:class:`AuditConfig` (documented in docs/audit.md). The measurements themselves are in
model.metrics.audit_checks (their names are importable from here too).

    rep = audit_object(obj)                 # ObjectAudit; rep.sim_ready, rep.failures
    reps = audit_paths(["out/"])           # every URDF folder under out/
    print(audit_table(reps)); write_contact_sheet(reps, "worst.png")
"""
from __future__ import annotations

import logging
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from model.core import ArticulatedObject, JointType
from model.core.contacts import checked_pairs, pair_overlaps  # noqa: F401  (re-exported)

from .audit_checks import (HINGED_LABELS, SLIDING_LABELS, _manifolds,  # noqa: F401
                           attachment_gaps, axis_angle_deg, hinge_offset, mesh_health,
                           opening_normal, overlaps, slide_angle_deg)

log = logging.getLogger(__name__)


@dataclass
class AuditConfig:
    states: int = 10               # openness ratios of the sweeps (0..1, rest included)
    max_overlap: float = 0.01      # intersection / smaller part volume, any pair, any state
    max_gap: float = 0.01          # m: a moving part's gap to its parent, rest and open
    max_axis_deg: float = 5.0      # hinge / drawer axis off its principal direction
    max_hinge_offset: float = 0.08 # hinge axis to the nearest door edge / panel width
    floater_area: float = 0.01     # a component under this share of its part's area floats
    face_budget: int = 30000       # faces per object (0: not checked)
    physics: bool = True           # run the MuJoCo check (needs a URDF; objects get exported)


@dataclass
class ObjectAudit:
    name: str
    path: str = ""                                   # URDF audited ("" for in-memory only)
    category: str = ""
    parts: int = 0
    max_overlap: float = 0.0
    worst_pair: Optional[tuple] = None               # (a, b, state description)
    max_gap: float = 0.0
    worst_gap_part: str = ""
    hinges: list = field(default_factory=list)       # {part, angle_deg, offset, ok}
    slides: list = field(default_factory=list)       # {part, angle_deg, ok}
    worst_components: int = 0
    floater_faces: int = 0
    watertight: bool = True
    faces: int = 0
    bytes: Optional[int] = None
    physics: Optional[dict] = None
    failures: list = field(default_factory=list)
    error: str = ""
    seconds: float = 0.0

    @property
    def sim_ready(self) -> bool:
        return not self.failures and not self.error

    def to_dict(self) -> dict:
        d = asdict(self)
        d["sim_ready"] = self.sim_ready
        return d


# ---------------------------------------------------------------------------------------------
# one object
# ---------------------------------------------------------------------------------------------
def audit_object(obj: ArticulatedObject, *, urdf: Optional[str] = None,
                 config: Optional[AuditConfig] = None, mesh_bytes: Optional[int] = None
                 ) -> ObjectAudit:
    """Audit one object. ``urdf``: its exported URDF for the physics check (without one the
    object is exported to a temporary folder when ``config.physics``)."""
    import time

    cfg = config or AuditConfig()
    t0 = time.perf_counter()
    rep = ObjectAudit(name=obj.name, path=str(urdf or ""), category=obj.category,
                      parts=len(obj.parts), bytes=mesh_bytes)
    try:
        _geometry_checks(obj, rep, cfg)
        if cfg.physics:
            _physics(obj, urdf, rep)
    except Exception as e:  # an unreadable object fails the audit with the reason
        rep.error = f"{type(e).__name__}: {e}"
        log.debug("audit of %s failed", obj.name, exc_info=True)
    rep.seconds = time.perf_counter() - t0
    return rep


def _geometry_checks(obj: ArticulatedObject, rep: ObjectAudit, cfg: AuditConfig) -> None:
    mans, hulls = _manifolds(obj)
    rep.max_overlap, rep.worst_pair = overlaps(obj, cfg.states, mans)
    if rep.max_overlap > cfg.max_overlap:
        a, b, where = rep.worst_pair
        rep.failures.append(f"{a} and {b} overlap by {rep.max_overlap:.1%} ({where})")
    gaps = attachment_gaps(obj, mans)
    if gaps:
        rep.worst_gap_part = max(gaps, key=gaps.get)
        rep.max_gap = gaps[rep.worst_gap_part]
        if rep.max_gap > cfg.max_gap:
            rep.failures.append(f"{rep.worst_gap_part} is {rep.max_gap * 1000:.0f} mm from "
                                f"its parent")
    for k in obj.movable_parts():
        p = obj.parts[k]
        if p.label in HINGED_LABELS and p.joint.type == JointType.REVOLUTE:
            ang, off = axis_angle_deg(p.joint.axis)[0], hinge_offset(p)
            ok = ang <= cfg.max_axis_deg and off <= cfg.max_hinge_offset
            rep.hinges.append({"part": p.name, "angle_deg": ang, "offset": off, "ok": ok})
            if not ok:
                rep.failures.append(f"{p.name} hinge {ang:.0f} deg off its axis, "
                                    f"{off:.0%} of its width from an edge")
        if p.label in SLIDING_LABELS and p.joint.type == JointType.PRISMATIC and p.parent >= 0:
            ang = slide_angle_deg(obj, k)
            ok = ang <= cfg.max_axis_deg
            rep.slides.append({"part": p.name, "angle_deg": ang, "ok": ok})
            if not ok:
                rep.failures.append(f"{p.name} slides {ang:.0f} deg off its opening's normal")
    health = [mesh_health(p.mesh, cfg.floater_area) for p in obj.parts if p.mesh is not None]
    rep.worst_components = max((h["components"] for h in health), default=0)
    rep.floater_faces = sum(h["floater_faces"] for h in health)
    rep.watertight = all(h["watertight"] for h in health) and not hulls
    rep.faces = sum(h["faces"] for h in health)
    if rep.floater_faces:
        rep.failures.append(f"{rep.floater_faces} floater faces")
    if not rep.watertight:
        rep.failures.append("a part mesh is not watertight")
    if cfg.face_budget and rep.faces > cfg.face_budget:
        rep.failures.append(f"{rep.faces} faces (budget {cfg.face_budget})")


def _physics(obj: ArticulatedObject, urdf: Optional[str], rep: ObjectAudit) -> None:
    from model.metrics.physics import physics_check

    if urdf:
        res = physics_check(urdf)
    else:
        from model.export import export_object
        with tempfile.TemporaryDirectory(prefix="artformer_audit_") as tmp:
            out = export_object(obj, Path(tmp) / "obj", preview=False, mesh_uri="relative")
            res = physics_check(out.urdf_path)
    rep.physics = res.to_dict()
    rep.failures.extend(f"physics: {f}" for f in res.failures)


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
