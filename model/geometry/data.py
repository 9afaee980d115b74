"""Part-level views of a prepared dataset (model/data/format.py) for the shape prior, and a
tiny primitive dataset writer for tests and smoke runs."""
from __future__ import annotations

import json
import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from model.core.files import atomic_torch_save
from model.data import format as fmt

log = logging.getLogger(__name__)


def category_words(category: str) -> str:
    """'StorageFurniture' / 'washing_machine' -> 'storage furniture' / 'washing machine'."""
    s = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", " ", category.strip())
    return re.sub(r"[_\-\s]+", " ", s).strip().lower()


def label_text(category: str, label: str) -> str:
    """The semantic-condition text of a part, e.g. 'storage furniture, drawer'."""
    return f"{category_words(category)}, {re.sub(r'[_-]+', ' ', label.strip().lower())}"


@dataclass
class PartSet:
    """All parts of one split, in memory (float16 to halve the footprint)."""
    points: torch.Tensor              # (M, P, 3) surface points, unit cube
    sdf: torch.Tensor                 # (M, S, 4) [xyz, sdf]
    texts: list[str]                  # (M,) label texts
    object_ids: list[str]             # (M,)
    part_index: list[int]             # (M,) index k of the part in its object
    center: np.ndarray                # (M, 3) unit-cube normalisation (object -> iso unit cube)
    scale: np.ndarray                 # (M,)
    box_center: torch.Tensor = None   # (M, 3) iso unit cube -> box frame: (x - c) * s
    box_scale: torch.Tensor = None    # (M, 3)
    data_version: str = ""
    root: str = ""
    text_vocab: list[str] = field(default_factory=list)
    text_ids: torch.Tensor = None     # (M,) index into text_vocab

    def __len__(self) -> int:
        return self.points.shape[0]

    def mesh_path(self, i: int) -> Path:
        return Path(self.root) / "meshes" / self.object_ids[i] / f"{self.part_index[i]}.obj"


MAX_STRETCH = 200.0


def box_frame(points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-part box normalisation from surface points (B, P, 3) in the iso unit cube:
    centre c (B, 3) and per-axis stretch s (B, 3) so that (x - c) * s spans [-0.95, 0.95]
    on every axis.

    Why: the articulation transformer predicts each part's bbox and the mesh is fitted into
    it per axis anyway, so the shape model only has to carry the shape inside its box. A
    2 cm door on a 70 cm cabinet is 0.03 thick in the iso cube (under one 64^3 cell) but
    fills the box frame, so thin parts become resolvable.
    """
    p = points.float()
    lo, hi = p.min(1).values, p.max(1).values                    # (B, 3)
    c = (lo + hi) / 2
    s = (0.95 / ((hi - lo) / 2).clamp_min(0.95 / MAX_STRETCH))   # (B, 3)
    return c, s


def to_box_sdf(points: torch.Tensor, normals: torch.Tensor, sdf: torch.Tensor,
               c: torch.Tensor, s: torch.Tensor, bound: float = 1.05) -> torch.Tensor:
    """Map SDF samples (K, S, 4) of K parts into their box frames.

    Positions are stretched; distances are rescaled to first order by |S n| with n the
    normal of the nearest surface point (exact near the surface, where it matters; the sign
    is always exact). Samples that leave [-bound, bound]^3 are replaced by random in-box
    samples of the same part. -> (K, S, 4).
    """
    from scipy.spatial import cKDTree
    out = torch.empty_like(sdf, dtype=torch.float32)
    rng = np.random.default_rng(0)
    for k in range(sdf.shape[0]):
        q = sdf[k, :, :3].float().numpy()
        d = sdf[k, :, 3].float().numpy()
        _, nn_idx = cKDTree(points[k].float().numpy()).query(q, k=1)
        n = normals[k].float().numpy()[nn_idx]                        # (S, 3)
        sk = s[k].numpy()
        factor = np.linalg.norm(n * sk, axis=1) / np.maximum(np.linalg.norm(n, axis=1), 1e-6)
        qb = (q - c[k].numpy()) * sk
        db = d * np.where(np.isfinite(factor) & (factor > 0), factor, sk.min())
        inside = np.all(np.abs(qb) <= bound, axis=1)
        if not inside.any():
            raise ValueError("a part has no SDF sample inside its box frame")
        keep = np.flatnonzero(inside)
        fill = rng.choice(keep, size=int((~inside).sum()), replace=True)
        qb[~inside], db[~inside] = qb[fill], db[fill]
        out[k, :, :3] = torch.from_numpy(qb)
        out[k, :, 3] = torch.from_numpy(db)
    return out


def box_samples_from_mesh(mesh_iso, n_points: int, n_sdf: int, rng: np.random.Generator):
    """Exact samples in the box frame from a watertight part mesh in the iso unit cube.

    -> points (P, 3), sdf (S, 4), c (3,), s (3,) with x_box = (x_iso - c) * s.
    """
    lo, hi = mesh_iso.bounds
    c = (lo + hi) / 2.0
    s = 0.95 / np.maximum((hi - lo) / 2.0, 0.95 / MAX_STRETCH)
    m = mesh_iso.copy()
    m.vertices = (np.asarray(m.vertices) - c) * s
    pts, _, sdf = sample_part(m, n_points, n_sdf, rng)
    return pts, sdf, c, s


def _exact_object(mesh_dir: Path, K: int, center, scale, P: int, S: int, seed: int):
    import trimesh
    rng = np.random.default_rng(seed)
    out = []
    for k in range(K):
        m = trimesh.load(mesh_dir / f"{k}.obj", force="mesh", process=True)
        m.apply_translation(-center[k])
        m.apply_scale(float(scale[k]))
        out.append(box_samples_from_mesh(m, P, S, rng))
    return out


def _cache_key(root, split, man, max_objects, with_sdf, max_sdf, seed, exact) -> str:
    import hashlib
    key = json.dumps([str(Path(root).resolve()), split, man.get("data_version", ""),
                      len(man["splits"].get(split, [])), max_objects, with_sdf, max_sdf, seed,
                      exact, CACHE_VERSION])
    return hashlib.sha1(key.encode()).hexdigest()[:16]


CACHE_VERSION = 1


def load_parts(root: str | Path, split: str, *, max_objects: int | None = None,
               progress: bool = False, with_sdf: bool = True, max_sdf: int | None = None,
               seed: int = 0, cache_dir: str | Path | None = None,
               exact: bool = True, workers: int = 1) -> PartSet:
    """Load every part of ``split`` (train / val / test) of a prepared dataset, in the box
    frame (see :func:`box_frame`).

    With ``exact`` and the prepared meshes present (``ROOT/meshes``), points and SDF samples
    are re-sampled exactly in the box frame (libigl signed distance, DESIGN §3.3 recipe: 30 %
    uniform, 70 % near the surface, sigma 0.012); otherwise the stored iso-frame samples are
    mapped (:func:`to_box_sdf`, first-order distances). ``with_sdf=False`` skips the SDF,
    ``max_sdf`` caps SDF samples per part. ``cache_dir`` keeps the result as a .pt file.

    The exact re-sampling (libigl, one core) runs in ``workers`` forked processes over shards
    of SHARD objects. With ``cache_dir`` every finished shard is kept on disk until the whole
    split is cached, so an interrupted run resumes at the first missing shard. Each object
    gets its own sampling seed, drawn up front from ``seed`` in split order, so the samples
    do not depend on ``workers`` or on interruptions.
    """
    man = fmt.load_manifest(root)
    cache = None
    if cache_dir is not None:
        cache = Path(cache_dir) / f"parts_{split}_{_cache_key(root, split, man, max_objects, with_sdf, max_sdf, seed, exact)}.pt"
        if cache.exists():
            try:
                d = torch.load(cache, weights_only=False)
                return PartSet(**d)
            except Exception as e:   # a damaged cache is rebuilt
                log.warning("ignoring unreadable cache %s (%s)", cache, e)
    rng = np.random.default_rng(seed)
    ids = fmt.split_ids(root, split)
    if max_objects is not None:
        ids = ids[:max_objects]
    if exact and with_sdf and all((Path(root) / "meshes" / i).is_dir() for i in ids):
        # exactly the seeds the sequential loop below would draw, one per object
        seeds = [int(rng.integers(2**31)) for _ in ids]
        col = _read_sharded(root, ids, seeds, max_sdf=max_sdf, workers=workers,
                            shard_dir=None if cache is None else cache.with_suffix(f".shards{SHARD}"),
                            progress=progress, desc=f"load {split}")
    else:
        it = ids
        if progress:
            from tqdm import tqdm
            it = tqdm(ids, desc=f"load {split}", unit="obj")
        col = _read_objects(root, it, rng, with_sdf=with_sdf, max_sdf=max_sdf, exact=exact)
    if not col["points"]:
        raise ValueError(f"{root}: split {split!r} has no objects")
    texts = col["texts"]
    vocab = sorted(set(texts))
    lookup = {t: i for i, t in enumerate(vocab)}
    out = dict(points=torch.cat(col["points"]),
               sdf=torch.cat(col["sdf"]) if with_sdf else None, texts=texts,
               object_ids=col["object_ids"], box_center=torch.cat(col["box_center"]),
               box_scale=torch.cat(col["box_scale"]), part_index=col["part_index"],
               center=np.concatenate(col["center"]), scale=np.concatenate(col["scale"]),
               data_version=str(man.get("data_version", "")), root=str(root),
               text_vocab=vocab, text_ids=torch.tensor([lookup[t] for t in texts]))
    if cache is not None:
        atomic_torch_save(cache, out)
        import shutil
        shutil.rmtree(cache.with_suffix(f".shards{SHARD}"), ignore_errors=True)
    return PartSet(**out)


SHARD = 128   # objects per cache shard of the exact re-sampling
COLUMNS = ("points", "sdf", "box_center", "box_scale", "center", "scale", "texts", "object_ids",
           "part_index")


def _shard_job(job: tuple) -> tuple[int, dict | None]:
    """One shard of _read_sharded (runs in a worker): its columns, or None once written to
    the shard file."""
    index, root, ids, seeds, max_sdf, path = job
    col = _read_objects(root, ids, None, with_sdf=True, max_sdf=max_sdf, exact=True, seeds=seeds)
    if path is None:
        return index, col
    atomic_torch_save(path, col)
    return index, None


def _read_sharded(root, ids: list, seeds: list, *, max_sdf: int | None, workers: int,
                  shard_dir: Path | None, progress: bool, desc: str) -> dict[str, list]:
    """_read_objects with one seed per object, over shards of SHARD objects in ``workers``
    processes; finished shards kept as ``shard_dir/NNNNN.pt`` (none: kept in memory)."""
    from model.core.runtime import map_jobs
    jobs = []
    for n, a in enumerate(range(0, len(ids), SHARD)):
        path = None if shard_dir is None else shard_dir / f"{n:05d}.pt"
        jobs.append((n, str(root), ids[a:a + SHARD], seeds[a:a + SHARD], max_sdf,
                     None if path is None else str(path)))
    if shard_dir is not None:
        shard_dir.mkdir(parents=True, exist_ok=True)
    todo = [j for j in jobs if j[5] is None or not Path(j[5]).exists()]
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(ids), initial=len(ids) - sum(len(j[2]) for j in todo),
                   desc=desc, unit="obj")
    done: dict[int, dict] = {}
    for n, col in map_jobs(_shard_job, todo, workers=workers, chunksize=1):
        if col is not None:
            done[n] = col
        if bar:
            bar.update(len(jobs[n][2]))
    if bar:
        bar.close()
    out: dict[str, list] = {k: [] for k in COLUMNS}
    for n, *_, path in jobs:
        col = done.pop(n) if n in done else torch.load(path, weights_only=False)
        for k, v in col.items():
            out[k].extend(v)
    return out


def _read_objects(root, ids, rng: np.random.Generator | None, *, with_sdf: bool,
                  max_sdf: int | None, exact: bool, seeds: list | None = None
                  ) -> dict[str, list]:
    """The parts of objects ``ids``, as lists to concatenate: box-frame ``points``, ``sdf``,
    ``box_center`` and ``box_scale`` (tensors of one part or one object each), the iso-cube
    ``center`` and ``scale`` (arrays per object), and per part its ``texts``, ``object_ids``
    and ``part_index``. Points and SDF samples per part are those of the first object
    (``max_sdf`` caps the SDF samples). ``seeds`` gives each object's exact-sampling seed
    instead of drawing it from ``rng``."""
    col: dict[str, list] = {k: [] for k in COLUMNS}
    P = S = None
    for j, oid in enumerate(ids):
        rec = fmt.load_record(root, oid)
        arr = fmt.load_part_arrays(root, oid)
        K = arr["points"].shape[0]
        if K != rec.num_parts:
            raise ValueError(f"{root}: object {oid} has {rec.num_parts} parts in its record but "
                             f"{K} in parts/{oid}.npz; re-run `artformer data prepare`")
        if P is None:
            P, S = arr["points"].shape[1], arr["sdf"].shape[1]
            if max_sdf is not None:
                S = min(S, max_sdf)
        center = arr["center"].astype(np.float32).reshape(K, 3)
        scale = arr["scale"].astype(np.float32).reshape(K)
        col["center"].append(center)
        col["scale"].append(scale)
        pts, sdf, bcs, bss = _object_samples(root, oid, arr, center, scale, P, S, rng,
                                             exact=exact, with_sdf=with_sdf,
                                             seed=None if seeds is None else seeds[j])
        col["points"] += pts
        col["sdf"] += sdf
        col["box_center"] += bcs
        col["box_scale"] += bss
        for k, lab in enumerate(rec.labels):
            col["texts"].append(label_text(rec.category, lab))
            col["object_ids"].append(oid)
            col["part_index"].append(k)
    return col


def _object_samples(root, oid: str, arr: dict, center: np.ndarray, scale: np.ndarray, P: int,
                    S: int, rng: np.random.Generator | None, *, exact: bool, with_sdf: bool,
                    seed: int | None = None) -> tuple[list, list, list, list]:
    """Box-frame points (.., P, 3), SDF samples (.., S, 4; none without ``with_sdf``), box
    centres and stretches (.., 3) of one object's K parts, as lists of tensors: re-sampled
    exactly from the prepared meshes (one tensor per part) when ``exact`` and the meshes are
    there, else the stored iso-frame samples mapped (one tensor for the object)."""
    mesh_dir = Path(root) / "meshes" / oid
    pts, sdf, bcs, bss = [], [], [], []
    if exact and with_sdf and mesh_dir.is_dir():
        if seed is None:
            seed = int(rng.integers(2**31))
        for p, d, c, s in _exact_object(mesh_dir, len(scale), center, scale, P, S, seed):
            pts.append(torch.from_numpy(p).half().unsqueeze(0))
            sdf.append(torch.from_numpy(d).half().unsqueeze(0))
            bcs.append(torch.from_numpy(c).float().unsqueeze(0))
            bss.append(torch.from_numpy(s).float().unsqueeze(0))
        return pts, sdf, bcs, bss
    if arr["points"].shape[1] != P:
        raise ValueError(f"{root}: object {oid} has a different number of points")
    p_iso = torch.from_numpy(arr["points"].astype(np.float32))   # (K, P, 3)
    c, s = box_frame(p_iso)
    bcs.append(c)
    bss.append(s)
    pts.append(((p_iso - c.unsqueeze(1)) * s.unsqueeze(1)).half())
    if with_sdf:
        nrm = torch.from_numpy(arr["normals"].astype(np.float32))
        raw = arr["sdf"]
        if raw.shape[1] > S:
            raw = raw[:, np.sort(rng.choice(raw.shape[1], S, replace=False))]
        sdf.append(to_box_sdf(p_iso, nrm, torch.from_numpy(raw.astype(np.float32)),
                              c, s).half())
    return pts, sdf, bcs, bss


def sample_batch(parts: PartSet, idx: torch.Tensor, n_points: int, n_queries: int,
                 generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Random subsets for parts ``idx`` (B,) -> points (B, n_points, 3), queries (B, n_queries, 3),
    sdf (B, n_queries)."""
    B = idx.shape[0]
    P, S = parts.points.shape[1], parts.sdf.shape[1]
    pi = torch.randint(0, P, (B, n_points), generator=generator)
    si = torch.randint(0, S, (B, n_queries), generator=generator)
    rows = idx.unsqueeze(1)
    pts = parts.points[rows, pi].float()                      # (B, n_points, 3)
    s = parts.sdf[rows, si].float()                           # (B, n_queries, 4)
    return pts, s[..., :3].contiguous(), s[..., 3].contiguous()


# -- a tiny dataset from primitives (tests, smoke runs) ----------------------------------------

def normalise_to_unit_cube(mesh) -> tuple[object, np.ndarray, float]:
    """Centre on the bbox, scale isotropically so the longest side spans [-0.95, 0.95]."""
    lo, hi = mesh.bounds
    center = (lo + hi) / 2.0
    scale = 1.9 / float(max(hi - lo))
    m = mesh.copy()
    m.apply_translation(-center)
    m.apply_scale(scale)
    return m, center, scale


def sample_part(mesh_unit, n_points: int, n_sdf: int, rng: np.random.Generator,
                sigma: float = 0.012, uniform_share: float = 0.3):
    """Surface points/normals and SDF samples of a watertight unit-cube mesh (DESIGN §3.3)."""
    import igl
    import trimesh
    seed = int(rng.integers(2**31))
    pts, fi = trimesh.sample.sample_surface(mesh_unit, n_points, seed=seed)
    normals = mesh_unit.face_normals[fi]
    n_u = int(round(n_sdf * uniform_share))
    uni = rng.uniform(-1.025, 1.025, (n_u, 3))
    near, _ = trimesh.sample.sample_surface(mesh_unit, n_sdf - n_u, seed=seed + 1)
    near = near + rng.normal(0.0, sigma, near.shape)
    q = np.concatenate([uni, near])
    # pseudonormal signs: exact on watertight meshes and 3x faster than the winding number
    d = igl.signed_distance(q.astype(np.float64), np.asarray(mesh_unit.vertices, dtype=np.float64),
                            np.asarray(mesh_unit.faces, dtype=np.int64),
                            sign_type=igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)[0]
    return pts, normals, np.concatenate([q, d[:, None]], axis=1)


def primitive_mesh(kind: str, rng: np.random.Generator):
    import trimesh
    if kind == "box":
        return trimesh.creation.box(extents=rng.uniform(0.1, 1.0, 3))
    if kind == "cylinder":
        return trimesh.creation.cylinder(radius=rng.uniform(0.1, 0.5), height=rng.uniform(0.1, 1.0),
                                         sections=48)
    if kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=3, radius=rng.uniform(0.2, 0.5))
    if kind == "capsule":
        return trimesh.creation.capsule(radius=rng.uniform(0.1, 0.3), height=rng.uniform(0.2, 0.8))
    raise ValueError(kind)


PRIMITIVE_LABELS = {"box": "body", "cylinder": "knob", "sphere": "button", "capsule": "handle"}


def make_primitive_dataset(root: str | Path, n_objects: int = 8, *, parts_per_object: int = 2,
                           n_points: int = 512, n_sdf: int = 2048, seed: int = 0,
                           kinds: tuple[str, ...] = ("box", "cylinder", "sphere", "capsule"),
                           splits: tuple[float, float] = (0.6, 0.2)) -> Path:
    """Write a prepared dataset of objects made of random primitives (fixed joints)."""
    root = Path(root)
    rng = np.random.default_rng(seed)
    ids = [f"prim{i:04d}" for i in range(n_objects)]
    n_tr = max(1, int(round(n_objects * splits[0])))
    n_va = max(1, int(round(n_objects * splits[1]))) if n_objects > 2 else 0
    split_of = {oid: ("train" if i < n_tr else "val" if i < n_tr + n_va else "test")
                for i, oid in enumerate(ids)}
    labels_all = set()
    for oid in ids:
        pts, nrm, sdf, centers, scales, labels, tokens = [], [], [], [], [], [], []
        offset = 0.0
        for k in range(parts_per_object):
            kind = kinds[int(rng.integers(len(kinds)))]
            mesh = primitive_mesh(kind, rng)
            mesh.apply_translation([offset - mesh.bounds[0][0], 0.0, -mesh.bounds[0][2]])
            offset = mesh.bounds[1][0]
            unit, c, s = normalise_to_unit_cube(mesh)
            p, n, d = sample_part(unit, n_points, n_sdf, rng)
            pts.append(p); nrm.append(n); sdf.append(d); centers.append(c); scales.append(s)
            labels.append(PRIMITIVE_LABELS[kind])
            lo, hi = mesh.bounds
            tokens.append([*(hi - lo), *((lo + hi) / 2), 0, 0, 0, 0, 0, 1, 0, 0, 0, 0])
            (root / "meshes" / oid).mkdir(parents=True, exist_ok=True)
            mesh.export(root / "meshes" / oid / f"{k}.obj")
        labels_all.update(labels)
        rec = fmt.ObjectRecord(id=oid, category="Primitives", split=split_of[oid], labels=labels,
                               parents=[-1] + [0] * (parts_per_object - 1),
                               joint_types=[0] * parts_per_object,
                               tokens=[[float(x) for x in t] for t in tokens],
                               part_names=[f"part{k}" for k in range(parts_per_object)])
        fmt.save_record(root, rec)
        fmt.save_part_arrays(root, oid, points=np.asarray(pts, np.float16),
                             normals=np.asarray(nrm, np.float16), sdf=np.asarray(sdf, np.float16),
                             center=np.asarray(centers, np.float32),
                             scale=np.asarray(scales, np.float32))
    fmt.atomic_write_json(root / "manifest.json", {
        "format": fmt.FORMAT_VERSION, "data_version": f"primitives-{seed}-{n_objects}",
        "source": "model.geometry.data.make_primitive_dataset", "seed": seed,
        "splits": {s: [o for o in ids if split_of[o] == s] for s in ("train", "val", "test")},
        "labels": sorted(labels_all), "categories": ["Primitives"]})
    return root
