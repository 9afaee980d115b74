"""Cause analysis of the shape prior: where thin walls are lost (``diagnose``; the numbers per
hypothesis are in docs/geometry.md)."""
from __future__ import annotations

from typing import Optional

import numpy as np
import torch

from .eval_metrics import (TruePart, _median, compare, encode_parts, part_label, select_parts,
                           summarise, true_part)
from .eval_samples import reconstruct

_RAW = {"min_island": 0}       # no island removal: every fragment the network makes counts
_H64 = 2.0 / 64                # one cell of a 64^3 grid over the [-1, 1] cube
_TRUE_RESOLUTIONS = {"box": (32, 64, 128), "iso": (64,)}   # the true SDF meshed per frame


def _to_frame(tp: TruePart, parts, i: int, frame: str):
    """The true mesh in the part's box frame (``"box"``) or iso unit cube (``"iso"``, the
    part's longest side spans [-0.95, 0.95]), with the map back to metric."""
    m = tp.mesh.copy()
    v = (np.asarray(m.vertices) - parts.center[i]) * float(parts.scale[i])     # iso cube
    if frame == "box":
        c, s = parts.box_center[i].numpy(), parts.box_scale[i].numpy()
    else:
        lo, hi = v.min(0), v.max(0)
        c, s = (lo + hi) / 2, np.full(3, 0.95 / max(float(np.max(hi - lo)) / 2, 1e-9))
    m.vertices = (v - c) * s
    back = (lambda w, c=c, s=s: (np.asarray(w) / s + c) / float(parts.scale[i]) + parts.center[i])
    return m, back


def _igl_sdf(mesh):
    import igl
    V = np.asarray(mesh.vertices, dtype=np.float64)
    Fc = np.asarray(mesh.faces, dtype=np.int64)

    def fn(xyz: torch.Tensor) -> torch.Tensor:
        q = xyz.reshape(-1, 3).double().numpy()
        d = igl.signed_distance(q, V, Fc, sign_type=igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)[0]
        return torch.from_numpy(d).float().reshape(xyz.shape[:-1])
    return fn


def wall_thickness(mesh, n: int, seed: int, step: float, steps: int = 48,
                   sdf_fn=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local wall thickness at ``n`` surface points of a watertight mesh: march inwards along
    the face normal in ``step`` increments until the SDF turns positive (capped at
    ``steps`` x ``step``). -> (points, inward normals, thickness)."""
    import trimesh
    pts, fi = trimesh.sample.sample_surface(mesh, n, seed=seed)
    nrm = -np.asarray(mesh.face_normals)[fi]
    sdf_fn = sdf_fn or _igl_sdf(mesh)
    t = step * np.arange(1, steps + 1)
    probe = pts[:, None, :] + t[None, :, None] * nrm[:, None, :]            # (n, K, 3)
    d = sdf_fn(torch.from_numpy(probe.reshape(1, -1, 3)).float()).reshape(n, steps).numpy()
    out = d > 0
    first = np.where(out.any(1), out.argmax(1), steps)
    return np.asarray(pts), nrm, np.where(first < steps, t[np.minimum(first, steps - 1)],
                                          t[-1] + step)


def diagnose(shape, data: str, *, split: str = "test", per_label_cap: int = 6,
             max_parts: Optional[int] = 80, seed: int = 0,
             resolutions: tuple[int, ...] = (32, 64, 128), progress: bool = True) -> dict:
    """Measure where thin walls are lost (numbers per hypothesis; see docs/geometry.md).

    a) meshing resolution: the auto-encoder's reconstructions at each of ``resolutions``,
       and the TRUE SDF (exact, libigl) meshed the same way at 32 / 64 / 128 (the ceiling of
       meshing alone);
    b) the auto-encoder's field: SDF error and sign errors of the decoder against exact
       box-frame SDF samples, binned by distance to the surface (in 64^3 cells), and the
       share of wall mid-points (by wall thickness) that the decoder puts outside;
    c) the normalisation: wall thickness in cells of a 64^3 grid in the box frame vs the iso
       frame, and the true SDF meshed at 64^3 in both frames;
    d) prior vs auto-encoder: retrieval decodes (training latents) of the same label texts;
    e) meshing-time remedies on the same latents: iso-level offsets (dilation), keeping the
       largest component.

    Everything is meshed with ``min_island=0`` (no island removal), so every fragment the
    network makes is counted.
    """
    from .data import load_parts
    parts = load_parts(data, split, with_sdf=False)
    idx = select_parts(parts, per_label=per_label_cap, max_parts=max_parts, seed=seed)
    truth: dict = {i: true_part(parts, i, seed) for i in idx}
    idx = [i for i in idx if truth[i] is not None]
    z = encode_parts(shape, parts, idx, seed)
    out: dict = {"parts": len(idx), "split": split, "data_version": parts.data_version,
                 "labels": sorted({part_label(parts.texts[i]) for i in idx})}
    # a) resolution, auto-encoder
    res_rows = {r: reconstruct(shape, parts, idx, resolution=r, seed=seed, truth=truth, z=z,
                               progress=progress, iou=False, mesh_kw=_RAW)
                for r in resolutions}
    out["a_ae_resolution"] = {str(r): _brief(rows) for r, rows in res_rows.items()}
    # a) + c) the true SDF meshed in the box / iso frame
    true_rows, thick, field, mids = _true_sdf_and_field(shape, parts, idx, truth, z, seed,
                                                        progress)
    out["a_true_sdf_box"], out["c_true_sdf_iso"] = {}, {}
    for key, rows in true_rows.items():
        tgt = out["a_true_sdf_box"] if key.startswith("box") else out["c_true_sdf_iso"]
        tgt[key[3:]] = _brief(rows)
    # b) field error by distance to the surface (cells of 64^3)
    out["b_field_error_by_distance"] = _field_error_by_distance(field)
    out["b_wall_midpoints_outside"] = _midpoints_outside(mids)
    # c) wall thickness distributions, box vs iso frame
    out["c_wall_thickness_cells"] = {frame: _thickness_summary(thick[frame])
                                     for frame in ("box", "iso")}
    # d) retrieval decodes of the same label texts (training latents through the AE)
    lat = shape.bank.get("latents") if shape.bank else None
    if lat is not None:
        texts = sorted({parts.texts[i] for i in idx})
        out["d_retrieval_64"] = _retrieval_decodes(shape, lat, texts, per_label_cap, seed)
    out["d_reconstruction_64_single_component"] = (
        float(np.mean([r["components"] == 1 for r in res_rows[64]])) if 64 in res_rows else None)
    # e) meshing-time remedies on the same latents
    out["e_remedies_64"] = _remedies(shape, parts, idx, truth, z, seed, res_rows.get(64))
    return out


def _brief(rows: list[dict]) -> dict:
    """The figures of a set of metric rows that the cause analysis compares, with the body
    parts' (the thin-walled carcasses) on their own."""
    s = summarise(rows)
    return {k: s.get(k) for k in ("n", "fscore", "chamfer_mm", "iou", "true_components",
                                  "with_floaters", "components_mean", "watertight")} | {
        "mesh_ms_median": _median([r.get("mesh_ms", float("nan")) for r in rows]),
        "body": {k: summarise([r for r in rows if r["label"] == "body"]).get(k)
                 for k in ("n", "fscore", "true_components")}}


def _scored(mesh, tp: TruePart, seed: int, label: str, index: int) -> dict:
    """Metric row (no IoU) of a mesh against its true part, labelled like reconstruct's."""
    row = compare(mesh, tp, seed, iou=False)
    row.update(label=label, true_components=tp.components, index=index)
    return row


def _true_sdf_and_field(shape, parts, idx: list[int], truth: dict, z: torch.Tensor, seed: int,
                        progress: bool) -> tuple[dict, dict, list, list]:
    """Per part, in its box and its iso frame: the true SDF meshed (rows under "box32" ...
    "iso64") and the wall thickness in 64^3 cells; in the box frame also the decoder's field
    against exact samples and at wall mid-points (:func:`_field_samples`).
    -> (true rows per key, (label, thickness) per frame, field samples, mid-point samples)."""
    from .meshing import mesh_sdf_batch
    thick: dict[str, list] = {"box": [], "iso": []}
    field, mids = [], []
    it = idx
    if progress:
        from tqdm import tqdm
        it = tqdm(idx, desc="true SDF / field", unit="part")
    true_rows: dict[str, list] = {}
    for j, i in zip(range(len(idx)), it):
        tp = truth[i]
        lab = part_label(parts.texts[i])
        for frame in ("box", "iso"):
            fm, back = _to_frame(tp, parts, i, frame)
            fn = _igl_sdf(fm)
            for r in _TRUE_RESOLUTIONS[frame]:
                mr = mesh_sdf_batch(fn, 1, r, **_RAW)[0]
                m = mr.mesh.copy()
                if mr.ok:
                    m.vertices = back(m.vertices)
                true_rows.setdefault(f"{frame}{r}", []).append(_scored(m, tp, seed, lab, i))
            # wall thickness in 64^3 cells of this frame
            _, _, t = wall_thickness(fm, 256, seed, step=_H64 / 4, sdf_fn=fn)
            thick[frame].append((lab, t / _H64))
            if frame == "box":
                f, mid = _field_samples(shape, z[j:j + 1], fm, fn, lab, seed + i, seed + 1)
                field.append(f)
                mids.append(mid)
    return true_rows, thick, field, mids


def _field_samples(shape, z: torch.Tensor, box_mesh, sdf_fn, label: str, sample_seed: int,
                   wall_seed: int) -> tuple[tuple, tuple]:
    """The decoder's field of one part (z: (1, D)) against the exact SDF of its box-frame
    mesh: -> (label, exact SDF, decoded SDF) at near-surface and uniform samples, and
    (label, wall thickness, decoded SDF) at the mid-points of its walls; all in 64^3 cells."""
    from .data import sample_part
    _, _, smp = sample_part(box_mesh, 16, 4096, np.random.default_rng(sample_seed))
    planes = shape.ae.decode_planes(z)
    q = torch.from_numpy(smp[:, :3]).float()[None]
    pred = shape.ae.query(planes, q)[0].numpy()
    p, nrm, t = wall_thickness(box_mesh, 512, wall_seed, step=_H64 / 4, sdf_fn=sdf_fn)
    midp = p + nrm * (t / 2)[:, None]
    pm = shape.ae.query(planes, torch.from_numpy(midp).float()[None])[0].numpy()
    return (label, smp[:, 3] / _H64, pred / _H64), (label, t / _H64, pm / _H64)


def _field_error_by_distance(field: list[tuple]) -> list[dict]:
    """Decoder SDF error and sign errors (all parts, body parts) binned by the exact
    distance to the surface."""
    bins = [0, 0.5, 1, 2, 4, 1e9]
    d = np.concatenate([r[1] for r in field])
    p = np.concatenate([r[2] for r in field])
    is_body = np.concatenate([np.full(len(r[1]), r[0] == "body") for r in field])
    b_err = []
    for lo, hi in zip(bins[:-1], bins[1:]):
        sel = (np.abs(d) >= lo) & (np.abs(d) < hi)
        b_err.append({"abs_distance_cells": f"{lo}-{hi if hi < 1e8 else 'inf'}",
                      "samples": int(sel.sum()),
                      "abs_error_cells": float(np.abs(p[sel] - d[sel]).mean()) if sel.any() else None,
                      "sign_errors": float((np.sign(p[sel]) != np.sign(d[sel])).mean()) if sel.any() else None,
                      "sign_errors_body": float((np.sign(p[sel & is_body]) != np.sign(d[sel & is_body])).mean()) if (sel & is_body).any() else None})
    return b_err


def _midpoints_outside(mids: list[tuple]) -> list[dict]:
    """Share of wall mid-points the decoder puts outside, binned by wall thickness."""
    t = np.concatenate([r[1] for r in mids])
    pm = np.concatenate([r[2] for r in mids])
    tb = [0, 1, 2, 4, 8, 1e9]
    return [
        {"wall_cells": f"{lo}-{hi if hi < 1e8 else 'inf'}", "points": int(sel.sum()),
         "decoded_outside": float((pm[sel] > 0).mean()) if sel.any() else None}
        for lo, hi in zip(tb[:-1], tb[1:]) for sel in [(t >= lo) & (t < hi)]]


def _thickness_summary(thick: list[tuple]) -> dict:
    """Median and thin shares of (label, wall thickness) samples of one frame."""
    allt = np.concatenate([x[1] for x in thick])
    bod = [x[1] for x in thick if x[0] == "body"]
    bodt = np.concatenate(bod) if bod else np.zeros(0)
    return {"median": float(np.median(allt)), "under_1_cell": float((allt < 1).mean()),
            "under_2_cells": float((allt < 2).mean()),
            "body_median": float(np.median(bodt)) if len(bodt) else None,
            "body_under_2_cells": float((bodt < 2).mean()) if len(bodt) else None}


def _retrieval_decodes(shape, lat: torch.Tensor, texts: list[str], per_label_cap: int,
                       seed: int) -> dict:
    """Components and watertightness of training latents of ``texts`` decoded at 64^3 (what
    the auto-encoder makes of latents the prior never sampled)."""
    from .meshing import components
    gen = torch.Generator().manual_seed(seed)
    comps, wt, body_one = [], [], []
    for tx in texts:
        if tx not in shape.bank["texts"]:
            continue
        sel = (shape.bank["text_ids"] == shape.bank["texts"].index(tx)).nonzero()[:, 0]
        pick = sel[torch.randperm(len(sel), generator=gen)[:per_label_cap]]
        for r in shape.decode(lat[pick].float(), 64, **_RAW):
            if not r.ok:
                continue
            comps.append(components(r.mesh)[0])
            wt.append(bool(r.mesh.is_watertight))
            if part_label(tx) == "body":
                body_one.append(comps[-1] == 1)
    return {"n": len(comps), "single_component": float(np.mean(np.array(comps) == 1)),
            "components_mean": float(np.mean(comps)),
            "components_max": int(max(comps)) if comps else 0,
            "watertight": float(np.mean(wt)),
            "body_single_component": float(np.mean(body_one)) if body_one else None}


def _remedies(shape, parts, idx: list[int], truth: dict, z: torch.Tensor, seed: int,
              base: Optional[list[dict]]) -> dict:
    """Meshing-time remedies at 64^3 on the same latents: the iso level raised by half / one
    cell (dilation), and only the largest component kept of ``base`` (the plain 64^3
    reconstructions; made here when missing)."""
    from .meshing import keep_largest_components
    rem = {}
    for lv in (0.5, 1.0):
        rows = reconstruct(shape, parts, idx, resolution=64, seed=seed, truth=truth, z=z,
                           mesh_kw={"level": lv * _H64, **_RAW}, iou=False)
        rem[f"level_+{lv}_cell"] = _brief(rows)
    base = base or reconstruct(shape, parts, idx, resolution=64, seed=seed, truth=truth, z=z,
                               iou=False, mesh_kw=_RAW)
    kept = []
    for r in base:
        if r.get("empty"):
            kept.append(r)
            continue
        m = keep_largest_components(r["mesh"], 1)
        kept.append(_scored(m, truth[r["index"]], seed, r["label"], r["index"]))
    rem["largest_component_only"] = _brief(kept)
    return rem
