"""Image-conditioned transformer: a tiny training run lowers the loss; checkpoint round trip."""
from pathlib import Path

import numpy as np
import pytest
import torch

from helpers import write_prepared

torch.set_num_threads(1)
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tiny_set(tmp_path_factory):
    from model.core.example import example_objects
    from model.imaging.renders import render_dataset
    root = tmp_path_factory.mktemp("imaging_train")
    objs = example_objects()
    write_prepared(root / "prepared", objs, {"train": ["cabinet", "bottle"], "val": ["bottle"],
                                             "test": ["cabinet"]})
    # (a val/test id repeated from train is fine for a mechanics test)
    render_dataset(root / "prepared", root / "renders", views=2, seed=0, workers=1)
    return root


def _run(root, trainable_blocks: int, steps: int, own_inputs: float = 0.0, multiscale=False,
         init="none", out=None, extra=(), trunk="", image_size=224, count_tokens="",
         count_truth=0.0, resume=False):
    from model.articulation.config import preset
    from model.articulation.targets import StandInTargets
    from model.imaging.train import ImageRunConfig, ImageTrainConfig, train_image
    net, tc = preset("tiny", max_steps=steps, val_every=10_000, ckpt_every=10_000, threads=1,
                     batch_size=8, lr=3e-3, cond_dropout=0.0, own_inputs=own_inputs)
    tg = StandInTargets(z_dim=net.z_dim, num_codebooks=net.num_codebooks,
                        codebook_size=net.codebook_size, cs_dim=net.cs_dim)
    rc = ImageRunConfig(data=str(root / "prepared"), renders=str(root / "renders"),
                        out=str(out or root / f"run{trainable_blocks}"), net=net, train=tc,
                        image=ImageTrainConfig(trainable_blocks=trainable_blocks, init=init,
                                               multiscale=multiscale, trunk=trunk,
                                               image_size=image_size,
                                               count_tokens=count_tokens,
                                               count_truth=count_truth),
                        targets=tg, progress=False, extra=list(extra), resume=resume)
    return train_image(rc), tg, tc


def test_image_training_resumes_and_checks_the_prior(tiny_set, tmp_path):
    """--resume continues OUT/last.pt (step, history, time); the checkpoint records the
    targets' prior fingerprint and the loader refuses it for another prior."""
    from model.core.checkpoint import CheckpointError
    from model.imaging.model import load_image_model
    out = tmp_path / "res"
    _run(tiny_set, 0, 3, out=out)
    first = torch.load(out / "last.pt", weights_only=False)
    path, tg, _ = _run(tiny_set, 0, 5, out=out, resume=True)
    ck = torch.load(path, weights_only=False)
    assert first["step"] == 3 and ck["step"] == 5 and "optimizer" not in ck
    assert len(ck["history"]) == len(first["history"]) + 1 and ck["elapsed"] >= first["elapsed"]
    assert ck["prior"] == tg.fingerprint == "stand-in"
    assert load_image_model(path, prior="stand-in").am is not None
    ck["prior"] = "0123456789abcdef"                # as if trained against another prior
    torch.save(ck, tmp_path / "other.pt")
    with pytest.raises(CheckpointError, match="another shape prior"):
        load_image_model(tmp_path / "other.pt", prior="fedcba9876543210")


def test_tiny_image_training_reduces_loss_and_round_trips(tiny_set):
    import json

    from model.articulation.train import _CodebookView, prepare_data
    from model.imaging.features import ViewFeatures, load_feature_cache
    from model.imaging.model import ImageModelError, load_image_model
    from model.imaging.renders import view_paths
    from model.imaging.train import ImageConditions, evaluate_image_loss

    path, tg, tc = _run(tiny_set, 0, 60)
    im = load_image_model(path)
    ck = torch.load(path, map_location="cpu", weights_only=False)
    assert ck["condition"] == "image" and ck["renders"]["views"] == 2
    # loss of the trained network vs the same architecture at initialisation, same samples
    data = prepare_data(str(tiny_set / "prepared"), _CodebookView(tg, im.am.cfg),
                        stats=ck["stats"], label_table=ck["label_table"])
    conds = ImageConditions(ViewFeatures(load_feature_cache(tiny_set / "renders")),
                            im.encoder, precompute=True)
    items = data.items["train"]
    trained = evaluate_image_loss(im.am.net, items, data.geo_shape, conds, tc, 4)["total"]
    from model.articulation.network import ArticulationTransformer
    torch.manual_seed(tc.seed)
    fresh = ArticulationTransformer(im.am.cfg)
    before = evaluate_image_loss(fresh, items, data.geo_shape, conds, tc, 4)["total"]
    assert trained < 0.5 * before, (before, trained)
    hist = json.loads((tiny_set / "run0" / "history.json").read_text())
    assert hist[-1]["step"] == 60
    # an image → tokens → decoded tree through the loaded model
    png = view_paths(tiny_set / "renders", "cabinet")[0]
    tokens, mask = im.encode(str(png))
    assert tokens.shape == (1, 49, 1280) and mask.all()
    trees = im.decode_image(str(png), samples=2, seed=0, max_nodes=8, temperature=0.0)
    assert len(trees) == 2 and all(t.num_nodes >= 1 for t in trees)
    assert trees[0].category in ("StorageFurniture", "Bottle")
    # a text checkpoint is refused with a clear message
    from model.articulation.checkpoint import save_checkpoint
    text = tiny_set / "text.pt"
    save_checkpoint(text, im.am.net, stats=ck["stats"], label_table=ck["label_table"],
                    text_encoder="x", data_version="t", seed=0, command="", step=0)
    with pytest.raises(ImageModelError, match="not an image"):
        load_image_model(text)
    with pytest.raises(ImageModelError, match="no image checkpoint"):
        load_image_model(tiny_set / "missing.pt")


def test_fine_tuned_tail_is_saved_and_used(tiny_set):
    from model.encoders.image import ImageEncoder, ImageEncoderConfig
    from model.imaging.model import load_image_model
    from model.imaging.renders import view_paths
    path, _, _ = _run(tiny_set, 1, 6, own_inputs=1.0)   # also runs scheduled sampling
    im = load_image_model(path)
    assert torch.load(path, map_location="cpu", weights_only=False)["train_config"]["own_inputs"] == 1.0
    assert im.encoder.config.trainable_blocks == 1
    frozen = ImageEncoder(ImageEncoderConfig())
    a = im.encoder.net._conv_head.weight
    b = frozen.net._conv_head.weight
    assert not torch.allclose(a, b)            # the tail moved during training
    png = str(view_paths(tiny_set / "renders", "bottle")[1])
    t1, _ = im.encode(png)
    t0, _ = frozen.encode(png).states, None
    assert not torch.allclose(t1, t0)


def test_multiscale_run_widens_a_plain_image_model(tiny_set):
    """--multiscale from a 1280-d image checkpoint: the projection keeps its columns and gains
    zero ones, so before training the network answers as the start model did; the run caches
    the block-10 features and saves a model whose tokens are 1728-d."""
    from model.encoders.image import FINE_SPLIT
    from model.imaging.features import cache_path
    from model.imaging.model import load_image_model
    from model.imaging.renders import view_paths
    from model.imaging.train import widen_image_projection
    start, _, _ = _run(tiny_set, 0, 20)
    path, _, _ = _run(tiny_set, 0, 4, multiscale=True, init=str(start),
                      out=tiny_set / "run_ms")
    assert cache_path(tiny_set / "renders", FINE_SPLIT).exists()
    im0, im = load_image_model(start), load_image_model(path)
    assert im.encoder.config.multiscale and im.am.cfg.cond_dims["image"] == 1728
    png = str(view_paths(tiny_set / "renders", "cabinet")[0])
    tokens, _ = im.encode(png)
    assert tokens.shape == (1, 49, 1728)
    trees = im.decode_image(png, samples=1, seed=0, max_nodes=6, temperature=0.0)
    assert trees[0].num_nodes >= 1
    # widening: same outputs as the start network on the first 1280 channels
    sd0 = {k: v.float() for k, v in torch.load(start, map_location="cpu",
                                                 weights_only=False)["state_dict"].items()}
    own = im.am.net.state_dict()
    key = "cond.proj.image.0.weight"
    assert widen_image_projection(sd0, own) and sd0[key].shape == own[key].shape
    assert torch.count_nonzero(sd0[key][:, 1280:]) == 0
    net = type(im.am.net)(im.am.cfg).eval()
    net.load_state_dict(sd0)
    tok0, m0 = im0.encode(png)
    with torch.inference_mode():
        mem_wide, _ = net.cond(tokens, torch.ones(1, 49, dtype=torch.bool), "image")
        mem_plain, _ = im0.am.net.eval().cond(tok0, m0, "image")
    assert torch.allclose(mem_wide, mem_plain, atol=1e-4)
    assert not widen_image_projection({key: torch.zeros(3, 5)}, {key: torch.zeros(4, 9)})


def test_extra_training_sets_join_the_training_objects(tiny_set, tmp_path):
    """--extra-train: every split of a second prepared set (own data version, own renders)
    trains beside the main train split; its cached features are found under prefixed ids;
    a set with the main version or other views is refused."""
    import json

    from model.core.example import example_objects
    from model.imaging.features import ViewFeatures, load_feature_cache
    from model.imaging.renders import render_dataset
    from model.imaging.train import merge_view_features
    objs = example_objects()
    write_prepared(tmp_path / "xprep", objs, {"train": ["cabinet"], "val": [], "test": ["bottle"]},
                   version="test-extra")
    render_dataset(tmp_path / "xprep", tmp_path / "xrend", views=2, seed=7, workers=1)
    out = tmp_path / "run_x"
    path, _, _ = _run(tiny_set, 0, 6, out=out, extra=[(tmp_path / "xprep", tmp_path / "xrend")])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["train_objects"] == 2 + 2 and summary["val_objects"] == 1
    ck = torch.load(path, map_location="cpu", weights_only=False)
    assert [(x["data_version"], x["objects"]) for x in ck["extra_train"]] == [("test-extra", 2)]
    main = ViewFeatures(load_feature_cache(tiny_set / "renders"))
    xf = ViewFeatures(load_feature_cache(tmp_path / "xrend"))
    both = merge_view_features([("", main), ("x0:", xf)])
    assert both.ids == main.ids + ["x0:" + i for i in xf.ids]
    # the same object id, different renders (seed 7): rows come from the right set
    assert torch.equal(both.batch(["x0:cabinet"], [1]), xf.batch(["cabinet"], [1]))
    assert torch.equal(both.batch(["cabinet"], [1]), main.batch(["cabinet"], [1]))
    assert not torch.equal(both.batch(["x0:cabinet"], [1]), both.batch(["cabinet"], [1]))
    with pytest.raises(ValueError, match="distinct prefix"):
        merge_view_features([("", main), ("", xf)])
    with pytest.raises(ValueError, match="own version"):
        _run(tiny_set, 0, 1, out=tmp_path / "bad1", extra=[(tiny_set / "prepared", tmp_path / "xrend")])
    render_dataset(tmp_path / "xprep", tmp_path / "xrend3", views=3, seed=7, workers=1)
    with pytest.raises(ValueError, match="views"):
        _run(tiny_set, 0, 1, out=tmp_path / "bad2", extra=[(tmp_path / "xprep", tmp_path / "xrend3")])


def test_image_pipeline_report_runs_images_through_the_whole_generator(tiny_set, tiny_image_model,
                                                                       tmp_path):
    """POR, validity and structure of image requests through Generator + export (the
    figures issue 8 asks for besides the decoding accuracy)."""
    from model.metrics.image_pipeline import image_pipeline_report

    ckpt = tiny_image_model
    rep = image_pipeline_report(str(tiny_set / "prepared"), str(tiny_set / "renders"),
                                checkpoint=str(ckpt), split="test", n=1, por_states=3,
                                out_dir=str(tmp_path / "out"), progress=False)
    assert rep["images"] == 1 and rep["failed"] == 0, rep["errors"]
    [row] = rep["rows"]
    assert row["id"] == "cabinet" and row["por"] >= 0 and row["por_max"] >= row["por"]
    assert (tmp_path / "out").is_dir() and row["urdf"].startswith(str(tmp_path / "out"))
    assert rep["validity"] == 1.0          # the sphere parts load and move in all simulators
    assert set(row) >= {"category", "counts", "joint_types", "all", "timings"}
    assert "image_encoding" in row["timings"]


@pytest.mark.slow     # trains an image model and its count head (~6 s on 2 busy cores)
def test_count_head_learns_counts_and_holds_decoding_to_them(tiny_set, tmp_path):
    """`artformer train image-counts`: a count head over the cached 7x7 map learns the
    per-label counts of its training renders, is stored in the image checkpoint and loaded
    with it, and the decoder never adds a part beyond its plan; damage is reported clearly."""
    import json

    from model.data import format as fmt
    from model.imaging.counts import cli_main, count_targets
    from model.imaging.model import ImageModelError, load_image_model
    from model.imaging.renders import view_paths

    from model.core.example import example_objects
    from model.imaging.renders import render_dataset

    image_ckpt, _, _ = _run(tiny_set, 0, 6, out=tmp_path / "img")
    labels = load_image_model(image_ckpt).am.cfg.count_labels
    assert labels
    # extra objects: every split of a second set trains too (here the bottle again)
    write_prepared(tmp_path / "xprep", example_objects(), {"train": [], "val": [], "test": ["bottle"]},
                   version="test-extra")
    render_dataset(tmp_path / "xprep", tmp_path / "xrend", views=2, seed=7, workers=1)
    out = tmp_path / "counts"
    assert cli_main(["--image", str(image_ckpt), "--data", str(tiny_set / "prepared"),
                     "--renders", str(tiny_set / "renders"), "--out", str(out),
                     "--extra-train", str(tmp_path / "xprep"), str(tmp_path / "xrend"),
                     "--epochs", "300", "--batch-size", "4", "--threads", "1"]) == 0
    ck = torch.load(out / "image.pt", map_location="cpu", weights_only=False)
    rec = ck["count_head"]["train"]
    assert rec["command"].startswith("artformer train image-counts") and rec["seed"] == 0
    assert rec["data_versions"] == ["test", "test-extra"] and rec["train_objects"] == 3
    assert rec["chosen"]["val_exact"] == 1.0        # the val bottle is also a train object
    assert json.loads((out / "count_history.json").read_text())["chosen"] == rec["chosen"]

    im = load_image_model(out / "image.pt")
    assert im.counter is not None and im.counter.cfg.labels == labels
    png = str(view_paths(tiny_set / "renders", "cabinet")[0])
    tokens, mask, plan = im.condition(png)
    truth = count_targets([fmt.load_record(tiny_set / "prepared", "cabinet")], labels, 20)
    assert tokens.shape == (1, 49, 1280) and torch.equal(plan, truth)
    t_plain, _ = load_image_model(image_ckpt).encode(png)
    assert torch.allclose(tokens, t_plain, atol=1e-5)   # one pass gives the same tokens
    # a list longer than one encoder pass (ENCODE_BATCH) gives every image its own row
    many = [png, str(view_paths(tiny_set / "renders", "bottle")[1])] * 3
    t6, m6, p6 = im.condition(many)
    assert t6.shape == (6, 49, 1280) and m6.shape == (6, 49) and p6.shape == (6, len(labels))
    assert torch.allclose(t6[4:5], tokens, atol=1e-5) and torch.equal(p6[2:3], plan)
    assert not torch.allclose(t6[0], t6[1], atol=1e-3)
    t6_plain, _ = load_image_model(image_ckpt).encode(many)
    assert torch.allclose(t6_plain, t6, atol=1e-5)

    for tree in im.decode_image(png, samples=3, seed=0, max_nodes=16, temperature=1.0):
        counts = tree.summary()["counts"]
        root = tree.labels[0]
        for lab, n in counts.items():
            assert n <= int(truth[0, labels.index(lab)]) + (lab == root), (lab, counts)
    # a plan of zeros: nothing beyond the root; a plan of the wrong shape is refused
    zero = torch.zeros(2, len(labels), dtype=torch.long)
    trees = im.am.decode(tokens.expand(2, -1, -1), mask.expand(2, -1), modality="image", plan=zero)
    assert [t.num_nodes for t in trees] == [1, 1]
    with pytest.raises(ValueError, match="plan must be"):
        im.am.decode(tokens, mask, modality="image", plan=torch.zeros(1, len(labels) + 1))

    ck["count_head"]["state_dict"].pop(next(iter(ck["count_head"]["state_dict"])))
    torch.save(ck, tmp_path / "broken.pt")
    with pytest.raises(ImageModelError, match="count head cannot be loaded"):
        load_image_model(tmp_path / "broken.pt")
    ck = torch.load(out / "image.pt", map_location="cpu", weights_only=False)
    ck["count_head"]["config"]["labels"] = list(reversed(labels))
    torch.save(ck, tmp_path / "relabelled.pt")
    with pytest.raises(ImageModelError, match="counts"):
        load_image_model(tmp_path / "relabelled.pt")
    # a missing image checkpoint is refused
    assert cli_main(["--image", str(tmp_path / "missing.pt")]) == 2


@pytest.mark.slow     # trains a trunk, then an image model on it (~7 s on 2 busy cores)
def test_fine_tuned_trunk_feeds_the_image_model(tiny_set, tmp_path):
    """`artformer train image-trunk` fine-tunes trunk blocks to count parts; `train image
    --trunk` caches features with them and stores them in the checkpoint; the loader applies
    them, a continued run keeps them, and a damaged trunk file is refused."""
    from model.encoders.image import ImageEncoder, ImageEncoderConfig
    from model.imaging.features import cache_path, load_feature_cache
    from model.imaging.model import load_image_model
    from model.imaging.renders import view_paths
    from model.imaging.trunk import TrunkError, cli_main, load_trunk

    image_ckpt, _, _ = _run(tiny_set, 0, 2, out=tmp_path / "img")
    out = tmp_path / "trunk"
    assert cli_main(["--image", str(image_ckpt), "--data", str(tiny_set / "prepared"),
                     "--renders", str(tiny_set / "renders"), "--out", str(out), "--steps", "24",
                     "--batch-size", "4", "--freeze", "12", "--evals", "3", "--lr", "1e-3",
                     "--threads", "1"]) == 0
    tr = load_trunk(out)
    rec = tr["train"]
    assert rec["command"].startswith("artformer train image-trunk") and rec["seed"] == 0
    assert rec["data_versions"] == ["test"] and rec["train_objects"] == 2 and len(rec["history"]) == 3
    assert rec["history"][-1]["train_loss"] < 0.5 * np.log(21)      # counts are being learnt
    assert {k.split(".")[1] for k in tr["state_dict"]} == {"12", "13", "14"}
    assert all(v.dtype == torch.float16 for v in tr["state_dict"].values() if v.is_floating_point())
    imagenet = ImageEncoder(ImageEncoderConfig()).net.state_dict()
    assert any(not torch.equal(v.float(), imagenet[k]) for k, v in tr["state_dict"].items())

    path, _, _ = _run(tiny_set, 0, 3, out=tmp_path / "img_trunk", trunk=str(out / "trunk.pt"))
    assert cache_path(tiny_set / "renders", tag=tr["tag"]).exists()
    ck = torch.load(path, map_location="cpu", weights_only=False)
    assert ck["image_encoder"]["trunk_info"]["tag"] == tr["tag"]
    assert "history" not in ck["image_encoder"]["trunk_info"]["train"]
    im = load_image_model(path)
    k = "_blocks.13._depthwise_conv.weight"
    assert torch.equal(im.encoder.net.state_dict()[k], tr["state_dict"][k].float())
    png = str(view_paths(tiny_set / "renders", "cabinet")[1])
    tokens, _ = im.encode(png)
    cache = load_feature_cache(tiny_set / "renders", tag=tr["tag"])
    row = cache["ids"].index("cabinet")
    with torch.no_grad():
        cached = im.encoder.tail(cache["feats"][row, 1:2].float(), start=cache["split"])
    assert torch.allclose(tokens, cached, atol=2e-2)              # cache = what the loader reads
    assert not torch.allclose(tokens, ImageEncoder(ImageEncoderConfig()).encode(png).states, atol=1e-2)
    # the ImageNet-feature count head refuses a checkpoint that reads a fine-tuned trunk
    from model.imaging.counts import cli_main as counts_main
    assert counts_main(["--image", str(path), "--data", str(tiny_set / "prepared"),
                        "--renders", str(tiny_set / "renders"), "--out", str(tmp_path / "c")]) == 2
    # continuing from the image checkpoint keeps its trunk
    path2, _, _ = _run(tiny_set, 0, 2, out=tmp_path / "img_cont", init=str(path))
    ck2 = torch.load(path2, map_location="cpu", weights_only=False)
    assert ck2["image_encoder"]["trunk_info"]["tag"] == tr["tag"]
    # damage is refused with a clear error
    raw = torch.load(out / "trunk.pt", map_location="cpu", weights_only=False)
    raw["state_dict"][k] = raw["state_dict"][k] + 1
    torch.save(raw, tmp_path / "damaged.pt")
    with pytest.raises(TrunkError, match="hash"):
        load_trunk(tmp_path / "damaged.pt")
    with pytest.raises(TrunkError, match="without a fine-tuned trunk"):
        load_trunk(image_ckpt)                     # an image checkpoint on ImageNet's trunk
    # an image checkpoint's own trunk: the same blocks and tag as the trunk file it came from
    from_image = load_trunk(path)
    assert from_image["tag"] == tr["tag"] and from_image["freeze"] == tr["freeze"]
    assert torch.equal(from_image["state_dict"][k], tr["state_dict"][k])
    (tmp_path / "garbage.pt").write_bytes(b"not a torch file")
    with pytest.raises(TrunkError, match="corrupt or not an artformer checkpoint"):
        load_trunk(tmp_path / "garbage.pt")


def test_upsampled_input_run_caches_its_own_features_and_round_trips(tiny_set, tmp_path):
    """--image-size 448: features of the 2x-upsampled renders are cached under their own tag
    (the 224-px cache is left alone), the checkpoint's encoder reads 448-px inputs, the loader
    gives the tokens the trainer saw, and a size that is no multiple of 224 is refused."""
    from model.imaging.features import cache_path, load_feature_cache
    from model.imaging.model import load_image_model
    from model.imaging.renders import view_paths
    from model.imaging.train import cli_main

    base, _, _ = _run(tiny_set, 0, 2, out=tmp_path / "img224")
    c224 = cache_path(tiny_set / "renders")
    before = c224.stat().st_mtime_ns
    path, _, _ = _run(tiny_set, 0, 3, out=tmp_path / "img448", init=str(base), image_size=448)
    assert c224.stat().st_mtime_ns == before
    cache = load_feature_cache(tiny_set / "renders", tag="imagenet-448px")
    assert cache["image_size"] == 448 and tuple(cache["feats"].shape[-3:]) == (192, 7, 7)
    ck = torch.load(path, map_location="cpu", weights_only=False)
    assert ck["image_encoder"]["config"]["image_size"] == 448
    im = load_image_model(path)
    assert im.encoder.config.image_size == 448
    png = str(view_paths(tiny_set / "renders", "cabinet")[1])
    tokens, _ = im.encode(png)
    with torch.no_grad():
        cached = im.encoder.tail(cache["feats"][cache["ids"].index("cabinet"), 1:2].float(),
                                 start=cache["split"])
    assert torch.allclose(tokens, cached, atol=2e-2)
    assert not torch.allclose(tokens, load_image_model(base).encode(png)[0], atol=1e-2)
    assert cli_main(["--data", str(tiny_set / "prepared"), "--renders", str(tiny_set / "renders"),
                     "--out", str(tmp_path / "bad"), "--image-size", "300", "--init", "none"]) == 2


@pytest.mark.slow     # ~100 s: two generators on freshly trained tiny checkpoints
def test_generator_follows_the_image_count_head(tiny_set, tiny_model_factory):
    """Image requests through the product decode to the count head's plan (here: a head
    that counts zero of everything, so only the root part is made)."""
    from model.imaging.counts import CountHead, CountHeadConfig
    from model.pipeline import GenerationConfig, Generator

    labels = ["body", "cap", "door", "drawer", "handle"]
    folder = tiny_model_factory("count_head", shape="sphere", image=True, count_labels=labels)
    ck = torch.load(folder / "image.pt", map_location="cpu", weights_only=False)
    head = CountHead(CountHeadConfig(labels=labels, max_count=4))
    with torch.no_grad():
        last = head.body[-1]
        last.weight.zero_()
        last.bias.copy_(torch.tensor([10.0, 0, 0, 0, 0] * len(labels)))   # count 0 wins
    ck["count_head"] = {"config": {**vars(head.cfg)}, "state_dict": head.state_dict(), "train": {}}
    torch.save(ck, folder / "image.pt")
    png = str(sorted((tiny_set / "renders" / "objects" / "cabinet").glob("*.png"))[0])
    kw = dict(checkpoint=str(folder), resolution=16, steps=2, structure_temperature=1.0)
    gen = Generator.load(GenerationConfig(follow_plan=("text", "image"), **kw))
    assert gen.image_model.counter is not None
    sizes = [len(gen.generate(image=png, seed=s)[0].obj.parts) for s in range(3)]
    assert sizes == [1, 1, 1]
    free = Generator.load(GenerationConfig(follow_plan=(), **kw))     # --no-plan
    assert max(len(free.generate(image=png, seed=s)[0].obj.parts) for s in range(3)) > 1
    assert gen.generate(text="a cabinet with two doors", seed=0)[0].obj.parts   # text unaffected


def test_alignment_report_with_visibility_breakdown(tiny_set, tmp_path):
    """`artformer train image --eval CKPT --visibility`: every decoded render is scored, and
    each also gets its parts' visible pixels (a part-id render with the render's camera);
    the visibility groups partition the renders."""
    import json

    from model.imaging.evaluate import visibility_breakdown
    from model.imaging.train import cli_main

    ckpt, _, _ = _run(tiny_set, 0, 6, out=tmp_path / "img")
    out = tmp_path / "eval.json"
    assert cli_main(["--eval", str(ckpt), "--data", str(tiny_set / "prepared"),
                     "--renders", str(tiny_set / "renders"), "--split", "train",
                     "--temperature", "0", "--visibility", "--visible-px", "16",
                     "--json", str(out), "--no-progress"]) == 0
    rep = json.loads(out.read_text())
    assert rep["images"] == 4 and len(rep["rows"]) == 4            # 2 objects x 2 views
    for r in rep["rows"]:
        labels = [lab for lab, _ in r["part_pixels"]]
        assert sorted(labels) == sorted(lab for lab, n in r["truth"]["counts"].items() for _ in range(n))
        body = dict(r["part_pixels"])["body"]
        assert 500 < body < 224 * 224
    groups = [v for k, v in rep["by_visibility"].items() if k != "parts_under_threshold"]
    assert sum(g["renders"] for g in groups) == 4
    assert set(rep["by_visibility"]["parts_under_threshold"]) == {"body", "cap", "door", "drawer", "handle"}
    # the grouping itself, on hand-made rows
    rows = [{"all": True, "part_pixels": [["body", 900], ["knob", 20]]},
            {"all": False, "part_pixels": [["body", 900], ["knob", 3]]},
            {"all": False, "part_pixels": [["body", 900], ["knob", 0]]},
            {"all": True, "part_pixels": [["body", 900], ["knob", 0]]}]
    b = visibility_breakdown(rows, 16)
    assert [g["renders"] for k, g in b.items() if k != "parts_under_threshold"] == [1, 1, 2]
    assert b["every part >= 16 px"]["alignment"] == 1.0 and b["a part hidden (0 px)"]["alignment"] == 0.5
    assert b["parts_under_threshold"] == {"body": 0.0, "knob": 0.75}


def test_centre_map_counts_visible_part_centres_per_label_and_cell():
    """A part-id image → per label and 32-px cell, the parts whose visible pixels are centred
    there; hidden parts and labels outside the list are not counted; mirroring the image
    mirrors the map."""
    from model.imaging.partmaps import centre_map
    ids = np.full((224, 224), -1, np.int64)
    ids[10:200, 40:180] = 0          # body, centre (105, 110) → cell (3, 3)
    ids[20:30, 40:50] = 1            # handle, centre (25, 45) → cell (0, 1)
    ids[20:28, 150:158] = 2          # handle, centre (24, 154) → cell (0, 4)
    ids[100:104, 200:204] = 3        # screw: not a counted label
    # part 4 (a handle) is hidden: no pixels
    m = centre_map(ids, ["body", "handle", "handle", "screw", "handle"], ["body", "door", "handle"])
    assert m.shape == (3, 7, 7) and m.dtype == np.uint8
    assert m[0, 3, 3] == 1 and m[0].sum() == 1
    assert m[1].sum() == 0
    assert m[2, 0, 1] == 1 and m[2, 0, 4] == 1 and m[2].sum() == 2
    assert np.array_equal(centre_map(ids[:, ::-1], ["body", "handle", "handle", "screw", "handle"],
                                     ["body", "door", "handle"]), m[..., ::-1])
    ids2 = ids.copy()
    ids2[22:26, 42:46] = 4           # a second handle centred in the first one's cell
    m2 = centre_map(ids2, ["body", "handle", "handle", "screw", "handle"], ["body", "door", "handle"])
    assert m2[2, 0, 1] == 2
    assert centre_map(np.full((224, 224), -1), ["body"], ["body"]).sum() == 0


@pytest.mark.slow     # trains an image model and two trunks (~11 s on 2 busy cores)
def test_partmaps_of_a_render_set_and_a_trunk_trained_on_them(tiny_set, tmp_path):
    """`artformer data partmaps` maps every rendered view (each part seen in the render is
    counted once); the file is reused; `image-trunk --centre-weight` learns the maps beside
    the counts and records both losses; --init-trunk starts from a trunk, and a missing map
    file or a checkpoint without a trunk is refused with a message; `data features` caches a
    trunk's features where the trainer reads them."""
    import shutil

    from model.imaging.commands import main as commands_main
    from model.imaging.partmaps import build_partmaps, load_partmaps, partmap_path
    from model.imaging.render import part_pixels
    from model.imaging.renders import object_from_record, view_specs
    from model.imaging.trunk import cli_main, initial_count_head, initial_trunk, load_trunk
    from model.data import format as fmt

    image_ckpt, _, _ = _run(tiny_set, 0, 2, out=tmp_path / "img")
    renders = tmp_path / "renders"
    shutil.copytree(tiny_set / "renders", renders)
    common = ["--data", str(tiny_set / "prepared"), "--renders", str(renders)]
    trunk_args = common + ["--image", str(image_ckpt), "--steps", "24", "--batch-size", "4",
                           "--freeze", "12", "--evals", "2", "--lr", "1e-3", "--threads", "1"]
    assert cli_main(trunk_args + ["--out", str(tmp_path / "t0"), "--centre-weight", "0.2"]) == 2
    assert commands_main(["data", "partmaps", *common, "--image", str(image_ckpt), "--workers", "1"]) == 0
    labels = list(torch.load(image_ckpt, weights_only=False)["config"]["count_labels"])
    pm = load_partmaps(renders, labels)
    assert sorted(pm["ids"]) == ["bottle", "cabinet"]
    assert tuple(pm["maps"].shape) == (2, 2, len(labels), 7, 7) and pm["maps"].dtype == torch.uint8
    for k, oid in enumerate(pm["ids"]):
        obj = object_from_record(tiny_set / "prepared", fmt.load_record(tiny_set / "prepared", oid))
        for v, spec in enumerate(view_specs(renders, oid)):
            seen = part_pixels(obj, spec) > 0
            for li, lab in enumerate(labels):
                want = sum(1 for p, s in zip(obj.parts, seen) if s and p.label == lab)
                assert int(pm["maps"][k, v, li].sum()) == want, (oid, v, lab)
    stamp = partmap_path(renders).stat().st_mtime_ns
    build_partmaps(tiny_set / "prepared", renders, labels, progress=False)
    assert partmap_path(renders).stat().st_mtime_ns == stamp          # complete: not rewritten

    assert cli_main(trunk_args + ["--out", str(tmp_path / "t1"), "--centre-weight", "0.2"]) == 0
    tr = load_trunk(tmp_path / "t1")
    hist = tr["train"]["history"]
    assert tr["train"]["config"]["centre_weight"] == 0.2 and "centre_head" in tr
    assert hist[-1]["centre_loss"] < hist[0]["centre_loss"] or hist[-1]["centre_loss"] < 1.0
    assert all("count_loss" in h for h in hist)
    # a second run starts from the first one's blocks
    start = initial_trunk(tmp_path / "t1" / "trunk.pt", 12)
    assert all(torch.equal(start[k], v.float()) for k, v in tr["state_dict"].items())
    with pytest.raises(ValueError, match="more than 13"):
        initial_trunk(tmp_path / "t1" / "trunk.pt", 13)           # would drop block 12
    with pytest.raises(ValueError, match="neither"):
        initial_trunk(image_ckpt, 12)
    (tmp_path / "garbage.pt").write_bytes(b"not a checkpoint")
    from model.core.checkpoint import CheckpointError
    with pytest.raises(CheckpointError, match="corrupt or not an artformer checkpoint"):
        initial_trunk(tmp_path / "garbage.pt", 12)
    assert cli_main(trunk_args + ["--out", str(tmp_path / "t2"), "--steps", "2", "--evals", "1",
                                  "--init-trunk", str(tmp_path / "t1" / "trunk.pt")]) == 0
    t2 = load_trunk(tmp_path / "t2")
    assert t2["train"]["config"]["init"].endswith("trunk.pt") and t2["train"]["head_continued"]
    # a continuation may unfreeze more blocks: block 11 starts at ImageNet's weights
    assert cli_main(trunk_args + ["--freeze", "11", "--out", str(tmp_path / "t4"), "--steps", "2",
                                  "--evals", "1", "--init-trunk", str(tmp_path / "t1" / "trunk.pt")]) == 0
    t4 = load_trunk(tmp_path / "t4")
    assert t4["freeze"] == 11 and any(k.startswith("_blocks.11.") for k in t4["state_dict"])
    from model.encoders.image import ImageEncoder, ImageEncoderConfig
    imagenet = ImageEncoder(ImageEncoderConfig()).net.state_dict()

    def gap(a, b, block):
        ks = [k for k in t4["state_dict"] if k.startswith(f"_blocks.{block}.")]
        return sum(float((a[k].float() - b[k].float()).abs().sum()) for k in ks)
    assert gap(t4["state_dict"], tr["state_dict"], 12) < gap(t4["state_dict"], imagenet, 12)
    assert gap(t4["state_dict"], imagenet, 11) < 0.5 * gap(tr["state_dict"], imagenet, 12)
    # the count head continues from a trunk file with the same labels, never from elsewhere
    from model.imaging.counts import CountHeadConfig
    cfg = CountHeadConfig(**tr["count_head"]["config"])
    head = initial_count_head(tmp_path / "t1" / "trunk.pt", cfg)
    assert all(torch.equal(head[k], v.float()) for k, v in tr["count_head"]["state_dict"].items())
    assert initial_count_head(tmp_path / "t1" / "trunk.pt",
                              CountHeadConfig(**{**tr["count_head"]["config"], "max_count": 3})) is None
    assert initial_count_head(image_ckpt, cfg) is None
    assert cli_main(trunk_args + ["--out", str(tmp_path / "t3"), "--init-trunk", str(image_ckpt)]) == 2

    # `artformer data features` caches what the trainer reads: the same file, reused as it is
    from model.imaging.features import build_feature_cache, cache_path, feature_tag
    assert commands_main(["data", "features", *common, "--trunk", str(tmp_path / "t1" / "trunk.pt"),
                          "--splits", "train,val"]) == 0
    enc = ImageEncoder(ImageEncoderConfig())
    enc.load_tail_state_dict(tr["state_dict"])
    tag = feature_tag(enc, tr["tag"])
    path = cache_path(renders, tag=tag)
    stamp = path.stat().st_mtime_ns
    ids = fmt.split_ids(tiny_set / "prepared", "train") + fmt.split_ids(tiny_set / "prepared", "val")
    cache = build_feature_cache(renders, ids, encoder=enc, tag=tag)
    assert sorted(cache["ids"]) == sorted(set(ids)) and path.stat().st_mtime_ns == stamp
    assert tuple(cache["feats"].shape[1:3]) == (2, enc.net._blocks[15]._block_args.input_filters)
    # --multiscale adds the block-10 map the multiscale tokens read, from the same encoder
    from model.encoders.image import FINE_SPLIT, preprocess
    from model.imaging.features import load_feature_cache
    from model.imaging.renders import view_paths
    assert commands_main(["data", "features", *common, "--trunk", str(tmp_path / "t1" / "trunk.pt"),
                          "--splits", "train", "--multiscale"]) == 0
    assert path.stat().st_mtime_ns == stamp                            # block 15: reused
    fine = load_feature_cache(renders, FINE_SPLIT, tag)
    oid = fine["ids"][0]
    assert tuple(fine["feats"].shape[1:]) == (2, 112, 14, 14) and fine["split"] == FINE_SPLIT
    with torch.no_grad():
        want = enc.features_at(preprocess([str(view_paths(renders, oid)[1])], 224), FINE_SPLIT)
    torch.testing.assert_close(fine["feats"][0, 1].float(), want[0], atol=2e-2, rtol=1e-2)
    assert commands_main(["data", "features", *common, "--trunk", str(tmp_path / "garbage.pt")]) == 2
    assert commands_main(["data", "features", *common, "--splits", "nope"]) == 2


def _trunk_file(path, labels: list, shift: float, seed: int = 0, freeze: int = 13):
    """A trunk file as `artformer train image-trunk` writes it: ImageNet's blocks FREEZE-14
    moved by ``shift`` and an untrained count head over ``labels`` (a mechanics fixture; training
    one is covered by test_fine_tuned_trunk_feeds_the_image_model)."""
    from dataclasses import asdict

    from model.core.state import half_state
    from model.encoders.image import ImageEncoder, ImageEncoderConfig
    from model.imaging.counts import CountHead, CountHeadConfig
    from model.imaging.trunk import TRUNK_KIND, trunk_keys, trunk_tag
    net = ImageEncoder(ImageEncoderConfig()).net
    sd = net.state_dict()
    state = half_state({k: sd[k] + shift for k in trunk_keys(net, freeze)})
    torch.manual_seed(seed)
    head = CountHead(CountHeadConfig(labels=list(labels)))
    torch.save({"kind": TRUNK_KIND, "freeze": freeze, "split": 15, "tag": trunk_tag(state),
                "state_dict": state,
                "count_head": {"config": asdict(head.cfg), "state_dict": half_state(head.state_dict())},
                "train": {"command": "fixture", "seed": seed}}, path)
    return path


def test_multiscale_tokens_read_the_fine_tuned_trunk(tiny_set, tmp_path):
    """--multiscale with --trunk: both cached maps (block 10's and the one entering block 15)
    come from the fine-tuned blocks, and the loader makes the same 1728-d tokens of a PNG."""
    from model.encoders.image import FINE_SPLIT, ImageEncoder, ImageEncoderConfig, preprocess
    from model.imaging.features import load_feature_cache
    from model.imaging.model import load_image_model
    from model.imaging.renders import view_paths
    from model.imaging.trunk import load_trunk

    image_ckpt, _, _ = _run(tiny_set, 0, 2, out=tmp_path / "img")
    labels = load_image_model(image_ckpt).am.cfg.count_labels
    trunk = _trunk_file(tmp_path / "trunk.pt", labels, 0.02, freeze=8)
    path, _, _ = _run(tiny_set, 0, 2, multiscale=True, init=str(image_ckpt), trunk=str(trunk),
                      out=tmp_path / "ms")
    tag = load_trunk(trunk)["tag"]
    im = load_image_model(path)
    png = str(view_paths(tiny_set / "renders", "cabinet")[1])
    tokens, _ = im.encode(png)
    coarse = load_feature_cache(tiny_set / "renders", tag=tag)
    fine = load_feature_cache(tiny_set / "renders", FINE_SPLIT, tag)
    r, q = coarse["ids"].index("cabinet"), fine["ids"].index("cabinet")
    with torch.no_grad():
        cached = im.encoder.tail(coarse["feats"][r, 1:2].float(), start=coarse["split"],
                                 fine=fine["feats"][q, 1:2].float())
        imagenet = ImageEncoder(ImageEncoderConfig()).features_at(preprocess([png], 224), FINE_SPLIT)
    assert tokens.shape == (1, 49, 1728)
    # the caches hold fp16: equal to what the loader reads up to its rounding
    assert float((tokens - cached).abs().max()) <= 1e-3 * float(tokens.abs().max())
    assert not torch.allclose(fine["feats"][q, 1].float(), imagenet[0], atol=2e-2, rtol=1e-2)


def test_count_tokens_join_the_image_condition(tiny_set, tmp_path):
    """`train image --count-tokens TRUNK_PT`: the trunk's count head turns the cached map of
    every view into one token per label carrying its count distribution; the checkpoint
    keeps the head, the loader adds the same tokens to every image, a continued run keeps
    them, and a head of another trunk or a missing head is refused."""
    from dataclasses import asdict

    from model.encoders.image import preprocess
    from model.imaging.counts import (CountHead, CountHeadConfig, count_distributions,
                                      count_token_entry)
    from model.imaging.model import ImageModelError, load_image_model
    from model.imaging.renders import view_paths

    image_ckpt, _, _ = _run(tiny_set, 0, 2, out=tmp_path / "img")
    labels = load_image_model(image_ckpt).am.cfg.count_labels
    trunk = _trunk_file(tmp_path / "trunk.pt", labels, 1e-3)
    path, _, _ = _run(tiny_set, 0, 3, out=tmp_path / "ct", trunk=str(trunk),
                      count_tokens=str(trunk))
    ck = torch.load(path, map_location="cpu", weights_only=False)
    n = len(labels)
    assert ck["config"]["count_tokens"] == {"image": [n, 21]}
    assert ck["count_tokens"]["trunk_tag"] == ck["image_encoder"]["trunk_info"]["tag"]
    im = load_image_model(path)
    assert im.token_counter is not None and im.counter is None
    png = str(view_paths(tiny_set / "renders", "cabinet")[1])
    tokens, mask, plan = im.condition(png)
    assert tokens.shape == (1, 49 + n, 1280) and mask.shape == (1, 49 + n) and plan is None
    with torch.no_grad():
        _, h = im.encoder.tokens_and_features(preprocess(png), 15)
    probs = count_distributions(im.token_counter, h)
    assert torch.allclose(tokens[0, 49:, :21], probs[0], atol=1e-5)
    assert torch.allclose(tokens[0, 49:, :21].sum(-1), torch.ones(n), atol=1e-4)
    assert not tokens[0, 49:, 21:].any()
    trees = im.decode_image(png, samples=2, seed=0, max_nodes=8, temperature=1.0)
    assert len(trees) == 2 and all(t.num_nodes >= 1 for t in trees)
    # a continued run keeps the count tokens without being told again
    path2, _, _ = _run(tiny_set, 0, 2, out=tmp_path / "ct2", init=str(path))
    ck2 = torch.load(path2, map_location="cpu", weights_only=False)
    assert ck2["config"]["count_tokens"] == {"image": [n, 21]}
    assert load_image_model(path2).condition(png)[0].shape == (1, 49 + n, 1280)
    # half of the views may carry the true counts instead (a continued run, tokens kept)
    path3, _, _ = _run(tiny_set, 0, 2, out=tmp_path / "ct3", init=str(path), count_truth=0.5)
    assert torch.load(path3, map_location="cpu", weights_only=False)["image_train_config"][
        "count_truth"] == 0.5
    with pytest.raises(ValueError, match="count_truth needs count tokens"):
        _run(tiny_set, 0, 1, out=tmp_path / "nt", count_truth=0.5)
    # a count head reading another trunk than the run's features is refused
    other = _trunk_file(tmp_path / "other.pt", labels, 2e-3, seed=1)
    with pytest.raises(ValueError, match="count head reads trunk"):
        _run(tiny_set, 0, 1, out=tmp_path / "bad", trunk=str(trunk), count_tokens=str(other))
    # a network that expects count tokens without its head, or a head of the wrong shape
    ck.pop("count_tokens")
    torch.save(ck, tmp_path / "headless.pt")
    with pytest.raises(ImageModelError, match="no count_tokens head"):
        load_image_model(tmp_path / "headless.pt")
    ck = torch.load(path, map_location="cpu", weights_only=False)
    small = torch.load(trunk, map_location="cpu", weights_only=False)
    head10 = CountHead(CountHeadConfig(labels=list(labels), max_count=10))
    small["count_head"] = {"config": asdict(head10.cfg), "state_dict": head10.state_dict()}
    ck["count_tokens"] = count_token_entry(small)
    torch.save(ck, tmp_path / "reshaped.pt")
    with pytest.raises(ImageModelError, match="expects count tokens"):
        load_image_model(tmp_path / "reshaped.pt")
    ck["config"]["count_tokens"] = {"image": [n, 11]}       # config and weights disagree
    torch.save(ck, tmp_path / "mismatched.pt")
    with pytest.raises(ImageModelError, match="do not fit its config"):
        load_image_model(tmp_path / "mismatched.pt")


def test_true_count_tokens_replace_the_heads_readings_of_chosen_rows():
    from types import SimpleNamespace

    from model.imaging.counts import pack_count_tokens
    from model.imaging.train import _true_count_tokens
    labels = ["body", "door", "drawer"]
    probs = torch.full((2, 3, 4), 0.25)
    cond = pack_count_tokens(torch.randn(2, 49, 16), probs)
    before = cond.clone()
    items = [SimpleNamespace(labels=["body", "door", "door"]),
             SimpleNamespace(labels=["body"] + ["drawer"] * 9)]
    _true_count_tokens(cond, items, labels, 4, [False, True])
    assert torch.equal(cond[0], before[0]), "an unselected row keeps the head's readings"
    assert torch.equal(cond[1, :49], before[1, :49]), "the image tokens are untouched"
    want = torch.zeros(3, 16)
    want[0, 1] = want[1, 0] = want[2, 3] = 1.0          # 1 body, 0 doors, 9 drawers -> class 3
    assert torch.equal(cond[1, 49:], want)
    _true_count_tokens(cond, items, labels, 4, [True, False])
    assert cond[0, 49:, :4].argmax(-1).tolist() == [1, 2, 0]


@pytest.mark.slow     # two processes each load the image encoder (~30 s)
def test_torchrun_two_processes_train_the_image_model(tiny_set, tmp_path):
    import os
    import subprocess
    import sys
    from pathlib import Path
    torchrun = Path(sys.executable).parent / "torchrun"
    if not torchrun.exists():
        pytest.skip("torchrun not installed in this environment")
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(root))
    cmd = [str(torchrun), "--standalone", "--nproc_per_node", "2", "-m", "model", "train", "image",
           "--data", str(tiny_set / "prepared"), "--renders", str(tiny_set / "renders"),
           "--prior", "none", "--preset", "tiny", "--init", "none", "--steps", "4",
           "--no-progress", "--threads", "1", "--out", str(tmp_path / "run")]
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    from model.imaging.model import load_image_model
    im = load_image_model(tmp_path / "run" / "image.pt", prior="stand-in")
    assert im.meta["step"] == 4



def test_the_shipped_image_models_trunk_serves_as_a_trunk_file():
    """`--trunk model/weights/image_small.pt`: the shipped fine-tuned blocks 4-14 for a new
    image model (the text recipe's image stage); a text checkpoint is refused."""
    from model.imaging.trunk import TrunkError, first_block, load_trunk
    tr = load_trunk(ROOT / "model" / "weights" / "image_small.pt")
    assert tr["freeze"] == 4 and first_block(tr["state_dict"]) == 4 and len(tr["tag"]) == 12
    with pytest.raises(TrunkError, match="without a fine-tuned trunk"):
        load_trunk(ROOT / "model" / "weights" / "transformer_small.pt")
