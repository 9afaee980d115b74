"""Text prompt → the structure it asks for (category, part counts, joint types).

Used by the alignment metric (DESIGN §7) on the dataset's template descriptions *and* on
free-form prompts no template wrote, and by generation to hold decoding to the parts a prompt
states (``model.pipeline.prompt_structure``). Rule-based on the vocabulary of ``model.data.vocab``
(categories, part synonyms and plurals, motion phrases) plus the extra wordings below.

What it understands
-------------------
* quantities: digits, number words ("three", "a", "a single"), "a pair of", "double"/"twin",
  "two pairs of", compounds ("a three-drawer dresser"), "no"/"without" (count 0);
  "both", "several", bare plurals and definite mentions give lower bounds only.
* distribution: "each drawer has a handle", "two doors, each with a knob",
  "a handle on every drawer", "one knob per burner" → counts multiplied.
* lists with sides: "a left door and a right door" → 2 doors; an appositive after a counted
  plural ("two doors, a left door and a right door") is not counted twice, nor is a count
  split into groups ("five drawers: two small ones on top and three large drawers below").
  Bare singulars on distinct sides are as many parts ("door on the left, door on the
  right" → 2 doors).
* "ones" is the part named last ("one wide drawer and three small ones" → 4 drawers).
* motion: adjectives ("sliding drawers", "hinged lid") and clauses ("the drawers slide out",
  "a door hinged on the left", "the cap screws off") attach to the nearest part mention;
  generic rotation words ("rotates", "turns", "rotating") accept revolute or continuous.

Example::

    >>> parse_prompt("A dresser with three sliding drawers, each with a handle").to_json()
    {'category': 'StorageFurniture', 'counts': {'drawer': 3, 'handle': 3},
     'min_counts': {}, 'joint_types': {'drawer': ['prismatic']}}

Modules: the words and the tokenizer in :mod:`model.metrics.prompt_lexicon`, spatial phrases
in :mod:`model.metrics.prompt_spatial`, ``ExpectedStructure`` and the annotated prompt file
in :mod:`model.metrics.expected_structure` (their public names are importable from here
too); here, per sentence, the part mentions with their quantifiers and motions, then the
counts.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from model.data import vocab

# the vocabulary tables, spatial patterns and ExpectedStructure lived in this module: their
# public names stay importable from it
from .expected_structure import (ARRANGEMENT_KEYS, SIDES, SPATIAL_KEYS,  # noqa: F401
                                 SPATIAL_KINDS, ExpectedStructure, read_annotated_prompts)
from .prompt_lexicon import (DEFINITE, DISTRIBUTIVE, EXACT_NUMBER_PHRASES,  # noqa: F401
                             EXTRA_CATEGORY, EXTRA_MOTION, EXTRA_PART, GENERIC_ROTATION,
                             LOWER_BOUND_PHRASES, LOWER_BOUND_WORDS,
                             REVOLUTE_OR_CONTINUOUS, SIDE_ADJECTIVES,
                             STOP_WORDS, ZERO_WORDS, _motion_in_phrase, _sentences, _Tok,
                             _tokenize)
from .prompt_size import read_size
from .prompt_spatial import (ARRANGED, HINGED, _N, _attach, _num, _rewrite_counts,  # noqa: F401
                             _spatial_facts)


# --------------------------------------------------------------------------------------------
# part mentions
# --------------------------------------------------------------------------------------------
@dataclass
class _Mention:
    label: str
    sent: int
    pos: int
    plural: bool
    exact: int | None = None       # exact count contributed
    lower: int | None = None       # lower bound contributed
    zero: bool = False
    side: bool = False             # a side adjective before the noun ("a left door")
    dist_of: str | None = None     # distributive: multiply by the count of this label
    dist_head: bool = False        # the part a distributive word quantifies ("each drawer")
    single: bool = False           # "the door", "its lid", "porthole door," (one, if nothing
                                   # else counts this part kind)
    breakdown: bool = False        # splits an earlier count ("five drawers: two small drawers
                                   # on top and three large ones below"): not counted again
    sided: bool = False            # a count on each of two sides ("3 drawers on each side")


def _scan_quantifier(toks: list[_Tok], k: int, m: _Mention, motions: list) -> None:
    """Walk back from the part noun at k over adjectives to its quantifier."""
    j, adjectives = k - 1, 0
    mult = 1
    while j >= 0 and adjectives <= 4:
        t = toks[j]
        if t.kind == "WORD":
            if t.text == "more" and j >= 2 and toks[j - 1].text == "or" \
                    and toks[j - 2].kind == "NUM":          # "three or more drawers"
                m.lower = int(toks[j - 2].value) * mult
                return
            if t.text in STOP_WORDS:
                break
            if t.text in SIDE_ADJECTIVES:
                m.side = True
            adjectives += 1
        elif t.kind == "MOTION":
            motions.append((t.value, k))
            adjectives += 1
        elif t.kind == "MULT":
            mult *= int(t.value)
            if j == 0 or toks[j - 1].kind != "NUM":   # "pairs of doors": at least two pairs
                m.lower = 2 * mult
                return
        elif t.kind == "NUM":
            if _after_lower_bound(toks, j):               # "at least four buttons"
                m.lower = int(t.value) * mult
            else:
                m.exact = int(t.value) * mult
            return
        elif t.kind == "CAT" and j == k - 1:
            adjectives += 1         # "a fridge door", "two cabinet doors": a modifier
        elif t.kind == "ZERO":
            m.zero = True
            return
        elif t.kind == "LOWER":
            m.lower = int(t.value)
            return
        elif t.kind in ("DET", "DIST"):
            m.lower = 1
            m.dist_head = t.kind == "DIST" and t.text != "both with"
            m.single = t.kind == "DET" and not m.plural and t.text not in ("all", "any")
            return
        else:   # PUNCT, PART, CAT end the noun phrase
            break
        j -= 1
    m.lower = 2 if m.plural else 1
    m.single = not m.plural


def _after_lower_bound(toks: list[_Tok], j: int) -> bool:
    """Whether the number at j follows "at least", "no fewer than", "a minimum of"..."""
    before = tuple(t.text for t in toks[max(0, j - 3):j])
    return any(before[len(before) - len(p):] == p for p in LOWER_BOUND_PHRASES)


def _distributive_target(toks: list[_Tok], k: int) -> str | None:
    """Label whose count multiplies the part at k, if a distributive word governs it."""
    # after: "<Y> on each <X>", "<Y> per <X>" (within 3 tokens)
    for j in range(k + 1, min(len(toks), k + 4)):
        if toks[j].kind == "DIST":
            for i in range(j + 1, min(len(toks), j + 5)):
                if toks[i].kind == "PART":
                    return toks[i].value
                if toks[i].kind == "PUNCT":
                    break
            for i in range(k - 1, max(-1, k - 8), -1):   # "four drawers with knobs on each"
                if toks[i].kind == "PART" and toks[i].value != toks[k].value:
                    return toks[i].value
            return None
        if not (toks[j].kind == "WORD" and toks[j].text in ("on", "for", "in", "at", "to", "of",
                                                              "above", "below", "under", "over",
                                                              "beneath", "underneath", "beside")):
            break
    # before: "each <X> has a <Y>" or "<X>, each with a <Y>"
    for j in range(k - 1, max(-1, k - 8), -1):
        t = toks[j]
        if t.kind == "DIST" and j + 1 < k and toks[j + 1].text in ("side", "sides", "end", "ends"):
            break      # "a door at each end and three drawers": two doors, not per door
        if t.kind == "DIST" and j + 1 < k and (toks[j + 1].text == "of"
                                               or t.text.endswith(" the")):
            break      # "a drawer over each of its (the) two doors": the doors are counted
                       # as said
        if t.kind == "DIST":
            for i in range(j + 1, k):
                if toks[i].kind == "PART":
                    return toks[i].value
            for i in range(j - 1, max(-1, j - 9), -1):
                if toks[i].kind == "PART":
                    return toks[i].value
            return None
        if t.kind in ("PUNCT",) and t.text in ";:":
            break
    return None


# --------------------------------------------------------------------------------------------
# parsing
# --------------------------------------------------------------------------------------------
def parse_prompt(text: str) -> ExpectedStructure:
    """The structure a prompt asks for (see the module docstring)."""
    out = ExpectedStructure()
    mentions: list[_Mention] = []
    motion_links: list[tuple[frozenset, str, bool]] = []   # (joint types, label, said with "or")
    last_part: str | None = None
    earlier_parts: list[str] = []
    for si, sentence in enumerate(_sentences(text)):
        sentence = _elided_parts(_ones_to_parts(sentence, last_part), last_part)
        sentence, grid_facts = _rewrite_counts(sentence)
        toks = _tokenize(sentence)
        for lab in _attach(grid_facts + _spatial_facts(sentence, toks), toks, earlier_parts,
                           out.spatial):
            motion_links.append((frozenset({"revolute"}), lab, False))
        earlier_parts += [t.value for t in toks if t.kind == "PART"]
        if out.category is None:
            out.category = next((t.value for t in toks if t.kind == "CAT"), None)
        prefix_motion_at = _read_mentions(toks, si, mentions, motion_links)
        motion_links += _motion_clauses(toks, prefix_motion_at, last_part)
        parts_here = [t.value for t in toks if t.kind == "PART"]
        if parts_here:
            last_part = parts_here[-1]
    out.counts, out.min_counts = _counts(mentions)
    _sided_singles(out, mentions)
    out.joint_types = _joint_types(motion_links, out.counts)
    _tidy(out, text)
    out.size = read_size(text)
    return out


def _ones_to_parts(sentence: str, last_part: str | None) -> str:
    """"one wide drawer and three small ones" -> "... three small drawers": each "ones" names
    the part mentioned last before it (in this sentence, else in an earlier one)."""
    import re
    out, at = [], 0
    for m in re.finditer(r"\bones\b", sentence):
        parts = [t.value for t in _tokenize(sentence[:m.start()]) if t.kind == "PART"]
        label = parts[-1] if parts else last_part
        if label:
            out += [sentence[at:m.start()], label + "s"]
            at = m.end()
    return "".join(out) + sentence[at:]


_ELIDED = re.compile(
    r"\b(\d+|" + "|".join(sorted(vocab.NUMBER_WORDS[2:13], key=len, reverse=True)) +
    r")(?= (?:on|at|along|below|above|under|underneath|beneath|beside)\b)"
    r"(?! (?:on|at) (?:each|either|both|every)\b)")


def _elided_parts(sentence: str, last_part: str | None) -> str:
    """"three drawers on the left and three on the right" -> "... three drawers on the
    right": a count of two or more said straight before a place names the part mentioned
    last before it (the six drawers had been read as three). "one on top" stays: one of
    those already counted ("two doors, one above the other"), as does "two on each side" (a
    share of the count before it: "four drawers, two on each side"), and a count after a
    counted part and a comma or colon, which shares that count out ("two drawers, two at the
    bottom"; "seven drawers, one on top and six below")."""
    out, at = [], 0
    for m in _ELIDED.finditer(sentence):
        before = _tokenize(sentence[:m.start()])
        at_part = [j for j, t in enumerate(before) if t.kind == "PART"]
        label = before[at_part[-1]].value if at_part else last_part
        said = []                     # the count said with that part ("seven drawers")
        for t in reversed(before[max(0, at_part[-1] - 3):at_part[-1]] if at_part else []):
            if t.kind == "NUM":
                said = [t.value]
            if t.kind != "WORD" or t.text in STOP_WORDS:
                break
        # after a counted part and a comma or colon, a count shares out the one said ("seven
        # drawers, one on top and six below": seven)
        shared = bool(said) and any(t.kind == "PUNCT" for t in before[at_part[-1] + 1:])
        after_of = bool(before) and before[-1].text.lower() in ("of", "x", "by", "times")
        if label and before and before[-1].kind != "PART" and not shared and not after_of:
            out += [sentence[at:m.end()], " " + vocab.plural(label)]
            at = m.end()
    return "".join(out) + sentence[at:]


def _read_mentions(toks: list[_Tok], si: int, mentions: list[_Mention],
                   motion_links: list) -> set[int]:
    """Append a _Mention for every part noun of sentence ``si`` (its quantifier and the part
    whose count distributes over it) and the motions its adjectives and own words give it;
    returns the token positions of those adjectives (not read again as motion clauses)."""
    prefix_motion_at: set[int] = set()
    for k, t in enumerate(toks):
        if t.kind != "PART":
            continue
        m = _Mention(t.value, si, k, t.plural)
        pre: list = []
        _scan_quantifier(toks, k, m, pre)
        for types, _ in pre:
            motion_links.append((types, t.value, False))
        for j in range(max(0, k - 5), k):
            if toks[j].kind == "MOTION" and any(toks[j].value == p[0] for p in pre):
                prefix_motion_at.add(j)
        own = _motion_in_phrase(t.text)
        if own:
            motion_links.append((own, t.value, False))
        if _on_both_sides(toks, k) and not m.plural and m.exact in (None, 1) and not m.zero:
            m.exact, m.lower, m.single, m.dist_head = 2, None, False, True
        elif _on_both_sides(toks, k) and m.plural and (m.exact or 0) >= 2 and not m.zero:
            m.exact, m.sided, m.dist_head = 2 * m.exact, True, True   # "3 drawers on each
                                                                        # side": six
        dist = _distributive_target(toks, k)
        if dist and dist != t.value and not m.zero and not m.dist_head:
            m.dist_of = dist
        mentions.append(m)
    return prefix_motion_at


def _on_both_sides(toks: list[_Tok], k: int) -> bool:
    """The part at k is followed by "at each end", "on either side", "on both sides": two of
    it ("a door at each end", "a button on either side of the dial")."""
    words = [t.text for t in toks[k + 1:k + 4]]
    return len(words) == 3 and words[0] in ("on", "at") and \
        words[1] in ("each", "either", "both") and words[2] in ("side", "sides", "end", "ends")


def _motion_clauses(toks: list[_Tok], skip: set[int],
                    last_part: str | None) -> list[tuple[frozenset, str, bool]]:
    """Motion clauses of a sentence ("the drawers slide out"), except the tokens ``skip``:
    each attaches to the nearest part before (or the last one of the text, or the next)."""
    links = []
    for k, t in enumerate(toks):
        if t.kind != "MOTION" or k in skip:
            continue
        target = None
        for j in range(k - 1, -1, -1):
            if toks[j].kind == "PART":
                target = toks[j].value
                break
        if target is None:
            target = last_part
        if target is None:
            for j in range(k + 1, len(toks)):
                if toks[j].kind == "PART":
                    target = toks[j].value
                    break
        if target is not None:
            # "can turn without limit or rotate on a hinge": either is acceptable
            j = k - 1
            is_or = False
            while j >= 0 and toks[j].kind != "PART":
                is_or |= toks[j].kind == "WORD" and toks[j].text == "or"
                j -= 1
            links.append((t.value, target, is_or))
    return links


def _counts(mentions: list[_Mention]) -> tuple[dict[str, int], dict[str, int]]:
    """(exact counts, lower bounds) per countable label: a first pass without distribution
    gives the counts a distributive mention ("a handle on every drawer") multiplies."""
    _mark_breakdowns(mentions)
    exact1, _ = _combine(mentions, {})
    exact, lower = _combine(mentions, exact1)
    # "the door is hinged on the left", "porthole door, soap drawer": one of each, when no
    # other mention counts or bounds that part kind
    for lab in list(lower):
        ms = [m for m in mentions if m.label == lab]
        if ms and all(m.single and m.dist_of is None for m in ms):
            exact[lab] = 1
            del lower[lab]
    return exact, lower


def _sided_singles(out: ExpectedStructure, mentions: list[_Mention]) -> None:
    """"Door on the left, door on the right": a part counted once only because every mention
    of it is a bare or definite singular is as many parts as the distinct sides stated for
    it (``hpos``), when there are two or more and as many mentions."""
    for lab, n in list(out.counts.items()):
        ms = [m for m in mentions if m.label == lab]
        sides = set((out.spatial.get(lab) or {}).get("hpos") or [])
        if n == 1 and len(sides) >= 2 and len(ms) >= len(sides) and all(m.single for m in ms):
            out.counts[lab] = len(sides)


def _mark_breakdowns(mentions: list[_Mention]) -> None:
    """A counted mention followed by two or more counted mentions of the same part whose counts
    add up to it ("four knobs. Two big ones and two small ones."): the later ones describe the
    same parts."""
    plain = [m for m in mentions if m.exact and not m.zero and m.dist_of is None]
    for i, m in enumerate(plain):
        if m.breakdown:
            continue
        group, total = [], 0
        for n in plain[i + 1:]:
            if n.label != m.label:
                continue
            group.append(n)
            total += n.exact
            if total >= m.exact:
                break
        if total == m.exact and (len(group) >= 2 or group and group[0].sided):
            for n in group:       # "six drawers, three drawers on each side": six
                n.breakdown = True


def _combine(ms: list[_Mention], base: dict[str, int]) -> tuple[dict, dict]:
    """Sum the mentions' counts (distributive ones times ``base``) into (exact, lower)."""
    countable = set(vocab.COUNTABLE_LABELS)
    exact: dict[str, int] = {}
    lower: dict[str, int] = {}
    zero: set[str] = set()
    plural_seen: dict[tuple[int, str], int] = {}
    for m in ms:
        if m.label not in countable:
            continue
        if m.zero:
            zero.add(m.label)
            continue
        if m.breakdown:
            continue
        if m.exact is not None:
            key = (m.sent, m.label)
            # appositive: "two doors, a left door and a right door"
            if m.exact == 1 and m.side and plural_seen.get(key, 0) >= 1:
                plural_seen[key] -= 1
                continue
            n = m.exact
            if m.dist_of is not None:
                if m.dist_of in base:
                    n = n * base[m.dist_of]
                else:
                    lower[m.label] = max(lower.get(m.label, 0), n)
                    continue
            exact[m.label] = exact.get(m.label, 0) + n
            if m.exact >= 2 and not m.side:     # "two upper doors and one lower door": 3
                plural_seen[key] = plural_seen.get(key, 0) + m.exact
        elif m.lower is not None:
            n = m.lower
            # "handles on every door", "each with its own handle": one per governing part
            if m.dist_of is not None and m.dist_of in base:
                exact[m.label] = exact.get(m.label, 0) + base[m.dist_of]
                continue
            lower[m.label] = max(lower.get(m.label, 0), n)
    for lab in zero:
        exact.setdefault(lab, 0)
    lower = {k: v for k, v in lower.items() if k not in exact}
    return exact, lower


def _joint_types(motion_links: list[tuple[frozenset, str, bool]],
                 counts: dict[str, int]) -> dict[str, list[str]]:
    """Acceptable joint types per countable label from its motion links: links said with "or"
    widen the choice, others narrow it (or widen it where they contradict); none for a label
    asked for zero times."""
    countable = set(vocab.COUNTABLE_LABELS)
    joint: dict[str, set] = {}
    for types, label, is_or in motion_links:
        if label not in countable:
            continue
        if label in joint and is_or:
            joint[label] = joint[label] | set(types)
        elif label in joint:
            both = joint[label] & set(types)
            joint[label] = both if both else joint[label] | set(types)
        else:
            joint[label] = set(types)
    return {k: sorted(v) for k, v in joint.items() if counts.get(k, 1) != 0}


# Everyday names that say which part an object has ("a swivel flash drive" has a swivel cap).
IMPLIED_PARTS = {
    "swivel usb stick": ("cap", "revolute"), "swivel flash drive": ("cap", "revolute"),
    "screw-top bottle": ("cap", "screw"), "flip-top bottle": ("lid", "revolute"),
}
# ... of one category: a front-loading washer is loaded through its door, a top loader
# through its lid (the procedural washers are built so), unless the prompt names either.
IMPLIED_BY_CATEGORY = {
    "WashingMachine": (
        (("front-loading", "front loading", "front-loader", "front loader", "front-load"),
         ("door", "revolute")),
        (("top-loading", "top loading", "top-loader", "top loader", "top-load"),
         ("lid", "revolute"))),
}
# A microwave's door hangs on its left side (the viewer's left) and swings open sideways,
# as the data's side-hinged ovens do, and a dishwasher's drops down, hinged at the bottom,
# as most of the data's ovens' do, unless the prompt says anything of hinges or opening:
# category -> ((names, hinge side, opening), ...).
HINGED_NAMES = {"Oven": ((("microwave",), "left", "sideways"),
                         (("dishwasher", "dish washer"), "bottom", "down"))}


# categories whose one door covers the whole front in the data (model/data/synth: every safe,
# oven and washer door is in the middle of its face); "on the left" can only say its hinge
FULL_FRONT_DOOR = ("Safe", "WashingMachine", "Oven")


def _side_as_hinge(out: ExpectedStructure) -> None:
    """"A safe with a door on the right": the only lateral fact a full-front door has is its
    hinge side, so a lone door stated on the left or right of such a category (``hpos``, no
    hinge or vertical opening stated, no other part placed left or right) is hinged on that
    side. Read as a position it made the door a strip on half the front, the rest open."""
    door = out.spatial.get("door") or {}
    side = door.get("hpos") or []
    if out.category not in FULL_FRONT_DOOR or out.counts.get("door") != 1 \
            or side not in (["left"], ["right"]) or door.get("hinge") \
            or set(door.get("opens") or []) - {"sideways"} \
            or any(f.get("hpos") for lab, f in out.spatial.items() if lab != "door"):
        return
    rest = {k: v for k, v in door.items() if k != "hpos"}
    out.spatial["door"] = {**rest, "hinge": list(side), "opens": ["sideways"]}


def _tidy(out: ExpectedStructure, text: str) -> None:
    """Category-specific readings and tidy spatial facts."""
    low = text.lower()
    for name, (lab, jt) in IMPLIED_PARTS.items():
        if name in low and lab not in out.counts and lab not in out.min_counts:
            out.counts[lab] = 1
            out.joint_types.setdefault(lab, [jt])
    named = set(out.counts) | set(out.min_counts)
    for names, (lab, jt) in IMPLIED_BY_CATEGORY.get(out.category, ()):
        if any(n in low for n in names) and not named & {"door", "lid"}:
            out.counts[lab] = 1
            out.joint_types.setdefault(lab, [jt])
            break
    for names, side, opens in HINGED_NAMES.get(out.category, ()):
        if not any(n in low for n in names) or out.counts.get("door", 1) != 1 \
                or "lid" in named:
            continue
        if "door" not in named:
            out.counts["door"] = 1
            out.joint_types.setdefault("door", ["revolute"])
        door = out.spatial.get("door", {})
        said = any(w in low for w in ("hinge", "open", "swing", "drop", "flap", "pull-down"))
        if not (door.get("hinge") or door.get("opens") or said):
            out.spatial["door"] = {**door, "hinge": [side], "opens": [opens]}
        break
    _side_as_hinge(out)
    if out.category == "USB" and "lid" in (set(out.counts) | set(out.min_counts)) \
            and "cap" not in out.counts:          # a USB stick's cover is its cap
        _relabel(out, "lid", "cap")
    if out.category == "Bottle" and out.joint_types.get("cap") == ["revolute"] \
            and "lid" not in out.counts:          # a bottle's hinged "cap" is a flip lid
        _relabel(out, "cap", "lid")
    if out.category == "Bottle" and out.joint_types.get("lid") == ["screw"] \
            and "cap" not in out.counts:          # a lid that twists off is a screw cap
        _relabel(out, "lid", "cap")
    _side_columns(out, low)
    for facts in out.spatial.values():
        h = facts.get("hinge")
        if h and "side" in h and len(h) > 1:
            facts["hinge"] = [x for x in h if x != "side"]
        if "rows" in facts and "columns" in facts and "layout" not in facts:
            R, C = facts["rows"], facts["columns"]
            facts["layout"] = "grid" if R > 1 and C > 1 else ("row" if R == 1 else "column")
    for lab, facts in list(out.spatial.items()):
        if out.counts.get(lab) == 1 and facts.get("layout") in ("row", "column") \
                and "rows" not in facts and "columns" not in facts:
            del facts["layout"]        # "one drawer across the top": no row of one; "a
            # stacked washer with a door": no column of one
        # "two doors side by side and a drawer above each door": as many above a row, a row;
        # "two doors and a drawer below each door" (or "below each of its two doors"): one
        # under each, so both side by side
        other = (facts.get("above") or facts.get("below") or [None])[0]
        theirs = out.spatial.get(other) or {}
        row = theirs.get("layout") == "row"
        each = other is not None and re.search(
            rf"\b(?:above|below|under|beneath|underneath|over) (?:each|every) "
            rf"(?:of (?:the|its|their) (?:[a-z0-9]+ )?)?{other}", low)
        if each and out.counts.get(other, 0) >= 2 and \
                not (facts.keys() | theirs.keys()) & ARRANGEMENT_KEYS:
            row = True
            out.spatial.setdefault(other, {})["layout"] = "row"
        if row and "layout" not in facts and out.counts.get(lab, 0) >= 2 \
                and out.counts.get(lab) == out.counts.get(other):
            facts["layout"] = "row"
        # "drawers in a 2 x 3 grid": as many as the grid holds, when nothing else counts them
        if lab not in out.counts and "rows" in facts and "columns" in facts:
            out.counts[lab] = int(facts["rows"]) * int(facts["columns"])
            out.min_counts.pop(lab, None)


def _side_columns(out: ExpectedStructure, low: str) -> None:
    """"three drawers on the left and three on the right" or "3 drawers on each side": two
    columns of three (the six had been made one column across the front; "two doors on the
    left and two on the right" four full-width strips). Only equal counts of two or more,
    and only where nothing else arranges those parts."""
    for lab in ("drawer", "door"):
        facts = out.spatial.get(lab) or {}
        if sorted(facts.get("hpos") or []) != ["left", "right"] \
                or facts.keys() & ARRANGEMENT_KEYS:
            continue
        noun = rf"(?:[a-z-]+ )?{vocab.plural(lab)}"
        sides = r"on the (left|right)(?: side)?"
        m = re.search(rf"\b{_N} {noun} {sides},? and {_N}(?: {noun})? {sides}", low)
        each = re.search(rf"\b{_N} {noun} on (?:each|either|both) sides?\b", low)
        if m and {m.group(2), m.group(4)} == {"left", "right"} and \
                _num(m.group(1)) == _num(m.group(3)):
            n = _num(m.group(1))
        elif each:
            n = _num(each.group(1))
        else:
            continue
        if n >= 2 and out.counts.get(lab) == 2 * n:
            del facts["hpos"]
            facts.update(layout="grid", rows=n, columns=2)


def _relabel(out: ExpectedStructure, a: str, b: str) -> None:
    for table in (out.counts, out.min_counts, out.joint_types, out.spatial):
        if a in table:
            table[b] = table.pop(a)
