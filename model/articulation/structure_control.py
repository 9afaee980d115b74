"""Structure control (docs/structure.md): what the training data's generator builds, and a
requested structure checked against it and against a model's label table.

    plan = resolve_structure({"drawer": 3, "door": {"count": 1, "hinge": "left"}},
                             am.table_categories, am.table_labels, am.cfg.plan_max_count)
    # -> StructurePlan, or ValueError saying why no category of the model can have it

``ArticulationModel.resolve_structure`` is this for its own label table; decoding under a plan
is ``_grow_structured`` in model.articulation.decode, which sets asked hinge sides with
``set_hinge``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from model.core.structure import hinge_side

# What the training data's generator builds (docs/data.md, "The generator"), per category and
# part label: the labels a part can be attached to, its joint types, the most parts of the
# label one object has, and (doors) the hinge sides a structure may ask for. Structure control
# (decode(structure=...)) holds decoding to it; checked against model.data.synth by
# test/test_structure_control.py.
_BODY = ("body",)
STRUCTURE_GRAMMAR: dict[str, dict[str, tuple]] = {
    "StorageFurniture": {"body": ((), ("fixed",), 1),
                         "door": (_BODY, ("revolute",), 18),
                         "drawer": (_BODY, ("prismatic",), 20),
                         "handle": (("door", "drawer"), ("fixed",), 40)},
    "Safe": {"body": ((), ("fixed",), 1),
             "door": (_BODY, ("revolute",), 2),
             "button": (("door",), ("prismatic",), 24),
             "dial": (("door",), ("continuous",), 2),
             "handle": (("door",), ("fixed", "revolute"), 2)},
    "Oven": {"body": ((), ("fixed",), 1),
             "door": (_BODY, ("revolute",), 1),
             "drawer": (_BODY, ("prismatic",), 1),
             "knob": (_BODY, ("revolute", "continuous"), 6),
             "button": (_BODY, ("prismatic",), 3),
             "tray": (_BODY, ("prismatic",), 2),
             "handle": (("door", "drawer"), ("fixed",), 2)},
    "WashingMachine": {"body": ((), ("fixed",), 1),
                       "door": (_BODY, ("revolute",), 1),
                       "lid": (_BODY, ("revolute",), 1),
                       "drawer": (_BODY, ("prismatic",), 1),
                       "dial": (_BODY, ("continuous",), 2),
                       "button": (_BODY, ("prismatic",), 5),
                       "handle": (("door", "drawer", "lid"), ("fixed",), 3)},
    "Bottle": {"body": ((), ("fixed",), 1),
               "cap": (_BODY, ("screw",), 1),
               "lid": (_BODY, ("revolute",), 1)},
    "USB": {"body": ((), ("fixed",), 1),
            "cap": (_BODY, ("revolute", "prismatic"), 1)},
}
# labels one object never has together (a bottle has a screw cap or a flip lid; a washing
# machine is a front loader with a door and maybe a drawer, or a top loader with a lid)
STRUCTURE_EXCLUSIVE = {"Bottle": [("cap", "lid")],
                       "WashingMachine": [("door", "lid"), ("drawer", "lid")]}
# labels every object of the category has in the data (an oven or safe is closed by a door)
STRUCTURE_REQUIRED = {"Oven": ("door",), "Safe": ("door",)}
HINGED_LABELS = ("door",)   # labels a structure may give hinge sides


@dataclass
class StructurePlan:
    """A structure checked against the model (``ArticulationModel.resolve_structure``):
    ``categories`` the object may be (decoding picks among them by the root's c_s);
    ``counts`` label -> exact count (labels not in it and not in ``auto`` are not produced);
    ``auto`` labels whose count the model decides; ``joints`` label -> joint type;
    ``hinges`` label -> hinge side per part (in decoding order)."""
    categories: list[str]
    counts: dict[str, int]
    auto: frozenset
    joints: dict[str, str]
    hinges: dict[str, tuple]

    def allowed(self, label: str) -> bool:
        return label in self.auto or self.counts.get(label, 0) > 0


def set_hinge(token: np.ndarray, side: str) -> np.ndarray:
    """A copy of a revolute part's token whose joint is hinged on ``side`` of the part's box
    and opens towards the front (+x), as the training data's doors do. The predicted joint is
    kept when it already is on that side, mirrored through the box centre when it is on the
    opposite edge (left <-> right, top <-> bottom), and rebuilt on that edge of the box at the
    predicted origin's depth otherwise; the joint limits stay the predicted ones."""
    tok = np.array(token, dtype=np.float64)
    have = hinge_side(tok)
    if have == side:
        return tok
    c, s = tok[3:6], tok[0:3]
    opposite = {"left": "right", "right": "left", "top": "bottom", "bottom": "top"}
    if have == opposite[side]:
        k = 1 if side in ("left", "right") else 2
        tok[6 + k] = 2 * c[k] - tok[6 + k]
        m = np.ones(3)
        m[k] = -1
        tok[9:12] = -m * tok[9:12]          # an axis is a pseudovector under reflection
        return tok
    x = tok[6]
    if side == "left":
        tok[6:9], tok[9:12] = (x, c[1] - s[1] / 2, c[2]), (0.0, 0.0, -1.0)
    elif side == "right":
        tok[6:9], tok[9:12] = (x, c[1] + s[1] / 2, c[2]), (0.0, 0.0, 1.0)
    elif side == "bottom":
        tok[6:9], tok[9:12] = (x, c[1], c[2] - s[2] / 2), (0.0, 1.0, 0.0)
    else:
        tok[6:9], tok[9:12] = (x, c[1], c[2] + s[2] / 2), (0.0, -1.0, 0.0)
    return tok


def resolve_structure(spec, table_categories: list[str], table_labels: list[str],
                      plan_max_count: Optional[int], *, max_nodes: int = 32,
                      max_children: int = 16) -> StructurePlan:
    """``ArticulationModel.resolve_structure`` for a label table (``table_categories`` and
    ``table_labels``, one entry per (category, label) pair the model was trained on) and the
    plan head's largest count (None: 20)."""
    from model.core.structure import GenerationError, parse_structure
    try:
        spec = parse_structure(spec)
    except GenerationError as e:
        raise ValueError(str(e)) from None
    known = set(table_labels)
    unknown = sorted(set(spec.parts) - known)
    if unknown:
        raise ValueError(f"structure: unknown part label(s) {unknown}; this model knows "
                         f"{sorted(known)}")
    cats = sorted(set(table_categories) & set(STRUCTURE_GRAMMAR))
    if spec.category is not None:
        match = [c for c in cats if c.lower() == spec.category.lower()]
        if not match:
            raise ValueError(f"structure: unknown category {spec.category!r}; this model "
                             f"knows {cats}")
        cats = match
    plans, why = [], {}
    for cat in cats:
        have = {lab for c, lab in zip(table_categories, table_labels) if c == cat}
        try:
            plans.append(_plan_for(cat, spec, have, int(plan_max_count or 20), max_nodes,
                                   max_children))
        except ValueError as e:
            why[cat] = str(e)
    if not plans:
        if len(why) == 1:
            raise ValueError(f"structure: {next(iter(why.values()))}")
        reasons = "; ".join(f"{c}: {m}" for c, m in why.items())
        raise ValueError(f"structure: no category of this model can have these parts "
                         f"({reasons})")
    first = plans[0]
    return StructurePlan(categories=[c for c in cats if c not in why], counts=first.counts,
                         auto=first.auto, joints=first.joints, hinges=first.hinges)


def _plan_for(cat: str, spec, have: set, cap: int, max_nodes: int,
              max_children: int) -> StructurePlan:
    """Check a parsed structure against one category whose model labels are ``have``, at most
    ``cap`` parts of a label (ValueError says why not)."""
    grammar = STRUCTURE_GRAMMAR[cat]
    counts: dict[str, int] = {"body": 1}
    auto, joints, hinges = set(), {}, {}
    for lab, req in spec.parts.items():
        if lab not in grammar or lab not in have:
            if req.count == 0:
                continue
            raise ValueError(f"a {cat} has no {lab!r} parts (it has "
                             f"{sorted(set(grammar) & have)})")
        hosts, jts, most = grammar[lab]
        if lab == "body":
            if req.count not in (None, 1) or (req.joint not in (None, "fixed")) or req.hinge:
                raise ValueError("the body is the one fixed root part: body must be 1 "
                                 "(fixed, no hinge)")
            continue
        if req.count is None:
            auto.add(lab)
        else:
            most = min(most, cap)
            if req.count > most:
                raise ValueError(f"{req.count} {lab} parts: at most {most} per {cat} are "
                                 f"supported (the training data's range)")
            counts[lab] = req.count
        if req.hinge:
            if lab not in HINGED_LABELS:
                raise ValueError(f"hinge sides are supported for {list(HINGED_LABELS)}, "
                                 f"not {lab!r}")
            hinges[lab] = tuple(req.hinge)
        if req.joint is not None:
            if req.joint not in jts:
                raise ValueError(f"a {cat} {lab} moves with a {' or '.join(jts)} joint, not "
                                 f"{req.joint}")
            joints[lab] = req.joint
    if "handle" in grammar and "handle" in have and "handle" not in spec.parts:
        auto.add("handle")          # handles come with their doors / drawers by default
    _check_counts(cat, counts, max_nodes, max_children)
    return StructurePlan([cat], counts, frozenset(auto), joints, hinges)


def _check_counts(cat: str, counts: dict[str, int], max_nodes: int, max_children: int) -> None:
    """The exact counts of one category's plan fit together and within the node caps
    (ValueError says why not)."""
    grammar = STRUCTURE_GRAMMAR[cat]
    for a, b in STRUCTURE_EXCLUSIVE.get(cat, []):
        if counts.get(a, 0) > 0 and counts.get(b, 0) > 0:
            raise ValueError(f"a {cat} has either {a} or {b} parts, not both")
    for lab, n in counts.items():
        hosts = grammar[lab][0]
        if n > 0 and hosts and not any(counts.get(h, 0) > 0 for h in hosts):
            raise ValueError(f"{lab} parts attach to a {' or '.join(hosts)}; ask for at "
                             f"least one with an exact count")
        only_body = hosts == _BODY
        if only_body and n > max_children:
            raise ValueError(f"{n} {lab} parts on the body: at most max_children="
                             f"{max_children} children per part")
    for hosts in {grammar[lab][0] for lab in counts} - {(), _BODY}:   # a safe's door's keys
        on = sum(n for lab, n in counts.items() if grammar[lab][0] == hosts)
        room = max_children * sum(counts.get(h, 0) for h in hosts)
        if on > room:
            raise ValueError(f"{on} parts on {' or '.join(hosts)} parts: at most "
                             f"max_children={max_children} children per part")
    on_body = sum(n for lab, n in counts.items() if grammar[lab][0] == _BODY)
    if on_body > max_children:
        raise ValueError(f"{on_body} parts on the body: at most max_children={max_children} "
                         f"children per part")
    total = sum(counts.values())
    if total > max_nodes:
        raise ValueError(f"{total} parts (body included): at most max_nodes={max_nodes}")
