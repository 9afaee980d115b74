"""Counts a prompt states are held during decoding (model.pipeline.prompt_structure): the
structure built from a parsed prompt, and the shipped model decoding under it."""
from collections import Counter
import dataclasses

import numpy as np

import pytest

from model.articulation.structure_control import STRUCTURE_GRAMMAR
from model.data.prompt_parse import parse_prompt
from model.pipeline.prompt_structure import stated_counts, structure_for


def _all_labels(cat):
    return set(STRUCTURE_GRAMMAR[cat])


def test_readme_example_gives_exact_counts_and_leaves_the_rest_to_the_model():
    e = parse_prompt("a kitchen cabinet with three drawers and a door on the left")
    assert stated_counts(e)
    s = structure_for(e, "StorageFurniture", _all_labels("StorageFurniture"))
    assert s == {"category": "StorageFurniture", "drawer": {"count": 3}, "door": {"count": 1},
                 "handle": "auto"}
    e = parse_prompt("a dresser with four drawers that pull out, each with its own handle")
    s = structure_for(e, "StorageFurniture", _all_labels("StorageFurniture"))
    assert s["drawer"] == {"count": 4, "joint": "prismatic"} and s["handle"] == {"count": 4}


def test_joint_types_hinge_sides_and_synonyms():
    e = parse_prompt("a cabinet whose single door opens on a hinge on the right side")
    s = structure_for(e, "StorageFurniture", _all_labels("StorageFurniture"))
    assert s["door"]["count"] == 1 and s["door"]["hinge"] == ["right"]
    assert s["drawer"] == "auto"
    # a safe's "knobs" are its dials, which hang on its door: the door comes with them
    e = parse_prompt("a strongbox with a door and two turning knobs")
    s = structure_for(e, "Safe", _all_labels("Safe"))
    assert s["dial"]["count"] == 2 and s["door"] == {"count": 1}
    e = parse_prompt("a safe with a 4 x 3 keypad")
    s = structure_for(e, "Safe", _all_labels("Safe"))
    assert s["button"]["count"] == 12 and s["door"] == {"count": 1}
    # an oven's "dials" are its knobs
    e = parse_prompt("a toaster oven with a door and two dials")
    assert structure_for(e, "Oven", _all_labels("Oven"))["knob"]["count"] == 2


def test_a_joint_type_the_category_lacks_is_said_not_held(caplog):
    """"two sliding doors": the data's cabinet doors all turn on hinges; the doors are held
    to their count, and the user is told the sliding is not."""
    e = parse_prompt("a low cabinet with two sliding doors")
    with caplog.at_level("WARNING", logger="model.pipeline.prompt_structure"):
        s = structure_for(e, "StorageFurniture", _all_labels("StorageFurniture"))
    assert s["door"] == {"count": 2}
    assert "door parts move only as revolute" in caplog.text and "prismatic" in caplog.text
    caplog.clear()
    with caplog.at_level("WARNING", logger="model.pipeline.prompt_structure"):
        structure_for(parse_prompt("a cabinet with two hinged doors"), "StorageFurniture",
                      _all_labels("StorageFurniture"))
    assert caplog.text == ""


def test_a_washers_loading_side_implies_its_door_or_lid():
    e = parse_prompt("a front-loading washing machine with a dial")
    assert e.counts == {"dial": 1, "door": 1} and e.joint_types["door"] == ["revolute"]
    assert parse_prompt("a top loader with two buttons").counts == {"button": 2, "lid": 1}
    # a stated door or lid is the prompt's own reading, a stated zero included
    assert parse_prompt("a front loader whose round door is hinged on the left").counts == {"door": 1}
    assert parse_prompt("a front-loading washer with no door").counts == {"door": 0}
    assert "door" not in parse_prompt("a front-loading storage cabinet").counts


def test_a_microwave_is_an_oven_whose_door_hangs_on_its_left_side():
    e = parse_prompt("a microwave with a keypad")
    assert e.category == "Oven" and e.counts["door"] == 1
    assert e.spatial["door"] == {"hinge": ["left"], "opens": ["sideways"]}
    s = structure_for(e, "Oven", _all_labels("Oven"))
    assert s["door"]["hinge"] == ["left"]
    # "a keypad" is at least two buttons, also when the network's own reading is another
    # category (the shipped model reads this prompt as a washer) and gives no open counts
    assert s["button"] == {"count": 2} and s["knob"] == "auto"
    # what the prompt says about the door wins; a microwave-sized safe is a safe
    assert parse_prompt("a microwave with a drop-down door").spatial["door"] == {"opens": ["down"]}
    assert parse_prompt("a microwave with its door hinged on the right").spatial["door"] == \
        {"hinge": ["right"]}
    assert "door" not in parse_prompt("a microwave hinged on the right").spatial   # no left
    assert "hinge" not in parse_prompt("a microwave with two doors").spatial.get("door", {})
    assert parse_prompt("a microwave-sized safe with a door").category == "Safe"


def test_nothing_to_hold_or_a_part_the_category_lacks():
    assert not stated_counts(parse_prompt("a cabinet"))
    assert stated_counts(parse_prompt("a cabinet with doors"))           # a lower bound
    assert not stated_counts(parse_prompt("a bottle"))
    e = parse_prompt("a bottle with three drawers")
    assert structure_for(e, "Bottle", _all_labels("Bottle")) is None
    # a stated zero of a label the category lacks is no obstacle
    e = parse_prompt("a water bottle with a screw cap and no drawers")
    assert structure_for(e, "Bottle", _all_labels("Bottle"))["cap"]["count"] == 1


@pytest.fixture(scope="module")
def shipped():
    from model.pipeline.api import GenerationConfig
    from model.pipeline.generator import Generator
    return Generator.load(GenerationConfig())


def test_more_parts_than_their_hosts_hold_are_cut_to_fit(shipped):
    """"a safe with 24 buttons": held at 16 buttons (max_children) plus the network's dial on
    one door, decoding ended a button short and raised. Parts hung on other parts are cut
    until their hosts hold them, the ones the prompt does not count first."""
    e = parse_prompt("a safe with 24 buttons")
    s = structure_for(e, "Safe", _all_labels("Safe"), open_counts={"dial": 1, "door": 1},
                      clamp=16)
    assert s["button"] == {"count": 16} and s["dial"] == {"count": 0}
    s = structure_for(parse_prompt("a safe with 15 buttons and 2 dials"), "Safe",
                      _all_labels("Safe"), open_counts={"door": 1}, clamp=16)
    assert s["button"] == {"count": 14} and s["dial"] == {"count": 2}
    trees, *_ = shipped.decode_trees("a safe with 24 buttons", seed=0, samples=2)
    assert all(Counter(t.labels)["button"] == 16 for t in trees)


def test_a_named_category_is_kept_without_the_parts_it_lacks(shipped, caplog):
    """"a bottle with three drawers" / "a dresser with two drawers and a lid": the category
    has no such part, so no structure of it holds the prompt; decoding had then gone free and
    made a washer, a bottle. The named category is held without those parts, with a warning.
    (A chest with a lid and nothing on its front is made: test_refine_orient.py.)"""
    for text, category, part in (("a bottle with three drawers", "Bottle", "drawer"),
                                 ("a dresser with two drawers and a lid", "StorageFurniture",
                                  "lid")):
        caplog.clear()
        with caplog.at_level("WARNING", logger="model.pipeline.prompt_structure"):
            trees, *_ = shipped.decode_trees(text, seed=0, samples=2)
        assert all(t.category == category and part not in t.labels for t in trees), text
        assert any(f"has no {part} part" in r.getMessage() for r in caplog.records), text


def test_shipped_model_reads_the_readme_example_with_every_seed(shipped):
    trees, *_ = shipped.decode_trees("a kitchen cabinet with three drawers and a door on the left",
                                     seed=0, samples=8)
    for t in trees:
        n = Counter(t.labels)
        assert t.category == "StorageFurniture" and n["drawer"] == 3 and n["door"] == 1, n
        assert t.structure["drawer"]["count"] == 3
    # seeds vary the layout within the stated structure (dropout layout sampling)
    from model.metrics.diversity import layout_key
    keys = {layout_key(t.labels, t.parents, t.joint_types, t.tokens) for t in trees}
    assert len(keys) >= 6
    # and the door ends up on the viewer's left in the refined layout the product meshes
    from model.data.spatial import part_position
    for t in trees:
        obj = shipped.layout(t)
        doors = [i for i, p in enumerate(obj.parts) if p.label == "door"]
        assert [part_position(obj, i)[0] for i in doors] == ["left"]


def test_shipped_model_builds_the_size_the_prompt_states(shipped):
    from model.metrics.alignment import alignment_of
    for text, seed in (("a kitchen cabinet 60 cm wide with two drawers", 0), ("a microwave", 1)):
        [res] = shipped.generate(text, seed=seed)
        assert res.obj.metadata["refine"]["size"]["factors"]
        if text == "a microwave":     # its usual size and layout, not stated ones
            obj = res.obj
            np.testing.assert_allclose(obj.parts[obj.root].bbox_size, [0.38, 0.5, 0.3],
                                       rtol=0.05)
            door = next(p for p in obj.parts if p.label == "door")
            for p in obj.parts:
                if p.label in ("knob", "button", "dial"):      # the control column
                    assert p.bbox_center[1] > door.bbox_center[1] + door.bbox_size[1] / 2
        else:
            al = alignment_of(text, res.obj)
            assert al.spatial.get("size") is True, al.failures
    # a size given outright wins over the text's, for images too; a bad one is refused
    trees, *_ = shipped.decode_trees("a cabinet 60 cm wide with two drawers", seed=0,
                                     size={"width": 0.9, "depth": 0.4})
    assert trees[0].size == {"width": 0.9, "depth": 0.4}
    np.testing.assert_allclose(shipped.layout(trees[0]).parts[0].bbox_size[:2], [0.4, 0.9])
    from model.pipeline.api import GenerationError
    with pytest.raises(GenerationError, match="unknown dimension 'tall'"):
        shipped.decode_trees("a cabinet", size={"tall": 1.0})


def test_shipped_model_holds_bounds_and_usual_parts_and_decodes_freely_when_off(shipped):
    # a lower bound alone is held too: "a cabinet with doors" decoded one door, seeds 0-3
    for seed in range(4):
        trees, *_ = shipped.decode_trees("a cabinet with doors", seed=seed)
        assert trees[0].structure is not None and trees[0].labels.count("door") >= 2, seed
    # a bare name is held to its usual parts (model.data.prompt_size.with_usual_parts)
    trees, *_ = shipped.decode_trees("a bottle", seed=0)
    assert trees[0].structure["cap"] == {"count": 1} and trees[0].labels.count("cap") == 1
    # a count beyond what the model was trained on: held at its maximum, no error
    from model.articulation.structure_control import STRUCTURE_GRAMMAR
    most = min(STRUCTURE_GRAMMAR["StorageFurniture"]["drawer"][2], shipped.config.max_children)
    trees, *_ = shipped.decode_trees("a cabinet with 99 drawers", seed=0)
    assert trees[0].structure is not None and trees[0].labels.count("drawer") == most
    # ... so the rest of the prompt is still held: a washer's lid beside seven buttons
    most = STRUCTURE_GRAMMAR["WashingMachine"]["button"][2]
    trees, *_ = shipped.decode_trees("a washer with a lid and seven buttons", seed=0)
    assert trees[0].labels.count("lid") == 1 and trees[0].labels.count("button") == most
    off = dataclasses.replace(shipped.config, prompt_structure=False)
    saved, shipped.config = shipped.config, off
    try:
        trees, *_ = shipped.decode_trees("a kitchen cabinet with three drawers", seed=0)
        assert trees[0].structure is None
    finally:
        shipped.config = saved


def test_open_parts_keep_the_networks_own_counts():
    """With the network's own reading, the parts the prompt leaves open keep its counts
    (within the label's training maximum, at least a stated lower bound); handles stay
    "auto"; a stated lid rules out a washer's door."""
    e = parse_prompt("an oven with four knobs")
    s = structure_for(e, "Oven", _all_labels("Oven"),
                      open_counts={"door": 1, "knob": 2, "drawer": 3, "handle": 1})
    assert s["knob"] == {"count": 4} and s["door"] == {"count": 1}
    assert s["drawer"] == {"count": 1} and s["tray"] == {"count": 0}     # an oven has <= 1
    assert s["handle"] == "auto"
    e = parse_prompt("a cabinet with drawers and a door")
    s = structure_for(e, "StorageFurniture", _all_labels("StorageFurniture"),
                      open_counts={"drawer": 1, "door": 2})
    assert s["drawer"] == {"count": 2} and s["door"] == {"count": 1}
    e = parse_prompt("a washing machine with a lid")
    s = structure_for(e, "WashingMachine", _all_labels("WashingMachine"),
                      open_counts={"door": 1, "dial": 1})
    assert s["lid"] == {"count": 1} and s["door"] == {"count": 0} and s["dial"] == {"count": 1}


def test_a_dishwasher_is_an_oven_that_keeps_its_door():
    """"a dishwasher with two racks": read as an oven (drop-down door, racks: the closest
    appliance of the data; it had been read as a washing machine with a porthole); the
    network's own reading made no door, which no oven or safe of the data lacks, so it gets
    one. A door the prompt rules out stays out."""
    e = parse_prompt("a dishwasher with two racks")
    assert e.category == "Oven" and e.counts["tray"] == 2
    assert e.spatial["door"] == {"hinge": ["bottom"], "opens": ["down"]}     # it drops down
    assert parse_prompt("a dishwasher with a side-hinged door").spatial["door"] == \
        {"hinge": ["side"]}
    e = parse_prompt("an oven with two racks")
    s = structure_for(e, "Oven", _all_labels("Oven"), open_counts={"door": 0, "tray": 2})
    assert s["door"] == {"count": 1} and s["tray"] == {"count": 2}
    s = structure_for(e, "Oven", _all_labels("Oven"))        # no own reading of an oven
    assert s["door"] == {"count": 1} and s["knob"] == "auto"
    assert structure_for(parse_prompt("a safe"), "Safe", _all_labels("Safe"))["door"] == "auto"
    s = structure_for(parse_prompt("a safe with a keypad"), "Safe", _all_labels("Safe"),
                      open_counts={"door": 0})
    assert s["door"] == {"count": 1}
    e = parse_prompt("an oven with no door and a drawer")
    s = structure_for(e, "Oven", _all_labels("Oven"), open_counts={"door": 1, "drawer": 1})
    assert s["door"] == {"count": 0}


def test_a_number_the_network_put_on_another_control_is_not_its_count():
    """"a microwave with a door and six buttons": the model makes at most three buttons, and
    its own reading put the six on knobs (3 buttons and 6 knobs came out). Held at the
    model's most, the unnamed control that took the stated number gets none; one the own
    reading counts otherwise keeps its count, and without a clamp nothing changes."""
    e = parse_prompt("a microwave with a door and six buttons")
    labels = _all_labels("Oven")
    s = structure_for(e, "Oven", labels, open_counts={"knob": 6, "door": 1}, clamp=20)
    assert s["button"] == {"count": 3} and s["knob"] == {"count": 0}
    s = structure_for(e, "Oven", labels, open_counts={"knob": 2, "door": 1}, clamp=20)
    assert s["knob"] == {"count": 2}
    s = structure_for(e, "Oven", labels, open_counts={"knob": 6, "door": 1})
    assert s["button"] == {"count": 6} and s["knob"] == {"count": 6}


def test_the_open_counts_come_from_the_reading_with_the_plan_held(shipped, monkeypatch):
    """The network's own reading that fills the counts a prompt leaves open is decoded as
    free text is: with the START plan head's counts held (``hold_plan``), else the soft plan."""
    am = shipped.articulation
    seen, decode = [], am.decode

    def spy(*a, **kw):
        seen.append(kw.get("follow_plan"))
        return decode(*a, **kw)

    monkeypatch.setattr(am, "decode", spy)
    shipped.decode_trees("a microwave with a keypad", seed=0)
    assert seen[0] == "hold"                  # the reading first, then the held structure
    saved = shipped.config
    shipped.config = dataclasses.replace(saved, hold_plan=False)
    try:
        seen.clear()
        shipped.decode_trees("a microwave with a keypad", seed=0)
        assert seen[0] is True
    finally:
        shipped.config = saved


def test_a_chest_with_a_lid_is_read_as_a_cabinet_with_a_flip_up_door():
    """Storage furniture has no lid in the data; a chest with a lid and nothing on its front
    is the cabinet with a door hinged at the top that turns into it (model.refine.orient):
    had been a bare carcass without the lid ("this model's StorageFurniture has no lid")."""
    from model.pipeline.prompt_structure import front_door_text, lids_as_front_doors
    e, turned = lids_as_front_doors(parse_prompt("a chest with a lid hinged at the back"))
    assert turned and e.counts == {"door": 1} and e.joint_types["door"] == ["revolute"]
    assert e.spatial == {"door": {"hinge": ["top"]}}
    assert front_door_text(e) == "A cabinet with a door hinged at the top that opens upward."
    two, turned = lids_as_front_doors(parse_prompt("a toy chest with two lids"))
    assert turned and two.counts == {"door": 2} and two.spatial["door"]["layout"] == "row"
    assert front_door_text(two) == "A cabinet with two doors hinged at the top that open upward."
    side, _ = lids_as_front_doors(parse_prompt("a chest with a lid hinged on the left"))
    assert side.spatial["door"]["hinge"] == ["left"]
    for text in ("a chest with a lid and two drawers", "a bottle with a lid",
                 "a top loading washer with a lid", "a cabinet with two doors"):
        e = parse_prompt(text)
        assert lids_as_front_doors(e) == (e, False), text


def test_the_network_reads_a_bare_names_usual_parts_named(shipped):
    """"a cabinet", "a storage cabinet" and "a closet" get two doors (with_usual_parts), but
    the network, reading a text that names no part, had decoded both lying on the body's
    bottom with 6 of 6 seeds. It reads the usual parts named ("a cabinet with two doors"):
    every door on the front."""
    from model.data.prompt_size import usual_parts_text, with_usual_parts
    from model.refine.layout import face_of
    said = parse_prompt("a cabinet")
    assert usual_parts_text("a cabinet", said, with_usual_parts("a cabinet", said)) == \
        "a cabinet with two doors"
    said = parse_prompt("An oven.")
    assert usual_parts_text("An oven.", said, with_usual_parts("An oven.", said)) == \
        "An oven with a door"
    said = parse_prompt("a cabinet with two doors")
    assert usual_parts_text("a cabinet with two doors", said, said) is None
    for text in ("a cabinet", "a storage cabinet", "a closet"):
        trees, *_ = shipped.decode_trees(text, seed=0, samples=4)
        for t in trees:
            obj = shipped.layout(t)
            doors = [i for i, p in enumerate(obj.parts) if p.label == "door"]
            assert len(doors) == 2 and all(face_of(obj, i) == (0, 1.0) for i in doors), text
