"""Network-level tests: TPE shapes and padding, masks honoured, loss decreases (tiny overfit)."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from model.articulation.config import preset
from model.articulation.network import ArticulationTransformer, Targets, TreeBatch, \
    TreePositionEmbedding

torch.set_num_threads(1)


def _tree_batch(parents_rows, cs_dim=64, seed=0):
    """parents_rows: per sample, list of node parents (node positions, -1 root); START added."""
    g = torch.Generator().manual_seed(seed)
    B = len(parents_rows)
    N = 1 + max(len(p) for p in parents_rows)
    tok = torch.zeros(B, N, 16)
    jt = torch.zeros(B, N, dtype=torch.long)
    cs = torch.zeros(B, N, cs_dim)
    par = torch.full((B, N), -1, dtype=torch.long)
    dep = torch.full((B, N), -1, dtype=torch.long)
    mask = torch.zeros(B, N, dtype=torch.bool)
    for b, ps in enumerate(parents_rows):
        n = len(ps)
        mask[b, : n + 1] = True
        tok[b, 1:n + 1] = torch.randn(n, 16, generator=g)
        jt[b, 1:n + 1] = torch.randint(0, 5, (n,), generator=g)
        cs[b, 1:n + 1] = torch.randn(n, cs_dim, generator=g)
        for i, p in enumerate(ps):
            par[b, i + 1] = p + 1 if p >= 0 else -1
            dep[b, i + 1] = 0 if p < 0 else dep[b, p + 1] + 1
    return TreeBatch(tok, jt, cs, par, dep, mask)


def test_tpe_shapes_and_ancestor_structure():
    torch.manual_seed(0)
    tpe = TreePositionEmbedding(d_in=8, hidden=16, code=4, levels=3)
    # START, root, child of root, grandchild, great-grandchild (deeper than 3 levels)
    parents = torch.tensor([[-1, -1, 1, 2, 3]])
    depth = torch.tensor([[-1, 0, 1, 2, 3]])
    x = torch.randn(1, 5, 8)
    e = tpe(x, parents, depth)
    assert e.shape == (1, 5, 12)
    assert torch.all(e[0, 0] == 0), "START has no tree position"
    assert torch.all(e[0, 1, 4:] == 0), "the root's ancestor slots are zero-padded"
    assert torch.all(e[0, 2, 8:] == 0) and torch.any(e[0, 2, 4:8] != 0)
    # e_i = concat(c_i, e_parent) truncated: slot k of a node = slot k-1 of its parent
    assert torch.allclose(e[0, 2, 4:8], e[0, 1, 0:4])
    assert torch.allclose(e[0, 3, 4:12], e[0, 2, 0:8])
    assert torch.allclose(e[0, 4, 4:12], e[0, 3, 0:8]), "deep nodes are truncated, not shifted"
    # the GRU chain: changing the root's features changes every descendant's own code
    x2 = x.clone()
    x2[0, 1] += 1.0
    e2 = tpe(x2, parents, depth)
    assert not torch.allclose(e2[0, 4, :4], e[0, 4, :4])


def test_padding_nodes_and_condition_tokens_do_not_change_outputs():
    torch.manual_seed(0)
    cfg, _ = preset("tiny")
    net = ArticulationTransformer(cfg).eval()
    small = _tree_batch([[-1, 0, 0, 1]])
    big = _tree_batch([[-1, 0, 0, 1], [-1, 0, 1, 2, 2, 0, 0]])   # row 0 now padded to 8
    cond = torch.randn(1, 5, 384)
    cmask = torch.tensor([[True, True, True, False, False]])
    cond_big = torch.cat([cond, torch.randn(1, 5, 384)])
    cond_big[0, 3:] = 100.0          # garbage under the mask must not matter
    cmask_big = torch.cat([cmask, torch.ones(1, 5, dtype=torch.bool)])
    # also pad the condition sequence of row 0 with more masked tokens
    cond_big = torch.cat([cond_big, torch.full((2, 2, 384), 7.0)], 1)
    cmask_big = torch.cat([cmask_big, torch.tensor([[False, False], [True, True]])], 1)
    with torch.no_grad():
        o1, _ = net(small, cond, cmask)
        o2, _ = net(big, cond_big, cmask_big)
    n = 5
    for k in ("end", "art", "jt", "cs", "geo"):
        assert torch.allclose(o1[k][0, :n], o2[k][0, :n], atol=1e-5), k
    # and the mask matters: unmasking the garbage changes the outputs
    with torch.no_grad():
        o3, _ = net(small, cond_big[:1, :5], torch.ones(1, 5, dtype=torch.bool))
    assert not torch.allclose(o1["art"], o3["art"], atol=1e-4)


def test_self_attention_is_not_causal():
    torch.manual_seed(0)
    cfg, _ = preset("tiny")
    net = ArticulationTransformer(cfg).eval()
    a = _tree_batch([[-1, 0, 0]], seed=1)
    b = _tree_batch([[-1, 0, 0]], seed=1)
    b.tokens[0, 3] += 1.0   # change the LAST node; the earlier nodes must see it
    cond, cmask = torch.randn(1, 3, 384), torch.ones(1, 3, dtype=torch.bool)
    with torch.no_grad():
        oa, _ = net(a, cond, cmask)
        ob, _ = net(b, cond, cmask)
    assert not torch.allclose(oa["end"][0, 1], ob["end"][0, 1])


def test_condition_dropout_leaves_only_the_null_token():
    torch.manual_seed(0)
    cfg, _ = preset("tiny")
    net = ArticulationTransformer(cfg).eval()
    tb = _tree_batch([[-1, 0]])
    with torch.no_grad():
        o1, _ = net(tb, torch.randn(1, 4, 384), torch.ones(1, 4, dtype=torch.bool),
                    drop=torch.tensor([True]))
        o2, _ = net(tb, torch.randn(1, 6, 384), torch.ones(1, 6, dtype=torch.bool),
                    drop=torch.tensor([True]))
    assert torch.allclose(o1["art"], o2["art"], atol=1e-5)


@pytest.mark.parametrize("ablation", ["none", "no_tpe", "one_codebook", "no_shape_prior"])
def test_loss_decreases_on_tiny_overfit(ablation):
    torch.manual_seed(0)
    cfg, _ = preset("tiny", ablation)
    net = ArticulationTransformer(cfg)
    tb = _tree_batch([[-1, 0, 0, 1], [-1, 0]])
    B, N = tb.mask.shape
    g = torch.Generator().manual_seed(3)
    has = torch.tensor([[1, 1, 1, 0, 0], [1, 0, 0, 0, 0]], dtype=torch.float32)
    P = torch.softmax(torch.randn(B, N, cfg.num_codebooks, cfg.codebook_size, generator=g) * 3, -1)
    t = Targets(has, torch.randn(B, N, 16, generator=g), torch.randint(0, 5, (B, N), generator=g),
                torch.randn(B, N, 64, generator=g),
                child_P=None if cfg.predict_z else P,
                child_z=torch.randn(B, N, cfg.z_dim, generator=g) if cfg.predict_z else None)
    cond, cmask = torch.randn(B, 3, 384), torch.ones(B, 3, dtype=torch.bool)
    opt = torch.optim.Adam(net.parameters(), lr=3e-3)
    losses = []
    for _ in range(60):
        _, L = net(tb, cond, cmask, targets=t)
        opt.zero_grad()
        L["total"].backward()
        opt.step()
        losses.append(float(L["total"].detach()))
    assert np.isfinite(losses).all()
    assert losses[-1] < 0.3 * losses[0], (losses[0], losses[-1])


def test_presets_build_and_paper_sizes():
    cfg, _ = preset("paper")
    assert (cfg.n_layers, cfg.d_model, cfg.n_heads, cfg.tpe_dim) == (8, 1024, 8, 1024)
    assert cfg.tpe_levels == 16 and cfg.tpe_code_dim == 64
    with pytest.raises(KeyError):
        preset("huge")
    with pytest.raises(ValueError):
        preset("tiny", "no_such_ablation")


def test_shared_condition_rows_equal_repeated_rows():
    """cond_index (several trees reading one encoded text) == the text repeated per tree."""
    torch.manual_seed(0)
    cfg, _ = preset("tiny")
    net = ArticulationTransformer(cfg).eval()
    tb = _tree_batch([[-1, 0], [-1, 0, 1], [-1]])
    cond = torch.randn(2, 4, 384)
    cmask = torch.tensor([[True, True, True, False], [True, True, False, False]])
    idx = torch.tensor([1, 0, 1])
    drop = torch.tensor([False, False, True])
    with torch.no_grad():
        a, _ = net(tb, cond, cmask, cond_index=idx, drop=drop)
        b, _ = net(tb, cond[idx], cmask[idx], drop=drop)
    for k in a:
        assert torch.allclose(a[k], b[k], atol=1e-5), k
    with torch.no_grad():   # an all-masked condition row stays finite (NULL token only)
        c, _ = net(tb, cond[idx], torch.zeros(3, 4, dtype=torch.bool))
    assert all(torch.isfinite(v).all() for v in c.values())


def test_child_count_features():
    cfg, _ = preset("tiny", count_labels=["drawer", "handle"])
    net = ArticulationTransformer(cfg)
    tb = _tree_batch([[-1, 0, 0, 1]])   # root, two children of the root, a grandchild
    tb.labels = torch.tensor([[-1, -1, 0, 0, 1]])
    c = net.child_counts(tb) * 4.0
    assert c.shape == (1, 5, 3)
    assert c[0, 0].tolist() == [1, 0, 0], "START has the root"
    assert c[0, 1].tolist() == [2, 2, 0], "root: two drawers"
    assert c[0, 2].tolist() == [1, 0, 1], "first drawer: one handle"
    assert c[0, 3].tolist() == [0, 0, 0] and c[0, 4].tolist() == [0, 0, 0]


def test_plan_head_loss():
    torch.manual_seed(0)
    cfg, _ = preset("tiny", count_labels=["drawer", "handle"])
    net = ArticulationTransformer(cfg)
    tb = _tree_batch([[-1, 0, 0, 1]])
    B, N = tb.mask.shape
    t = Targets(torch.zeros(B, N), torch.zeros(B, N, 16), torch.zeros(B, N, dtype=torch.long),
                torch.zeros(B, N, 64), child_P=torch.full((B, N, 4, 16), 1 / 16),
                plan_counts=torch.tensor([[2, 1]]))
    out, L = net(tb, torch.randn(1, 3, 384), torch.ones(1, 3, dtype=torch.bool), targets=t)
    assert out["plan"].shape == (1, 2, cfg.plan_max_count + 1)
    assert "plan" in L and torch.isfinite(L["plan"])


def test_image_grid_positions_make_token_order_matter():
    """Without a position grid the condition is a set (a permutation of the 49 image tokens
    gives the same outputs); with cond_grid the layout of the feature map reaches the
    decoder. Older configs (no cond_grid key) still load, without the embedding."""
    from model.articulation.config import ArticulationConfig
    from model.articulation.network import grid_sincos
    from dataclasses import asdict
    torch.manual_seed(0)
    tb = _tree_batch([[-1, 0, 0]], seed=2)
    cond = torch.randn(1, 49, 1280)
    cmask = torch.ones(1, 49, dtype=torch.bool)
    perm = torch.randperm(49)
    outs = {}
    for grid in ({}, {"image": [7, 7]}):
        cfg, _ = preset("tiny", cond_grid=grid)
        torch.manual_seed(0)
        net = ArticulationTransformer(cfg).eval()
        with torch.no_grad():
            a, _ = net(tb, cond, cmask, "image")
            b, _ = net(tb, cond[:, perm], cmask, "image")
        outs[bool(grid)] = torch.allclose(a["art"], b["art"], atol=1e-5)
        if grid:
            with pytest.raises(ValueError, match="position grid"):
                net(tb, cond[:, :48], cmask[:, :48], "image")
            # text tokens (no grid for that modality) of any length still work
            net(tb, torch.randn(1, 5, 384), torch.ones(1, 5, dtype=torch.bool), "text")
    assert outs[False], "without positions the image tokens are an unordered set"
    assert not outs[True], "with the grid embedding the token layout changes the outputs"
    code = grid_sincos(7, 7, 32)[0]
    assert code.shape == (49, 32) and len({tuple(r.tolist()) for r in code}) == 49
    old = asdict(preset("tiny")[0])
    old.pop("cond_grid")
    assert ArticulationConfig.from_dict(old).cond_grid == {}


def test_count_tokens_carry_their_distributions_to_the_decoder():
    """With cfg.count_tokens the condition ends with one token per counted label whose first
    ``classes`` channels are a count distribution: those channels reach the outputs, the
    padding channels after them do not, too few tokens are refused, and configs from before
    count tokens load without them."""
    from dataclasses import asdict

    from model.articulation.config import ArticulationConfig
    from model.imaging.counts import pack_count_tokens
    torch.manual_seed(0)
    tb = _tree_batch([[-1, 0, 0]], seed=2)
    cfg, _ = preset("tiny", cond_grid={"image": [7, 7]}, count_tokens={"image": [3, 5]})
    net = ArticulationTransformer(cfg).eval()
    grid = torch.randn(1, 49, 1280)
    probs = torch.softmax(torch.randn(1, 3, 5), -1)
    cond = pack_count_tokens(grid, probs)
    assert cond.shape == (1, 52, 1280)
    assert torch.equal(cond[:, 49:, :5], probs) and not cond[:, 49:, 5:].any()
    cmask = torch.ones(1, 52, dtype=torch.bool)
    with torch.no_grad():
        a, _ = net(tb, cond, cmask, "image")
        other = pack_count_tokens(grid, torch.softmax(torch.randn(1, 3, 5), -1))
        b, _ = net(tb, other, cmask, "image")
        padded = cond.clone()
        padded[:, 49:, 5:] = 7.0
        c, _ = net(tb, padded, cmask, "image")
    assert not torch.allclose(a["art"], b["art"], atol=1e-5), "the distributions are read"
    assert torch.allclose(a["art"], c["art"]), "channels past the classes are ignored"
    with pytest.raises(ValueError, match="count tokens"):
        net(tb, grid[:, :3], cmask[:, :3], "image")
    with pytest.raises(ValueError, match="position grid"):
        net(tb, grid, cmask[:, :49], "image")      # 49 tokens read as 46 + 3 count tokens
    with pytest.raises(ValueError, match="do not fit"):
        pack_count_tokens(torch.zeros(1, 49, 4), probs)
    old = asdict(preset("tiny")[0])
    old.pop("count_tokens")
    assert ArticulationConfig.from_dict(old).count_tokens == {}
