"""Articulation modes (ArticulationConfig.art_modes): the head proposes K candidate tokens
with probabilities, is trained winner-takes-all, and decoding draws one candidate."""
import numpy as np
import pytest
import torch
from torch import nn

from model.articulation.config import preset
from model.articulation.decode import ArticulationModel
from model.articulation.network import MODE_EPS, ArticulationTransformer, Targets
from model.articulation.trees import batch_rows, initial_row

torch.set_num_threads(1)


def _net(K: int) -> ArticulationTransformer:
    torch.manual_seed(0)
    cfg, _ = preset("tiny", art_modes=K)
    return ArticulationTransformer(cfg).eval()


def _model(net) -> ArticulationModel:
    return ArticulationModel(net, {
        "stats": {"tok_mean": np.r_[[0.4] * 3, [0.0] * 13].astype(np.float32),
                  "tok_std": np.ones(16, np.float32),
                  "cs_mean": np.zeros(64, np.float32), "cs_std": np.ones(64, np.float32)},
        "label_table": {"categories": ["StorageFurniture"] * 2, "labels": ["body", "drawer"],
                        "cs": np.eye(2, 64, dtype=np.float32)},
        "text_encoder": "all-minilm-l6-v2", "train_config": {}})


def _batch(am):
    return batch_rows(am, [initial_row(am, None, 8)])


def test_the_head_proposes_modes_and_art_is_the_most_probable_one():
    net = _net(3)
    am = _model(net)
    cond = torch.randn(1, 4, 384), torch.ones(1, 4, dtype=torch.bool)
    out, _ = net(_batch(am), *cond)
    assert out["art_modes"].shape == (1, 1, 3, 16) and out["art_logits"].shape == (1, 1, 3)
    k = int(out["art_logits"][0, 0].argmax())
    assert torch.equal(out["art"][0, 0], out["art_modes"][0, 0, k])
    one, _ = _net(1)(_batch(am), *cond)
    assert "art_modes" not in one and one["art"].shape == (1, 1, 16)


def test_winner_takes_all_loss_and_the_mode_target():
    net = _net(2)
    B, N = 1, 2
    modes = torch.zeros(B, N, 2, 16)
    modes[..., 1, :] = 1.0                        # mode 1 sits on the target
    out = {"end": torch.zeros(B, N), "art": modes[..., 0, :], "art_modes": modes,
           "art_logits": torch.tensor([[[2.0, 0.0], [2.0, 0.0]]]),
           "jt": torch.zeros(B, N, 5), "cs": torch.zeros(B, N, 64),
           "geo": torch.zeros(B, N, net.cfg.num_codebooks, net.cfg.codebook_size)}
    t = Targets(has_child=torch.tensor([[1.0, 0.0]]), child_tokens=torch.ones(B, N, 16),
                child_jtypes=torch.zeros(B, N, dtype=torch.long), child_cs=torch.zeros(B, N, 64),
                child_P=torch.full((B, N, net.cfg.num_codebooks, net.cfg.codebook_size),
                                   1.0 / net.cfg.codebook_size))
    L = net.losses(out, torch.ones(B, N, dtype=torch.bool), t, {})
    # best mode error 0, the other 1: only MODE_EPS of the mean error is left
    assert float(L["art"]) == pytest.approx(MODE_EPS * 0.5)
    # the mode logits are pushed towards mode 1, the one that fits
    assert float(L["mode"]) == pytest.approx(float(torch.log1p(torch.exp(torch.tensor(2.0)))))


def test_decoding_draws_one_mode_greedy_or_by_its_probability():
    net = _net(2)
    last = [m for m in net.head_art.modules() if isinstance(m, nn.Linear)][-1]
    with torch.no_grad():                         # two fixed candidates of equal probability
        last.weight.zero_()
        last.bias.zero_()
        last.bias[3:6] = -0.2                     # mode 0: centre -0.2
        last.bias[16 + 3:16 + 6] = 0.2            # mode 1: centre +0.2
        last.bias[32] = 0.01                      # mode 0 slightly more probable
    am = _model(net)
    tok, mask = torch.randn(1, 4, 384), torch.ones(1, 4, dtype=torch.bool)
    def centre(seed, temperature):
        tree = am.decode(tok, mask, seed=seed, temperature=temperature, max_nodes=1)[0]
        return round(float(tree.tokens[0, 3]), 3)
    assert {centre(s, 0.0) for s in range(4)} == {-0.2}
    drawn = {centre(s, 1.0) for s in range(12)}
    assert drawn == {-0.2, 0.2}


def test_the_training_flags_reach_the_configs():
    from model.articulation.commands import parser, training_overrides
    args = parser().parse_args(["--data", "d", "--out", "o", "--art-modes", "4",
                                "--mode-weight", "0.1", "--token-frame", "parent"])
    net, train = preset("tiny", **training_overrides(args))
    assert (net.art_modes, train.w_mode, train.token_frame) == (4, 0.1, "parent")
    net, train = preset("tiny", **training_overrides(parser().parse_args(["--data", "d",
                                                                           "--out", "o"])))
    assert (net.art_modes, train.w_mode, train.token_frame) == (1, 1.0, "absolute")


# -- sibling_room: a candidate box over an earlier sibling is drawn again -----------------------
def _room(temperature: float = 0.0, free=(False, False, True)):
    """``_make_room`` on one row: the body (token 1) already has a drawer; the three candidate
    tokens for its next child have logits 3 > 2 > 1 and collide with the drawer where
    ``free`` is False. -> (token chosen, candidates)."""
    from model.articulation.decode import _make_room
    am = _model(_net(3))

    def tok(size, centre):
        raw = np.zeros(16, np.float32)
        raw[0:3], raw[3:6] = size, centre
        return (torch.as_tensor(raw) - am.tok_mean) / am.tok_std

    body, drawer = tok([1, 1, 1], [0, 0, 0.5]), tok([0.4, 0.8, 0.2], [0.3, 0, 0.2])
    modes = torch.stack([tok([0.4, 0.8, 0.2], [0.3, 0, 0.2 + (0.0 if f is False else 0.21)
                                                           + 0.05 * k])
                         for k, f in enumerate(free)])
    row = {"tok": [body, drawer], "par": [-1, 0], "done": [True, False, False]}
    out = {"art_modes": torch.stack([modes] * 3)[None], "art_logits": torch.tensor(
        [[[3.0, 2.0, 1.0]] * 3]), "art": torch.stack([modes[0]] * 3)[None].clone()}
    _make_room(am, [row], [torch.Generator().manual_seed(0)], out, None, temperature)
    return out["art"][0, 1], modes, out["art"][0, 2]


def test_a_candidate_over_a_sibling_is_drawn_again_among_the_free_ones():
    got, modes, other = _room()
    assert torch.equal(got, modes[2])            # the only candidate clear of the drawer
    assert torch.equal(other, modes[0])          # the drawer itself has no children yet
    got, modes, _ = _room(temperature=1.0, free=(False, True, True))   # drawn among 1 and 2
    assert torch.equal(got, modes[1]) or torch.equal(got, modes[2])


def test_with_no_free_candidate_the_least_colliding_one_is_kept():
    got, modes, _ = _room(free=(False, False, False))
    # all three overlap the drawer; the one shifted furthest (0.1 of its 0.2 height) least
    assert torch.equal(got, modes[2])


def test_box_overlap_is_the_share_of_the_smaller_box():
    from model.articulation.decode import box_overlap
    a = torch.tensor([1.0, 1, 1, 0, 0, 0])
    assert float(box_overlap(a, torch.tensor([0.5, 0.5, 0.5, 0, 0, 0]))) == pytest.approx(1.0)
    assert float(box_overlap(a, torch.tensor([1.0, 1, 1, 0.5, 0, 0]))) == pytest.approx(0.5)
    assert float(box_overlap(a, torch.tensor([1.0, 1, 1, 1.0, 0, 0]))) == 0.0   # touching
