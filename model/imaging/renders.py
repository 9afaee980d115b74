"""The cached render set of a prepared dataset (``artformer data render``).

Layout of a render folder ``OUT`` (one per render version)::

    OUT/manifest.json          {"format": 1, "render_version": int, "data": str,
                                "data_version": str, "views": K, "size": 224, "seed": int}
    OUT/objects/<id>/<k>.png   view k of object <id> (224×224 RGB), k = 0..K-1
    OUT/objects/<id>/views.json  {"id", "category", "split", "views": [ViewSpec...]}
                               (written last: its presence marks the object done)
    OUT/features/<tag>.npz     cached encoder trunk features of every view (model.imaging.train)

Rendering is resumable (done objects are skipped), deterministic per (object id, seed), and
parallel over objects (a process pool). ``reuse`` names an earlier render folder (same render
settings) of another data version: an object whose render inputs (record tree and tokens,
prepared mesh bytes) are the same in both datasets gets that folder's views instead of being
rendered again, so a data version that changes one category re-renders only that category.
"""
from __future__ import annotations

import hashlib
import io
import json
import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from model.core import ArticulatedObject
from model.data.format import ObjectRecord, atomic_write_bytes, atomic_write_json, load_manifest, load_record

from .render import RENDER_SIZE, ViewSpec, render_view, sample_views

log = logging.getLogger(__name__)

RENDER_FORMAT = 1
RENDER_VERSION = 1      # bump when the view distribution or the renderer changes


class RenderSetError(RuntimeError):
    """A render folder is missing, incomplete or does not match the request."""


def object_from_record(data_root: os.PathLike, rec: ObjectRecord) -> ArticulatedObject:
    """Rebuild a record's object with part meshes (rest pose, object frame).

    Uses the prepared watertight meshes ``meshes/<id>/<k>.obj`` when they exist, else reads the
    source object folder with the dataset's PartNet-Mobility loader.
    """
    import trimesh
    root = Path(data_root)
    obj = ArticulatedObject.from_tokens(np.asarray(rec.tokens, float), rec.joint_types, rec.parents,
                                        rec.labels, category=rec.category, name=rec.id)
    mesh_dir = root / "meshes" / rec.id
    paths = [mesh_dir / f"{k}.obj" for k in range(rec.num_parts)]
    if all(p.exists() for p in paths):
        for part, p in zip(obj.parts, paths):
            part.mesh = trimesh.load(p, force="mesh", process=False)
        return obj
    if rec.source and Path(rec.source).exists():
        return _object_from_source(rec)
    raise RenderSetError(f"object {rec.id}: no prepared meshes in {mesh_dir} and source folder "
                         f"{rec.source!r} is missing; re-run `artformer data prepare` with meshes")


def _object_from_source(rec: ObjectRecord) -> ArticulatedObject:
    from model.data.partnet import load_partnet  # the dataset's PartNet-Mobility loader
    obj = load_partnet(rec.source)
    if len(obj.parts) != rec.num_parts:
        log.warning("object %s: source has %d parts, record %d", rec.id, len(obj.parts), rec.num_parts)
    obj.name, obj.category = rec.id, rec.category
    return obj


def _png_bytes(img: np.ndarray) -> bytes:
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG", optimize=False, compress_level=6)
    return buf.getvalue()


def _render_one(args) -> tuple[str, Optional[str]]:
    data_root, out_root, obj_id, views, seed, size = args
    try:
        done = Path(out_root) / "objects" / obj_id / "views.json"
        if done.exists():
            return obj_id, None
        rec = load_record(data_root, obj_id)
        obj = object_from_record(data_root, rec)
        specs = sample_views(obj_id, list(rec.labels), views, seed)
        folder = done.parent
        for k, spec in enumerate(specs):
            atomic_write_bytes(folder / f"{k}.png", _png_bytes(render_view(obj, spec, size)))
        atomic_write_json(done, {"id": obj_id, "category": rec.category, "split": rec.split,
                                 "views": [s.to_json() for s in specs]})
        return obj_id, None
    except Exception as e:  # one broken object must not stop the set; reported at the end
        return obj_id, f"{type(e).__name__}: {e}"


def render_inputs(data_root: os.PathLike, obj_id: str) -> Optional[str]:
    """A digest of what the renders of one object depend on besides the view settings: its
    record's tree, labels and tokens and the bytes of its prepared meshes (None when a mesh
    or the record is missing: such an object is always rendered)."""
    try:
        rec = load_record(data_root, obj_id)
    except FileNotFoundError:
        return None
    return _inputs_digest(data_root, rec)


def _inputs_digest(data_root: os.PathLike, rec: ObjectRecord) -> Optional[str]:
    root, obj_id = Path(data_root), rec.id
    h = hashlib.sha256(json.dumps([rec.category, rec.labels, rec.parents, rec.joint_types,
                                   rec.tokens]).encode())
    for k in range(rec.num_parts):
        path = root / "meshes" / obj_id / f"{k}.obj"
        if not path.exists():
            return None
        h.update(path.read_bytes())
    return h.hexdigest()


def _reuse_one(args) -> tuple[str, bool]:
    """Copy one object's views from an earlier render folder when its inputs are the same."""
    data_root, out_root, obj_id, old_data, old_out = args
    src = Path(old_out) / "objects" / obj_id
    if not (src / "views.json").exists():
        return obj_id, False
    try:
        rec = load_record(data_root, obj_id)
    except FileNotFoundError:       # rendering it reports the missing record
        return obj_id, False
    mine = _inputs_digest(data_root, rec)
    if mine is None or mine != render_inputs(old_data, obj_id):
        return obj_id, False
    meta = json.loads((src / "views.json").read_text())
    folder = Path(out_root) / "objects" / obj_id
    folder.mkdir(parents=True, exist_ok=True)
    for k in range(len(meta["views"])):      # a hard link where both folders share a disk
        tmp = folder / f".{k}.png.link"
        try:
            tmp.unlink(missing_ok=True)
            os.link(src / f"{k}.png", tmp)
            os.replace(tmp, folder / f"{k}.png")
        except OSError:
            atomic_write_bytes(folder / f"{k}.png", (src / f"{k}.png").read_bytes())
    atomic_write_json(folder / "views.json", {**meta, "category": rec.category,
                                              "split": rec.split})
    return obj_id, True


def _settings_diff(have: dict, want: dict, keys: tuple[str, ...]) -> dict:
    """The render settings among ``keys`` that differ: key -> (have, want)."""
    return {k: (have.get(k), want[k]) for k in keys if have.get(k) != want[k]}


def _reuse_source(reuse: os.PathLike, want: dict) -> tuple[Path, Path]:
    """The earlier render folder and its dataset, checked against the requested settings."""
    reuse = Path(reuse)
    have = load_render_manifest(reuse)
    diff = _settings_diff(have, want, ("format", "render_version", "views", "size", "seed"))
    if diff:
        raise RenderSetError(f"--reuse {reuse} was rendered with other settings {diff} "
                             f"(its, requested): its views cannot stand in for new ones")
    old_data = Path(have.get("data", ""))
    if not (old_data / "manifest.json").exists():
        raise RenderSetError(f"--reuse {reuse}: its dataset {str(old_data)!r} is not here, so "
                             f"its objects cannot be compared with the new ones")
    return reuse, old_data


@dataclass
class RenderReport:
    rendered: int
    skipped: int
    failed: dict
    seconds: float
    reused: int = 0


def render_dataset(data_root: os.PathLike, out_root: os.PathLike, views: int = 8, seed: int = 0,
                   workers: int = 2, limit: int = 0, splits: tuple[str, ...] = ("train", "val", "test"),
                   progress: bool = False, reuse: Optional[os.PathLike] = None) -> RenderReport:
    """Render every object of the given splits (``limit`` > 0: the first N ids of each split).
    ``reuse``: an earlier render folder whose views stand in for objects with the same render
    inputs (module doc); ``RenderReport.reused`` counts them."""
    import time
    t0 = time.perf_counter()
    data_root, out_root = Path(data_root), Path(out_root)
    manifest = load_manifest(data_root)
    want = {"format": RENDER_FORMAT, "render_version": RENDER_VERSION,
            "data": str(data_root), "data_version": manifest.get("data_version", ""),
            "views": int(views), "size": RENDER_SIZE, "seed": int(seed)}
    mpath = out_root / "manifest.json"
    if mpath.exists():
        have = json.loads(mpath.read_text())
        diff = _settings_diff(have, want, ("format", "render_version", "data_version", "views",
                                           "size", "seed"))
        if diff:
            raise RenderSetError(f"{out_root} holds renders made with other settings {diff} "
                                 f"(existing, requested); choose a new --out or delete it")
    else:
        atomic_write_json(mpath, want)
    ids = []
    for s in splits:
        sid = list(manifest["splits"].get(s, []))
        ids += sid[:limit] if limit > 0 else sid
    todo = [i for i in ids if not (out_root / "objects" / i / "views.json").exists()]
    from model.core.runtime import map_jobs
    reused = 0
    if reuse is not None and todo:
        old_out, old_data = _reuse_source(reuse, want)
        copied = {oid for oid, ok in map_jobs(
            _reuse_one, [(str(data_root), str(out_root), i, str(old_data), str(old_out))
                         for i in todo], workers) if ok}
        reused = len(copied)
        todo = [i for i in todo if i not in copied]
    jobs = [(str(data_root), str(out_root), i, int(views), int(seed), RENDER_SIZE) for i in todo]
    failed = {}
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(jobs), desc="render", unit="obj")
    for oid, err in map_jobs(_render_one, jobs, workers):
        if err:
            failed[oid] = err
        if bar:
            bar.update(1)
    if bar:
        bar.close()
    for oid, err in list(failed.items())[:5]:
        log.warning("render of %s failed: %s", oid, err)
    return RenderReport(rendered=len(jobs) - len(failed),
                        skipped=len(ids) - len(jobs) - reused, failed=failed,
                        seconds=time.perf_counter() - t0, reused=reused)


# ---------------------------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------------------------
def load_render_manifest(out_root: os.PathLike) -> dict:
    path = Path(out_root) / "manifest.json"
    if not path.exists():
        raise RenderSetError(f"{out_root} is not a render folder (no manifest.json); "
                             f"run `artformer data render` first")
    m = json.loads(path.read_text())
    if m.get("format") != RENDER_FORMAT:
        raise RenderSetError(f"{out_root}: render format {m.get('format')} != {RENDER_FORMAT}")
    return m


def rendered_ids(out_root: os.PathLike, ids: list[str]) -> list[str]:
    """The ids among ``ids`` whose renders are complete."""
    root = Path(out_root) / "objects"
    return [i for i in ids if (root / i / "views.json").exists()]


def view_paths(out_root: os.PathLike, obj_id: str) -> list[Path]:
    folder = Path(out_root) / "objects" / obj_id
    meta = json.loads((folder / "views.json").read_text())
    return [folder / f"{k}.png" for k in range(len(meta["views"]))]


def view_specs(out_root: os.PathLike, obj_id: str) -> list[ViewSpec]:
    meta = json.loads((Path(out_root) / "objects" / obj_id / "views.json").read_text())
    return [ViewSpec(**v) for v in meta["views"]]
