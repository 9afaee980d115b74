"""Reader over a prepared dataset folder (format: :mod:`model.data.format`) for the trainers.

    ds = PreparedDataset("data/prepared/v1", split="train")
    rec = ds.record(0)                  # ObjectRecord: labels, parents, joint types, tokens, texts
    arrays = ds.part_arrays(0)          # points (K, P, 3), normals, sdf (K, S, 4), center, scale
    part = ds.part(17)                  # one part of the split: {"points", "normals", "sdf", ...}
    obj = ds.to_object(0)               # ArticulatedObject (+ watertight meshes when kept)

Arrays are read lazily and a small LRU cache keeps the last objects' arrays.
"""
from __future__ import annotations

from collections import OrderedDict
from pathlib import Path
from typing import Iterator, Optional, Union

import numpy as np

from model.data.format import ObjectRecord, load_manifest, load_part_arrays, load_record


class PreparedDataset:
    """Objects of one split (``"train" | "val" | "test" | "all"``) of a prepared folder."""

    def __init__(self, root: Union[str, Path], split: str = "train", cache_objects: int = 64):
        self.root = Path(root)
        self.manifest = load_manifest(self.root)
        if split == "all":
            self.ids = [i for s in ("train", "val", "test") for i in self.manifest["splits"].get(s, [])]
        elif split in self.manifest["splits"]:
            self.ids = list(self.manifest["splits"][split])
        else:
            raise KeyError(f"unknown split {split!r}; have {sorted(self.manifest['splits'])} or 'all'")
        self.split = split
        self._records: dict[str, ObjectRecord] = {}
        self._arrays: OrderedDict[str, dict] = OrderedDict()
        self._cache = max(1, int(cache_objects))
        self._part_index: Optional[list[tuple[str, int]]] = None

    # -- objects ---------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.ids)

    def __iter__(self) -> Iterator[ObjectRecord]:
        for i in range(len(self)):
            yield self.record(i)

    def _id(self, key: Union[int, str]) -> str:
        return self.ids[key] if isinstance(key, (int, np.integer)) else str(key)

    def record(self, key: Union[int, str]) -> ObjectRecord:
        obj_id = self._id(key)
        if obj_id not in self._records:
            self._records[obj_id] = load_record(self.root, obj_id)
        return self._records[obj_id]

    def part_arrays(self, key: Union[int, str]) -> dict[str, np.ndarray]:
        obj_id = self._id(key)
        if obj_id in self._arrays:
            self._arrays.move_to_end(obj_id)
            return self._arrays[obj_id]
        arr = load_part_arrays(self.root, obj_id)
        self._arrays[obj_id] = arr
        if len(self._arrays) > self._cache:
            self._arrays.popitem(last=False)
        return arr

    def mesh_path(self, key: Union[int, str], k: int) -> Optional[Path]:
        p = self.root / "meshes" / self._id(key) / f"{k}.obj"
        return p if p.exists() else None

    def to_object(self, key: Union[int, str], with_meshes: bool = True):
        """The record as an ArticulatedObject (token order; meshes in object coordinates)."""
        from model.core.objects import ArticulatedObject
        rec = self.record(key)
        obj = ArticulatedObject.from_tokens(np.asarray(rec.tokens), rec.joint_types, rec.parents, rec.labels,
                                            category=rec.category, name=rec.id)
        if rec.part_names and len(set(rec.part_names)) == len(rec.part_names):
            for p, n in zip(obj.parts, rec.part_names):
                p.name = n
        if with_meshes:
            import trimesh
            for k, p in enumerate(obj.parts):
                path = self.mesh_path(key, k)
                if path is not None:
                    p.mesh = trimesh.load(str(path), force="mesh", process=False)
        obj.metadata.update(descriptions=rec.descriptions, summary=rec.summary, source=rec.source)
        return obj

    # -- parts (for the shape model) -------------------------------------------------------
    @property
    def part_index(self) -> list[tuple[str, int]]:
        """(object id, part k) of every part of the split, object by object."""
        if self._part_index is None:
            self._part_index = [(self.ids[i], k) for i in range(len(self))
                                for k in range(self.record(i).num_parts)]
        return self._part_index

    def num_parts(self) -> int:
        return len(self.part_index)

    def part(self, j: int) -> dict:
        """Part j of the split: points (P, 3), normals (P, 3), sdf (S, 4) as float32, plus
        label, category, object id, index k, center (3,) and scale."""
        obj_id, k = self.part_index[j]
        arr = self.part_arrays(obj_id)
        rec = self.record(obj_id)
        return {"points": arr["points"][k].astype(np.float32), "normals": arr["normals"][k].astype(np.float32),
                "sdf": arr["sdf"][k].astype(np.float32), "center": arr["center"][k], "scale": float(arr["scale"][k]),
                "label": rec.labels[k], "category": rec.category, "object_id": obj_id, "k": k}

    def texts(self, key: Union[int, str], length: Optional[str] = None) -> list[str]:
        """Descriptions of an object (one length, or all lengths flattened)."""
        d = self.record(key).descriptions
        if length is not None:
            return list(d.get(length, []))
        return [t for v in d.values() for t in v]
