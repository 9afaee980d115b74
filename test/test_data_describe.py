"""Descriptions: four lengths, several variants, varied wording, and agreement with the
structured summary (every counted part kind appears with its count and a matching noun)."""
import re

import numpy as np
import pytest

from model.data import synth, vocab
from model.data.describe import _pluralise_verb, describe, structured_summary
from model.data.format import DESCRIPTION_LENGTHS

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
    obj = synth.generate_object(seed=11, index=i, category=cat)
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
            words += ["swing on a hinge", "pivot", "rotate on a hinge", "slide", "translate", "spin freely",
                      "turn without limit", "rotate continuously", "screw on and off", "twist off"]
            assert any(w in tl or _pluralise_verb(w) in tl for w in words), (jt, t)


def test_lengths_ordered_and_wording_varies():
    objs = [synth.generate_object(seed=4, index=i) for i in range(15)]
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
    obj = synth.generate_object(seed=0, index=3)
    assert describe(obj, np.random.default_rng(5)) == describe(obj, np.random.default_rng(5))
