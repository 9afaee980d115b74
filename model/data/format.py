"""On-disk format of the prepared (preprocessed) dataset — the contract between data
preparation and every trainer.

Layout of a prepared dataset folder ``ROOT`` (one per data version)::

    ROOT/manifest.json            {"format": 1, "data_version": str, "source": str,
                                   "seed": int, "splits": {"train": [ids], "val": [...], "test": [...]},
                                   "labels": [sorted part labels], "categories": [...]}
    ROOT/objects/<id>.json        ObjectRecord (structure, tokens, texts), see below
    ROOT/parts/<id>.npz           per-part geometry arrays, part k in the object's token order:
        points     (K, P, 3) float16  surface points in the part's unit cube
        normals    (K, P, 3) float16  their normals
        sdf        (K, S, 4) float16  [x, y, z, signed distance] in the unit cube (neg. inside)
        center     (K, 3)   float32   unit-cube normalisation: x_unit = (x_obj - center) * scale
        scale      (K,)     float32
    ROOT/meshes/<id>/<k>.obj      (optional) the watertight part mesh in object coordinates

Unit cube: part centred on its bbox centre, isotropic scale so its longest side spans
[-0.95, 0.95] (DESIGN §3.3).
"""
from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from model.core.files import atomic_write_bytes, atomic_write_json, atomic_write_text  # noqa: F401

FORMAT_VERSION = 1
DESCRIPTION_LENGTHS = ("detailed", "sentences", "sentence", "words")


@dataclass
class ObjectRecord:
    id: str
    category: str
    split: str                       # train | val | test
    labels: list[str]                # part labels, token order (parents before children)
    parents: list[int]               # parent index in token order, -1 for the root
    joint_types: list[int]           # model.core.JointType values
    tokens: list[list[float]]        # (K, 16) articulation tokens (object frame, metres)
    descriptions: dict[str, list[str]] = field(default_factory=dict)  # length -> texts
    summary: dict = field(default_factory=dict)                       # structured summary
    part_names: list[str] = field(default_factory=list)
    source: str = ""                 # path of the source object folder

    @property
    def num_parts(self) -> int:
        return len(self.labels)

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict) -> "ObjectRecord":
        return cls(**d)


def save_record(root: os.PathLike, rec: ObjectRecord) -> None:
    atomic_write_json(Path(root) / "objects" / f"{rec.id}.json", rec.to_json())


def load_record(root: os.PathLike, obj_id: str) -> ObjectRecord:
    with open(Path(root) / "objects" / f"{obj_id}.json") as f:
        return ObjectRecord.from_json(json.load(f))


def save_part_arrays(root: os.PathLike, obj_id: str, **arrays: np.ndarray) -> None:
    import io
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write_bytes(Path(root) / "parts" / f"{obj_id}.npz", buf.getvalue())


def load_part_arrays(root: os.PathLike, obj_id: str) -> dict[str, np.ndarray]:
    with np.load(Path(root) / "parts" / f"{obj_id}.npz") as z:
        return {k: z[k] for k in z.files}


def load_manifest(root: os.PathLike) -> dict:
    path = Path(root) / "manifest.json"
    if not path.exists():
        raise FileNotFoundError(f"{root} is not a prepared dataset (no manifest.json); "
                                f"run `artformer data prepare` first")
    with open(path) as f:
        m = json.load(f)
    if m.get("format") != FORMAT_VERSION:
        raise ValueError(f"{root}: prepared-data format {m.get('format')} != {FORMAT_VERSION}; "
                         f"re-run `artformer data prepare`")
    return m


def split_ids(root: os.PathLike, split: str) -> list[str]:
    m = load_manifest(root)
    if split not in m["splits"]:
        raise KeyError(f"unknown split {split!r}; have {sorted(m['splits'])}")
    return list(m["splits"][split])
