"""Training renders: view sampling and rendering deterministic under a seed, resumable cache."""
import json

import numpy as np
import pytest

from helpers import write_prepared
from model.imaging.render import render_view, sample_views


@pytest.fixture(scope="module")
def examples():
    from model.core.example import example_objects
    return example_objects()


def test_views_and_renders_are_deterministic(examples):
    obj = examples["cabinet"]
    labels = [p.label for p in obj.parts]
    a = sample_views("cab", labels, 5, seed=3)
    b = sample_views("cab", labels, 5, seed=3)
    c = sample_views("cab", labels, 5, seed=4)
    assert [v.to_json() for v in a] == [v.to_json() for v in b]
    assert [v.to_json() for v in a] != [v.to_json() for v in c]
    assert [v.openness for v in a[:3]] == [0.0, 1.0, 0.5]
    img1, img2 = render_view(obj, a[1]), render_view(obj, b[1])
    assert img1.shape == (224, 224, 3) and img1.dtype == np.uint8
    assert np.array_equal(img1, img2)
    # the object is in frame (not just background) and moving parts change the picture
    bg = np.asarray(a[1].background) * 255
    assert (np.abs(img1[112] - bg).max(-1) > 10).mean() > 0.2
    shut = render_view(obj, a[1].__class__(**{**a[1].to_json(), "openness": 0.0}))
    assert np.abs(shut.astype(int) - img1).max() > 50


def test_render_dataset_cache_is_resumable_and_versioned(tmp_path, examples):
    from PIL import Image
    from model.imaging.renders import (RenderSetError, load_render_manifest, render_dataset,
                                       rendered_ids, view_paths, view_specs)
    data = tmp_path / "prepared"
    write_prepared(data, examples, {"train": ["cabinet"], "val": [], "test": ["bottle"]})
    out = tmp_path / "renders"
    rep = render_dataset(data, out, views=3, seed=1, workers=1)
    assert rep.rendered == 2 and rep.skipped == 0 and not rep.failed
    assert load_render_manifest(out)["views"] == 3
    assert rendered_ids(out, ["cabinet", "bottle", "nope"]) == ["cabinet", "bottle"]
    paths = view_paths(out, "bottle")
    assert len(paths) == 3 and all(p.exists() for p in paths)
    assert np.asarray(Image.open(paths[0])).shape == (224, 224, 3)
    assert view_specs(out, "bottle")[2].openness == 0.5
    meta = json.loads((out / "objects" / "bottle" / "views.json").read_text())
    assert meta["category"] == examples["bottle"].category and meta["split"] == "test"
    # resumable: a second run renders nothing; a deleted object is redone identically
    before = paths[1].read_bytes()
    assert render_dataset(data, out, views=3, seed=1, workers=1).skipped == 2
    (out / "objects" / "bottle" / "views.json").unlink()
    rep = render_dataset(data, out, views=3, seed=1, workers=1)
    assert rep.rendered == 1 and paths[1].read_bytes() == before
    # other settings in the same folder are refused
    with pytest.raises(RenderSetError, match="other settings"):
        render_dataset(data, out, views=4, seed=1, workers=1)


def test_a_new_data_version_takes_the_views_of_unchanged_objects(tmp_path, examples):
    """--reuse: the object whose mesh changed is rendered again, the unchanged one takes the
    earlier folder's views, byte for byte what rendering it would give; other render
    settings or a missing earlier dataset are refused."""
    import copy
    import shutil

    from model.imaging.renders import RenderSetError, render_dataset
    splits = {"train": ["cabinet"], "val": [], "test": ["bottle"]}
    old, new = tmp_path / "v_old", tmp_path / "v_new"
    write_prepared(old, examples, splits, version="old")
    changed = dict(examples, bottle=copy.deepcopy(examples["bottle"]))
    changed["bottle"].parts[0].mesh.apply_scale(0.9)         # a thinner body, same tree
    write_prepared(new, changed, splits, version="new")
    render_dataset(old, tmp_path / "r_old", views=2, seed=1, workers=1)
    rep = render_dataset(new, tmp_path / "r_new", views=2, seed=1, workers=1,
                         reuse=tmp_path / "r_old")
    assert (rep.reused, rep.rendered, rep.skipped, rep.failed) == (1, 1, 0, {})
    fresh = render_dataset(new, tmp_path / "r_fresh", views=2, seed=1, workers=1)
    assert fresh.rendered == 2
    def views(folder, oid):
        return [(tmp_path / folder / "objects" / oid / f"{k}.png").read_bytes() for k in (0, 1)]
    assert views("r_new", "cabinet") == views("r_fresh", "cabinet") == views("r_old", "cabinet")
    assert views("r_new", "bottle") == views("r_fresh", "bottle") != views("r_old", "bottle")
    meta = json.loads((tmp_path / "r_new" / "objects" / "cabinet" / "views.json").read_text())
    assert meta["split"] == "train"
    # done objects stay done; a reuse source of other settings or without its data is refused
    assert render_dataset(new, tmp_path / "r_new", views=2, seed=1, workers=1,
                          reuse=tmp_path / "r_old").skipped == 2
    with pytest.raises(RenderSetError, match="other settings"):
        render_dataset(new, tmp_path / "r_3", views=2, seed=2, workers=1, reuse=tmp_path / "r_old")
    shutil.rmtree(old)
    with pytest.raises(RenderSetError, match="is not here"):
        render_dataset(new, tmp_path / "r_4", views=2, seed=1, workers=1, reuse=tmp_path / "r_old")


def test_objects_without_prepared_meshes_come_from_their_source_folder(tmp_path, examples):
    import shutil

    from model.data.format import load_record, save_record
    from model.data.partnet import write_partnet
    from model.imaging.renders import RenderSetError, object_from_record
    data = tmp_path / "prepared"
    write_prepared(data, examples, {"train": ["bottle"], "val": [], "test": []})
    rec = load_record(data, "bottle")
    view = sample_views("bottle", rec.labels, 1, seed=0)[0]
    from_meshes = render_view(object_from_record(data, rec), view)
    shutil.rmtree(data / "meshes" / "bottle")
    with pytest.raises(RenderSetError, match="no prepared meshes"):
        object_from_record(data, rec)
    write_partnet(examples["bottle"], tmp_path / "src" / "bottle")
    rec.source = str(tmp_path / "src" / "bottle")
    save_record(data, rec)
    from_source = render_view(object_from_record(data, rec), view)
    assert from_source.shape == (224, 224, 3)
    # same object, same view: the two routes give (nearly) the same picture
    assert np.abs(from_source.astype(int) - from_meshes).mean() < 3.0
