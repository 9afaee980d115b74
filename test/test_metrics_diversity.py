"""`artformer eval diversity` (model.metrics.diversity) and the seed-driven layout sampling of
the decoding (decode(dropout_sampling=True), GenerationConfig.layout_sampling)."""
from collections import Counter
from types import SimpleNamespace

import numpy as np
import pytest

from model.metrics.diversity import (box_distance, layout_key, main, mean_pairwise,
                                     score_prompt, structure_key, summarise)


def _tok(size, centre):
    t = np.zeros(16)
    t[0:3], t[3:6] = size, centre
    return t


def _tree(cat, labels, parents, boxes, jts=None):
    toks = np.stack([_tok(s, c) for s, c in boxes])
    return SimpleNamespace(category=cat, labels=list(labels), parents=np.asarray(parents),
                           joint_types=np.asarray(jts or [0] + [2] * (len(labels) - 1)),
                           tokens=toks)


BODY = ((0.5, 0.8, 0.9), (0, 0, 0.45))
D1, D2 = ((0.4, 0.7, 0.3), (0.05, 0, 0.2)), ((0.4, 0.7, 0.3), (0.05, 0, 0.6))


def test_layout_key_is_canonical_and_rounds_to_the_centimetre():
    a = _tree("S", ["body", "drawer", "drawer"], [-1, 0, 0], [BODY, D1, D2])
    b = _tree("S", ["body", "drawer", "drawer"], [-1, 0, 0], [BODY, D2, D1])   # other order
    key = layout_key(a.labels, a.parents, a.joint_types, a.tokens)
    assert key == layout_key(b.labels, b.parents, b.joint_types, b.tokens)
    moved = a.tokens.copy()
    moved[1, 5] += 0.003                       # 3 mm: the same layout at 1 cm
    assert layout_key(a.labels, a.parents, a.joint_types, moved) == key
    moved[1, 5] += 0.02                        # 2.3 cm: another layout
    assert layout_key(a.labels, a.parents, a.joint_types, moved) != key
    assert layout_key(a.labels, a.parents, a.joint_types, moved, cm=0.1) == \
        layout_key(a.labels, a.parents, a.joint_types, a.tokens, cm=0.1)
    # a joint type or a parent changes the layout
    assert layout_key(a.labels, a.parents, [0, 2, 1], a.tokens) != key
    assert layout_key(a.labels, [-1, 0, 1], a.joint_types, a.tokens) != key


def test_box_distance_matches_parts_of_each_label_and_ignores_handles():
    a = (["body", "drawer", "drawer"], np.stack([_tok(*BODY), _tok(*D1), _tok(*D2)]))
    b = (["body", "drawer", "drawer", "handle"],
         np.stack([_tok(*BODY), _tok(*D2), _tok(*D1), _tok((0.01, 0.1, 0.02), (0.3, 0, 0.2))]))
    assert box_distance(a, b) == pytest.approx(0.0)           # matched across the order
    c = (a[0], a[1].copy())
    c[1][0, 3] += 0.3                                         # the body moves 30 cm
    assert box_distance(a, c) == pytest.approx(0.3 / 3)       # averaged over the 3 parts
    assert box_distance(a, (["body", "drawer"], a[1][:2])) is None
    assert mean_pairwise([a, b, c]) == pytest.approx((0 + 0.1 + 0.1) / 3)
    assert mean_pairwise([a]) is None
    assert structure_key("S", b[0]) == ("S", (("body", 1), ("drawer", 2)))


def test_score_prompt_counts_layouts_structures_and_the_data_spread():
    same = [_tree("S", ["body", "drawer", "drawer"], [-1, 0, 0], [BODY, D1, D2])] * 6
    moved = _tree("S", ["body", "drawer", "drawer"], [-1, 0, 0],
                  [((0.5, 0.8, 0.9), (0, 0, 0.55)), D1, D2])
    other = _tree("S", ["body", "drawer"], [-1, 0], [BODY, D1])
    trees = same + [moved, other]
    data = [{"labels": t.labels, "parents": t.parents, "joint_types": t.joint_types,
             "tokens": t.tokens} for t in (same[0], moved)]
    pool = {structure_key("S", same[0].labels): data}
    row = score_prompt(trees, pool)
    assert row["distinct"] == 3 and row["structures"] == 2 and row["main_share"] == 7 / 8
    assert row["main_structure"] == {"category": "S", "counts": {"body": 1, "drawer": 2}}
    assert row["data_objects"] == 2 and row["data_distinct"] == 2 and row["room"] is True
    # 7 seeds with the main structure: 6 identical + 1 whose body moved 10 cm
    assert row["spread_m"] == pytest.approx((6 * 0.1 / 3) / 21)
    assert row["data_spread_m"] == pytest.approx(0.1 / 3)
    assert row["ratio"] == pytest.approx(row["spread_m"] / row["data_spread_m"])
    assert score_prompt(trees, {})["room"] is None
    s = summarise([row, {**row, "distinct": 8}, {**row, "room": None, "ratio": None}])
    assert s["room_prompts"] == 2 and s["share_room_with_6_distinct"] == 0.5
    assert s["mean_ratio"] == pytest.approx(row["ratio"])


def test_cli_refuses_bad_arguments_before_loading_the_model(capsys):
    assert main(["--structure", '{"drawer": 2']) == 1
    assert "not valid JSON" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--seeds", "1"])


# -- the shipped model -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def am():
    from model.articulation import ArticulationModel
    from model.pipeline.generator import find_checkpoints
    return ArticulationModel.load(find_checkpoints(None)["transformer"])


def test_dropout_sampling_varies_the_layout_per_seed_reproducibly(am):
    cond, mask = am.encode_text(["a cabinet with two drawers"] * 4)
    keys = lambda trees: [layout_key(t.labels, t.parents, t.joint_types, t.tokens) for t in trees]
    # greedy: every choice, a multi-mode head's token among them, is the likeliest one, so
    # every seed gets the same layout
    plain = am.decode(cond, mask, seed=0, temperature=0.0, follow_plan=True)
    assert len(set(keys(plain))) == 1
    sampled = am.decode(cond, mask, seed=0, temperature=0.3, follow_plan=True,
                        dropout_sampling=True)
    assert len(set(keys(sampled))) == 4
    # every decision comes from the deterministic pass: same structure as without sampling
    assert {tuple(t.labels) for t in sampled} == {tuple(plain[0].labels)}
    # a row depends on its seed only (not on its batch), and repeats
    again = am.decode(cond[:1], mask[:1], seed=2, temperature=0.3, follow_plan=True,
                      dropout_sampling=True)
    assert keys(again) == keys(sampled)[2:3]
    np.testing.assert_array_equal(again[0].tokens, sampled[2].tokens)
    assert not am.net.training                 # the network is back in eval mode


def test_dropout_sampling_keeps_an_asked_structure(am):
    cond, mask = am.encode_text(["a storage cabinet"] * 6)
    structure = {"drawer": 3, "door": {"count": 1, "hinge": "left"}}
    trees = am.decode(cond, mask, seed=5, temperature=0.3, structure=structure,
                      dropout_sampling=True)
    from model.pipeline.api import hinge_side
    for t in trees:
        c = Counter(t.labels)
        assert c["drawer"] == 3 and c["door"] == 1 and set(c) <= {"body", "drawer", "door", "handle"}
        assert [hinge_side(tok) for tok, lab in zip(t.tokens, t.labels) if lab == "door"] == ["left"]
    assert len({layout_key(t.labels, t.parents, t.joint_types, t.tokens) for t in trees}) == 6


def test_generator_samples_layouts_when_a_structure_is_forced_only():
    """layout_sampling 'structure' (default): seeds vary the layout of a forced structure,
    asked for or stated by the prompt; free text decodes as before (its alignment is what
    the plain decoding measures)."""
    from model.pipeline.api import GenerationConfig, GenerationError
    from model.pipeline.generator import Generator, validate_config
    with pytest.raises(GenerationError, match="layout_sampling"):
        validate_config(GenerationConfig(layout_sampling="sometimes"))
    # greedy tree decoding: without dropout masks every seed gets one layout
    gen = Generator.load(GenerationConfig(prompt_structure=False, structure_temperature=0.0))
    keys = lambda trees: {layout_key(t.labels, t.parents, t.joint_types, t.tokens) for t in trees}
    free, *_ = gen.decode_trees("a wardrobe with two doors", seed=0, samples=3)
    forced, *_ = gen.decode_trees("a wardrobe with two doors", seed=0, samples=3,
                                  structure={"door": 2})
    assert len(keys(free)) == 1 and len(keys(forced)) == 3
    gen.config.prompt_structure = True      # the prompt's "two doors" is held: sampled too
    assert len(keys(gen.decode_trees("a wardrobe with two doors", seed=0, samples=3)[0])) == 3
    gen.config.prompt_structure = False
    gen.config.layout_sampling = "always"
    assert len(keys(gen.decode_trees("a wardrobe with two doors", seed=0, samples=3)[0])) == 3
    gen.config.layout_sampling = "never"
    assert len(keys(gen.decode_trees("a wardrobe", seed=0, samples=3,
                                     structure={"door": 2})[0])) == 1


def test_sample_choices_draws_labels_and_plan_counts_from_the_seed(am):
    """sample_choices: off (default) is the plain decoding; at temperature 0 it draws nothing;
    on, the plan counts are draws from the plan head (a vague prompt gets several counts)."""
    cond, mask = am.encode_text(["a cabinet with drawers"] * 8)   # the count left open
    kw = dict(seed=0, follow_plan=True)
    plain = am.decode(cond, mask, temperature=0.3, **kw)
    default = am.decode(cond, mask, temperature=0.3, sample_choices=False, **kw)
    assert [t.labels for t in plain] == [t.labels for t in default]
    greedy = am.decode(cond, mask, temperature=0.0, **kw)
    assert [t.labels for t in am.decode(cond, mask, temperature=0.0, sample_choices=True, **kw)] \
        == [t.labels for t in greedy]
    drawn = am.decode(cond, mask, temperature=1.0, sample_choices=True, **kw)
    assert all(lab in am.table_labels for t in drawn for lab in t.labels)
    assert len({tuple(sorted(Counter(t.labels).items())) for t in drawn}) >= 2
