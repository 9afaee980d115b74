"""The parts a text prompt states, held during decoding (docs/structure.md, "Counts the prompt
states").

The articulation transformer reads a prompt through MiniLM and its cross-attention, and it
miscounts: "three drawers" often decodes as one. Where a prompt states its parts outright
("three drawers and a door", "a 3x4 keypad", "each drawer has a handle", "a screw cap"), the
rule-based reader :func:`model.data.prompt_parse.parse_prompt` gives those counts, joint
types and hinge sides exactly, and decoding is held to them through structure control
(``decode(structure=...)``). The network still chooses everything the prompt leaves open: the
category when the prompt does not name one, the count of every part it does not mention, all
boxes, joints and shapes. A prompt that states no count, or counts this model's categories
cannot hold, decodes freely, as without this step; one that names its category keeps it,
without the parts the category lacks.
"""
from __future__ import annotations

import logging
from collections import Counter
from typing import Iterable, Optional

from model.data.expected_structure import RELATION_KEYS

log = logging.getLogger(__name__)

# A person's word for a part that a category calls otherwise: a safe's "knob" is its dial, an
# oven's "dials" are its knobs, a cabinet's "knobs" are its handles (pulls).
CATEGORY_SYNONYMS: dict[str, dict[str, str]] = {
    "Safe": {"knob": "dial"},
    "Oven": {"dial": "knob"},
    "WashingMachine": {"knob": "dial"},
    "StorageFurniture": {"knob": "handle"},
}


def stated_counts(expected) -> bool:
    """Whether a parsed prompt (``ExpectedStructure``) fixes the count of any part but the
    body, or bounds it from below ("a cabinet with doors": at least two; the network alone
    made one with every seed 0-3): only then is there something to hold decoding to."""
    return any(lab != "body" for lab in (*expected.counts, *expected.min_counts))


def structure_for(expected, category: str, labels: Iterable[str],
                  open_counts: Optional[dict] = None, clamp: int = 0) -> Optional[dict]:
    """A parsed prompt -> the structure dict (``model.core.structure.parse_structure`` form)
    that holds one category's decoding to what the prompt states, or None when the prompt
    names a part this category does not have.

    Stated counts are exact, a single stated joint type the label can take is forced, and
    stated hinge sides of doors are kept. A counted part that can only hang on one kind of
    host (a safe's buttons on its door) gets that host too, at least one of it. Every other
    part label of the category is left to the network: its count in ``open_counts`` (what
    the network's own decoding of the prompt made, within the label's training maximum; at
    least a stated lower bound such as "drawers"), or ``"auto"`` without it (a stated lower
    bound is then the count: "a keypad" is at least two buttons); a label every training
    object of the category has (``STRUCTURE_REQUIRED``: an oven's door) at least one.
    Handles stay ``"auto"``: they follow their doors and drawers. ``clamp`` (> 0): stated
    counts above a label's training maximum, or above ``clamp``, are held at the smaller of
    the two, and parts hung on other parts are cut until their hosts hold them
    (``_within_hosts``).
    """
    from model.articulation.structure_control import (HINGED_LABELS, STRUCTURE_EXCLUSIVE,
                                                      STRUCTURE_GRAMMAR, STRUCTURE_REQUIRED)
    from model.core.structure import HINGE_SIDES
    from model.data.prompt_spatial import CONTROLS

    grammar = STRUCTURE_GRAMMAR[category]
    have = set(labels) & set(grammar)
    rename = CATEGORY_SYNONYMS.get(category, {})

    def own(lab: str) -> str:
        return _own_label(category, lab, have)

    out: dict = {"category": category}
    out.update({lab: "auto" for lab in sorted(have - {"body"})})
    lows = {own(lab): int(n) for lab, n in expected.min_counts.items()}
    for lab in have - {"body", "handle"}:
        if open_counts is not None or lab in lows:
            n = max(int((open_counts or {}).get(lab, 0)), lows.get(lab, 0))
            out[lab] = {"count": min(n, int(grammar[lab][2]))}
    counts: dict[str, int] = {}
    for lab, n in expected.counts.items():
        if lab != "body":
            counts[own(lab)] = counts.get(own(lab), 0) + int(n)
    for lab, n in counts.items():
        if lab not in have:
            if n == 0:
                continue
            return None
        if clamp:
            n = counts[lab] = min(n, int(grammar[lab][2]), clamp)
        req: dict = {"count": n}
        joints = expected.joint_types.get(lab) or expected.joint_types.get(
            next((k for k, v in rename.items() if v == lab), ""), [])
        if n > 0 and len(joints) == 1 and joints[0] in grammar[lab][1]:
            req["joint"] = joints[0]
        elif n > 0 and joints and not set(joints) & set(grammar[lab][1]):
            log.warning("%s %s: this model's %s parts move only as %s (its training data's); "
                        "the prompt's %s is not held", category, lab, lab,
                        "/".join(grammar[lab][1]), "/".join(joints))
        sides = _hinge_sides(expected, lab, n, HINGE_SIDES) if lab in HINGED_LABELS else None
        if sides and req.get("joint", "revolute") == "revolute":
            req["hinge"] = sides
        out[lab] = req
    # a count the prompt gives more of one control than the model makes, which the network's
    # own reading put on another control the prompt does not name, is not that control's:
    # "a microwave with a door and six buttons" read as six knobs, to go with three buttons
    over = {int(expected.counts[lab]) for lab in expected.counts
            if own(lab) in counts and int(expected.counts[lab]) > counts[own(lab)]}
    for lab in CONTROLS:
        if over and lab in have and lab not in counts and lab not in lows \
                and int((open_counts or {}).get(lab, 0)) in over:
            out[lab] = {"count": 0}
    for a, b in STRUCTURE_EXCLUSIVE.get(category, ()):     # a stated lid: no door
        for lab, other in ((a, b), (b, a)):
            if counts.get(lab, 0) > 0 and other not in counts and other in out:
                out[other] = {"count": 0}
    # a part every object of the data has, left to the network, is there: "a dishwasher with
    # two racks" had been decoded with no door (an "auto" one too, when at most one is made)
    for lab in STRUCTURE_REQUIRED.get(category, ()):
        if lab not in counts and lab in have and (out.get(lab) == {"count": 0} or (
                out.get(lab) == "auto" and int(grammar[lab][2]) == 1)):
            out[lab] = {"count": 1}
    for lab, n in counts.items():
        hosts = grammar[lab][0] if lab in have else ()
        if n > 0 and len(hosts) == 1 and hosts[0] != "body" and out.get(hosts[0]) == "auto":
            out[hosts[0]] = {"count": max(1, int(expected.min_counts.get(hosts[0], 1)))}
    if clamp:
        _within_hosts(out, grammar, set(counts), clamp)
    return out


def _within_hosts(out: dict, grammar: dict, stated: set, most: int) -> None:
    """Exact counts of parts that hang on other parts (a safe's buttons and dial on its door)
    cut until the hosts hold them, ``most`` each: the labels the prompt does not count
    first, then the largest ("a safe with 24 buttons": 16 held buttons and the network's
    dial on one door had ended decoding a button short)."""
    def exact(lab: str) -> int:
        req = out.get(lab)
        return int(req["count"]) if isinstance(req, dict) and req.get("count") != "auto" else 0
    for hosts in {grammar[lab][0] for lab in out if lab in grammar} - {(), ("body",)}:
        labs = [lab for lab in out if lab in grammar and grammar[lab][0] == hosts]
        room = most * sum(exact(h) for h in hosts)
        while sum(exact(lab) for lab in labs) > room:
            lab = max(labs, key=lambda x: (exact(x) > 0 and x not in stated, exact(x)))
            out[lab]["count"] = exact(lab) - 1


def _own_label(category: str, lab: str, have) -> str:
    """A person's word for a part (``lab``) as ``category`` calls it (CATEGORY_SYNONYMS),
    where the category has no part of that name (``have``: the labels it has)."""
    other = CATEGORY_SYNONYMS.get(category, {}).get(lab)
    return other if lab not in have and other in have else lab


def spatial_for(spatial: Optional[dict], category: str) -> Optional[dict]:
    """A parsed prompt's spatial facts (label -> facts) in ``category``'s part names, as
    :func:`structure_for` names its counts: "a knob on the right" of a washer is about its
    dial. None when there are none."""
    from model.articulation.structure_control import STRUCTURE_GRAMMAR

    if not spatial:
        return None
    have = set(STRUCTURE_GRAMMAR.get(category, ()))
    out: dict = {}
    for lab, facts in spatial.items():
        mine = dict(facts)
        for key in RELATION_KEYS:
            if key in mine:
                mine[key] = sorted({_own_label(category, o, have) for o in mine[key]})
        out.setdefault(_own_label(category, lab, have), {}).update(mine)
    return out


def in_category_names(expected, category: Optional[str]):
    """A parsed or annotated structure (``ExpectedStructure``) with its part words in
    ``category``'s part names (CATEGORY_SYNONYMS, where the category has no part of that
    name): what a "dresser with eight knobs" asks of a storage cabinet is eight handles.
    The structure itself when the category is unknown or nothing is renamed."""
    from dataclasses import replace

    from model.articulation.structure_control import STRUCTURE_GRAMMAR

    have = set(STRUCTURE_GRAMMAR.get(category or "", ()))
    stated = set(expected.counts) | set(expected.min_counts) | set(expected.joint_types) \
        | set(expected.spatial)
    if not have or all(_own_label(category, lab, have) == lab for lab in stated):
        return expected

    def summed(table: dict) -> dict:
        out: dict[str, int] = {}
        for lab, n in table.items():
            mine = _own_label(category, lab, have)
            out[mine] = out.get(mine, 0) + int(n)
        return out

    joints: dict[str, list] = {}
    for lab, types in expected.joint_types.items():
        mine = _own_label(category, lab, have)
        joints[mine] = [t for t in joints[mine] if t in types] if mine in joints else list(types)
    return replace(expected, counts=summed(expected.counts),
                   min_counts=summed(expected.min_counts), joint_types=joints,
                   spatial=spatial_for(expected.spatial, category) or {})


OPENS_TO_HINGE = {"down": "bottom", "up": "top"}


def _hinge_sides(expected, lab: str, count: int, allowed) -> Optional[list]:
    """The hinge sides a prompt states for ``count`` parts of ``lab`` (one for all, or one
    per part), when every one is a side structure control takes. A door stated to open
    downwards ("a drop-down flap") is hinged at the bottom, one that opens upwards ("a flap
    that lifts up") at the top."""
    facts = expected.spatial.get(lab) or {}
    sides = facts.get("hinge")
    opens = facts.get("opens") or []
    if not sides and lab == "door" and opens and all(o in OPENS_TO_HINGE for o in opens):
        sides = [OPENS_TO_HINGE[o] for o in opens]
    if not sides or count <= 0:
        return None
    sides = [sides] if isinstance(sides, str) else list(sides)
    if not all(s in allowed for s in sides) or len(sides) not in (1, count):
        return None
    return sides


def resolve_prompt_structure(decoder, expected, categories: list[str], *, max_nodes: int,
                             max_children: int, own_reading=None):
    """The first of ``categories`` (in order of preference) whose structure for the parsed
    prompt this decoder can produce -> (structure dict, StructurePlan); where none can and the
    first is the category the prompt names, that category's structure without the parts it
    lacks (with a warning); else (None, None) (the prompt then decodes freely).
    ``own_reading``: the network's own decoding of the prompt (a DecodedTree); the parts the
    prompt leaves open keep its counts where its category is the one held, else they are
    ``"auto"``."""
    labels_of: dict[str, set] = {}
    for cat, lab in zip(decoder.table_categories, decoder.table_labels):
        labels_of.setdefault(cat, set()).add(lab)
    why = []
    # as stated first; then with counts beyond what the model was trained on held at its
    # maximum ("seven buttons" on a washer that had at most five), so that the rest of the
    # prompt (its lid, the hinge side) is still held
    for clamp in (0, max_children):
        for cat in categories:
            tries = [None]
            if own_reading is not None and own_reading.category == cat:
                tries.insert(0, Counter(own_reading.labels))
            for open_counts in tries:
                spec = structure_for(expected, cat, labels_of.get(cat, ()), open_counts,
                                     clamp)
                if spec is None:
                    why.append(f"{cat}: a stated part is not one of its parts")
                    break
                try:
                    plan = decoder.resolve_structure(spec, max_nodes=max_nodes,
                                                     max_children=max_children)
                except ValueError as e:
                    why.append(f"{cat}: {e}")
                    continue
                if clamp:
                    log.warning("the prompt asks for more parts than the model makes (%s); "
                                "holding %s", "; ".join(dict.fromkeys(why)), spec)
                return spec, plan
    named = expected.category
    if named is not None and categories and categories[0] == named:
        # the category the prompt names, without the parts it lacks ("a jewelry box with a
        # lid" had been decoded freely: a bottle), rather than another category
        have = labels_of.get(named, set())
        missing = sorted({lab for lab, n in expected.counts.items() if n and lab != "body"
                          and _own_label(named, lab, have) not in have}
                         | {lab for lab in expected.min_counts
                            if _own_label(named, lab, have) not in have})
        if missing:
            kept = _without(expected, missing)
            spec, plan = resolve_prompt_structure(decoder, kept, [named], max_nodes=max_nodes,
                                                  max_children=max_children,
                                                  own_reading=own_reading)
            if spec is not None:
                log.warning("this model's %s has no %s part (its training data's); the "
                            "prompt's %s not made", named, "/".join(missing), "/".join(missing))
                return spec, plan
    log.info("the prompt's stated parts are not held (%s); decoding freely", "; ".join(why))
    return None, None


FRONT_PARTS = ("door", "drawer", "tray")     # what a cabinet has on its front


def lids_as_front_doors(expected):
    """A chest with a lid (a storage-furniture prompt that states lids and no part on the
    front: "a chest with a lid hinged at the back", "a toy box") -> (the prompt read as the
    cabinet that turns into it, True): each lid a revolute front door hinged at the top
    (``LID_TO_DOOR_HINGE``: a lid hinged at the back), side by side when there are more;
    the pipeline turns the object front up after meshing (model.refine.orient). Any other
    parse -> (itself, False): a chest with a lid and drawers keeps its drawers, without the
    lid (the data has no lid on storage furniture)."""
    from dataclasses import replace

    from model.refine.orient import LID_TO_DOOR_HINGE

    lids = int(expected.counts.get("lid", 0)) or int(expected.min_counts.get("lid", 0))
    front = any(expected.counts.get(lab, 0) or expected.min_counts.get(lab, 0)
                for lab in FRONT_PARTS)
    if expected.category != "StorageFurniture" or lids <= 0 or front:
        return expected, False

    def moved(table: dict) -> dict:
        out = {k: v for k, v in table.items() if k != "lid"}
        if "lid" in table:
            out["door"] = table["lid"]
        return out

    facts = dict(expected.spatial.get("lid") or {})
    sides = [LID_TO_DOOR_HINGE.get(s) for s in facts.pop("hinge", None) or ["back"]]
    facts.pop("opens", None)
    facts["hinge"] = [s for s in sides if s] or ["top"]
    if lids > 1:
        facts.setdefault("layout", "row")
    spatial = {k: v for k, v in expected.spatial.items() if k not in ("lid", "door")}
    spatial["door"] = facts
    return replace(expected, counts=moved(expected.counts),
                   min_counts=moved(expected.min_counts),
                   joint_types={**moved(expected.joint_types), "door": ["revolute"]},
                   spatial=spatial), True


def front_door_text(expected) -> str:
    """What the text model reads for a chest with a lid, once :func:`lids_as_front_doors` made
    its lids front doors (``expected``): the cabinet it is decoded as, in the words of the
    data's descriptions ("A cabinet with a door hinged at the top that opens upward."). The
    network never saw a lid on storage furniture: "a chest with a lid" had decoded a 20 cm
    door lying flat in the cabinet's bottom."""
    from model.data import vocab

    n = int(expected.counts.get("door", 0)) or int(expected.min_counts.get("door", 1))
    sides = (expected.spatial.get("door") or {}).get("hinge") or ["top"]
    where = "at the top" if set(sides) == {"top"} else \
        "at the bottom" if set(sides) == {"bottom"} else f"on the {sides[0]}"
    doors = "a door" if n == 1 else f"{vocab.number_word(n)} doors"
    verb = "opens" if n == 1 else "open"
    motion = {"at the top": f" that {verb} upward", "at the bottom": f" that {verb} downward"}
    return f"A cabinet with {doors} hinged {where}{motion.get(where, '')}."


def _without(expected, labels: list[str]):
    """A copy of a parsed prompt (ExpectedStructure) without anything it says of ``labels``."""
    import copy

    out = copy.deepcopy(expected)
    for lab in labels:
        for facts in (out.counts, out.min_counts, out.joint_types, out.spatial):
            facts.pop(lab, None)
    return out
