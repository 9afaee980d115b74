"""`artformer data stats`: counts per category, parts per object, joint types, labels and
description lengths of a prepared dataset (or of a folder of PartNet-Mobility objects)."""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np

from model.core.objects import JointType
from model.data.format import DESCRIPTION_LENGTHS


def _records(root: Path):
    """(category, labels, joint type names, descriptions, split) per object."""
    if (root / "manifest.json").exists():
        from model.data.format import load_manifest, load_record
        m = load_manifest(root)
        for split, ids in m["splits"].items():
            for i in ids:
                r = load_record(root, i)
                yield r.category, r.labels, [JointType(t).name.lower() for t in r.joint_types], r.descriptions, split
        return
    from model.data.partnet import find_object_folders, load_partnet
    for folder in find_object_folders(root):
        d = {}
        if (folder / "descriptions.json").exists():
            with open(folder / "descriptions.json") as f:
                d = json.load(f).get("descriptions", {})
        try:
            obj = load_partnet(folder)
        except Exception:  # stats of a damaged folder are not worth a crash
            continue
        yield (obj.category, [p.label for p in obj.parts], [p.joint.type.name.lower() for p in obj.parts],
               d or obj.metadata.get("descriptions", {}), "-")


def compute_stats(root) -> dict:
    root = Path(root)
    cats, splits, labels, joints = Counter(), Counter(), Counter(), Counter()
    parts_hist, moving_hist = Counter(), Counter()
    desc_words: dict[str, list[int]] = {k: [] for k in DESCRIPTION_LENGTHS}
    per_cat_parts: dict[str, list[int]] = {}
    n = 0
    for cat, labs, jts, desc, split in _records(root):
        n += 1
        cats[cat] += 1
        splits[split] += 1
        labels.update(labs)
        joints.update(jts)
        parts_hist[len(labs)] += 1
        moving = sum(j != "fixed" for j in jts)
        moving_hist[moving] += 1
        per_cat_parts.setdefault(cat, []).append(len(labs))
        for k, texts in (desc or {}).items():
            desc_words.setdefault(k, []).extend(len(t.split()) for t in texts)
    if n == 0:
        raise FileNotFoundError(f"{root}: no objects found (not a prepared dataset or PartNet-Mobility folder)")
    return {"root": str(root), "objects": n, "categories": dict(cats), "splits": dict(splits),
            "labels": dict(labels), "joint_types": dict(joints),
            "parts_per_object": dict(sorted(parts_hist.items())),
            "moving_per_object": dict(sorted(moving_hist.items())),
            "parts_per_category": {c: [float(np.mean(v)), int(min(v)), int(max(v))] for c, v in per_cat_parts.items()},
            "description_words": {k: [float(np.mean(v)), int(min(v)), int(max(v)), len(v)]
                                  for k, v in desc_words.items() if v}}


def format_table(st: dict, markdown: bool = False) -> str:
    rows = [("objects", str(st["objects"]))]
    rows += [(f"split {k}", str(v)) for k, v in sorted(st["splits"].items())]
    for c, v in sorted(st["categories"].items()):
        mean, lo, hi = st["parts_per_category"][c]
        rows.append((f"category {c}", f"{v} objects, parts/object mean {mean:.1f} (min {lo}, max {hi})"))
    rows.append(("parts per object", ", ".join(f"{k}:{v}" for k, v in st["parts_per_object"].items())))
    rows.append(("moving parts per object", ", ".join(f"{k}:{v}" for k, v in st["moving_per_object"].items())))
    rows.append(("joint types", ", ".join(f"{k} {v}" for k, v in sorted(st["joint_types"].items()))))
    rows.append(("part labels", ", ".join(f"{k} {v}" for k, v in sorted(st["labels"].items(), key=lambda x: -x[1]))))
    for k, (mean, lo, hi, cnt) in st["description_words"].items():
        rows.append((f"description '{k}'", f"{cnt} texts, words mean {mean:.1f} (min {lo}, max {hi})"))
    if markdown:
        out = ["| statistic | value |", "|---|---|"] + [f"| {a} | {b} |" for a, b in rows]
        return "\n".join(out)
    w = max(len(a) for a, _ in rows)
    return "\n".join(f"{a:<{w}}  {b}" for a, b in rows)


def save_plot(st: dict, path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(2, 2, figsize=(11, 7))
    c = st["categories"]
    ax[0, 0].bar(list(c), list(c.values()), color="tab:blue")
    ax[0, 0].set_title("objects per category")
    ax[0, 0].tick_params(axis="x", rotation=30)
    h = st["parts_per_object"]
    m = st["moving_per_object"]
    ax[0, 1].bar([int(k) - 0.2 for k in h], list(h.values()), width=0.4, label="parts")
    ax[0, 1].bar([int(k) + 0.2 for k in m], list(m.values()), width=0.4, label="moving parts")
    ax[0, 1].set_title("parts per object")
    ax[0, 1].legend()
    j = st["joint_types"]
    ax[1, 0].bar(list(j), list(j.values()), color="tab:orange")
    ax[1, 0].set_title("joint types (all parts)")
    d = st["description_words"]
    ax[1, 1].bar(list(d), [v[0] for v in d.values()], yerr=None, color="tab:green")
    ax[1, 1].set_title("mean words per description")
    fig.suptitle(f"{st['root']} — {st['objects']} objects")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def audit_objects(root, states: int = 10, limit: int = 0) -> dict:
    """Physical audit of PartNet-Mobility folders (e.g. ``data/synth/v1``): at ``states``
    openness ratios, exact pairwise intersection volumes and volume IoUs of all parts (POR as
    DESIGN §7 defines it: mean over states of the mean pairwise IoU), the largest overlap seen,
    the objects with a real overlap (> 1 mm³ or a mean thickness 2V/A > 0.2 mm, the
    generator's own criterion) and how many objects are distinct (rounded tokens)."""
    import hashlib

    from model.core import meshops
    from model.data.partnet import find_object_folders, load_partnet
    folders = find_object_folders(root)
    if limit:
        folders = folders[:limit]
    por, por_max, worst = [], [], (0.0, "")
    hashes, overlapping = set(), set()
    for folder in folders:
        obj = load_partnet(folder)
        toks = obj.tokens()[0]
        hashes.add(hashlib.sha1(np.round(toks, 4).tobytes() + obj.category.encode()).hexdigest())
        mans = {p.name: meshops.to_manifold(p.mesh) for p in obj.parts}
        per_state = []
        for r in np.linspace(0.0, 1.0, states):
            T = obj.link_transforms(ratio=float(r))
            posed = [mans[p.name].transform(np.ascontiguousarray(T[p.name][:3, :4])) for p in obj.parts]
            inter = meshops.pairwise_intersection_volumes(posed)
            n = len(posed)
            iu = np.triu_indices(n, 1)
            for a, b in zip(*iu):
                v = inter[a, b]
                if v > 1e-12 and folder.name not in overlapping:
                    x = posed[a] ^ posed[b]
                    if v > 1e-9 or 2 * v / max(x.surface_area(), 1e-18) > 2e-4:
                        overlapping.add(folder.name)
            vols = np.diag(inter)
            union = vols[:, None] + vols[None, :] - inter
            iou = inter[iu] / np.maximum(union[iu], 1e-30)
            per_state.append(float(iou.mean()) if len(iou) else 0.0)
            if len(iou) and inter[iu].max() > worst[0]:
                worst = (float(inter[iu].max()), f"{folder.name} r={r:.2f}")
        por.append(float(np.mean(per_state)))
        por_max.append(float(np.max(per_state)))
    return {"objects": len(folders), "distinct": len(hashes), "overlapping": sorted(overlapping),
            "por_mean": float(np.mean(por)),
            "por_max_state": float(np.max(por_max)), "max_intersection_m3": worst[0], "worst": worst[1]}
