"""Preprocessing: outputs in the documented format, resumable, deterministic splits; the
dataset reader and the stats command."""
import json

import numpy as np
import pytest

from model.data import format as fmt
from model.data.preprocess import PrepareConfig, assign_splits, make_watertight, prepare_dataset
from model.data.synth import synthesize_dataset


@pytest.fixture(scope="module")
def three(tmp_path_factory):
    root = tmp_path_factory.mktemp("synth")
    synthesize_dataset(str(root / "src"), 3, seed=9, workers=1, progress=False)
    return root


def _cfg(root, **kw):
    return PrepareConfig(src=str(root / "src"), out=str(root / "prep"), points=512, samples=2000, workers=1, **kw)


def test_prepare_three_is_resumable(three):
    m = prepare_dataset(_cfg(three), progress=False)
    ids = sorted(i for s in m["splits"].values() for i in s)
    assert ids == ["000000", "000001", "000002"] and not m["errors"]
    assert m["last_run"]["processed"] == 3
    assert m["points_per_part"] == 512 and m["sdf_samples_per_part"] == 2000 and m["data_version"]
    out = three / "prep"
    assert fmt.load_manifest(out)["format"] == fmt.FORMAT_VERSION
    # remove one object's record: only that one is redone
    (out / "objects" / "000001.json").unlink()
    mtime = (out / "parts" / "000000.npz").stat().st_mtime_ns
    m2 = prepare_dataset(_cfg(three), progress=False)
    assert m2["last_run"]["processed"] == 1
    assert (out / "parts" / "000000.npz").stat().st_mtime_ns == mtime
    assert m2["splits"] == m["splits"]
    m3 = prepare_dataset(_cfg(three), progress=False)
    assert m3["last_run"]["processed"] == 0


def test_prepared_arrays_and_record(three):
    prepare_dataset(_cfg(three), progress=False)
    out = three / "prep"
    rec = fmt.load_record(out, "000002")
    arr = fmt.load_part_arrays(out, "000002")
    K = rec.num_parts
    assert arr["points"].shape == (K, 512, 3) and arr["points"].dtype == np.float16
    assert arr["normals"].shape == (K, 512, 3) and arr["sdf"].shape == (K, 2000, 4)
    assert arr["center"].shape == (K, 3) and arr["scale"].shape == (K,)
    assert len(rec.tokens) == K and len(rec.tokens[0]) == 16 and rec.parents[0] == -1
    assert all(rec.parents[k] < k for k in range(1, K)), "parents before children"
    assert set(rec.descriptions) == set(fmt.DESCRIPTION_LENGTHS)
    assert rec.summary["num_parts"] == K
    pts = arr["points"].astype(np.float32)
    assert np.abs(pts).max() <= 0.951 and np.isclose(np.abs(pts).max(axis=(1, 2)), 0.95, atol=0.01).all()
    sdf = arr["sdf"].astype(np.float32)
    n_uni = int(round(0.3 * 2000))
    assert np.abs(sdf[:, :n_uni, :3]).max() <= 1.026
    assert (sdf[:, :, 3] < 0).any(axis=1).all(), "every part has inside samples"
    # near-surface samples have small distances; the stored unit transform maps the mesh back
    assert np.median(np.abs(sdf[:, n_uni:, 3])) < 0.03
    import trimesh
    mesh = trimesh.load(str(out / "meshes" / "000002" / "0.obj"), force="mesh")
    unit = (mesh.vertices - arr["center"][0]) * arr["scale"][0]
    assert np.isclose(np.abs(unit).max(), 0.95, atol=1e-3)


def test_splits_fixed_and_by_object():
    ids = [f"{i:04d}" for i in range(200)]
    a, b = assign_splits(ids, 0), assign_splits(list(reversed(ids)), 0)
    assert a == b
    counts = {s: sum(v == s for v in a.values()) for s in ("train", "val", "test")}
    assert counts == {"train": 160, "val": 20, "test": 20}
    assert assign_splits(ids, 1) != a


def test_make_watertight_closes_open_soup():
    import trimesh
    from model.core import meshops
    box = trimesh.creation.box([0.4, 0.3, 0.2])
    soup = trimesh.Trimesh(box.vertices, box.faces[:-4], process=False)   # two faces open
    shell = make_watertight(soup, 40)
    assert shell.is_watertight and meshops.volume(shell) > 0
    assert np.allclose(shell.bounds, soup.bounds, atol=0.02)


def test_dataset_reader_and_stats(three, tmp_path):
    from model.data.commands import main
    from model.data.dataset import PreparedDataset
    prepare_dataset(_cfg(three), progress=False)
    out = three / "prep"
    ds = PreparedDataset(out, "all")
    assert len(ds) == 3 and ds.num_parts() == sum(ds.record(i).num_parts for i in range(3))
    p = ds.part(0)
    assert p["points"].shape == (512, 3) and p["sdf"].shape == (2000, 4) and p["label"] == "body"
    obj = ds.to_object(0)
    assert len(obj.parts) == ds.record(0).num_parts and obj.parts[0].mesh is not None
    obj.validate()
    assert ds.texts(0, "words")
    png = tmp_path / "stats.png"
    assert main(["data", "stats", str(out), "--plot", str(png)]) == 0
    assert png.exists() and png.stat().st_size > 1000
    with pytest.raises(KeyError):
        PreparedDataset(out, "nope")
    json.dumps(ds.manifest)


def test_only_closed_meshes_skip_the_shell():
    import trimesh
    from model.data.preprocess import is_closed_manifold
    box = trimesh.creation.box([0.4, 0.3, 0.2])
    assert is_closed_manifold(box)
    holed = trimesh.Trimesh(box.vertices, box.faces[:-1], process=False)   # repairable, but not closed
    assert not is_closed_manifold(holed)
    inverted = trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False)
    assert not is_closed_manifold(inverted)


def test_synth_command_categories(tmp_path, capsys):
    from model.data.commands import main
    from model.data.partnet import find_object_folders
    assert main(["data", "synth", "--n", "3", "--out", str(tmp_path / "u"), "--workers", "1",
                 "--categories", "USB"]) == 0
    folders = find_object_folders(tmp_path / "u")
    assert len(folders) == 3
    assert all(json.loads((f / "meta.json").read_text())["model_cat"] == "USB" for f in folders)
    assert main(["data", "synth", "--n", "1", "--out", str(tmp_path / "x"), "--categories", "Lamp"]) == 2
