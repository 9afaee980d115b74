"""Training, checkpoints, the public API and DDP of the shape prior on tiny data."""
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from model.geometry.autoencoder import SDFAutoEncoder
from model.geometry.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from model.geometry.config import get_preset

torch.set_num_threads(1)
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def prim_data(tmp_path_factory):
    from model.geometry.data import make_primitive_dataset
    return make_primitive_dataset(tmp_path_factory.mktemp("prim") / "data", 6,
                                  n_points=256, n_sdf=1024, seed=3)


def occupancy_iou(ae, pts, sdf_fn, res=24):
    ax = torch.linspace(-1, 1, res)
    grid = torch.stack(torch.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(1, -1, 3)
    pred = ae.query(ae.decode_planes(ae.encode(pts)), grid)[0] < 0
    true = sdf_fn(grid[0]) < 0
    return float((pred & true).sum()) / float((pred | true).sum())


def test_tiny_autoencoder_overfits_one_primitive():
    """A cylinder in its box frame (radius and half height 0.95): IoU must rise."""
    torch.manual_seed(0)
    g = torch.Generator().manual_seed(0)
    cfg = get_preset("tiny").sdf
    ae = SDFAutoEncoder(cfg)

    def cyl(x):   # (N, 3) -> (N,), axis z
        d = torch.stack([x[:, :2].norm(dim=-1) - 0.95, x[:, 2].abs() - 0.95], -1)
        return d.clamp_min(0).norm(dim=-1) + d.max(-1).values.clamp_max(0)
    th = torch.rand(256, generator=g) * 6.2832
    zc = torch.rand(256, generator=g) * 1.9 - 0.95
    p = torch.stack([0.95 * th.cos(), 0.95 * th.sin(), zc], -1)          # side
    p[:64, :2] *= torch.rand(64, 1, generator=g).sqrt()                  # caps
    p[:64, 2] = 0.95 * torch.sign(torch.rand(64, generator=g) - 0.5)
    pts = p.unsqueeze(0)
    before = occupancy_iou(ae.eval(), pts, cyl)
    opt = torch.optim.Adam(ae.parameters(), lr=3e-3)
    ae.train()
    for _ in range(150):
        q = (torch.rand(1, 512, 3, generator=g) * 2 - 1)           # half uniform, half near surface
        q[:, :256] = p[torch.randint(0, 256, (256,), generator=g)] + 0.05 * torch.randn(256, 3, generator=g)
        loss, _ = ae(pts, q, cyl(q[0]).unsqueeze(0))
        opt.zero_grad()
        loss.backward()
        opt.step()
    after = occupancy_iou(ae.eval(), pts, cyl)
    assert after > before + 0.2 and after > 0.85, (before, after)


def test_checkpoint_round_trip_and_errors(tmp_path):
    cfg = get_preset("tiny").sdf
    ae = SDFAutoEncoder(cfg).eval()
    path = tmp_path / "a.pt"
    save_checkpoint(path, "sdf", ae, data_version="dv1", seed=5, argv=["x"], step=7)
    ae2, ck = load_checkpoint(path, "sdf")
    assert ck["data_version"] == "dv1" and ck["seed"] == 5 and ck["step"] == 7
    pts, q = torch.rand(2, 64, 3), torch.rand(2, 32, 3)
    assert torch.allclose(ae.query(ae.decode_planes(ae.encode(pts)), q),
                          ae2.query(ae2.decode_planes(ae2.encode(pts)), q))
    with pytest.raises(CheckpointError, match="'prior' one is needed"):
        load_checkpoint(path, "prior")
    other = get_preset("small").sdf
    with pytest.raises(CheckpointError, match="differs from the requested"):
        load_checkpoint(path, "sdf", expect_config=other)
    bad = tmp_path / "bad.pt"
    bad.write_bytes(path.read_bytes()[:200])
    with pytest.raises(CheckpointError, match="corrupt.*re-run `artformer train sdf`"):
        load_checkpoint(bad, "sdf")
    with pytest.raises(CheckpointError, match="does not exist"):
        load_checkpoint(tmp_path / "missing.pt", "sdf")
    half = tmp_path / "half.pt"
    save_checkpoint(half, "sdf", ae, half=True)
    assert half.stat().st_size < path.stat().st_size


def _cli(*args):
    from model.cli import main
    return main(list(args))


def test_train_commands_api_and_resume(prim_data, tmp_path):
    sdf_out, prior_out = tmp_path / "sdf", tmp_path / "prior"
    assert _cli("train", "sdf", "--data", str(prim_data), "--out", str(sdf_out), "--preset", "tiny",
                "--steps", "30", "--no-progress", "--threads", "1", "--device", "auto") == 0
    ck = torch.load(sdf_out / "ckpt.pt", weights_only=True)
    assert ck["step"] == 30 and ck["data_version"] == "primitives-3-6" and "optimizer" in ck
    # the header says what made it: "cpu", or "cuda (<GPU name>)" where torch sees a GPU
    assert ck["device"] == "cpu" if not torch.cuda.is_available() else \
        ck["device"].startswith("cuda (")
    assert ck["command"].startswith("artformer train sdf") and ck["format"] == 2
    # resume continues from step 30 to 40
    assert _cli("train", "sdf", "--data", str(prim_data), "--out", str(sdf_out), "--preset", "tiny",
                "--steps", "40", "--resume", "--no-progress", "--threads", "1") == 0
    assert torch.load(sdf_out / "ckpt.pt", weights_only=True)["step"] == 40
    logs = (sdf_out / "log.jsonl").read_text().splitlines()
    assert len(logs) >= 2 and '"val"' in logs[-1]
    assert _cli("train", "prior", "--data", str(prim_data), "--out", str(prior_out), "--preset",
                "tiny", "--sdf", str(sdf_out / "ckpt.pt"), "--steps", "20", "--no-progress",
                "--threads", "1", "--export", str(tmp_path / "prior_fp16.pt")) == 0

    from model.geometry.api import ShapeModel
    shape = ShapeModel.load(sdf_out / "ckpt.pt", tmp_path / "prior_fp16.pt")
    texts = ["primitives, body", "primitives, knob", "a label never seen"]
    cs = shape.semantic_condition(texts)
    assert cs.shape == (3, get_preset("tiny").prior.cs_dim)
    P = shape.label_logits(texts)
    z = shape.sample_from_logits(P, cs, steps=5, generator=torch.Generator().manual_seed(0))
    assert z.shape == (3, get_preset("tiny").sdf.z_dim)
    Pgt = shape.code_distribution(z)
    assert torch.allclose(Pgt.sum(-1), torch.ones(3, 4), atol=1e-5)
    meshes = shape.decode_meshes(z, resolution=32)
    assert len(meshes) == 3
    assert all(m.metadata["surface"] in ("ok", "empty", "full") for m in meshes)
    zr, idx = shape.retrieve(z, texts)
    bank = shape.bank
    for b in range(2):   # restricted to the same label text
        assert bank["texts"][int(bank["text_ids"][idx[b]])] == texts[b]
    assert torch.allclose(zr, bank["latents"][idx].float())
    # a thinned bank: at most K latents per label, label statistics those of the whole bank
    from model.geometry.train import export_weights
    export_weights(prior_out / "ckpt.pt", tmp_path / "prior_thin.pt", "prior", bank_per_text=2)
    thin = ShapeModel.load(sdf_out / "ckpt.pt", tmp_path / "prior_thin.pt")
    counts = torch.bincount(thin.bank["text_ids"], minlength=len(bank["texts"]))
    assert counts.max() <= 2 and len(thin.bank["object_ids"]) == len(thin.bank["latents"])
    assert len(thin.bank["latents"]) < len(bank["latents"])
    assert torch.allclose(thin.label_logits(texts), P, atol=2e-2)
    zt, it = thin.retrieve(z, texts)
    assert thin.bank["texts"][int(thin.bank["text_ids"][it[0]])] == texts[0]
    enc = shape.encode(torch.rand(2, 128, 3) * 0.5)
    assert enc.shape == (2, get_preset("tiny").sdf.z_dim)
    # prior checkpoint paired with the wrong auto-encoder is refused
    wrong = tmp_path / "wrong.pt"
    cfg = get_preset("tiny").sdf
    cfg.z_dim = 16
    save_checkpoint(wrong, "sdf", SDFAutoEncoder(cfg))
    with pytest.raises(CheckpointError, match="matching"):
        ShapeModel.load(wrong, tmp_path / "prior_fp16.pt")
    # the one_codebook ablation's prior: one codebook of 64 codes instead of the preset's 4 x 16
    one = tmp_path / "prior_one"
    assert _cli("train", "prior", "--data", str(prim_data), "--out", str(one), "--preset", "tiny",
                "--sdf", str(sdf_out / "ckpt.pt"), "--steps", "5", "--no-progress", "--threads",
                "1", "--codebooks", "1", "--codebook-size", "64") == 0
    shape1 = ShapeModel.load(sdf_out / "ckpt.pt", one / "ckpt.pt")
    P1 = shape1.code_distribution(z)
    assert P1.shape == (3, 1, 64) and torch.allclose(P1.sum(-1), torch.ones(3, 1), atol=1e-5)
    z1 = shape1.sample_from_logits(torch.randn(3, 1, 64), cs, steps=3,
                                   generator=torch.Generator().manual_seed(0))
    assert z1.shape == z.shape


def test_eval_and_bench_commands(prim_data, tmp_path, capsys):
    sdf_out, prior_out = tmp_path / "sdf", tmp_path / "prior"
    _cli("train", "sdf", "--data", str(prim_data), "--out", str(sdf_out), "--preset", "tiny",
         "--steps", "10", "--no-progress", "--threads", "1")
    _cli("train", "prior", "--data", str(prim_data), "--out", str(prior_out), "--preset", "tiny",
         "--sdf", str(sdf_out / "ckpt.pt"), "--steps", "10", "--no-progress", "--threads", "1")
    capsys.readouterr()
    assert _cli("eval", "geometry", "--data", str(prim_data), "--sdf", str(sdf_out / "ckpt.pt"),
                "--prior", str(prior_out / "ckpt.pt"), "--resolution", "32", "--labels", "2",
                "--samples-per-label", "2", "--steps", "5", "--threads", "1",
                "--json", str(tmp_path / "e.json")) == 0
    import json
    res = json.loads((tmp_path / "e.json").read_text())
    rec = res["reconstruction"]
    assert rec["parts"] > 0 and 0.0 <= rec["iou_mean"] <= 1.0 or rec["empty"] == rec["parts"]
    assert 0.0 <= res["prior"]["yield"] <= 1.0
    assert _cli("bench", "geometry", "--sdf", str(sdf_out / "ckpt.pt"), "--prior",
                str(prior_out / "ckpt.pt"), "--resolution", "32", "--parts", "2", "--steps", "5",
                "--repeats", "1", "--threads", "1") == 0
    out = capsys.readouterr().out
    assert "mesh_one_part_ms" in out and "ddim_2_parts_5_steps_ms" in out
    assert _cli("eval", "geometry", "--data", str(prim_data), "--sdf",
                str(tmp_path / "nothing.pt")) == 1


def test_ddp_two_processes(prim_data, tmp_path):
    torchrun = Path(sys.executable).parent / "torchrun"
    if not torchrun.exists():
        pytest.skip("torchrun not installed in this environment")
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    cmd = [str(torchrun), "--standalone", "--nproc_per_node", "2", "-m", "model", "train", "sdf",
           "--data", str(prim_data), "--out", str(tmp_path / "ddp"), "--preset", "tiny",
           "--steps", "4", "--no-progress", "--threads", "2"]
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=240, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    ck = torch.load(tmp_path / "ddp" / "ckpt.pt", weights_only=True)
    assert ck["step"] == 4


def test_box_frame_samples_exact_and_fallback(prim_data):
    from model.geometry.data import load_parts
    exact = load_parts(prim_data, "train")
    approx = load_parts(prim_data, "train", exact=False)
    assert exact.points.shape[0] == approx.points.shape[0] == len(exact.texts)
    for ps in (exact, approx):
        p = ps.points.float()
        ext = p.max(1).values - p.min(1).values                     # (M, 3)
        assert torch.allclose(ext, torch.full_like(ext, 1.9), atol=0.08)   # every axis fills the box
        assert ps.sdf.shape[-1] == 4 and ps.sdf[..., :3].abs().max() <= 1.05 + 1e-3
    # parts labelled "body" are boxes: exact box-frame SDF is the SDF of the 0.95 cube
    assert any(t.endswith("body") for t in exact.texts)
    for i, t in enumerate(exact.texts):
        if t.endswith("body"):
            s = exact.sdf[i].float()
            q = s[:, :3].abs() - 0.95
            ref = q.clamp_min(0).norm(dim=-1) + q.max(-1).values.clamp_max(0)
            assert (s[:, 3] - ref).abs().max() < 0.01
            # the first-order fallback agrees in sign everywhere
            assert ((approx.sdf[i, :, 3].float() < 0) == (approx_ref(approx, i) < 0)).float().mean() > 0.99
            break


def approx_ref(ps, i):
    q = ps.sdf[i, :, :3].float().abs() - 0.95
    return q.clamp_min(0).norm(dim=-1) + q.max(-1).values.clamp_max(0)


def test_box_frame_cache_in_shards_resumes_and_ignores_workers(prim_data, tmp_path, monkeypatch):
    import model.geometry.data as gd
    ref = gd.load_parts(prim_data, "train")                  # sequential, no cache
    ids = list(dict.fromkeys(ref.object_ids))
    assert len(ids) >= 3
    monkeypatch.setattr(gd, "SHARD", 1)
    read_objects, seen = gd._read_objects, []

    def failing(root, oids, rng, **kw):
        seen.extend(oids)
        if oids[0] == ids[2]:
            raise RuntimeError("interrupted")
        return read_objects(root, oids, rng, **kw)

    cache = tmp_path / "cache"
    monkeypatch.setattr(gd, "_read_objects", failing)
    with pytest.raises(RuntimeError, match="interrupted"):
        gd.load_parts(prim_data, "train", cache_dir=cache)
    shards = sorted((cache).glob("*.shards1/*.pt"))
    assert len(shards) == 2 and not list(cache.glob("parts_train_*.pt"))
    seen.clear()
    monkeypatch.setattr(gd, "_read_objects", lambda root, oids, rng, **kw:
                        seen.extend(oids) or read_objects(root, oids, rng, **kw))
    resumed = gd.load_parts(prim_data, "train", cache_dir=cache)
    assert seen == ids[2:]                                   # the two finished shards are kept
    assert not list(cache.glob("*.shards*")) and len(list(cache.glob("parts_train_*.pt"))) == 1
    parallel = gd.load_parts(prim_data, "train", workers=2)  # forked workers, no cache
    for ps in (resumed, parallel):
        assert ps.object_ids == ref.object_ids and ps.texts == ref.texts
        assert torch.equal(ps.points, ref.points) and torch.equal(ps.sdf, ref.sdf)
        assert torch.equal(ps.box_scale, ref.box_scale)


def test_training_device_is_resolved_or_refused_clearly():
    from model.core.training import resolve_device
    assert resolve_device("cpu").type == "cpu"
    assert resolve_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    with pytest.raises(ValueError, match="cpu, cuda or auto"):
        resolve_device("tpu")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="no CUDA device"):
            resolve_device("cuda")


def test_prior_in_another_priors_code_space(prim_data, tmp_path, capsys):
    """`train prior --codes-from`: a prior for a new auto-encoder that keeps the old prior's
    codebooks and semantic encoder, so transformers trained for the old one are accepted,
    learns to read the old codes from the new latents, and is refused once its code space
    no longer matches."""
    from model.core.checkpoint import (CheckpointMeta, prior_fingerprint, read_checkpoint,
                                       write_checkpoint)
    from model.geometry.api import ShapeModel
    from model.geometry.data import load_parts
    from model.geometry.train import encode_parts
    run = {}
    for name, seed in (("a", 0), ("b", 1)):
        sdf = tmp_path / f"sdf_{name}"
        assert _cli("train", "sdf", "--data", str(prim_data), "--out", str(sdf), "--preset",
                    "tiny", "--steps", "10", "--seed", str(seed), "--no-progress",
                    "--threads", "1") == 0
        run[name] = sdf / "ckpt.pt"
    old = tmp_path / "prior_a"
    assert _cli("train", "prior", "--data", str(prim_data), "--out", str(old), "--preset", "tiny",
                "--sdf", str(run["a"]), "--steps", "10", "--no-progress", "--threads", "1",
                "--export", str(tmp_path / "prior_a.pt")) == 0
    common = ["--data", str(prim_data), "--preset", "tiny", "--sdf", str(run["b"]),
              "--no-progress", "--threads", "1", "--codes-from", str(tmp_path / "prior_a.pt"),
              "--codes-sdf", str(run["a"])]
    assert _cli("train", "prior", "--out", str(tmp_path / "prior_b0"), "--steps", "1",
                *common) == 0
    assert _cli("train", "prior", "--out", str(tmp_path / "prior_b"), "--steps", "80",
                "--lr", "3e-3", "--export", str(tmp_path / "prior_b.pt"), *common) == 0
    a = ShapeModel.load(run["a"], tmp_path / "prior_a.pt")
    b = ShapeModel.load(run["b"], tmp_path / "prior_b.pt")
    assert torch.equal(a.prior.codebooks, b.prior.codebooks)
    for k, v in a.prior.sem_encoder.state_dict().items():
        assert torch.equal(v, b.prior.sem_encoder.state_dict()[k])
    texts = ["primitives, body", "primitives, knob"]
    assert torch.allclose(a.semantic_condition(texts), b.semantic_condition(texts))
    assert b.info["accepts"] == [b.info["fingerprint"], a.info["fingerprint"]]
    assert a.info["accepts"] == [a.info["fingerprint"]]
    # a transformer trained for prior a runs with prior b, one trained for another is refused
    t = tmp_path / "t.pt"
    write_checkpoint(t, CheckpointMeta(kind="articulation", prior=a.info["fingerprint"]),
                     {"config": {}, "state_dict": {}})
    read_checkpoint(t, "articulation", prior=b.info["accepts"])
    with pytest.raises(CheckpointError, match="another shape prior"):
        read_checkpoint(t, "articulation", prior=[b.info["fingerprint"]])

    # b reads from its own latents the codes a reads from its latents of the same parts
    parts = load_parts(prim_data, "train", with_sdf=False)

    def code_kl(prior_file):
        sb = ShapeModel.load(run["b"], prior_file)
        pa = a.code_distribution(encode_parts(a.ae, parts, 256))
        pb = sb.code_distribution(encode_parts(sb.ae, parts, 256))
        return float((pa * (pa.clamp_min(1e-12).log() - pb.clamp_min(1e-12).log()))
                     .sum(-1).mean())
    before, after = code_kl(tmp_path / "prior_b0" / "ckpt.pt"), code_kl(tmp_path / "prior_b.pt")
    assert after < 0.5 * before, (before, after)

    # scripts/code_space_check.py score: shapes drawn from a's codes through a and through b;
    # a pair that does not read a's code space is refused
    import importlib.util
    spec = importlib.util.spec_from_file_location("code_space_check",
                                                  ROOT / "scripts" / "code_space_check.py")
    csc = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(csc)
    pairs = [(str(run["a"]), str(tmp_path / "prior_a.pt")),
             (str(run["b"]), str(tmp_path / "prior_b.pt"))]
    res = csc.score(str(prim_data), "train", pairs, 2, 0)
    assert [r["prior"] for r in res] == [p for _, p in pairs]
    assert all(r["n"] == res[0]["n"] > 0 and 0.0 <= r["fscore"] <= 1.0 for r in res)
    with pytest.raises(CheckpointError, match="does not read the code space"):
        csc.score(str(prim_data), "train", pairs[::-1], 2, 0)

    # a prior chained on b accepts all three; a tampered code space is refused
    assert _cli("train", "prior", "--data", str(prim_data), "--out", str(tmp_path / "prior_c"),
                "--preset", "tiny", "--sdf", str(run["a"]), "--steps", "2", "--no-progress",
                "--threads", "1", "--codes-from", str(tmp_path / "prior_b.pt"),
                "--codes-sdf", str(run["b"])) == 0
    c = ShapeModel.load(run["a"], tmp_path / "prior_c" / "ckpt.pt")
    assert c.info["accepts"][1:] == b.info["accepts"]
    ck = torch.load(tmp_path / "prior_b.pt", weights_only=True)
    ck["state_dict"]["codebooks"] = ck["state_dict"]["codebooks"] + 0.5
    torch.save(ck, tmp_path / "tampered.pt")
    with pytest.raises(CheckpointError, match="claims the code space"):
        ShapeModel.load(run["b"], tmp_path / "tampered.pt")
    assert prior_fingerprint(read_checkpoint(run["b"], "sdf"), ck) != b.info["fingerprint"]
    capsys.readouterr()
    assert _cli("train", "prior", "--out", str(tmp_path / "prior_d"), "--steps", "1",
                "--codebooks", "2", *common) != 0
    assert "codebook layout of that prior" in capsys.readouterr().err
