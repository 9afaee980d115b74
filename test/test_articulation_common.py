"""Shared helpers of the articulation tests: a tiny prepared dataset written in the real
format (model.data.format), with simple cabinets and bottles whose descriptions state the
structure."""
from __future__ import annotations

import numpy as np

from model.data import format as fmt

WORDS = ["zero", "one", "two", "three", "four"]


def _cabinet(rng, n_drawers: int, door: bool):
    labels, parents, jts, toks = ["body"], [-1], [0], []
    w, d, h = 0.6, 0.5, 0.3 + 0.15 * n_drawers
    toks.append([w, d, h, 0, 0, h / 2, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0])
    for k in range(n_drawers):
        z = h - 0.15 * (k + 0.5)
        labels.append("drawer"); parents.append(0); jts.append(2)
        toks.append([0.45, 0.5, 0.12, 0, 0, z, 0.25, 0, z, 1, 0, 0, 0, 0.3, 0, 0])
        labels.append("handle"); parents.append(len(labels) - 2); jts.append(0)
        toks.append([0.02, 0.1, 0.02, 0.27, 0, z, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0])
    if door:
        labels.append("door"); parents.append(0); jts.append(1)
        toks.append([0.02, 0.3, 0.15, 0.26, 0.1, 0.1, 0.26, -0.05, 0.1, 0, 0, 1, 0, 0, 0, 1.57])
    toks = np.asarray(toks) * (1 + 0.05 * rng.normal(size=(len(toks), 16)))
    return "StorageFurniture", labels, parents, jts, toks


def _bottle(rng):
    toks = np.array([[0.08, 0.08, 0.25, 0, 0, 0.125, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0],
                     [0.03, 0.03, 0.02, 0, 0, 0.26, 0, 0, 0.26, 0, 0, 1, 0, 0.02, 0, 6.28]])
    toks = toks * (1 + 0.05 * rng.normal(size=toks.shape))
    return "Bottle", ["body", "cap"], [-1, 0], [0, 4], toks


def _texts(cat, labels, door):
    if cat == "Bottle":
        return {"detailed": ["A bottle whose cap screws on and off the body."],
                "sentences": ["A bottle. It has a screw cap."],
                "sentence": ["A bottle with a twist-off cap."],
                "words": ["screw cap bottle"]}
    n = labels.count("drawer")
    extra = " and a hinged door" if door else ""
    return {"detailed": [f"A storage cabinet with {WORDS[n]} sliding drawers{extra}; "
                         f"every drawer has a handle."],
            "sentences": [f"A cabinet. It has {WORDS[n]} drawers{extra}."],
            "sentence": [f"A cabinet with {WORDS[n]} drawers{extra}."],
            "words": [f"{WORDS[n]} drawer cabinet" + (" door" if door else "")]}


def write_toy_dataset(root, n: int = 24, seed: int = 0, points: int = 64,
                      version: str = "toy1", wordings: int = 1) -> list[str]:
    """Write n objects (train/val/test = 60/20/20 %) to ``root``; returns the ids. With
    ``wordings`` > 1 every description length gets that many wordings (numbered copies)."""
    rng = np.random.default_rng(seed)
    ids, splits = [], {"train": [], "val": [], "test": []}
    for i in range(n):
        kind = i % 4
        if kind == 3:
            cat, labels, parents, jts, toks = _bottle(rng)
            door = False
        else:
            door = kind == 2
            cat, labels, parents, jts, toks = _cabinet(rng, 1 + (i // 4) % 3, door)
        oid = f"toy_{i:03d}"
        split = "train" if i < 0.6 * n else ("val" if i < 0.8 * n else "test")
        splits[split].append(oid)
        rec = fmt.ObjectRecord(id=oid, category=cat, split=split, labels=labels,
                               parents=parents, joint_types=jts, tokens=toks.tolist(),
                               descriptions={k: v + [f"{v[0]} ({j + 2})" for j in range(wordings - 1)]
                                             for k, v in _texts(cat, labels, door).items()})
        fmt.save_record(root, rec)
        K = len(labels)
        pts = rng.uniform(-0.95, 0.95, size=(K, points, 3)) * rng.uniform(0.3, 1, size=(K, 1, 3))
        fmt.save_part_arrays(root, oid, points=pts.astype(np.float16),
                             normals=np.zeros_like(pts, dtype=np.float16),
                             sdf=np.zeros((K, 8, 4), np.float16),
                             center=np.zeros((K, 3), np.float32), scale=np.ones(K, np.float32))
        ids.append(oid)
    fmt.atomic_write_json(f"{root}/manifest.json", {
        "format": fmt.FORMAT_VERSION, "data_version": version, "source": "test", "seed": seed,
        "splits": splits, "labels": sorted({"body", "drawer", "handle", "door", "cap"}),
        "categories": ["Bottle", "StorageFurniture"]})
    return ids
