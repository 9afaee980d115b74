"""Descriptions: four lengths, several variants, varied wording, and agreement with the
structured summary (every counted part kind appears with its count and a matching noun)."""
import re

import numpy as np
import pytest

from model.data import synth, vocab
from model.data.describe import _pluralise_verb, describe, structured_summary
from model.data.format import DESCRIPTION_LENGTHS

from helpers import built_object

OBJECTS = [(c, i) for c in synth.GENERATORS for i in range(2)]


def _count_phrases(n):
    words = {vocab.number_word(n), str(n)}
    if n == 1:
        words |= {"a", "an", "one", "a single"}
    if n == 2:
        words.add("a pair of")
    if n == 4:
        words.add("two pairs of")
    return words


def _mentions(text: str, label: str, n: int) -> bool:
    """True if `text` has '<count> [adjective...] <synonym of label>' with the right number,
    or the compound '<count>-<label>' ("a three-drawer dresser"), or an 'R x C keypad' of n
    buttons."""
    roles = [w for (c, lab), ws in vocab.ROLE_NAMES.items() if lab == label for w in ws]
    nouns = list(vocab.PART_SYNONYMS[label] if n == 1 else vocab.PART_PLURALS[label])
    nouns += roles if n == 1 else [vocab.plural(w) for w in roles]
    t = text.lower()
    if re.search(rf"\b{re.escape(vocab.number_word(n))}-{label}\b", t):
        return True
    if label == "button":
        for r, c in re.findall(r"(\d+) x (\d+) keypad", t):
            if int(r) * int(c) == n:
                return True
    for count in _count_phrases(n):
        for noun in nouns:
            # up to two adjective words between the count and the noun
            if re.search(rf"(^|[\s,]){re.escape(count)}\s+(\S+\s+){{0,2}}{re.escape(noun)}\b", t):
                return True
    return False


def _category_named(text: str, category: str) -> bool:
    t = text.lower()
    return any(re.search(rf"\b{re.escape(w)}", t) for w in vocab.CATEGORY_SYNONYMS[category])


@pytest.mark.parametrize("cat,i", OBJECTS)
def test_descriptions_agree_with_summary(cat, i):
    obj = built_object(11, i, cat)
    summ = structured_summary(obj)
    assert set(summ) >= {"category", "counts", "joint_types", "num_parts", "num_movable"}
    texts = describe(obj, np.random.default_rng(i))
    assert list(texts) == list(DESCRIPTION_LENGTHS)
    for length, variants in texts.items():
        assert len(variants) >= 3
        for t in variants:
            assert _category_named(t, cat), (length, t)
            for label, n in summ["counts"].items():
                if label in vocab.COUNTABLE_LABELS:
                    assert _mentions(t, label, n), (length, label, n, t)
    # the long forms say how parts move
    movable_types = {jt for lab, jts in summ["joint_types"].items() for jt in jts if jt != "fixed"}
    for t in texts["sentence"] + texts["detailed"]:
        tl = t.lower()
        for jt in movable_types:
            words = [w for (lab, j), ws in vocab.LABEL_MOTION_SYNONYMS.items() if j == jt for w in ws]
            words += list(vocab.MOTION_SYNONYMS[jt]) + list(vocab.MOTION_ADJECTIVES[jt])
            if jt == "revolute":     # "opens downward" says how a hinged part moves
                words += [w for ws in vocab.OPENING_PHRASES.values() for w in ws]
            words += ["swing on a hinge", "pivot", "rotate on a hinge", "slide", "translate", "spin freely",
                      "turn without limit", "rotate continuously", "screw on and off", "twist off"]
            assert any(w in tl or _pluralise_verb(w) in tl for w in words), (jt, t)


def test_lengths_ordered_and_wording_varies():
    objs = [built_object(4, i) for i in range(15)]
    lens = {k: [] for k in DESCRIPTION_LENGTHS}
    sentences = set()
    for k, o in enumerate(objs):
        d = describe(o, np.random.default_rng(k))
        for length, v in d.items():
            lens[length] += [len(t.split()) for t in v]
        sentences.update(d["sentence"])
    means = [np.mean(lens[k]) for k in DESCRIPTION_LENGTHS]
    assert means == sorted(means, reverse=True), means      # detailed > sentences > sentence > words
    assert len(sentences) == 45                              # no two variants identical
    # several phrasings of the same fact: drawer nouns used across the set
    all_text = " ".join(sentences).lower()
    assert sum(w in all_text for w in vocab.PART_PLURALS["drawer"]) >= 2 or \
        sum(w in all_text for w in vocab.PART_SYNONYMS["door"]) >= 2


def test_deterministic_for_rng():
    obj = built_object(0, 3)
    assert describe(obj, np.random.default_rng(5)) == describe(obj, np.random.default_rng(5))


# --- spatial facts are true of the object -----------------------------------------------------
def _spatial_objects():
    return [built_object(21, i, c)
            for c in ("StorageFurniture", "StorageFurniture", "Safe", "Oven", "WashingMachine",
                      "Bottle") for i in range(4)]


@pytest.fixture(scope="module")
def spatial_objects():
    return _spatial_objects()


def test_hinge_side_from_geometry_matches_the_generator(spatial_objects):
    """The geometric hinge side equals the side the generator built the hinge on (its
    'left' is the viewer's left, -y): one definition of left everywhere."""
    from model.data.describe import hinge_side, opening_direction
    assert vocab.SIDE_DIRECTIONS["left"] == (0.0, -1.0, 0.0)
    seen = set()
    for obj in spatial_objects:
        meta = obj.metadata["parts"]
        for i, p in enumerate(obj.parts):
            side = meta[p.name].get("side")
            if p.label in ("door", "lid") and side:
                assert hinge_side(obj, i) == side, (obj.name, p.name)
                want = {"left": "sideways", "right": "sideways", "bottom": "down", "top": "up",
                        "back": "up"}[side]
                assert opening_direction(obj, i) == want, (obj.name, p.name)
                seen.add(side)
                # the hinge line is on that side of the part's box
                d = p.joint.origin - p.bbox_center
                assert float(np.dot(d, vocab.SIDE_DIRECTIONS[side])) > 0
    assert {"left", "right", "bottom", "back"} <= seen


def test_a_thick_lid_hinged_on_its_underside_opens_up():
    """A flip lid 2.6 cm thick on a 3.7 cm neck, hinged on its underside's back edge (as the
    refinement hinges a bottle's lids): its front edge rises as it opens, though its top
    front corner swings mostly backwards ("a shampoo bottle with a flip-up cap", seed 2,
    read "sideways")."""
    from model.core import ArticulatedObject, Joint, JointType, Part
    from model.data.spatial import opening_direction
    obj = ArticulatedObject(category="Bottle", name="bottle", parts=[
        Part(name="body_0", label="body", parent=-1, bbox_center=np.array([0, 0, 0.115]),
             bbox_size=np.array([0.06, 0.06, 0.23])),
        Part(name="lid_0", label="lid", parent=0, bbox_center=np.array([0, 0, 0.244]),
             bbox_size=np.array([0.037, 0.038, 0.026]),
             joint=Joint(JointType.REVOLUTE, np.array([-0.0185, 0, 0.231]),
                         np.array([0.0, -1.0, 0.0]), r_range=(0.0, 2.79)))])
    assert opening_direction(obj, 1) == "up"


def test_arrangement_matches_the_generator_cells(spatial_objects):
    """Rows / columns of drawers and doors agree with the generator's bands and columns."""
    from model.data.describe import spatial_summary
    checked = 0
    for obj in spatial_objects:
        if obj.category != "StorageFurniture":
            continue
        meta = obj.metadata["parts"]
        sp = spatial_summary(obj)
        for label in ("drawer", "door"):
            cells = [(meta[p.name]["band"], meta[p.name]["col"]) for p in obj.parts
                     if p.label == label]
            if len(cells) < 2:
                continue
            bands = {b for b, _ in cells}
            f = sp[label]
            assert f["rows"] == len(bands), (obj.name, label, f, cells)
            if f["layout"] == "row":
                assert len(bands) == 1
            if f["layout"] == "column":
                assert len(cells) == len(bands)
            if f["layout"] == "grid":
                assert all(sum(b == x for b, _ in cells) == f["columns"] for x in bands)
            checked += 1
    assert checked >= 3


def test_description_phrases_are_true(spatial_objects):
    """What the descriptions say, read back by the prompt parser, checked against the raw
    object (part centres, the generator's hinge sides and cells), not against the summary."""
    from model.data.prompt_parse import parse_prompt
    seen: set = set()
    for k, obj in enumerate(spatial_objects):
        body = obj.parts[obj.root]
        meta = obj.metadata["parts"]
        for texts in describe(obj, np.random.default_rng(k)).values():
            for t in texts:
                e = parse_prompt(t)
                tl = t.lower()
                if re.search(r"\ba pair of (\w+ )?doors\b", tl):
                    assert sum(p.label == "door" for p in obj.parts) == 2, t
                    seen.add("pair")
                for label, facts in e.spatial.items():
                    parts = [p for p in obj.parts if p.label == label]
                    if facts.get("hpos") == ["left"]:      # the viewer's left is -y
                        assert all(p.bbox_center[1] < body.bbox_center[1] for p in parts), t
                        seen.add("left")
                    if facts.get("hpos") == ["right"]:
                        assert all(p.bbox_center[1] > body.bbox_center[1] for p in parts), t
                        seen.add("right")
                    if "hinge" in facts and all("side" in meta[p.name] for p in parts):
                        assert facts["hinge"] == sorted({meta[p.name]["side"] for p in parts}), t
                        seen.add("hinge")
                    if facts.get("columns") == 2 and obj.category == "StorageFurniture":
                        cols = {meta[p.name]["col"] for p in parts}
                        assert len(cols) == 2, t
                        seen.add("two columns")
                    if facts.get("layout") == "column":
                        zs = sorted(p.bbox_center[2] for p in parts)
                        hs = [p.bbox_size[2] for p in parts]
                        assert all(b - a > 0.5 * min(hs) for a, b in zip(zs, zs[1:])), t
                        seen.add("stacked")
                    for other in facts.get("above", []):
                        top_of_other = max(p.bbox_center[2] + p.bbox_size[2] / 2
                                           for p in obj.parts if p.label == other)
                        assert all(p.bbox_center[2] > top_of_other for p in parts), t
                        seen.add("above")
    assert {"pair", "hinge", "stacked", "above"} <= seen, seen


def test_everyday_names_fit_the_object():
    from model.data.describe import everyday_names
    for i in range(30):
        obj = built_object(5, i)
        names = everyday_names(obj)
        labels = [p.label for p in obj.parts]
        if "dresser" in names:
            assert "drawer" in labels and "door" not in labels
        if "top loader" in names:
            assert obj.metadata.get("loading") == "top"
        if "front-loader" in names:
            assert obj.metadata.get("loading") == "front"
        if "range" in names:
            assert labels.count("knob") >= 4
        if "wall oven" in names:
            assert any(obj.metadata["parts"][p.name].get("side") in ("left", "right")
                       for p in obj.parts if p.label == "door")
        if "locker" in names:
            assert "drawer" not in labels
        assert all(n in vocab.CATEGORY_SYNONYMS[obj.category] for n in names), names
