"""Place classes (ArticulationConfig.place_bins): each coordinate of a child's joint origin
(relative to its own box) and of its box centre (relative to its parent's box) is classified
as on a face, flush, centred or elsewhere; decoding puts a classified coordinate exactly
there instead of regressing it."""
from dataclasses import asdict

import numpy as np
import pytest
import torch

from model.articulation.checkpoint import build_network
from model.articulation.config import preset
from model.articulation.data import collate, make_item, round_sample
from model.articulation.decode import ArticulationModel
from model.articulation.frames import ORIGIN_GRID, PLACE_CLASSES, place_classes, to_frame
from model.articulation.network import ArticulationTransformer
from model.data.format import ObjectRecord

torch.set_num_threads(1)
O, C = PLACE_CLASSES[0] - 1, PLACE_CLASSES[1] - 1     # "elsewhere" of origin / centre


def _net(**kw) -> ArticulationTransformer:
    torch.manual_seed(0)
    cfg, _ = preset("tiny", place_bins=True, token_frame="parent", **kw)
    net = ArticulationTransformer(cfg).eval()
    net.set_token_norm(np.zeros(16, np.float32), np.ones(16, np.float32))
    return net


def _model(net) -> ArticulationModel:
    return ArticulationModel(net, {
        "stats": {"tok_mean": np.zeros(16, np.float32), "tok_std": np.ones(16, np.float32),
                  "cs_mean": np.zeros(64, np.float32), "cs_std": np.ones(64, np.float32),
                  "frame": "parent"},
        "label_table": {"categories": ["StorageFurniture"] * 2, "labels": ["body", "door"],
                        "cs": np.eye(2, 64, dtype=np.float32)},
        "text_encoder": "all-minilm-l6-v2", "train_config": {}})


def _cabinet() -> ObjectRecord:
    """A body and a door flush with its front (-y) face, hinged on the door's left edge."""
    body = [0.6, 0.4, 0.8, 0, 0, 0.4, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0]
    door = [0.5, 0.02, 0.7, 0, -0.19, 0.43, -0.25, -0.19, 0.43, 0, 0, 1, 0, 0, 0, 1.6]
    return ObjectRecord(id="c", category="StorageFurniture", split="train",
                        joint_types=[0, 1], labels=["body", "door"], parents=[-1, 0],
                        tokens=[body, door])


def _rel(size, centre, origin):
    t = np.zeros(16)
    t[0:3], t[3:6], t[6:9] = np.log(size), centre, origin
    return t


def test_place_classes_read_faces_flush_touching_centred_and_elsewhere():
    # part of half the parent's size: outside -x touching, flush inside +y, centred in z
    t = _rel([0.5, 0.5, 0.5], [-0.75, 0.25, 0.0], [-0.5, 0.0, 0.5])
    assert place_classes(t).tolist() == [0, 1, 2, 0, 3, 2]
    t = _rel([0.5, 0.5, 0.5], [0.75, 0.1, 0.004], [-0.49, 0.011, 0.3])
    assert place_classes(t).tolist() == [0, 1, O, 4, C, 2]


def test_targets_carry_the_door_classes_and_train_a_loss():
    rec = _cabinet()
    rel = to_frame(np.array(rec.tokens), rec.parents, "parent")
    assert rel[1, 6:9].tolist() == pytest.approx([-0.5, 0.0, 0.0])
    item = make_item(rec, np.zeros(16), np.ones(16), np.zeros((2, 64)),
                     np.zeros((2, 2, 16), np.float32), np.array([0, 1]), "parent")
    # hinge: left face, centre, centre; box: centred in x, flush with the -y face, other z
    assert item.place[1].tolist() == [0, 1, 1, 2, 1, C]
    batch, targets = collate([round_sample(item, k) for k in range(2)], (2, 16))
    assert targets.child_place[1, 1].tolist() == [0, 1, 1, 2, 1, C]   # the body's child
    assert targets.child_place[0, 1].tolist() == [O] * 3 + [C] * 3    # padding: unused
    net = _net(num_codebooks=2)
    _, losses = net(batch, torch.randn(2, 3, 384), torch.ones(2, 3, dtype=torch.bool),
                    targets=targets)
    assert "place" in losses and float(losses["place"].detach()) > 0
    absolute = make_item(rec, np.zeros(16), np.ones(16), np.zeros((2, 64)),
                         np.zeros((2, 2, 16), np.float32), np.array([0, 1]), "absolute")
    assert absolute.place is None
    _, t = collate([round_sample(absolute, 0)], (2, 16))
    assert t.child_place is None


def test_snap_puts_classified_coordinates_in_place_in_normalised_space():
    net = _net()
    mean, std = np.full(16, 0.1, np.float32), np.full(16, 2.0, np.float32)
    net.set_token_norm(mean, std)
    raw = _rel([0.5, 0.2, 1.0], [0.3, 0.3, 0.3], [0.3, 0.3, 0.3])
    art = torch.tensor((raw - mean) / std, dtype=torch.float32)[None]
    out = net.snap(art, torch.tensor([[0, 2, O, 4, 1, C]]))[0].numpy() * std + mean
    assert out[6:9].tolist() == pytest.approx([-0.5, 0.5, 0.3], abs=1e-6)
    assert out[3:6].tolist() == pytest.approx([0.5 + 0.25, -0.5 + 0.1, 0.3], abs=1e-6)
    assert out[0:3].tolist() == pytest.approx(raw[0:3].tolist(), abs=1e-6)


def _root(net, seed: int, temperature: float) -> np.ndarray:
    """The decoded root's origin (in its box sizes from its centre), centre and size (metres;
    the root's parent is a 1 m box at the origin)."""
    am = _model(net)
    tok, mask = torch.randn(1, 4, 384), torch.ones(1, 4, dtype=torch.bool)
    t = am.decode(tok, mask, seed=seed, temperature=temperature, max_nodes=1)[0].tokens[0]
    return np.round(np.r_[(t[6:9] - t[3:6]) / t[0:3], t[3:6], t[0:3]], 4)


def test_decoding_puts_the_parts_in_the_drawn_places():
    net = _net()
    with torch.no_grad():                 # origin x: both faces equally likely; y, z: centre;
        net.head_place.weight.zero_()     # centre: x flush inside -x, y and z elsewhere
        bias = [5.0, -9, 5.0, -9] + [-9, 5.0, -9, -9] * 2 + [-9, 5, -9, -9, -9, -9]
        net.head_place.bias.copy_(torch.tensor(bias + [-9, -9, -9, -9, -9, 5.0] * 2))
        net.head_place.bias[0] += 0.01    # the -x face slightly more probable
    first = _root(net, 0, 0.0)
    assert first[0:3].tolist() == [-0.5, 0.0, 0.0]
    assert first[3] == pytest.approx(-0.5 + first[6] / 2, abs=1e-3)
    assert {_root(net, s, 0.0)[0] for s in range(3)} == {-0.5}
    assert {_root(net, s, 1.0)[0] for s in range(12)} == {-0.5, 0.5}
    with torch.no_grad():                 # origin x "elsewhere": the regressed value stands
        net.head_place.bias[:4] = torch.tensor([-9.0, -9, -9, 5.0])
    assert _root(net, 0, 0.0)[0] not in (-0.5, 0.0, 0.5)


def test_the_statistics_travel_with_the_checkpoint_and_need_the_parent_frame():
    net = _net()
    net.set_token_norm(np.full(16, 0.2, np.float32), np.ones(16, np.float32))
    back = build_network({"config": asdict(net.cfg), "state_dict": net.state_dict()})
    assert torch.equal(back.tok_norm, net.tok_norm)
    with pytest.raises(ValueError, match="token_frame 'parent'"):
        preset("tiny", place_bins=True)
    from model.articulation.commands import parser, training_overrides
    args = parser().parse_args(["--data", "d", "--out", "o", "--place-bins",
                                "--token-frame", "parent"])
    assert preset("tiny", **training_overrides(args))[0].place_bins
    assert not preset("tiny", **training_overrides(parser().parse_args(
        ["--data", "d", "--out", "o"])))[0].place_bins


def test_the_training_command_learns_the_places_of_the_toy_parts(tmp_path):
    """Not a quality bar: 150 tiny steps bring the place loss down, the checkpoint stores the
    token statistics and decoding puts every classified coordinate exactly in place."""
    import json

    from model.articulation.commands import main
    from helpers import write_toy_dataset
    write_toy_dataset(tmp_path / "data", n=20)
    assert main(["train", "transformer", "--data", str(tmp_path / "data"), "--prior", "none",
                 "--preset", "tiny", "--out", str(tmp_path / "run"), "--steps", "150",
                 "--token-frame", "parent", "--place-bins", "--no-progress"]) == 0
    hist = json.loads((tmp_path / "run" / "history.json").read_text())
    assert hist[-1]["val"]["place"] < 0.5 * hist[0]["val"]["place"]
    am = ArticulationModel.load(tmp_path / "run" / "transformer.pt")
    assert am.net.tok_norm[1].tolist() == pytest.approx(am.tok_std.tolist())
    from model.data.format import load_record, split_ids
    texts = [load_record(tmp_path / "data", i).descriptions["sentence"][0]
             for i in split_ids(tmp_path / "data", "train")[:8]]
    tok, mask = am.encode_text(texts)
    kids = np.concatenate([to_frame(t.tokens, t.parents, "parent")[1:]
                           for t in am.decode(tok, mask, seed=0, temperature=0.0)])
    # a regressed origin is never exactly on a face or centre line; a placed one is
    off_grid = np.abs(kids[:, 6:9, None] - np.array(ORIGIN_GRID)).min(-1)
    assert len(kids) >= 4 and (off_grid < 1e-4).mean() >= 0.3
