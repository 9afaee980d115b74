"""Token frames (model.articulation.frames): the parent frame turns back into the same
absolute tokens, describes a part by its place in its parent's box, and a network trained in
it decodes absolute trees."""
import numpy as np
import pytest

from model.articulation.frames import from_frame, to_frame, token_to_frame


def _cabinet(width: float) -> tuple[np.ndarray, list[int]]:
    """A body of ``width`` with a door hinged on its left edge and a handle on the door."""
    body = np.r_[[0.5, width, 0.8], [0, 0, 0.4], [0, 0, 0], [0, 0, 1], [0, 0, 0, 0]]
    door = np.r_[[0.02, width, 0.8], [0.26, 0, 0.4], [0.26, -width / 2, 0.4], [0, 0, 1],
                 [0, 0, 0, 1.57]]
    handle = np.r_[[0.03, 0.02, 0.15], [0.285, width / 2 - 0.05, 0.4], [0.285, 0, 0.4],
                   [0, 0, 1], [0, 0, 0, 0]]
    return np.stack([body, door, handle]), [-1, 0, 1]


def test_parent_frame_turns_back_into_the_same_tokens():
    toks, parents = _cabinet(0.6)
    rel = to_frame(toks, parents, "parent")
    assert np.allclose(from_frame(rel, parents, "parent"), toks, atol=1e-9)
    assert np.array_equal(to_frame(toks, parents, "absolute"), toks)


def test_parent_frame_reads_a_part_by_its_place_in_the_parent():
    small, parents = _cabinet(0.4)
    wide, _ = _cabinet(1.2)
    rs, rw = to_frame(small, parents, "parent"), to_frame(wide, parents, "parent")
    # the door fills its body's front whatever the width: same size ratio, centre, hinge
    assert np.allclose(rs[1, :9], rw[1, :9])
    assert rs[1, 7] == pytest.approx(-0.5)          # hinge on the door's left edge
    assert rs[1, 1] == pytest.approx(0.0)           # as wide as the body: log ratio 0
    assert not np.allclose(small[1, :9], wide[1, :9])


def test_tiny_parts_and_a_parent_after_its_child_are_handled():
    toks, parents = _cabinet(0.6)
    toks[2, 0] = 0.0                                # a flat part: read as MIN_SIZE
    back = from_frame(to_frame(toks, parents, "parent"), parents, "parent")
    assert back[2, 0] == pytest.approx(1e-4)
    with pytest.raises(ValueError, match="does not come before"):
        from_frame(toks, [1, -1, 1], "parent")
    with pytest.raises(ValueError, match="unknown token frame"):
        token_to_frame(toks[0], None, "world")


def test_a_network_trained_in_the_parent_frame_decodes_absolute_trees(tmp_path):
    """The training command with --token-frame parent: the frame is stored with the stats,
    training items carry parent-frame tokens, decoding and editing give absolute trees."""
    import torch

    from model.articulation.commands import main
    from model.articulation.decode import ArticulationModel
    from model.articulation.checkpoint import read_checkpoint
    from model.core.objects import ArticulatedObject
    from helpers import write_toy_dataset

    torch.set_num_threads(1)
    write_toy_dataset(tmp_path / "data", n=12)
    assert main(["train", "transformer", "--data", str(tmp_path / "data"), "--prior", "none",
                 "--preset", "tiny", "--out", str(tmp_path / "run"), "--steps", "40",
                 "--no-progress", "--token-frame", "parent"]) == 0
    ck = read_checkpoint(tmp_path / "run" / "transformer.pt")
    assert ck["stats"]["frame"] == "parent" and ck["train_config"]["token_frame"] == "parent"
    am = ArticulationModel.load(tmp_path / "run" / "transformer.pt")
    assert am.frame == "parent"
    tok, mask = am.encode_text(["A cabinet with two drawers."])
    tree = am.decode(tok, mask, seed=0, temperature=0.0, max_nodes=8)[0]
    body = tree.tokens[0]
    for i, p in enumerate(tree.parents):             # children decoded near their parent
        if p >= 0:
            gap = np.abs(tree.tokens[i, 3:6] - tree.tokens[p, 3:6]) / body[0:3]
            assert (gap < 3).all() and (tree.tokens[i, 0:3] > 0).all()
    # editing: kept absolute parts go in through the frame and come back unchanged
    obj = ArticulatedObject.from_tokens(
        np.stack([np.r_[0.5, 0.6, 0.8, 0, 0, 0.4, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0],
                  np.r_[0.4, 0.5, 0.2, 0.05, 0, 0.6, 0.05, 0, 0.6, 1, 0, 0, 0, 0.3, 0, 0]]),
        [0, 2], [-1, 0], ["body", "drawer"], category="StorageFurniture")
    res = am.decode(tok, mask, seed=1, keep=obj, max_nodes=6)[0]
    assert np.allclose(res.tokens[:2], np.stack([p.token() for p in obj.parts]), atol=1e-5)
