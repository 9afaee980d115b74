"""Layout precision against the truth (model.metrics.layout_precision) on known cases."""
import numpy as np
import pytest

from model.core import ArticulatedObject, Joint, JointType, Part
from model.metrics.layout_precision import (axis_line_distance, box_iou, compare_layouts,
                                            match_parts, sibling_collapse, teacher_forced)


def _part(name, label, parent, size, centre, joint=None):
    return Part(name=name, label=label, parent=parent, bbox_center=np.asarray(centre, float),
                bbox_size=np.asarray(size, float), joint=joint or Joint())


def _cabinet(dx=0.0, door_axis=(0, 0, 1)):
    return ArticulatedObject(category="StorageFurniture", name="c", parts=[
        _part("body_0", "body", -1, (0.5, 1.0, 1.0), (0, 0, 0.5)),
        _part("door_0", "door", 0, (0.02, 0.5, 0.9), (0.26 + dx, 0.25, 0.5),
              Joint(JointType.REVOLUTE, (0.27 + dx, 0.5, 0.5), door_axis, r_range=(0, 1.5))),
        _part("drawer_0", "drawer", 0, (0.4, 0.45, 0.3), (0.05 + dx, -0.25, 0.8),
              Joint(JointType.PRISMATIC, (0.05 + dx, -0.25, 0.8), (1, 0, 0), t_range=(0, 0.3))),
        _part("drawer_1", "drawer", 0, (0.4, 0.45, 0.3), (0.05 + dx, -0.25, 0.4),
              Joint(JointType.PRISMATIC, (0.05 + dx, -0.25, 0.4), (1, 0, 0), t_range=(0, 0.3))),
    ])


def test_box_iou_and_axis_line_distance_of_known_cases():
    a = _part("a", "x", -1, (1, 1, 1), (0, 0, 0))
    b = _part("b", "x", -1, (1, 1, 1), (0.5, 0, 0))
    assert box_iou(a, a) == pytest.approx(1.0)
    assert box_iou(a, b) == pytest.approx(0.5 / 1.5)
    assert box_iou(a, _part("c", "x", -1, (1, 1, 1), (2, 0, 0))) == 0.0
    assert axis_line_distance((0, 0, 0), (0, 0, 1), (0.3, 0.4, 5), (0, 0, -1)) == pytest.approx(0.5)
    assert axis_line_distance((0, 0, 0), (1, 0, 0), (0, 0, 0.2), (0, 1, 0)) == pytest.approx(0.2)


def test_identical_layouts_score_perfectly_and_a_shift_shows_as_its_size():
    got = compare_layouts(_cabinet(), _cabinet())
    assert got["pairs"] == 4 and got["extra"] == got["missed"] == 0
    assert min(got["iou"]) == pytest.approx(1.0) and max(got["centre_m"]) == pytest.approx(0.0)
    assert max(got["axis_deg"]) == pytest.approx(0.0, abs=1e-6)
    moved = compare_layouts(_cabinet(dx=0.1, door_axis=(0, 1, 1)), _cabinet())
    assert sorted(moved["centre_m"])[1:] == pytest.approx([0.1, 0.1, 0.1])   # the body stays
    assert max(moved["axis_deg"]) == pytest.approx(45.0)


def test_parts_are_matched_within_their_label_and_the_rest_counted():
    pred = _cabinet()
    pred.parts = pred.parts[:3]                                # one drawer short
    pairs, extra, missed = match_parts(pred, _cabinet())
    assert (extra, missed) == (0, 1)
    assert all(pred.parts[i].label == _cabinet().parts[j].label for i, j in pairs)
    # the drawer left is matched to the true drawer nearest it, the top one
    assert (2, 2) in pairs


def test_sibling_collapse_counts_moving_siblings_on_top_of_each_other():
    assert sibling_collapse(_cabinet()) == (0, 3)
    heap = _cabinet()
    heap.parts[3].bbox_center = heap.parts[2].bbox_center + np.array([0, 0, 0.05])
    assert sibling_collapse(heap) == (1, 3)


def test_teacher_forcing_reads_each_part_in_its_true_parents_frame(monkeypatch):
    """A network whose articulation head always answers one part's true parent-frame token
    places that part exactly (and only that part): predictions are matched to their own part
    and read in the true parent's frame."""
    import torch
    from torch import nn

    from model.articulation.config import preset
    from model.articulation.data import canonical_order
    from model.articulation.decode import ArticulationModel
    from model.articulation.frames import to_frame
    from model.articulation.network import ArticulationTransformer
    from model.data import format as fmt

    true = _cabinet()
    toks, jts, parents, labels = true.tokens()
    rec = fmt.ObjectRecord(id="c", category="StorageFurniture", split="test", labels=labels,
                           parents=[int(p) for p in parents], joint_types=[int(j) for j in jts],
                           tokens=toks.tolist(), descriptions={})
    order, _, _ = canonical_order(labels, parents, toks)
    rel = to_frame(toks, parents, "parent")
    target = int(order[-1])                                     # the lower drawer
    torch.manual_seed(0)
    cfg, _ = preset("tiny")
    net = ArticulationTransformer(cfg)
    last = [m for m in net.head_art.modules() if isinstance(m, nn.Linear)][-1]
    with torch.no_grad():
        last.weight.zero_()
        last.bias.zero_()
    table = ["body", "drawer", "door"]
    am = ArticulationModel(net, {
        "stats": {"tok_mean": rel[target].astype(np.float32), "tok_std": np.ones(16, np.float32),
                  "cs_mean": np.zeros(64, np.float32), "cs_std": np.ones(64, np.float32),
                  "frame": "parent"},
        "label_table": {"categories": ["StorageFurniture"] * 3, "labels": table,
                        "cs": np.eye(3, 64, dtype=np.float32)},
        "text_encoder": "all-minilm-l6-v2", "train_config": {}})
    monkeypatch.setattr(am, "encode_text", lambda texts: (torch.randn(1, 4, 384),
                                                          torch.ones(1, 4, dtype=torch.bool)))
    got = teacher_forced(am, rec, "a cabinet")
    assert got["pairs"] == 4
    assert sorted(got["iou"])[-1] == pytest.approx(1.0) and sorted(got["iou"])[-2] < 0.9
    assert min(got["centre_m"]) == pytest.approx(0.0, abs=1e-6)
