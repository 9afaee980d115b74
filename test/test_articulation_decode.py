"""Decoding, editing, checkpoints and the training command on a tiny toy dataset."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from model.articulation.checkpoint import CheckpointError, read_checkpoint, save_checkpoint
from model.articulation.config import preset
from model.articulation.decode import ArticulationModel, DecodedTree
from model.articulation.network import ArticulationTransformer
from model.articulation.trees import batch_rows, initial_row
from model.core.objects import ArticulatedObject, JointType
from model.data import format as fmt

from helpers import write_toy_dataset

torch.set_num_threads(1)

LABELS = [("StorageFurniture", "body"), ("StorageFurniture", "drawer"),
          ("StorageFurniture", "handle"), ("StorageFurniture", "door"), ("Bottle", "body"),
          ("Bottle", "cap")]


def _random_model(end_bias: float = 0.0, seed: int = 0) -> ArticulationModel:
    torch.manual_seed(seed)
    cfg, _ = preset("tiny")
    net = ArticulationTransformer(cfg)
    with torch.no_grad():
        net.head_end.bias.fill_(end_bias)
    g = np.random.default_rng(seed)
    ckpt = {"stats": {"tok_mean": np.zeros(16, np.float32), "tok_std": np.ones(16, np.float32),
                      "cs_mean": np.zeros(64, np.float32), "cs_std": np.ones(64, np.float32)},
            "label_table": {"categories": [c for c, _ in LABELS], "labels": [l for _, l in LABELS],
                            "cs": g.normal(size=(len(LABELS), 64)).astype(np.float32)},
            "text_encoder": "all-minilm-l6-v2", "train_config": {}}
    return ArticulationModel(net, ckpt)


def _cond(S=3, L=4, seed=0):
    g = torch.Generator().manual_seed(seed)
    return torch.randn(S, L, 384, generator=g), torch.ones(S, L, dtype=torch.bool)


def _check_tree(t: DecodedTree, max_nodes, max_depth, max_children):
    assert 1 <= t.num_nodes <= max_nodes
    assert (t.parents < 0).sum() == 1 and t.parents[0] == -1
    assert all(p < i for i, p in enumerate(t.parents)), "parents come before children"
    assert t.depth().max() <= max_depth
    kids = np.bincount(t.parents[t.parents >= 0], minlength=t.num_nodes)
    assert kids.max(initial=0) <= max_children
    assert t.joint_types[0] == int(JointType.FIXED)
    assert t.tokens.shape == (t.num_nodes, 16) and t.cs.shape == (t.num_nodes, 64)
    assert t.P_logits.shape[0] == t.num_nodes
    obj = t.to_object()
    assert isinstance(obj, ArticulatedObject)
    obj.validate()
    assert len(obj.parts) == t.num_nodes


@pytest.mark.parametrize("caps", [(5, 4, 16), (32, 1, 3), (12, 2, 2), (1, 4, 16)])
def test_decoding_respects_caps_and_gives_valid_single_root_trees(caps):
    am = _random_model(end_bias=8.0)       # wants children everywhere: only caps stop it
    tok, mask = _cond()
    trees = am.decode(tok, mask, seed=0, max_nodes=caps[0], max_depth=caps[1],
                      max_children=caps[2])
    assert len(trees) == 3
    for t in trees:
        _check_tree(t, *caps)
    if caps == (5, 4, 16):
        assert all(t.num_nodes == 5 for t in trees)


def test_free_decoding_gives_each_label_only_the_joint_types_its_category_has():
    """An untrained joint-type head draws any type; the grammar of the data's generator
    (a cabinet's drawer slides, its door turns, its handle is fixed, a bottle's cap screws)
    holds every part of every tree to its label's types."""
    from model.articulation.structure_control import STRUCTURE_GRAMMAR
    am = _random_model(end_bias=8.0)
    tok, mask = _cond()
    kinds = {lab: {int(JointType.parse(j)) for j in STRUCTURE_GRAMMAR[cat][lab][1]}
             for cat, lab in LABELS if lab != "body"}
    seen = 0
    for seed in range(4):
        for t in am.decode(tok, mask, seed=seed, max_nodes=12, temperature=1.0):
            for lab, jt in zip(t.labels[1:], t.joint_types[1:]):
                if lab in kinds:
                    assert int(jt) in kinds[lab], (lab, jt)
                    seen += 1
    assert seen > 20


def test_decoding_stops_on_end_and_always_has_a_root():
    am = _random_model(end_bias=-30.0)     # END everywhere
    trees = am.decode(*_cond(), seed=0)
    assert [t.num_nodes for t in trees] == [1, 1, 1]


def test_determinism_under_a_seed_and_variety_across_seeds():
    am = _random_model(end_bias=0.5, seed=1)
    tok, mask = _cond(S=1)
    a = am.decode(tok, mask, seed=7, max_nodes=16)
    b = am.decode(tok, mask, seed=7, max_nodes=16)
    assert np.array_equal(a[0].parents, b[0].parents)
    assert np.allclose(a[0].tokens, b[0].tokens) and a[0].labels == b[0].labels
    # a row's result depends only on seed + row index, not on the batch around it
    tok3 = torch.cat([tok, torch.randn(2, 4, 384)])
    c = am.decode(tok3, torch.ones(3, 4, dtype=torch.bool), seed=7, max_nodes=16)
    assert np.array_equal(a[0].parents, c[0].parents)
    assert np.allclose(a[0].tokens, c[0].tokens, atol=1e-5)   # batched float noise only
    many = am.decode(tok.expand(8, -1, -1), mask.expand(8, -1), seed=0, max_nodes=16)
    shapes = {(tuple(t.parents), tuple(t.joint_types)) for t in many}
    assert len(shapes) > 1, "different seeds should give different trees"
    g = am.decode(tok, mask, seed=0, temperature=0.0, max_nodes=16)
    h = am.decode(tok, mask, seed=99, temperature=0.0, max_nodes=16)
    assert np.array_equal(g[0].parents, h[0].parents), "temperature 0 is greedy"


def _planning_model(end_bias: float, plan_count: int) -> ArticulationModel:
    """A random model with a plan head fixed to say ``plan_count`` parts of every label."""
    from dataclasses import replace
    am = _random_model(end_bias=end_bias, seed=2)
    cfg = replace(am.cfg, count_labels=["body", "drawer", "handle", "door", "cap"], plan_head=True)
    torch.manual_seed(2)
    net = ArticulationTransformer(cfg)
    with torch.no_grad():
        net.head_end.weight.zero_()          # END logit = end_bias everywhere
        net.head_end.bias.fill_(end_bias)
        net.head_plan.weight.zero_()
        bias = torch.full((len(cfg.count_labels), cfg.plan_max_count + 1), -10.0)
        bias[:, plan_count] = 10.0
        net.head_plan.bias.copy_(bias.flatten())
    return ArticulationModel(net, {"stats": {k: v for k, v in _stats(am).items()},
                                   "label_table": {"categories": [c for c, _ in LABELS],
                                                   "labels": [l for _, l in LABELS],
                                                   "cs": am.table_cs.numpy()},
                                   "text_encoder": "all-minilm-l6-v2", "train_config": {}})


def _stats(am: ArticulationModel) -> dict:
    return {"tok_mean": am.tok_mean.numpy(), "tok_std": am.tok_std.numpy(),
            "cs_mean": am.cs_mean.numpy(), "cs_std": am.cs_std.numpy()}


def _label_counts(t: DecodedTree) -> dict:
    return {lab: t.labels.count(lab) for lab in set(t.labels)}


def test_follow_plan_holds_end_decisions_to_the_plan_head():
    tok, mask = _cond(S=4)
    # END head wants children everywhere; a plan of 0 parts per label allows only the root
    greedy = _planning_model(end_bias=8.0, plan_count=0)
    free = greedy.decode(tok, mask, seed=0, temperature=0, max_nodes=12)
    held = greedy.decode(tok, mask, seed=0, temperature=0, max_nodes=12, follow_plan=True)
    assert all(t.num_nodes == 12 for t in free)
    assert [t.num_nodes for t in held] == [1, 1, 1, 1]
    # END head hesitant (p ~ 27 %): the plan (2 of every label) adds children up to the plan
    # and never beyond it; without the plan the greedy END head stops at the root
    hesitant = _planning_model(end_bias=-1.0, plan_count=2)
    free = hesitant.decode(tok, mask, seed=0, temperature=0, max_nodes=32)
    held = hesitant.decode(tok, mask, seed=0, temperature=0, max_nodes=32, follow_plan=True)
    assert [t.num_nodes for t in free] == [1, 1, 1, 1]
    assert all(t.num_nodes > 1 for t in held)
    for t in held:
        _check_tree(t, 32, 4, 16)
        assert max(_label_counts(t).values()) <= 2, t.labels   # the root counts too
    # a confident END (p ~ 1e-13) is never overridden into a child
    sure = _planning_model(end_bias=-30.0, plan_count=2)
    assert [t.num_nodes for t in sure.decode(tok, mask, seed=0, temperature=0,
                                             follow_plan=True)] == [1, 1, 1, 1]


def test_plans_may_leave_labels_free_and_trees_carry_their_log_probability():
    """A negative plan entry leaves that label's END decisions to the network; every tree
    records the untempered log-probability of its END and joint-type decisions and the START
    plan head's count logits."""
    import math
    tok, mask = _cond(S=2)
    am = _planning_model(end_bias=8.0, plan_count=0)
    n = len(am.cfg.count_labels)
    free = am.decode(tok, mask, seed=0, temperature=0, max_nodes=12)
    loose = am.decode(tok, mask, seed=0, temperature=0, max_nodes=12,
                      plan=torch.full((2, n), -1, dtype=torch.long))
    held = am.decode(tok, mask, seed=0, temperature=0, max_nodes=12,
                     plan=torch.zeros(2, n, dtype=torch.long))
    assert [t.num_nodes for t in free] == [12, 12]
    assert all(np.array_equal(a.parents, b.parents) and a.labels == b.labels
               for a, b in zip(free, loose))
    assert [t.num_nodes for t in held] == [1, 1]
    # the root's only counted decision: END (logit 8) overridden by the plan to stop
    for t in held:
        assert t.log_prob == pytest.approx(math.log(1 / (1 + math.exp(8.0))), rel=1e-5)
        assert t.plan_logits.shape == (n, am.cfg.plan_max_count + 1)
        assert int(np.argmax(t.plan_logits[0])) == 0
    # the free trees: 11 children added at p = sigmoid(8) each, plus their joint types
    for t in free:
        assert t.log_prob < 11 * math.log(1 / (1 + math.exp(-8.0))) < 0
    sampled = am.decode(tok.repeat(3, 1, 1), mask.repeat(3, 1), seed=3, temperature=1.0,
                        max_nodes=12)
    assert all(math.isfinite(t.log_prob) and t.log_prob < 0 for t in sampled)


def test_editing_keeps_the_given_nodes_and_regrows():
    am = _random_model(end_bias=0.5, seed=2)
    tok, mask = _cond(S=2)
    full = am.decode(tok[:1], mask[:1], seed=3, max_nodes=10)[0]
    # partial tree: the root and its first child only (a DecodedTree)
    keep = DecodedTree(tokens=full.tokens[:1], joint_types=full.joint_types[:1],
                       parents=full.parents[:1], labels=full.labels[:1], category=full.category,
                       cs=full.cs[:1], cs_raw=full.cs_raw[:1], P_logits=full.P_logits[:1])
    edited = am.decode(tok, mask, seed=5, keep=keep, max_nodes=10)
    for t in edited:
        assert t.kept[:1].all() and not t.kept[1:].any()
        assert np.allclose(t.tokens[0], keep.tokens[0], atol=1e-5)
        assert t.labels[0] == keep.labels[0]
        assert np.allclose(t.P_logits[0], keep.P_logits[0])
        _check_tree(t, 10, 4, 16)
    # an ArticulatedObject with parts removed works too; kept parts come first
    obj = ArticulatedObject.from_tokens(
        np.tile(np.r_[0.5, 0.5, 0.5, 0, 0, 0.25, 0, 0, 0, 1, 0, 0, 0, 0.3, 0, 0], (3, 1)),
        [0, 2, 2], [-1, 0, 0], ["body", "drawer", "drawer"], category="StorageFurniture")
    del obj.parts[2]
    always = _random_model(end_bias=8.0, seed=2)
    res = always.decode(tok[:1], mask[:1], seed=0, keep=obj, max_nodes=6)[0]
    assert res.num_nodes == 6 and list(res.kept) == [True, True, False, False, False, False]
    assert list(res.source_index[:2]) == [0, 1] and res.labels[:2] == ["body", "drawer"]
    assert np.allclose(res.tokens[:2], np.stack([p.token() for p in obj.parts]), atol=1e-5)
    assert list(res.parents[:2]) == [-1, 0]
    with pytest.raises(ValueError):
        always.decode(tok[:1], mask[:1], keep=obj, max_nodes=1)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny model trained by the real command on the toy dataset (a few seconds)."""
    from model.articulation.commands import main
    root = tmp_path_factory.mktemp("toy")
    data, out = root / "data", root / "run"
    write_toy_dataset(data, n=20)
    rc = main(["train", "transformer", "--data", str(data), "--prior", "none", "--preset", "tiny",
               "--out", str(out), "--steps", "150", "--no-progress", "--half", str(root / "h.pt")])
    assert rc == 0
    return root, data, out


def test_training_command_writes_resumable_checkpoints(trained):
    root, data, out = trained
    ck = read_checkpoint(out / "last.pt")
    assert ck["step"] == 150 and "optimizer" in ck
    assert ck["data_version"] == "toy1" and ck["seed"] == 0 and "--preset tiny" in ck["command"]
    # trained on stand-in targets: recorded as such, also in the fp16 copy (--half)
    assert ck["prior"] == "stand-in" and read_checkpoint(root / "h.pt")["prior"] == "stand-in"
    hist = json.loads((out / "history.json").read_text())
    assert "val" in hist[-1] and np.isfinite(hist[-1]["val"]["total"])
    from model.articulation.commands import main
    assert main(["train", "transformer", "--data", str(data), "--prior", "none", "--preset",
                 "tiny", "--out", str(out), "--steps", "160", "--resume", "--no-progress"]) == 0
    ck2 = read_checkpoint(out / "last.pt")
    assert ck2["step"] == 160
    assert len(ck2["history"]) > len(ck["history"])


def test_checkpoint_round_trip_and_fp16_copy(trained, tmp_path):
    root, data, out = trained
    am = ArticulationModel.load(out / "transformer.pt")
    ck = read_checkpoint(out / "transformer.pt")
    assert read_checkpoint(root / "h.pt")["state_dict"]["head_end.weight"].dtype == torch.float16
    save_checkpoint(tmp_path / "half.pt", am.net, stats=ck["stats"], label_table=ck["label_table"],
                    text_encoder=ck["text_encoder"], data_version="x", seed=3, command="c",
                    step=1, half=True)
    am16 = ArticulationModel.load(tmp_path / "half.pt")
    assert set(am.table_labels) == {"body", "drawer", "handle", "door", "cap"}
    tok, mask = am.encode_text(["A cabinet with two drawers.", "A bottle with a twist-off cap."])
    a = am.decode(tok, mask, seed=1, temperature=0.0)
    b = ArticulationModel.load(out).decode(tok, mask, seed=1, temperature=0.0)  # folder works
    for x, y in zip(a, b):
        assert np.array_equal(x.parents, y.parents) and np.allclose(x.tokens, y.tokens)
    with torch.no_grad():
        tb = batch_rows(am, [initial_row(am, None, 8)])
        o32, _ = am.net(tb, tok[:1], mask[:1])
        o16, _ = am16.net(tb, tok[:1], mask[:1])
    assert torch.allclose(o32["art"], o16["art"], atol=0.05)
    # save -> load gives identical weights and the config rebuilds the model alone
    save_checkpoint(tmp_path / "copy.pt", am.net, stats=ck["stats"], label_table=ck["label_table"],
                    text_encoder=ck["text_encoder"], data_version="x", seed=3, command="c", step=1)
    again = ArticulationModel.load(tmp_path / "copy.pt")
    for k, v in am.net.state_dict().items():
        assert torch.equal(v, again.net.state_dict()[k])
    torch.save({"kind": "prior"}, tmp_path / "other.pt")
    with pytest.raises(CheckpointError, match="not an articulation"):
        read_checkpoint(tmp_path / "other.pt")
    with pytest.raises(CheckpointError, match="no articulation checkpoint"):
        read_checkpoint(tmp_path / "missing.pt")


def test_trained_tiny_model_learns_the_toy_structure(trained, tmp_path):
    """Not a quality bar: 150 tiny steps must learn the category and joint types of its own
    training objects (exact part counts need longer training)."""
    from model.metrics.text_alignment import alignment_report
    root, data, out = trained
    rep = alignment_report(str(out / "transformer.pt"), str(data), split="train", limit=12,
                           progress=False, temperature=0.0)
    assert rep["prompts"] == 48 and 0.0 <= rep["alignment"] <= 1.0
    assert rep["category"] > 0.8 and rep["joint_types"] > 0.6
    assert "prompt_alignment" in rep and rep["prompt_checked"] == 48


def test_prior_targets_from_geometry_checkpoints(tmp_path):
    """The real target provider on randomly initialised tiny shape-prior checkpoints."""
    from model.articulation.targets import PriorTargets
    from model.geometry.autoencoder import SDFAutoEncoder
    from model.geometry.checkpoint import save_checkpoint as geo_save
    from model.geometry.config import get_preset
    from model.geometry.prior import ShapePrior
    torch.manual_seed(0)
    p = get_preset("tiny")
    geo_save(tmp_path / "sdf.pt", "sdf", SDFAutoEncoder(p.sdf), train_cfg=p.sdf_train)
    geo_save(tmp_path / "prior.pt", "prior", ShapePrior(p.prior))
    t = PriorTargets(str(tmp_path / "prior.pt"), str(tmp_path / "sdf.pt"))
    assert (t.z_dim, t.num_codebooks, t.codebook_size, t.cs_dim) == (32, 4, 8, 16)
    pts = np.random.default_rng(0).uniform(-0.9, 0.9, size=(3, 300, 3)).astype(np.float32)
    z = t.part_latents(pts)
    assert z.shape == (3, 32) and np.allclose(z, t.part_latents(pts))
    P = t.code_distribution(torch.as_tensor(z))
    assert P.shape == (3, 4, 8) and torch.allclose(P.sum(-1), torch.ones(3, 4), atol=1e-5)
    cs = t.semantic_condition(["storage furniture, drawer", "bottle, cap"])
    assert cs.shape == (2, 16) and not torch.allclose(cs[0], cs[1])
    # and a tiny training run on them
    from model.articulation.config import preset
    from model.articulation.train import RunConfig, train
    write_toy_dataset(tmp_path / "data", n=10)
    net, tc = preset("tiny", max_steps=4, val_every=2, ckpt_every=2)
    path = train(RunConfig(data=str(tmp_path / "data"), out=str(tmp_path / "run"), net=net,
                           train=tc, targets=t, progress=False))
    am = ArticulationModel.load(path)
    assert am.cfg.cs_dim == 16 and am.cfg.codebook_size == 8 and am.table_cs.shape[1] == 16
    trees = am.decode(*am.encode_text(["a bottle"]), seed=0, max_nodes=4)
    assert trees[0].P_logits.shape[1:] == (4, 8)


def test_init_from_checkpoint_fine_tunes(trained, tmp_path):
    from model.articulation.commands import main
    root, data, out = trained
    src = read_checkpoint(out / "transformer.pt")
    assert main(["train", "transformer", "--data", str(data), "--prior", "none", "--preset",
                 "tiny", "--out", str(tmp_path / "ft"), "--steps", "1", "--lr", "1e-12",
                 "--init", str(out / "transformer.pt"), "--no-progress"]) == 0
    ft = read_checkpoint(tmp_path / "ft" / "transformer.pt")
    assert ft["init"] == str(out / "transformer.pt") and ft["step"] == 1
    w0, w1 = src["state_dict"]["head_jt.weight"], ft["state_dict"]["head_jt.weight"]
    assert torch.allclose(w0, w1, atol=1e-6), "weights start from the given checkpoint"


def test_extra_training_sets_join_the_training_objects(trained, tmp_path):
    """--extra-train: every split of another prepared set (its own data version) trains
    beside --data's train split, normalised with --data's stats; recorded in the checkpoint;
    the main set again and a resume with other extras are refused."""
    from model.articulation.commands import main
    from model.articulation.data import TextCache
    root, data, out = trained
    extra = tmp_path / "extra"
    write_toy_dataset(extra, n=5, seed=1, version="toy2")
    run = tmp_path / "x"
    base = ["train", "transformer", "--data", str(data), "--prior", "none", "--preset", "tiny",
            "--no-progress", "--out", str(run)]
    assert main(base + ["--steps", "2", "--extra-train", str(extra)]) == 0
    ck = read_checkpoint(run / "transformer.pt")
    assert ck["extra_train"] == [{"data": str(extra), "data_version": "toy2", "objects": 5,
                                  "wordings": "all"}]
    assert ck["data_version"] == "toy1"
    ref = read_checkpoint(out / "transformer.pt")       # stats come from --data alone
    assert np.allclose(ck["stats"]["tok_mean"], ref["stats"]["tok_mean"])
    # every description of the extra objects, test split included, was encoded for training
    cache = TextCache.load(run / "cache" / "texts.pt", ck["text_encoder"])
    xtexts = {t for i in fmt.load_manifest(extra)["splits"]["test"]
              for ts in fmt.load_record(extra, i).descriptions.values() for t in ts}
    assert xtexts and xtexts <= set(cache.index)
    with pytest.raises(ValueError, match="own version"):
        main(base[:-1] + [str(tmp_path / "y"), "--steps", "1", "--extra-train", str(data)])
    with pytest.raises(ValueError, match="same --extra-train"):
        main(base + ["--steps", "3", "--resume"])
    # --extra-wordings 1: only the first wording of each length of the extra objects is
    # encoded; --data's objects keep all of theirs; a resume must keep the same setting
    extra3 = tmp_path / "extra3"
    write_toy_dataset(extra3, n=5, seed=1, version="toy3", wordings=3)
    run1 = tmp_path / "w1"
    one = base[:-1] + [str(run1), "--extra-train", str(extra3), "--extra-wordings", "1"]
    assert main(one + ["--steps", "2"]) == 0
    assert read_checkpoint(run1 / "transformer.pt")["extra_train"][0]["wordings"] == 1
    cache = TextCache.load(run1 / "cache" / "texts.pt", ck["text_encoder"])
    recs = [fmt.load_record(extra3, i) for s in ("train", "val", "test")
            for i in fmt.load_manifest(extra3)["splits"][s]]
    firsts = {ts[0] for r in recs for ts in r.descriptions.values() if ts}
    rest = {t for r in recs for ts in r.descriptions.values() for t in ts[1:]} - firsts
    assert firsts <= set(cache.index) and rest and not rest & set(cache.index)
    main_texts = {t for i in fmt.load_manifest(data)["splits"]["train"]
                  for ts in fmt.load_record(data, i).descriptions.values() for t in ts}
    assert main_texts <= set(cache.index)
    with pytest.raises(ValueError, match="same --extra-wordings"):
        main(base[:-1] + [str(run1), "--extra-train", str(extra3), "--steps", "3", "--resume"])


def test_own_inputs_feed_back_the_networks_teacher_forced_predictions(trained, tmp_path):
    """Scheduled sampling: with share 1 every existing node carries what the network predicts
    for it from its parent (ground-truth tree before that node's round); share 0 is a no-op;
    the command trains with --own-inputs."""
    from model.articulation.commands import main
    from model.articulation.data import TextCache, collate, group_rounds, round_sample
    from model.articulation.targets import StandInTargets
    from model.articulation.train import make_batch, own_input_tokens, prepare_data
    root, data, out = trained
    am = ArticulationModel.load(out / "transformer.pt")
    net, cfg = am.net, am.cfg
    tg = StandInTargets(z_dim=cfg.z_dim, num_codebooks=cfg.num_codebooks,
                        codebook_size=cfg.codebook_size, cs_dim=cfg.cs_dim)
    ck = read_checkpoint(out / "transformer.pt")
    pd = prepare_data(str(data), tg, stats=ck["stats"], label_table=ck["label_table"],
                      progress=False)
    items = pd.items["train"]
    cache = TextCache(am.text_encoder_name)
    cache.add([t for it in items for g in it.texts for t in g])
    rng = np.random.default_rng(0)
    groups = group_rounds(items, np.arange(len(items)), 16, 4, rng)[0]
    batch, _, cond, cmask, idx = make_batch(items, groups, pd.geo_shape, cache, rng,
                                            None, cfg.count_labels)
    gt = batch.tokens.clone()
    assert own_input_tokens(net, items, groups, batch, cond, cmask, "text", 0.0, rng,
                            pd.geo_shape) == 0
    assert torch.equal(batch.tokens, gt)
    net.train()
    assert own_input_tokens(net, items, groups, batch, cond, cmask, "text", 1.0, rng,
                            pd.geo_shape) == len(groups)
    assert net.training, "the training mode is restored"
    # reference for the last round sample of the first object: its nodes one by one
    u, (i, rounds) = 0, groups[0]
    it, k = items[i], rounds[-1]
    present = np.nonzero(it.rounds < k)[0]
    net.eval()
    with torch.no_grad():
        for n, c in enumerate(present):
            s = round_sample(it, int(it.rounds[c]))
            b, _ = collate([s], pd.geo_shape, None, cfg.count_labels)
            o, _ = net(b, cond[u:u + 1], cmask[u:u + 1], "text")
            slot = int(np.nonzero(s["target"] == c)[0][0])
            assert torch.allclose(batch.tokens[len(rounds) - 1, 1 + n], o["art"][0, slot],
                                  atol=1e-5)
    assert not torch.equal(batch.tokens, gt)
    assert torch.equal(batch.tokens[:, 0], gt[:, 0]), "START stays"
    assert main(["train", "transformer", "--data", str(data), "--prior", "none", "--preset",
                 "tiny", "--out", str(tmp_path / "own"), "--steps", "3", "--own-inputs", "0.5",
                 "--init", str(out / "transformer.pt"), "--no-progress"]) == 0
    assert read_checkpoint(tmp_path / "own" / "transformer.pt")["train_config"]["own_inputs"] == 0.5
