"""`artformer eval` / `artformer bench` end to end on a tiny prepared dataset, with tiny
random-weight checkpoints of the pipeline (the CI smoke run of the whole evaluation)."""
import json

import pytest

from helpers import build_prepared


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    """Retrieval keys are cached under XDG_CACHE_HOME: keep the tests' out of ~/.cache."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


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
               "--freeform", "0", "--no-validity", "--no-plots", "--no-retrieval",
               "--out", str(out)])
    assert rc == 0
    res = json.loads((out / "results.json").read_text())
    assert [r["name"] for r in res["rows"]] == ["train (floor)", "test (GT)"]
    floor = res["rows"][0]
    assert floor["mmd"] > 0 and 0 < floor["cov"] <= 1 and 0 <= floor["nna"] <= 1


@pytest.fixture(scope="module")
def tiny_checkpoints(tiny_model, tiny_model_factory):
    return tiny_model, tiny_model_factory("no_tpe", ablation="no_tpe")


def test_eval_tiny_checkpoint_with_ablation(prepared, tiny_checkpoints, tmp_path):
    """The CI run: generation with the pipeline + every metric + baselines + an ablation row."""
    from model.metrics.commands import main
    full, no_tpe = tiny_checkpoints
    out = tmp_path / "eval"
    # the ablation is given as a bare transformer file: sdf / prior come from --checkpoint;
    # random-weight trees at the product's low decoding temperature are mostly a lone root,
    # where the TPE has nothing to say, so sample the trees at temperature 1
    rc = main(["eval", "--checkpoint", str(full), "--data", str(prepared), "--preset", "tiny",
               "--ablation", f"no_tpe={no_tpe / 'transformer.pt'}", "--out", str(out),
               "--structure-temperature", "1"])
    assert rc == 0
    res = json.loads((out / "results.json").read_text())
    rows = {r["name"]: r for r in res["rows"]}
    assert list(rows) == ["model", "no_tpe", "retrieval", "train (floor)", "test (GT)"]
    assert "part retrieval" in res["skipped_rows"][0]      # random priors have no bank
    for name in ("model", "no_tpe"):
        r = rows[name]
        assert r["n_prompts"] == res["n_test"] + res["n_freeform"] == 6
        assert r["n_failed"] < r["n_prompts"], r["errors"]
        assert r["por"] is not None and r["por"] >= 0 and r["por_max"] >= r["por"] - 1e-12
        assert r["mmd"] > 0 and 0 < r["cov"] <= 1 and 0 <= r["nna"] <= 1
        assert 0 <= r["alignment"] <= 1
        assert r["diversity"] is not None and r["diversity"] >= 0
        assert 0 <= r["validity"] <= 1
        assert {"text_encoding", "decoding", "diffusion", "meshing"} <= set(r["timings_median"])
    # ablation rows differ from the model row (a different network made them)
    assert rows["model"]["nearest_reference_id"] != rows["no_tpe"]["nearest_reference_id"]
    # baselines of the same run: GT objects are collision-checked by the generator (POR ~ 0)
    # and their own descriptions parse back to their structure; dataset objects simulate.
    assert rows["test (GT)"]["por"] < 1e-3
    assert rows["test (GT)"]["alignment_test"] == 1.0
    assert rows["retrieval"]["validity"] == 1.0
    assert len(rows["retrieval"]["retrieved_ids"]) == 6
    for name in ("retrieval", "train (floor)"):
        r = rows[name]
        assert r["mmd"] >= 0 and 0 < r["cov"] <= 1 and 0 <= r["nna"] <= 1
    md = (out / "results.md").read_text()
    assert "| model |" in md and "| no_tpe |" in md and "ArtFormer (paper)" in md
    for f in ("por.png", "id_set_metrics.png", "alignment.png", "diversity.png", "validity.png"):
        assert (out / f).stat().st_size > 1000


@pytest.mark.slow     # a cold start in a fresh process (~7 s on 2 busy cores)
def test_bench_tiny_checkpoint_in_fresh_process(tiny_checkpoints, tmp_path):
    from model.metrics.commands import main
    out = tmp_path / "bench.json"
    rc = main(["bench", "--checkpoint", str(tiny_checkpoints[0]), "--n", "2", "--threads", "1",
               "--steps", "3", "--resolution", "16", "--warmup", "0", "--out", str(out)])
    assert rc == 0
    res = json.loads(out.read_text())
    assert res["n"] == 2
    for stage in ("text_encoding", "decoding", "diffusion", "meshing", "export", "total"):
        s = res["stages"][stage]
        assert s["n"] == 2 and 0 <= s["median"] <= s["p95"]
    # the high-water mark covers at least the loaded model and torch
    assert res["peak_rss_mb"] >= res["rss_after_load_mb"] > 100
    assert res["load_seconds"] > 0


@pytest.mark.slow     # loads the shipped image model and its encoder (~10 s on 2 busy cores)
def test_bench_times_image_requests_of_the_shipped_model(tmp_path):
    from PIL import Image
    from skimage import data as skdata
    from model.metrics.commands import main
    img = tmp_path / "photo.png"
    Image.fromarray(skdata.chelsea()).save(img)
    out = tmp_path / "bench.json"
    assert main(["bench", "--images", str(tmp_path / "missing.png"), "--out", str(out)]) == 2
    assert not out.exists()
    rc = main(["bench", "--images", str(img), "--n", "1", "--threads", "1", "--steps", "3",
               "--resolution", "16", "--warmup", "0", "--out", str(out)])
    assert rc == 0
    res = json.loads(out.read_text())
    assert res["n"] == 1 and res["requests"] == "images" and not res["failures"]
    assert "image_encoding" in res["stages"] and "text_encoding" not in res["stages"]
    assert res["stages"]["to_urdf"]["median"] >= res["stages"]["export"]["median"] > 0
