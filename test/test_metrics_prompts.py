"""Free-form prompt parser and the alignment check."""
from pathlib import Path

import pytest

from model.core import ArticulatedObject, Joint, JointType, Part
from model.metrics.alignment import (GeneratedStructure, alignment_of, check_alignment,
                                     summarise)
from model.data.prompt_parse import ExpectedStructure, parse_prompt

CASES = [
    # (prompt, category, exact counts, lower bounds, joint types)
    ("A dresser with three sliding drawers, each with a handle",
     "StorageFurniture", {"drawer": 3, "handle": 3}, {}, {"drawer": ["prismatic"]}),
    ("A tall wardrobe with a left door and a right door, both hinged.",
     "StorageFurniture", {"door": 2}, {}, {"door": ["revolute"]}),
    ("two doors, a left door and a right door", None, {"door": 2}, {}, {}),
    ("two drawers on the left and a drawer on the right", None, {"drawer": 3}, {}, {}),
    ("a three-drawer chest of drawers with no handles",
     "StorageFurniture", {"drawer": 3, "handle": 0}, {}, {}),
    ("A kitchen cabinet. It has two doors. The doors swing open. Below them are three drawers "
     "that pull out, and each drawer has a small knob.", "StorageFurniture",
     {"door": 2, "drawer": 3, "knob": 3}, {}, {"door": ["revolute"], "drawer": ["prismatic"]}),
    ("an oven with a door that drops down and 4 knobs", "Oven", {"door": 1, "knob": 4}, {},
     {"door": ["revolute"]}),
    ("A kitchen stove with a glass door. It has three control knobs that turn.", "Oven",
     {"door": 1, "knob": 3}, {}, {"knob": ["continuous", "revolute"]}),
    ("a safe with a keypad of buttons and a door hinged on the left", "Safe",
     {"door": 1}, {"button": 2}, {"door": ["revolute"]}),
    ("a compact safe with a combination dial that spins freely", "Safe", {"dial": 1}, {},
     {"dial": ["continuous"]}),
    ("a top-loading washer whose lid is hinged at the back", "WashingMachine", {"lid": 1},
     {}, {"lid": ["revolute"]}),
    ("laundry machine with a porthole door, a program dial and three push buttons",
     "WashingMachine", {"door": 1, "dial": 1, "button": 3}, {}, {"button": ["prismatic"]}),
    ("a bottle with a cap that twists off", "Bottle", {"cap": 1}, {}, {"cap": ["screw"]}),
    ("a thumb drive with a protective cap that slides off", "USB", {"cap": 1}, {},
     {"cap": ["prismatic"]}),
    ("a memory stick with a swivel cap", "USB", {"cap": 1}, {}, {"cap": ["revolute"]}),
    ("a nightstand with two pairs of doors", "StorageFurniture", {"door": 4}, {}, {}),
    ("a cupboard with a handle on every door and two doors", "StorageFurniture",
     {"handle": 2, "door": 2}, {}, {}),
    ("one knob per drawer and three drawers", None, {"knob": 3, "drawer": 3}, {}, {}),
    ("two doors and each drawer has a knob", None, {"door": 2}, {"drawer": 1, "knob": 1}, {}),
    ("a cabinet with drawers", "StorageFurniture", {}, {"drawer": 2}, {}),
    ("kitchen cupboard: two swinging doors, no drawers", "StorageFurniture",
     {"door": 2, "drawer": 0}, {}, {"door": ["revolute"]}),
    # "ones" names the part said last; a count split into groups is counted once
    ("a chest with one wide drawer and three small ones", "StorageFurniture",
     {"drawer": 4}, {}, {}),
    ("a dresser with five drawers: two small ones on top and three large drawers below",
     "StorageFurniture", {"drawer": 5}, {}, {}),
    ("A stove with four knobs. Two big ones and two small ones.", "Oven", {"knob": 4}, {}, {}),
    ("a cabinet with one door and one drawer, plus one door", "StorageFurniture",
     {"door": 2, "drawer": 1}, {}, {}),
    # bare singulars on distinct sides are as many parts; one side said twice is one
    ("Cabinet. Door on the left, door on the right, one drawer in the middle between them.",
     "StorageFurniture", {"door": 2, "drawer": 1}, {}, {}),
    ("a cabinet. The door is on the left. The door is on its left.", "StorageFurniture",
     {"door": 1}, {}, {}),
    # a number after "at least" or before "or more" is a lower bound
    ("a washer with at least four buttons and a door", "WashingMachine", {"door": 1},
     {"button": 4}, {}),
    ("a cabinet with three or more drawers and no fewer than 2 doors", "StorageFurniture", {},
     {"drawer": 3, "door": 2}, {}),
    # "each of its N parts": the N parts are counted as said, one per each of them
    ("a sideboard with a drawer over each of its two doors", "StorageFurniture",
     {"drawer": 2, "door": 2}, {}, {}),
    ("a cabinet with a knob on each of its three drawers", "StorageFurniture",
     {"knob": 3, "drawer": 3}, {}, {}),
    # a handle of a style is one part: "knob handles" had been one knob and the handles
    ("a dresser with four drawers with knob handles", "StorageFurniture", {"drawer": 4},
     {"handle": 2}, {}),
    ("a cabinet with two doors, each with a cup pull", "StorageFurniture",
     {"door": 2, "handle": 2}, {}, {}),
    # a category word before a part is a modifier: two doors, not one
    ("a fridge with a freezer door on top and a fridge door below", "StorageFurniture",
     {"door": 2}, {}, {}),
    ("an oven with an oven door", "Oven", {"door": 1}, {}, {}),
    # a spec list: "drawers: 4" is four drawers (had been at least two)
    ("Cabinet with drawers: 4. Doors: 2.", "StorageFurniture", {"drawer": 4, "door": 2}, {}, {}),
    ("oven - knobs: 4, buttons: 2, door: 1", "Oven", {"knob": 4, "button": 2, "door": 1}, {},
     {}),
    ("an entertainment center with two doors", "StorageFurniture", {"door": 2}, {}, {}),
]


@pytest.mark.parametrize("prompt,category,counts,lower,joints", CASES)
def test_parse_free_form(prompt, category, counts, lower, joints):
    e = parse_prompt(prompt)
    assert e.category == category
    assert e.counts == counts
    assert e.min_counts == lower
    assert e.joint_types == joints


@pytest.mark.parametrize("prompt,line", [
    # a grid gives the count when nothing else does; "N columns, M rows"
    ("low chest of drawers, drawers in a 2x3 grid", "StorageFurniture drawer=6 "
     "drawer.layout=grid drawer.rows=2 drawer.columns=3"),
    ("a safe with a keypad of ten buttons: 2 columns, 5 rows", "Safe button=10 "
     "button.rows=5 button.columns=2 button.layout=grid"),
    # one on each side / at each end is two; "a drawer above each door" one per door
    ("a washer with the dial in the middle and a button on each side of it",
     "WashingMachine button=2 dial=1 dial.hpos=middle"),
    ("a vanity with two doors side by side and a drawer above each door",
     "StorageFurniture door=2 drawer=2 door.layout=row drawer.above=door drawer.layout=row"),
    # right of a part: that part is on the left; a number in an adjective counts nothing
    ("a cabinet with a door, and two drawers stacked to the right of the door",
     "StorageFurniture door=1 drawer=2 drawer.layout=column drawer.hpos=right "
     "door.hpos=left"),
    ("a gun safe with a three-spoke handle", "Safe handle=1"),
    # rows without an article; an arrangement is of the plural part named before
    ("a toaster oven with a column of 6 buttons on the right",
     "Oven button=6 button.layout=column button.hpos=right"),
    ("Countertop oven. Two knobs below the door, side by side.",
     "Oven knob=2 door=1 knob.below=door knob.layout=row"),
    ("a range with six knobs across the front", "Oven knob=6 knob.layout=row"),
    ("a hutch with two doors up top", "StorageFurniture door=2 door.vpos=top"),
    # grids said as width and height, bare "3 by 3", stacks, "N rows with M per row"
    ("apothecary cabinet w/ 12 tiny drawers, 4 wide x 3 tall", "StorageFurniture drawer=12 "
     "drawer.layout=grid drawer.rows=3 drawer.columns=4"),
    ("a locker unit with 12 doors, four tall and three wide", "StorageFurniture door=12 "
     "door.layout=grid door.rows=4 door.columns=3"),
    ("medicine cabinet w/ 9 drawers arranged 3 by 3", "StorageFurniture drawer=9 "
     "drawer.layout=grid drawer.rows=3 drawer.columns=3"),
    ("two stacks of five drawers in a low cabinet", "StorageFurniture drawer=10 "
     "drawer.layout=grid drawer.rows=5 drawer.columns=2"),
    ("a cabinet, 3 rows with 3 drawers per row", "StorageFurniture drawer=9 "
     "drawer.layout=grid drawer.rows=3 drawer.columns=3"),
    ("a safe with a phone-style number pad", "Safe button=12 button.layout=grid "
     "button.rows=4 button.columns=3"),
    ("a cabinet 60 x 40 cm with two drawers", "StorageFurniture drawer=2"),
    ("tea chest w/ ten drawers: a top row of five and a bottom row of five",
     "StorageFurniture drawer=10 drawer.layout=grid drawer.rows=2 drawer.columns=5"),
    ("a big chest with six pairs of drawers side by side", "StorageFurniture drawer=12 "
     "drawer.layout=grid drawer.rows=6 drawer.columns=2"),
    # an upper and a lower tier: as many in each is two rows; otherwise counted in both
    ("a hutch with two upper doors and two lower doors", "StorageFurniture door=4 "
     "door.layout=grid door.rows=2 door.columns=2"),
    ("a hutch with 3 upper and 3 lower glass doors", "StorageFurniture door=6 "
     "door.layout=grid door.rows=2 door.columns=3"),
    ("a cabinet with two upper doors and one lower door", "StorageFurniture door=3 "
     "door.vpos=bottom/top"),
    ("a cabinet with two upper and one lower door", "StorageFurniture door=3 "
     "door.vpos=bottom/top"),
    ("a cabinet with two upper doors and two lower drawers", "StorageFurniture door=2 "
     "drawer=2 door.vpos=top drawer.vpos=bottom"),
    # double (French) doors are a pair side by side
    ("a gun safe with double doors", "Safe door=2 door.layout=row"),
    ("a double-door cabinet", "StorageFurniture door=2 door.layout=row"),
    # a name with "under-" places nothing
    ("an under-sink cabinet with two doors", "StorageFurniture door=2"),
    # the middle: "in the middle (of the door)", "top center"
    ("a safe, the combination dial sits in the middle of the door", "Safe dial=1 door=1 "
     "dial.hpos=middle"),
    ("a range with a row of five buttons at the top center", "Oven button=5 "
     "button.layout=row button.vpos=top button.hpos=middle"),
    ("a cabinet with a drawer in the middle row", "StorageFurniture drawer=1"),
    # a grid said after its part keeps the words after it ("... below the dial")
    ("a safe with a dial and six buttons in two rows of three below the dial",
     "Safe dial=1 button=6 button.layout=grid button.rows=2 button.columns=3 "
     "button.below=dial"),
    # a place said of a control panel is its controls' place, not the part named before
    ("a washer, door at the bottom, control panel at the top with two dials and six buttons",
     "WashingMachine door=1 dial=2 button=6 door.vpos=bottom dial.vpos=top button.vpos=top"),
    # the top of the object itself ("on top of the cabinet" stays a place on its top face)
    ("a cabinet with a drawer at the top of the cabinet and two doors below",
     "StorageFurniture drawer=1 door=2 drawer.vpos=top door.below=drawer"),
    ("a fridge-style cabinet with a door at the bottom of the unit", "StorageFurniture door=1 "
     "door.vpos=bottom"),
    # a relation said of an open shelf places the part the other way ("an open shelf below":
    # the drawer at the top; it had been read as the drawer at the bottom)
    ("a printer stand with a drawer and an open shelf below", "StorageFurniture drawer=1 "
     "drawer.vpos=top"),
    ("a nightstand with an open shelf above a drawer", "StorageFurniture drawer=1 "
     "drawer.vpos=bottom"),
    ("a cabinet with two doors and an open compartment below them", "StorageFurniture door=2 "
     "door.vpos=top"),
    # a row of several at the top over the rest: parts per row, top row first
    ("a dresser with two small drawers on top and three large drawers below",
     "StorageFurniture drawer=5 drawer.per_row=2/1/1/1"),
    ("a dresser with 3 drawers on top and 3 drawers side by side below",
     "StorageFurniture drawer=6 drawer.per_row=3/3"),
    ("a chest of drawers: five drawers, the top one split into two",
     "StorageFurniture drawer=6 drawer.per_row=2/1/1/1/1"),
    # the top tier said last, or as what it is on (had been all five on top, or nothing)
    ("a chest of drawers with 3 big drawers and 2 small drawers on top",
     "StorageFurniture drawer=5 drawer.per_row=2/1/1/1"),
    ("a dresser with 2 small drawers on top of 3 large ones",
     "StorageFurniture drawer=5 drawer.per_row=2/1/1/1"),
    ("a cabinet with a drawer on top of two doors", "StorageFurniture drawer=1 door=2 "
     "drawer.above=door"),
    # doors under a row of doors stand side by side; a count shared out between the tiers
    # ("four doors, two on top and two below" had been four full-width doors in a column)
    ("a cupboard with two doors on top and two doors at the bottom",
     "StorageFurniture door=4 door.per_row=2/2"),
    ("a tall pantry cabinet with four doors, two on top and two below",
     "StorageFurniture door=4 door.per_row=2/2"),
    ("a hutch with two doors above and two below", "StorageFurniture door=4 door.per_row=2/2"),
    ("a cabinet with three doors, one on top and two below",
     "StorageFurniture door=3 door.per_row=1/2"),
    ("a chest with five drawers, two on top and three below",
     "StorageFurniture drawer=5 drawer.per_row=2/1/1/1"),
    ("a cabinet with three drawers, one on top and two below side by side",
     "StorageFurniture drawer=3 drawer.per_row=1/2"),
    # "beside" / "next to" / "alongside" a part: side by side, either way round ("a drawer
    # beside a door" had been read as nothing, and laid out above it)
    ("a cabinet with a drawer beside a door", "StorageFurniture drawer=1 door=1 "
     "drawer.beside=door"),
    ("a cabinet with a door and a drawer next to it", "StorageFurniture door=1 drawer=1 "
     "drawer.beside=door"),
    ("a washer with a dial and three buttons alongside the dial", "WashingMachine dial=1 "
     "button=3 button.beside=dial"),
    ("a bank of lockers: three doors next to each other", "StorageFurniture door=3 "
     "door.layout=row"),
    # no column of one ("stacked" said of a washer-dryer stack)
    ("a stacked washer with a door hinged on the right", "WashingMachine door=1 "
     "door:revolute door.hinge=right"),
    # "N over M drawers" counts N + M (it had been M)
    ("a dresser with 3 over 3 drawers", "StorageFurniture drawer=6 drawer.layout=grid "
     "drawer.rows=2 drawer.columns=3"),
    ("a chest with two over three drawers", "StorageFurniture drawer=5 drawer.per_row=2/1/1/1"),
    ("a cabinet with 1 over 2 drawers", "StorageFurniture drawer=3 drawer.per_row=1/2"),
    # "over" before a part is "above" ("over 2 m tall" places nothing)
    ("a base cabinet with one drawer over two doors", "StorageFurniture drawer=1 door=2 "
     "drawer.above=door"),
    ("a cabinet over two metres tall with two doors", "StorageFurniture door=2"),
    # a number compound that names no part counts nothing ("4-digit" had been four dials);
    # an N-key keypad has N buttons
    ("a fireproof safe with a 4-digit combination dial", "Safe dial=1"),
    ("a safe with a 3-spoke handle", "Safe handle=1"),
    ("a wall safe with a 10-key keypad", "Safe button=10"),
    ("a safe with a keypad of 12 keys", "Safe button=12"),
    # "at each end" is two, one on each side, and multiplies nothing after it (the three
    # drawers had been read as three per door: six)
    ("a sideboard with a door at each end and three drawers in the middle",
     "StorageFurniture door=2 drawer=3 door.hpos=left/right drawer.hpos=middle"),
    # "a drawer below each door": one under each, so both side by side
    ("a wardrobe with two doors and a drawer below each door", "StorageFurniture door=2 "
     "drawer=2 drawer.below=door drawer.layout=row door.layout=row"),
    # a shoe rack is a cabinet, its "rack" no oven tray
    ("a shoe rack cabinet with three flip-down doors stacked", "StorageFurniture door=3 "
     "door:revolute door.opens=down door.layout=column"),
    # a flip cap is a hinged lid (it had been read as a cap, "a flip-top cap" as a cap and a lid)
    ("a squeeze bottle with a flip cap", "Bottle lid=1"),
    ("a bottle with a flip-top cap", "Bottle lid=1"),
    # a lid said to twist or screw off is the data's screw cap (it had been made a flip lid)
    ("a glass bottle with a twist-off lid", "Bottle cap=1 cap:screw"),
    ("a jar with a lid that unscrews", "Bottle cap=1 cap:screw"),
    # a count said straight before a place names the part said last (six drawers had been
    # read as three); a share of the count before it ("two on each side") or a restatement
    # ("two drawers, two at the bottom") adds none
    ("a wide dresser with three drawers on the left and three on the right",   # two columns
     "StorageFurniture drawer=6 drawer.layout=grid drawer.rows=3 drawer.columns=2"),
    ("a cabinet with 4 drawers on the left and 2 on the right",
     "StorageFurniture drawer=6 drawer.hpos=left/right"),
    ("a sideboard with two doors on the left and two on the right",
     "StorageFurniture door=4 door.layout=grid door.rows=2 door.columns=2"),
    ("a dresser with two drawers on top and three below",        # a row of two on top
     "StorageFurniture drawer=5 drawer.per_row=2/1/1/1"),
    ("a chest with four drawers, two on each side", "StorageFurniture drawer=4 "
     "drawer.hpos=left/right"),
    ("a cabinet with two doors and two drawers, two at the bottom", "StorageFurniture door=2 "
     "drawer=2 drawer.vpos=bottom"),
    ("a safe whose door opens to the left, with one combination dial and a six-button keypad "
     "laid out in two rows of three below the dial", "Safe dial=1 button=6 door=1 door:revolute "
     "button.layout=grid button.rows=2 button.columns=3 button.below=dial door.hinge=left "
     "door.opens=sideways"),
    # "above each of its three doors": one above each, in a row (read as a column at the top)
    ("a sideboard with a drawer above each of its three doors", "StorageFurniture drawer=3 "
     "door=3 drawer.above=door drawer.layout=row door.layout=row"),
    # a count on each side of the front is as many on both, in two columns (three had been
    # read); a share of the count said before it is not counted again
    ("a dresser with 3 drawers on each side", "StorageFurniture drawer=6 drawer.layout=grid "
     "drawer.rows=3 drawer.columns=2"),
    ("a chest with six drawers, three drawers on each side", "StorageFurniture drawer=6 "
     "drawer.layout=grid drawer.rows=3 drawer.columns=2"),
    ("a sideboard with two doors at each end and three drawers in the middle",
     "StorageFurniture door=4 drawer=3 door.hpos=left/right drawer.hpos=middle"),
    ("a chest with seven drawers, one on top and six below in two columns",
     "StorageFurniture drawer=7 drawer.per_row=1/2/2/2"),
    ("a cabinet with drawers: three on the right", "StorageFurniture drawer=3 drawer.hpos=right"),
    # "two rows of drawers, three in each row": two rows of three (nothing had been counted)
    ("a cabinet with two rows of drawers, three in each row", "StorageFurniture drawer=6 "
     "drawer.layout=grid drawer.rows=2 drawer.columns=3"),
    ("a wardrobe with a drawer below each of the two doors", "StorageFurniture door=2 "
     "drawer=2 drawer.below=door drawer.layout=row door.layout=row"),
    # a dryer is a laundry machine (the network alone made it an oven), a pendrive a USB stick
    ("a compact dryer with a door and one knob", "WashingMachine door=1 knob=1"),
    ("a pendrive with a cap", "USB cap=1"),
    ("a desk pedestal with two stacked drawers on top and three drawers below",   # no row
     "StorageFurniture drawer=5 drawer.layout=column drawer.vpos=bottom/top"),
    # a full-front door stated on one side is hinged there (a safe's door had been made a
    # strip on the right half of its front); a cabinet's door keeps its place beside the rest
    ("a safe with a keypad and a door on the right", "Safe door=1 button>=2 "
     "door.hinge=right door.opens=sideways"),
    ("a washing machine with a door on the left", "WashingMachine door=1 door.hinge=left "
     "door.opens=sideways"),
    ("a safe whose door is on the left and opens downward", "Safe door=1 door:revolute "
     "door.hpos=left door.opens=down"),
    ("an oven with a door on the right and knobs on the left", "Oven door=1 knob>=2 "
     "door.hpos=right knob.hpos=left"),
    ("a cabinet with a door on the right", "StorageFurniture door=1 door.hpos=right"),
    # a row at the top or bottom said with "along" or "row" (doors made full-height strips
    # and the drawers a column beside them: no place had been read)
    ("a long cabinet with four doors in the top row and four drawers in the bottom row",
     "StorageFurniture door=4 drawer=4 door.vpos=top door.layout=row drawer.vpos=bottom "
     "drawer.layout=row"),
    ("a sideboard with three doors along the top and three drawers along the bottom",
     "StorageFurniture door=3 drawer=3 door.vpos=top door.layout=row drawer.vpos=bottom "
     "drawer.layout=row"),
    ("a cabinet with two doors in the upper row and two drawers in the lower row",
     "StorageFurniture door=2 drawer=2 door.vpos=top door.layout=row drawer.vpos=bottom "
     "drawer.layout=row"),
    ("a wardrobe with two doors and one drawer along the bottom",     # no row of one
     "StorageFurniture door=2 drawer=1 drawer.vpos=bottom"),
    # a list of controls shares its row; a list of fronts leaves it to the last one
    ("a stove with 5 knobs and 2 buttons along the top", "Oven knob=5 button=2 knob.vpos=top "
     "knob.layout=row button.vpos=top button.layout=row"),
    # "on each side" / "on both sides" of the object is one left and one right; "on either
    # side of the dial" is about the dial
    ("a bookcase with a door on each side", "StorageFurniture door=2 door.hpos=left/right"),
    ("a cabinet with drawers on both sides and a door in the middle", "StorageFurniture door=1 "
     "drawer>=2 drawer.hpos=left/right door.hpos=middle"),
    ("a washer with a button on either side of the dial", "WashingMachine button=2 dial=1"),
])
def test_parse_spatial_wordings(prompt, line):
    assert parse_prompt(prompt).to_json() == ExpectedStructure.from_line(line).to_json()


def test_shipped_free_form_prompts_all_parse_to_something():
    path = Path(__file__).resolve().parents[1] / "model" / "metrics" / "prompts_freeform.txt"
    prompts = [l.strip() for l in path.read_text().splitlines()
               if l.strip() and not l.startswith("#")]
    assert len(prompts) >= 30
    cats = set()
    for p in prompts:
        e = parse_prompt(p)
        assert e.category is not None, p
        assert e.counts or e.min_counts, p
        cats.add(e.category)
    assert len(cats) == 6


def _cabinet(n_drawers: int, door_joint=JointType.REVOLUTE, category="StorageFurniture"):
    parts = [Part("body", "body", -1)]
    for i in range(n_drawers):
        parts.append(Part(f"drawer_{i}", "drawer", 0,
                          joint=Joint(JointType.PRISMATIC, [0.3, 0, 0.2 * i], [1, 0, 0], (0, 0.3))))
    parts.append(Part("door_0", "door", 0,
                      joint=Joint(door_joint, [0.3, 0.3, 0], [0, 0, 1] if door_joint != JointType.PRISMATIC
                                  else [0, 1, 0], (0, 0.3) if door_joint == JointType.PRISMATIC
                                  else (0, 0), (0, 1.5) if door_joint == JointType.REVOLUTE else (0, 0))))
    return ArticulatedObject(parts, category=category).validate()


def test_alignment_pass_and_fail():
    prompt = "a storage cabinet with two sliding drawers and a hinged door"
    assert alignment_of(prompt, _cabinet(2)).aligned
    r = alignment_of(prompt, _cabinet(3))
    assert not r.aligned and r.counts_ok is False and r.joints_ok is True
    r = alignment_of(prompt, _cabinet(2, door_joint=JointType.PRISMATIC))
    assert not r.aligned and r.joints_ok is False and r.counts_ok is True
    r = alignment_of(prompt, _cabinet(2, category="Safe"))
    assert not r.aligned and r.category_ok is False


def test_alignment_lower_bounds_and_unchecked():
    got = GeneratedStructure.from_object(_cabinet(3))
    assert check_alignment(parse_prompt("a cabinet with drawers"), got).aligned
    assert not check_alignment(parse_prompt("a cabinet with drawers and no doors"), got).aligned
    empty = check_alignment(parse_prompt("something nice"), got)
    assert not empty.checked and not empty.aligned
    s = summarise([check_alignment(parse_prompt("a cabinet with drawers"), got), empty])
    assert s["alignment"] == 1.0 and s["n_checked"] == 1 and s["n_prompts"] == 2


def test_parser_reads_back_the_dataset_templates():
    """Every template description of a synthetic object must parse to a structure the
    object itself satisfies (the alignment metric's ceiling on template prompts)."""
    import numpy as np
    from model.data.describe import describe
    from helpers import built_object
    total = aligned = spatial = spatial_ok = 0
    failures = []
    for i in range(12):
        obj = built_object(7, i)
        for length, texts in describe(obj, np.random.default_rng(i)).items():
            for t in texts:
                r = alignment_of(t, obj)
                # a template's size is the nominal carcass: tops overhang it by up to 8 %,
                # a washer's control panel stands 15 % above it; the body's box is checked
                r.failures = [f for f in r.failures if not f.startswith("size.")]
                r.spatial.pop("size", None)
                r.spatial_ok = all(r.spatial.values()) if r.spatial else None
                total += 1
                aligned += r.aligned
                if r.spatial_ok is not None:     # the spatial facts it states hold too
                    spatial += 1
                    spatial_ok += r.spatial_ok
                if not r.aligned or r.spatial_ok is False:
                    failures.append((t, r.failures))
    assert total > 0
    assert aligned / total >= 0.97, failures[:5]
    assert spatial >= 30 and spatial_ok / spatial >= 0.97, failures[:5]
