"""`artformer eval` end to end on a tiny prepared dataset (baselines; the model run needs the
pipeline's tiny checkpoints and is in test_metrics_eval_model.py)."""
import json
from pathlib import Path

import numpy as np
import pytest

from model.data import format as fmt


def build_prepared(root: Path, n_train: int = 6, n_test: int = 3, seed: int = 11) -> Path:
    """A minimal prepared dataset (records + meshes) from the procedural generator."""
    from model.data.describe import describe
    from model.data.synth import generate_object
    ids = {"train": [], "val": [], "test": []}
    for i in range(n_train + n_test):
        obj = generate_object(seed=seed, index=i)
        split = "train" if i < n_train else "test"
        oid = f"obj{i:03d}"
        toks, types, parents, labels = obj.tokens()
        order = obj.topological_order()
        rec = fmt.ObjectRecord(id=oid, category=obj.category, split=split, labels=labels,
                               parents=parents.tolist(), joint_types=types.tolist(),
                               tokens=toks.tolist(),
                               descriptions=describe(obj, np.random.default_rng(i)),
                               summary=obj.summary(),
                               part_names=[obj.parts[k].name for k in order])
        fmt.save_record(root, rec)
        mdir = root / "meshes" / oid
        mdir.mkdir(parents=True, exist_ok=True)
        for k, j in enumerate(order):
            obj.parts[j].mesh.export(mdir / f"{k}.obj")
        ids[split].append(oid)
    fmt.atomic_write_json(root / "manifest.json", {
        "format": fmt.FORMAT_VERSION, "data_version": "test", "source": "synth", "seed": seed,
        "splits": ids, "labels": [], "categories": []})
    return root


@pytest.fixture(scope="module")
def prepared(tmp_path_factory):
    return build_prepared(tmp_path_factory.mktemp("prepared"))


def test_reference_objects_round_trip(prepared):
    from model.metrics.reference import Dataset
    data = Dataset.open(prepared)
    obj = data.object(data.ids("test")[0])
    assert all(p.mesh is not None for p in obj.parts)
    obj.validate()


def test_eval_baselines_only(prepared, tmp_path):
    from model.metrics.commands import main
    out = tmp_path / "eval"
    rc = main(["eval", "--data", str(prepared), "--baselines-only", "--preset", "tiny",
               "--freeform", "4", "--out", str(out)])
    assert rc == 0
    res = json.loads((out / "results.json").read_text())
    rows = {r["name"]: r for r in res["rows"]}
    assert set(rows) == {"retrieval", "train (floor)", "test (GT)"}
    # GT objects are collision-checked by the generator: POR ~ 0; their own descriptions
    # parse back to their structure.
    assert rows["test (GT)"]["por"] < 1e-3
    assert rows["test (GT)"]["alignment_test"] == 1.0
    for name in ("retrieval", "train (floor)"):
        r = rows[name]
        assert r["mmd"] >= 0 and 0 < r["cov"] <= 1 and 0 <= r["nna"] <= 1
    assert rows["retrieval"]["validity"] == 1.0       # dataset objects export and simulate
    assert len(rows["retrieval"]["retrieved_ids"]) == res["n_test"] + res["n_freeform"]
    md = (out / "results.md").read_text()
    assert "| retrieval |" in md and "ArtFormer (paper)" in md
    for f in ("por.png", "id_set_metrics.png", "alignment.png", "validity.png"):
        assert (out / f).stat().st_size > 1000
