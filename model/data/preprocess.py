"""Cached, resumable, parallel preprocessing of PartNet-Mobility-format folders (synthetic or
real) into the prepared format of :mod:`model.data.format` (DESIGN §3.3).

Per object: load (:func:`model.data.partnet.load_partnet`), tokens in topological order, and
per part: a watertight mesh, normalisation into the unit cube (centre on the bbox centre,
longest side spanning [-0.95, 0.95]), surface points + normals, SDF samples (30 % uniform in
[-1.025, 1.025]³, 70 % surface points + N(0, σ = 0.012)) with libigl's exact signed distance
(pseudonormal sign; exact for the closed meshes used here). Descriptions come from the folder's ``descriptions.json``, or are
generated from the structure (:func:`model.data.describe.describe`) when it has none (real
data).

Watertightness: meshes that are already closed 2-manifolds (all procedural parts) are used as
they are; any other mesh (real PartNet-Mobility shells: thin, open, many pieces) becomes the
surface of its one-voxel shell: unsigned distance on a grid, marching cubes at |d| = 0.87 voxel.

    prepare_dataset(PrepareConfig(src="data/synth/v1", out="data/prepared/v1", workers=2))
"""
from __future__ import annotations

import logging
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from model.data.format import (FORMAT_VERSION, ObjectRecord, atomic_write_bytes, atomic_write_json,
                               save_part_arrays, save_record)

log = logging.getLogger(__name__)

UNIT_HALF = 0.95       # longest side of a part spans [-0.95, 0.95]
SAMPLE_HALF = 1.025    # uniform SDF samples in [-1.025, 1.025]³


@dataclass
class PrepareConfig:
    src: str = "data/synth/v1"
    out: str = "data/prepared/v1"
    points: int = 4096           # surface points per part (DESIGN *ref* 4,096)
    samples: int = 16000         # SDF samples per part (*ref* 16,000)
    uniform_share: float = 0.3
    sigma: float = 0.012
    shell_resolution: int = 96   # grid of the one-voxel shell for non-watertight meshes
    seed: int = 0                # split seed (and sampling seed base)
    split: tuple[float, float, float] = (0.8, 0.1, 0.1)
    workers: int = 2
    write_meshes: bool = True
    up_axis: str = "auto"
    data_version: str = ""       # default: "<folder name>-f<format>-p<points>-s<samples>"
    limit: int = 0               # only the first N object folders (0 = all)


# =============================================================================================
# geometry
# =============================================================================================
def is_closed_manifold(mesh) -> bool:
    """Closed, oriented 2-manifold as given (no repair), enclosing a positive volume."""
    from model.core import meshops
    try:
        return meshops.to_manifold(mesh, repair=False).volume() > 0
    except meshops.NotWatertightError:
        return False


def make_watertight(mesh, resolution: int = 96):
    """Closed surface of the one-voxel shell around ``mesh`` (any triangle soup).

    The grid covers the mesh bounds plus 3 voxels; the shell is |unsigned distance| ≤ one voxel,
    re-meshed by marching cubes. Returns a new trimesh mesh (same coordinates as the input).
    """
    import igl
    import trimesh
    from skimage import measure

    V = np.asarray(mesh.vertices, dtype=np.float64)
    F = np.asarray(mesh.faces, dtype=np.int64)
    lo, hi = V.min(0), V.max(0)
    voxel = float((hi - lo).max()) / resolution
    pad = 3 * voxel
    lo, hi = lo - pad, hi + pad
    dims = np.ceil((hi - lo) / voxel).astype(int) + 1
    axes = [lo[i] + voxel * np.arange(dims[i]) for i in range(3)]
    G = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)   # (N, 3)
    d, _, _, _ = igl.signed_distance(G, V, F, sign_type=igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_UNSIGNED)
    # Half-thickness just under one voxel and off the grid spacing: axis-aligned sheets would
    # otherwise put exact zeros on grid nodes, which makes marching cubes non-manifold.
    half = voxel * 0.87
    vol = np.abs(d).reshape(tuple(dims)) - half                             # (X, Y, Z) neg. inside shell
    verts, faces, _, _ = measure.marching_cubes(vol, level=0.0, spacing=(voxel, voxel, voxel),
                                                gradient_direction="ascent")
    out = trimesh.Trimesh(vertices=verts + lo, faces=faces, process=True)
    trimesh.repair.fix_normals(out)
    return out


def unit_transform(mesh) -> tuple[np.ndarray, float]:
    """(center (3,), scale) with x_unit = (x - center) * scale."""
    lo, hi = mesh.bounds
    center = (lo + hi) / 2.0
    extent = float((hi - lo).max())
    scale = 2 * UNIT_HALF / max(extent, 1e-9)
    return center, scale


def sample_part(mesh_unit, points: int, samples: int, rng: np.random.Generator, *,
                uniform_share: float = 0.3, sigma: float = 0.012) -> dict[str, np.ndarray]:
    """Surface points / normals (P, 3) and SDF samples (S, 4) of a watertight unit-cube mesh."""
    import igl
    import trimesh

    pts, fid = trimesh.sample.sample_surface(mesh_unit, points, seed=int(rng.integers(2**31)))
    nrm = mesh_unit.face_normals[fid]
    n_uni = int(round(samples * uniform_share))
    n_near = samples - n_uni
    uni = rng.uniform(-SAMPLE_HALF, SAMPLE_HALF, (n_uni, 3))
    base, _ = trimesh.sample.sample_surface(mesh_unit, n_near, seed=int(rng.integers(2**31)))
    near = base + rng.normal(0.0, sigma, (n_near, 3))
    Q = np.concatenate([uni, near]).astype(np.float64)                 # (S, 3)
    sd, _, _, _ = igl.signed_distance(Q, np.asarray(mesh_unit.vertices, dtype=np.float64),
                                      np.asarray(mesh_unit.faces, dtype=np.int64),
                                      sign_type=igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)
    sdf = np.concatenate([Q, sd[:, None]], axis=1)                     # (S, 4)
    return {"points": pts.astype(np.float32), "normals": nrm.astype(np.float32), "sdf": sdf.astype(np.float32)}


# =============================================================================================
# one object
# =============================================================================================
def object_id(src_root: Path, folder: Path) -> str:
    rel = folder.relative_to(src_root) if folder != src_root else Path(folder.name)
    return "_".join(rel.parts) or folder.name


def prepare_object(folder: str, obj_id: str, split: str, cfg: PrepareConfig, index: int) -> dict:
    """Prepare one object folder; returns a small status dict (for the progress bar / stats)."""
    import trimesh

    from model.data import describe as describe_mod
    from model.data.partnet import load_partnet

    t0 = time.time()
    out = Path(cfg.out)
    obj = load_partnet(folder, cfg.up_axis)
    missing = [p.name for p in obj.parts if p.mesh is None or len(p.mesh.faces) == 0]
    if missing:
        raise ValueError(f"parts without geometry: {missing}")
    toks, types, parents, labels = obj.tokens()
    order = obj.topological_order()
    rng = np.random.default_rng([cfg.seed, index, 11])
    arrays = {k: [] for k in ("points", "normals", "sdf", "center", "scale")}
    repaired = 0
    for k, i in enumerate(order):
        mesh = obj.parts[i].mesh
        if not is_closed_manifold(mesh):
            mesh = make_watertight(mesh, cfg.shell_resolution)
            repaired += 1
        center, scale = unit_transform(mesh)
        unit = trimesh.Trimesh(vertices=(np.asarray(mesh.vertices) - center) * scale,
                               faces=np.asarray(mesh.faces), process=False)
        s = sample_part(unit, cfg.points, cfg.samples, rng, uniform_share=cfg.uniform_share, sigma=cfg.sigma)
        for key in ("points", "normals", "sdf"):
            arrays[key].append(s[key].astype(np.float16))
        arrays["center"].append(center.astype(np.float32))
        arrays["scale"].append(np.float32(scale))
        if cfg.write_meshes:
            from model.data.partnet_writer import obj_bytes
            atomic_write_bytes(out / "meshes" / obj_id / f"{k}.obj", obj_bytes(mesh))
    save_part_arrays(out, obj_id, points=np.stack(arrays["points"]), normals=np.stack(arrays["normals"]),
                     sdf=np.stack(arrays["sdf"]), center=np.stack(arrays["center"]),
                     scale=np.asarray(arrays["scale"], dtype=np.float32))
    texts = obj.metadata.get("descriptions")
    if not texts:
        texts = describe_mod.describe(obj, np.random.default_rng([cfg.seed, index, 13]))
    rec = ObjectRecord(id=obj_id, category=obj.category, split=split, labels=list(labels),
                       parents=[int(x) for x in parents], joint_types=[int(x) for x in types],
                       tokens=[[float(v) for v in row] for row in toks], descriptions=texts,
                       summary=obj.summary(), part_names=[obj.parts[i].name for i in order],
                       source=str(folder))
    save_record(out, rec)   # written last: its presence marks the object as done
    return {"id": obj_id, "parts": len(order), "repaired": repaired, "seconds": time.time() - t0}


def _worker(args) -> dict:
    folder, obj_id, split, cfg, index = args
    try:
        return prepare_object(folder, obj_id, split, cfg, index)
    except Exception as e:  # a broken object is reported and skipped, never fatal
        return {"id": obj_id, "error": f"{type(e).__name__}: {e}"}


# =============================================================================================
# dataset
# =============================================================================================
def assign_splits(ids: list[str], seed: int, fractions=(0.8, 0.1, 0.1)) -> dict[str, str]:
    """Deterministic object-level split (depends only on the sorted id list and the seed)."""
    ids = sorted(ids)
    perm = np.random.default_rng(seed).permutation(len(ids))
    n = len(ids)
    n_train = int(round(fractions[0] * n))
    n_val = int(round(fractions[1] * n))
    out = {}
    for rank, j in enumerate(perm):
        out[ids[j]] = "train" if rank < n_train else ("val" if rank < n_train + n_val else "test")
    return out


def _is_done(out: Path, obj_id: str) -> bool:
    return (out / "objects" / f"{obj_id}.json").exists() and (out / "parts" / f"{obj_id}.npz").exists()


def prepare_dataset(cfg: PrepareConfig, progress: bool = True) -> dict:
    """Prepare every object folder under ``cfg.src`` into ``cfg.out``; returns the manifest.

    Resumable: objects whose record and arrays exist are skipped. Parallel over objects.
    """
    from model.data.partnet import find_object_folders

    src, out = Path(cfg.src), Path(cfg.out)
    folders = find_object_folders(src)
    if cfg.limit:
        folders = folders[: cfg.limit]
    if not folders:
        raise FileNotFoundError(f"no PartNet-Mobility object folders (mobility.urdf) under {src}")
    ids = [object_id(src, f) for f in folders]
    if len(set(ids)) != len(ids):
        raise ValueError(f"{src}: object ids are not unique")
    splits = assign_splits(ids, cfg.seed, cfg.split)
    out.mkdir(parents=True, exist_ok=True)
    todo = [(str(f), i, splits[i], cfg, k) for k, (f, i) in enumerate(zip(folders, ids)) if not _is_done(out, i)]
    log.info("prepare: %d objects, %d to do, %d workers", len(ids), len(todo), cfg.workers)
    results, errors = [], {}
    t0 = time.time()
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(todo), desc="prepare", unit="obj")
    if cfg.workers > 1 and len(todo) > 1:
        import multiprocessing as mp
        ctx = mp.get_context("fork" if hasattr(os, "fork") else "spawn")
        with ctx.Pool(cfg.workers) as pool:
            for r in pool.imap_unordered(_worker, todo, chunksize=2):
                results.append(r)
                if "error" in r:
                    errors[r["id"]] = r["error"]
                if bar:
                    bar.update(1)
    else:
        for a in todo:
            r = _worker(a)
            results.append(r)
            if "error" in r:
                errors[r["id"]] = r["error"]
            if bar:
                bar.update(1)
    if bar:
        bar.close()
    done = [i for i in ids if _is_done(out, i)]
    return write_manifest(cfg, splits, done, errors, processed=len(todo),
                          seconds=time.time() - t0)


def write_manifest(cfg: PrepareConfig, splits: dict[str, str], done: list[str], errors: dict,
                   *, processed: int, seconds: float, extra: Optional[dict] = None) -> dict:
    """Write ``cfg.out/manifest.json`` for the prepared objects ``done`` (id -> split in
    ``splits``) and return it; ``extra`` keys are added as given."""
    from model.data import vocab
    from model.data.format import load_record

    src, out = Path(cfg.src), Path(cfg.out)
    labels, cats = set(), set()
    for i in done:
        rec = load_record(out, i)
        labels.update(rec.labels)
        cats.add(rec.category)
    version = cfg.data_version or f"{src.name}-f{FORMAT_VERSION}-p{cfg.points}-s{cfg.samples}"
    cfg_d = asdict(cfg)
    cfg_d["split"] = list(cfg.split)
    manifest = {
        "format": FORMAT_VERSION, "data_version": version, "source": str(src), "seed": cfg.seed,
        "splits": {s: sorted(i for i in done if splits[i] == s) for s in ("train", "val", "test")},
        "labels": sorted(labels), "categories": sorted(cats),
        "vocab_labels": list(vocab.LABELS), "vocab_categories": list(vocab.CATEGORIES),
        "points_per_part": cfg.points, "sdf_samples_per_part": cfg.samples,
        "sdf_uniform_share": cfg.uniform_share, "sdf_sigma": cfg.sigma, "unit_half": UNIT_HALF,
        "sample_half": SAMPLE_HALF, "config": cfg_d, "errors": errors,
        "last_run": {"processed": processed, "seconds": round(seconds, 1)},
        **(extra or {}),
    }
    atomic_write_json(out / "manifest.json", manifest)
    return manifest
