"""The hand-written free-form prompt set, its structure lines, the spatial-fact checks of the
alignment metric and the free-form breakdown of `artformer eval`."""
import re

import numpy as np
import pytest

from model.core import ArticulatedObject, Joint, JointType, Part
from model.data import vocab
from model.metrics.alignment import GeneratedStructure, alignment_of, check_alignment, summarise
from model.metrics.evaluate import freeform_breakdown, freeform_table, part_bucket
from model.data.prompt_parse import (ExpectedStructure, parse_prompt,
                                        read_annotated_prompts)

ITEMS = read_annotated_prompts()


# --- the set -------------------------------------------------------------------------------
def test_set_size_categories_counts_and_spatial_facts():
    assert len(ITEMS) >= 150
    prompts = [p for p, _ in ITEMS]
    assert len(set(p.lower() for p in prompts)) == len(prompts), "duplicate prompts"
    cats = {e.category for _, e in ITEMS}
    assert cats == set(vocab.CATEGORIES)
    per_cat = {c: sum(e.category == c for _, e in ITEMS) for c in vocab.CATEGORIES}
    assert min(per_cat.values()) >= 15, per_cat
    counts = {n for _, e in ITEMS for n in e.counts.values() if n > 0}
    assert set(range(1, 13)) <= counts and max(counts) == 12, sorted(counts)
    buckets = [part_bucket(e.num_parts) for _, e in ITEMS]
    assert buckets.count("8+") >= 15 and buckets.count("4-7") >= 30
    kinds = {}
    for _, e in ITEMS:
        for facts in e.spatial.values():
            for key in facts:
                kinds[key] = kinds.get(key, 0) + 1
    for key in ("hinge", "opens", "layout", "rows", "columns", "hpos", "vpos", "above", "below"):
        assert kinds.get(key, 0) >= 2, kinds
    # everyday names a person uses
    text = " ".join(prompts).lower()
    for name in ("dresser", "sideboard", "nightstand", "locker", "microwave-sized safe", "range",
                 "top loader", "thumb drive", "wardrobe", "filing cabinet"):
        assert name in text, name


def test_dev_set_reads_and_the_parser_gets_most_of_it():
    """The spatial dev set (prompts_dev.txt) is well formed and every category's wording is
    in it; the reader gets at least 68 % of its spatial facts (it was widened on this set;
    generated objects are scored by `artformer eval --freeform-only`)."""
    from pathlib import Path
    dev = read_annotated_prompts(Path(__file__).parents[1] / "model/metrics/prompts_dev.txt")
    assert len(dev) >= 60 and {e.category for _, e in dev} == set(vocab.CATEGORIES)
    total = right = 0
    for p, e in dev:
        got = parse_prompt(p).spatial
        for lab, facts in e.spatial.items():
            for key, want in facts.items():
                total += 1
                right += (got.get(lab) or {}).get(key) == want
    assert total >= 150 and right >= 0.68 * total, (right, total)


def test_parser_reads_the_structure_lines():
    """The rule parser agrees with the hand-written structure of nearly every prompt (the
    metric itself scores against the structure lines)."""
    bad = [(p, e.to_line(), parse_prompt(p).to_line()) for p, e in ITEMS
           if parse_prompt(p).to_json() != e.to_json()]
    assert len(bad) <= 0.02 * len(ITEMS), bad


def _norm(text: str) -> str:
    t = text.lower()
    t = re.sub(r"\d+", lambda m: vocab.number_word(int(m.group(0))), t)
    t = re.sub(r"[^a-z ]+", " ", t)
    t = re.sub(r"\b(a|an|the|one|single)\b", " ", t)
    return " ".join(t.split())


def _copies(n_objects: int) -> list:
    from model.data.describe import describe
    from helpers import built_object
    prompts = {_norm(p): p for p, _ in ITEMS}
    words = {k: set(k.split()) for k in prompts}
    found = []
    for i in range(n_objects):
        obj = built_object(3, i)
        for texts in describe(obj, np.random.default_rng(i)).values():
            for t in texts:
                nt = _norm(t)
                if nt in prompts:
                    found.append((prompts[nt], t))
                    continue
                tw = set(nt.split())
                for k, w in words.items():   # near-copy: nearly the same words
                    if len(w | tw) and len(w & tw) / len(w | tw) >= 0.9:
                        found.append((prompts[k], t))
    return found


def test_no_prompt_is_a_copy_of_a_description():
    assert not _copies(40)


@pytest.mark.slow
def test_no_prompt_is_a_copy_of_a_description_300_objects():
    assert not _copies(300)


def test_structure_line_round_trip_and_errors(tmp_path):
    e = ExpectedStructure.from_line(
        "Oven knob=4 door>=1 door:revolute knob.layout=row knob.above=door door.hinge=bottom "
        "drawer.rows=2")
    assert e.counts == {"knob": 4} and e.min_counts == {"door": 1}
    assert e.spatial == {"knob": {"layout": "row", "above": ["door"]},
                         "door": {"hinge": ["bottom"]}, "drawer": {"rows": 2}}
    assert ExpectedStructure.from_line(e.to_line()).to_json() == e.to_json()
    for bad in ("Kitchen drawer=2", "- drawer=two", "- wheel=2", "- door.hinge=diagonal",
                "- door.colour=red", "- door:wobbly"):
        with pytest.raises(ValueError):
            ExpectedStructure.from_line(bad)
    f = tmp_path / "p.txt"
    f.write_text("a cabinet with two drawers\n")
    with pytest.raises(ValueError, match="structure line"):
        read_annotated_prompts(f)
    f.write_text("# only\n#> - drawer=2\n")
    with pytest.raises(ValueError, match="without a prompt"):
        read_annotated_prompts(f)


# --- the parser reads spatial phrases ----------------------------------------------------------
@pytest.mark.parametrize("prompt,label,facts", [
    ("a cupboard with a door hinged on the left", "door", {"hinge": ["left"]}),
    ("a right-hinged door", "door", {"hinge": ["right"]}),
    ("a lid hinged at the rear", "lid", {"hinge": ["back"]}),
    ("a pair of doors hinged on the left and on the right", "door", {"hinge": ["left", "right"]}),
    ("an oven door that opens downward", "door", {"opens": ["down"]}),
    ("a drop-down door", "door", {"opens": ["down"]}),
    ("a lid that flips up", "lid", {"opens": ["up"]}),
    ("a door that swings open sideways", "door", {"opens": ["sideways"]}),
    ("a door that swings open to the right", "door", {"hinge": ["right"], "opens": ["sideways"]}),
    ("three stacked drawers", "drawer", {"layout": "column"}),
    ("four drawers one above the other", "drawer", {"layout": "column"}),
    ("two doors side by side", "door", {"layout": "row"}),
    ("five knobs in a row", "knob", {"layout": "row"}),
    ("six drawers in two columns", "drawer", {"columns": 2}),
    ("six drawers in two rows of three", "drawer", {"layout": "grid", "rows": 2, "columns": 3}),
    ("a 2 x 3 grid of drawers", "drawer", {"layout": "grid", "rows": 2, "columns": 3}),
    ("a door on the left", "door", {"hpos": ["left"]}),
    ("a drawer on the right-hand side", "drawer", {"hpos": ["right"]}),
    ("a left door and a right door", "door", {"hpos": ["left", "right"]}),
    ("a drawer at the bottom", "drawer", {"vpos": ["bottom"]}),
    ("control knobs above the door", "knob", {"above": ["door"]}),
    ("a drawer below the door", "drawer", {"below": ["door"]}),
    ("one drawer, and below it a door", "door", {"below": ["drawer"]}),
    ("a dial in the middle of the door with a handle below it", "handle", {"below": ["dial"]}),
    ("a safe with a keypad at the top of its door", "button", {"vpos": ["top"]}),
    ("A cabinet with a door. It is hinged on the right.", "door", {"hinge": ["right"]}),
])
def test_parser_reads_spatial_phrases(prompt, label, facts):
    assert parse_prompt(prompt).spatial.get(label) == facts


@pytest.mark.parametrize("prompt,counts", [
    ("a dresser with a pair of drawers", {"drawer": 2}),
    ("two pairs of doors", {"door": 4}),
    ("a three-drawer dresser", {"drawer": 3}),
    ("a safe with a 3 x 3 keypad", {"button": 9}),
    ("a keypad of twelve buttons", {"button": 12}),
    ("two rows of three drawers", {"drawer": 6}),
    ("a washer with a program dial and a detergent drawer", {"dial": 1, "drawer": 1}),
    ("12 drawers", {"drawer": 12}),
    ("twelve drawers", {"drawer": 12}),
])
def test_parser_reads_counts(prompt, counts):
    assert parse_prompt(prompt).counts == counts


# --- the alignment check on spatial facts -------------------------------------------------------
def _cabinet(hinge: str = "left", drawers: int = 0, drawer_layout: str = "column",
             door_y: float = 0.0) -> ArticulatedObject:
    """A 0.8 m wide, 1 m tall cabinet (front +x) with one door hinged on the viewer's
    ``hinge`` side (left = -y) and drawers stacked or in a row above it."""
    parts = [Part("body_0", "body", -1, bbox_center=[0, 0, 0.5], bbox_size=[0.4, 0.8, 1.0])]
    w = 0.36
    y0, y1 = door_y - w / 2, door_y + w / 2
    origin = [0.2, y0 if hinge == "left" else y1, 0.25]
    axis = [0, 0, -1] if hinge == "left" else [0, 0, 1]
    parts.append(Part("door_0", "door", 0, bbox_center=[0.19, door_y, 0.25],
                      bbox_size=[0.02, w, 0.45],
                      joint=Joint(JointType.REVOLUTE, origin, axis, r_range=(0, 1.6))))
    for k in range(drawers):
        c = [0.19, 0.0, 0.6 + 0.12 * k] if drawer_layout == "column" else \
            [0.19, -0.3 + 0.2 * k, 0.7]
        parts.append(Part(f"drawer_{k}", "drawer", 0, bbox_center=c, bbox_size=[0.3, 0.18, 0.1],
                          joint=Joint(JointType.PRISMATIC, c, [1, 0, 0], t_range=(0, 0.2))))
    return ArticulatedObject(parts, category="StorageFurniture").validate()


def test_alignment_checks_hinge_side_apart_from_counts():
    prompt = "a cabinet with a door hinged on the left"
    r = alignment_of(prompt, _cabinet("left"))
    assert r.aligned and r.spatial_ok is True and r.spatial == {"hinge": True}
    r = alignment_of(prompt, _cabinet("right"))
    assert r.aligned                          # counts / labels / joints are right ...
    assert r.spatial_ok is False and r.spatial == {"hinge": False}   # ... the hinge side not
    assert any("door.hinge" in f for f in r.failures)
    # no spatial fact stated: not scored
    assert alignment_of("a cabinet with a door", _cabinet("right")).spatial_ok is None


def test_alignment_checks_opening_arrangement_and_position():
    obj = _cabinet("right", drawers=3, drawer_layout="column", door_y=-0.2)
    ok = alignment_of("a cabinet with three stacked drawers above a door on the left that "
                      "swings open sideways", obj)
    assert ok.aligned and ok.spatial_ok, ok.failures
    assert set(ok.spatial) == {"arrangement", "position", "opening"}
    bad = alignment_of("a cabinet with three drawers side by side and a door on the right "
                       "that drops down", obj)
    assert bad.aligned and bad.spatial == {"arrangement": False, "position": False,
                                          "opening": False}
    row = _cabinet("left", drawers=3, drawer_layout="row")
    assert alignment_of("three drawers in a row", row).spatial_ok
    assert not alignment_of("three drawers in two columns", row).spatial_ok
    assert not alignment_of("three drawers below the door", row).spatial_ok


def test_beside_is_checked_as_side_by_side_either_way_round():
    """"a drawer beside a door": the drawer group is all on one side of the door group,
    left or right, at a height the door spans; stacked above it is not beside it."""
    line = "StorageFurniture drawer=1 door=1 drawer.beside=door"
    assert ExpectedStructure.from_line(line).to_line() == line
    stacked = _cabinet("left", drawers=1)                  # the drawer above the door
    assert alignment_of("a cabinet with a drawer beside a door", stacked).spatial == \
        {"position": False}
    for y in (-0.3, 0.3):                                  # on the left, on the right
        obj = _cabinet("left", drawers=1, door_y=-y)
        d = next(p for p in obj.parts if p.label == "drawer")
        d.bbox_center = np.array([0.19, y, 0.4])
        assert alignment_of("a cabinet with a drawer beside a door", obj).spatial == \
            {"position": True}


def test_a_stated_top_row_is_checked_row_by_row():
    """"two drawers on top and two below": parts per row, top row first, as the spatial
    summary reads them; the annotation line keeps their order."""
    line = "StorageFurniture drawer=4 drawer.per_row=2/1/1"
    assert ExpectedStructure.from_line(line).to_line() == line
    assert ExpectedStructure.from_line(line).spatial["drawer"]["per_row"] == [2, 1, 1]
    obj = _cabinet("left", drawers=4)            # one column of four above the door
    expected = parse_prompt("a cabinet with a door, two drawers on top and two drawers below")
    assert expected.spatial["drawer"]["per_row"] == [2, 1, 1]
    assert check_alignment(expected, GeneratedStructure.from_object(obj)).spatial == \
        {"arrangement": False}
    d = [p for p in obj.parts if p.label == "drawer"]
    for p, (y, z) in zip(d, [(-0.2, 0.95), (0.2, 0.95), (0.0, 0.8), (0.0, 0.65)]):
        p.bbox_center = np.array([0.19, y, z])
    assert check_alignment(expected, GeneratedStructure.from_object(obj)).spatial == \
        {"arrangement": True}


def test_generated_structure_without_geometry_fails_spatial_facts():
    got = GeneratedStructure("StorageFurniture", {"door": 1}, {"door": ["revolute"]})
    r = check_alignment(parse_prompt("a cabinet with a door hinged on the left"), got)
    assert r.aligned and r.spatial_ok is False


def test_people_words_are_checked_in_the_category_part_names():
    # a dresser's "knobs" are its handles, a safe's "knob" its dial (the dataset's labels)
    dresser = GeneratedStructure.from_labels("StorageFurniture", ["body"] + ["drawer"] * 8
                                             + ["handle"] * 8, ["fixed"] + ["prismatic"] * 8
                                             + ["fixed"] * 8)
    r = check_alignment(ExpectedStructure.from_line("StorageFurniture drawer=8 knob=8"), dresser)
    assert r.aligned and not r.failures
    r = check_alignment(ExpectedStructure.from_line("StorageFurniture drawer=8 knob=7"), dresser)
    assert not r.aligned and r.failures == ["handle: 8 != 7"]
    safe = GeneratedStructure.from_labels("Safe", ["body", "door", "dial", "dial"],
                                          ["fixed", "revolute", "continuous", "revolute"])
    line = "Safe door=1 knob=2 knob:continuous/revolute"
    assert check_alignment(ExpectedStructure.from_line(line), safe).aligned
    # an oven has knobs of its own: its "knobs" stay knobs
    oven = GeneratedStructure.from_labels("Oven", ["body", "door", "dial"],
                                          ["fixed", "revolute", "continuous"])
    assert not check_alignment(ExpectedStructure.from_line("Oven door=1 knob=1"), oven).aligned


# --- the breakdown -----------------------------------------------------------------------------
def test_breakdown_by_category_and_part_count():
    assert [part_bucket(n) for n in (0, 1, 3, 4, 7, 8, 20)] == \
        ["1-3", "1-3", "1-3", "4-7", "4-7", "8+", "8+"]
    obj = _cabinet("left", drawers=3)
    exps = [ExpectedStructure.from_line("StorageFurniture door=1 door.hinge=left"),
            ExpectedStructure.from_line("StorageFurniture door=1 drawer=3 handle=4"),
            ExpectedStructure.from_line("Safe door=1 door.hinge=right")]
    got = GeneratedStructure.from_object(obj)
    res = [check_alignment(e, got) for e in exps]
    bd = freeform_breakdown(exps, res)
    assert bd["all"]["n_checked"] == 3 and bd["all"]["alignment"] == pytest.approx(1 / 3)
    assert bd["by_category"]["StorageFurniture"]["alignment"] == 0.5
    assert bd["by_category"]["Safe"]["spatial_hinge"] == 0.0
    assert bd["by_parts"]["1-3"]["n_checked"] == 2 and bd["by_parts"]["8+"]["alignment"] == 0.0
    assert bd["all"]["spatial"] == 0.5 and bd["all"]["n_spatial"] == 2
    table = freeform_table(bd)
    assert "| Safe | 0.0 % (1)" in table and "8+ parts asked" in table
    assert summarise(res)["n_spatial_hinge"] == 2
    with pytest.raises(ValueError):
        freeform_breakdown(exps, res[:2])


def test_freeform_only_command(tmp_path, capsys):
    """`artformer eval --freeform-only` on the shipped model prints the table and writes rows."""
    import json

    from model.metrics.commands import main
    out = tmp_path / "ff.json"
    assert main(["eval", "--freeform-only", "--freeform", "3", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "| **all** |" in text and "parts asked" in text
    res = json.loads(out.read_text())
    assert len(res["rows"]) == 3 and res["n_prompts"] == 3
    assert all({"prompt", "seed", "expected", "aligned", "failures"} <= set(r) for r in res["rows"])
    bad = tmp_path / "bad.txt"
    bad.write_text("a cabinet with two drawers\n")
    assert main(["eval", "--freeform-only", "--freeform-file", str(bad)]) == 2
