"""Arrangements a prompt states, held in the layout (model.refine.arrange): rows and columns
of a group, its side, one group above another; never a change of structure."""
import numpy as np
import pytest

from model.core import ArticulatedObject, Joint, JointType, Part
from model.data.prompt_parse import parse_prompt
from model.data.spatial import arrangement, part_position, spatial_summary, is_above
from model.refine import arrange_stated, place_stated_sides, refine_layout, safe_keypads
from model.refine.arrange import _grid


def _part(name, label, parent, size, centre, joint=None):
    return Part(name=name, label=label, parent=parent, bbox_center=np.asarray(centre, float),
                bbox_size=np.asarray(size, float), joint=joint or Joint())


def _drawer(n, centre, size=(0.4, 0.8, 0.12)):
    return _part(f"drawer_{n}", "drawer", 0, size, centre,
                 Joint(JointType.PRISMATIC, centre, (1, 0, 0), t_range=(0, 0.3)))


def _door(n, size, centre, hinge, axis=(0, 0, 1), r_range=(0, 1.6)):
    return _part(f"door_{n}", "door", 0, size, centre,
                 Joint(JointType.REVOLUTE, hinge, axis, r_range=r_range))


def _structure(obj):
    return [(p.label, p.parent, p.joint.type) for p in obj.parts]


def _grid_of(obj, group):
    """(layout, rows, columns) the spatial summary reads for ``group``."""
    got = arrangement(obj, group)
    return got["layout"], got["rows"], got["columns"]


def _layout_same(obj, prompt):
    """:func:`_layout`, and the object's structure is what it was."""
    before = _structure(obj)
    _layout(obj, prompt)
    assert _structure(obj) == before


def _layout(obj, prompt):
    """What Generator.layout does with a prompt's facts."""
    facts = parse_prompt(prompt).spatial
    arrange_stated(obj, facts)
    safe_keypads(obj, facts)
    refine_layout(obj, stated=facts)
    place_stated_sides(obj, facts)
    return obj


def test_grid_of_a_stated_arrangement():
    assert _grid({"columns": 2}, 6) == [2, 2, 2]
    assert _grid({"rows": 2}, 10) == [5, 5]
    assert _grid({"layout": "grid", "rows": 4, "columns": 3}, 12) == [3, 3, 3, 3]
    assert _grid({"layout": "column"}, 3) == [1, 1, 1]
    assert _grid({"layout": "row"}, 4) == [4]
    assert _grid({"columns": 3}, 7) == [3, 3, 1]           # the bottom row takes what is left
    assert _grid({"rows": 2, "columns": 2}, 5) is None       # 5 parts do not fit 2 x 2
    assert _grid({"hpos": ["left"]}, 4) is None and _grid({"columns": 2}, 1) is None
    assert _grid({"per_row": [2, 1, 1, 1]}, 5) == [2, 1, 1, 1]     # a row of two on top
    assert _grid({"per_row": [2, 1, 1, 1]}, 4) is None              # not the stated count


def test_two_small_drawers_on_top_of_three_large_ones():
    """Five drawers decoded in one column: "two small drawers on top and three large drawers
    below" lays them out as a row of two over three full-width drawers (they had stayed one
    column of five)."""
    from model.data.spatial import arrangement
    parts = [_part("body_0", "body", -1, (0.5, 1.0, 1.0), (0, 0, 0.5))]
    for n in range(5):
        parts.append(_drawer(n, (0.05, 0.0, 0.85 - 0.17 * n)))
    obj = ArticulatedObject(category="StorageFurniture", name="dresser", parts=parts)
    _layout_same(obj, "a dresser with two small drawers on top and three large drawers below")
    drawers = [i for i, p in enumerate(obj.parts) if p.label == "drawer"]
    assert arrangement(obj, drawers)["per_row"] == [2, 1, 1, 1]


def test_six_drawers_decoded_in_one_column_end_up_in_two_columns():
    """The decoder stacked all six drawers (overlapping, full width); "in two columns" puts
    them on a 3 x 2 grid inside the front they cover, handles moving with their drawers."""
    parts = [_part("body_0", "body", -1, (0.5, 1.0, 1.0), (0, 0, 0.5))]
    for n in range(6):
        parts.append(_drawer(n, (0.05, 0.0, 0.85 - 0.13 * n)))
    parts.append(_part("handle_0", "handle", 1, (0.03, 0.1, 0.02), (0.27, 0.0, 0.85)))
    obj = ArticulatedObject(category="StorageFurniture", name="sideboard", parts=parts)
    _layout_same(obj, "a sideboard with six small drawers in two columns")
    drawers = [i for i, p in enumerate(obj.parts) if p.label == "drawer"]
    assert _grid_of(obj, drawers) == ("grid", 3, 2)
    handle, drawer = obj.parts[-1], obj.parts[1]
    lo, hi = drawer.bbox_center - drawer.bbox_size / 2, drawer.bbox_center + drawer.bbox_size / 2
    assert np.all(handle.bbox_center[1:] >= lo[1:]) and np.all(handle.bbox_center[1:] <= hi[1:])
    for a in drawers:                                # no two drawers overlap
        for b in drawers:
            if a < b:
                pa, pb = obj.parts[a], obj.parts[b]
                gap = np.abs(pa.bbox_center - pb.bbox_center) - (pa.bbox_size + pb.bbox_size) / 2
                assert gap[1:].max() > 0


def _door_and_drawers(door_y, drawer_y):
    return ArticulatedObject(category="StorageFurniture", name="kitchen", parts=[
        _part("body_0", "body", -1, (0.5, 1.0, 0.9), (0, 0, 0.45)),
        _door(0, (0.02, 0.45, 0.8), (0.24, door_y, 0.45), (0.25, door_y + 0.22, 0.45)),
        _drawer(0, (0.05, drawer_y, 0.75), (0.4, 0.45, 0.2)),
        _drawer(1, (0.05, drawer_y, 0.45), (0.4, 0.45, 0.2)),
        _drawer(2, (0.05, drawer_y, 0.15), (0.4, 0.45, 0.2)),
    ])


def test_a_door_stated_on_the_left_is_mirrored_there_and_still_opens_outwards():
    obj = _door_and_drawers(door_y=0.25, drawer_y=-0.25)          # the door on the right
    _layout_same(obj, "a kitchen cabinet with three drawers and a door on the left")
    assert part_position(obj, 1)[0] == "left"
    assert all(part_position(obj, i)[0] == "right" for i in (2, 3, 4))
    door = obj.parts[1]
    T = door.joint.transform(0.0, 1.0)                            # open by 1 rad
    free = door.bbox_center + np.array([0.0, 0.2, 0.0])          # away from the hinge
    assert (T[:3, :3] @ free + T[:3, 3])[0] > free[0]              # swings out, not in
    # already on its stated side: left alone
    obj = _door_and_drawers(door_y=-0.25, drawer_y=0.25)
    assert place_stated_sides(obj, {"door": {"hpos": ["left"]}}) == []


def test_a_drawer_stated_beside_a_door_is_put_beside_it():
    """"a cabinet with a drawer beside a door" as decoded: a full-width drawer over a
    full-width door. The two are banded side by side across the front (the drawer on the
    side the network put more of it, here the viewer's right), neither overlapping."""
    from model.data.spatial import is_beside
    cab = ArticulatedObject(category="StorageFurniture", name="base", parts=[
        _part("body_0", "body", -1, (0.5, 0.8, 0.9), (0, 0, 0.45)),
        _drawer(0, (0.05, 0.02, 0.75), (0.4, 0.74, 0.2)),
        _door(0, (0.02, 0.74, 0.6), (0.24, 0.0, 0.33), (0.25, -0.37, 0.33), axis=(0, 0, -1)),
    ])
    assert not is_beside(spatial_summary(cab), "drawer", "door")
    _layout_same(cab, "a cabinet with a drawer beside a door")
    sp = spatial_summary(cab)
    assert is_beside(sp, "drawer", "door")
    assert part_position(cab, 1)[0] == "right" and part_position(cab, 2)[0] == "left"
    a, b = cab.parts[1], cab.parts[2]
    alo, ahi = a.bbox_center - a.bbox_size / 2, a.bbox_center + a.bbox_size / 2
    blo, bhi = b.bbox_center - b.bbox_size / 2, b.bbox_center + b.bbox_size / 2
    assert not np.all((alo < bhi) & (blo < ahi))


def test_drawers_stated_above_the_doors_swap_top_and_bottom_but_an_oven_does_not():
    cab = ArticulatedObject(category="StorageFurniture", name="base", parts=[
        _part("body_0", "body", -1, (0.5, 1.0, 0.9), (0, 0, 0.45)),
        _drawer(0, (0.05, 0.0, 0.12), (0.4, 0.9, 0.18)),
        _door(0, (0.02, 0.9, 0.55), (0.24, 0.0, 0.6), (0.25, 0.45, 0.6)),
    ])
    _layout(cab, "a kitchen base unit with one drawer above a door")
    assert is_above(spatial_summary(cab), "drawer", "door")
    oven = ArticulatedObject(category="Oven", name="oven", parts=[
        _part("body_0", "body", -1, (0.5, 0.6, 0.6), (0, 0, 0.3)),
        _door(0, (0.03, 0.5, 0.3), (0.235, 0, 0.45), (0.25, 0, 0.3), axis=(0, 1, 0),
              r_range=(0, 1.4)),
        _part("knob_0", "knob", 0, (0.03, 0.05, 0.05), (0.265, 0.1, 0.1),
              Joint(JointType.CONTINUOUS, (0.265, 0.1, 0.1), (1, 0, 0))),
    ])
    refine_layout(oven)
    z = oven.parts[1].bbox_center[2]
    assert place_stated_sides(oven, {"knob": {"above": ["door"]}}) == []
    assert oven.parts[1].bbox_center[2] == pytest.approx(z)   # a drop-down door stays put


def test_drawers_stated_across_the_top_are_stacked_above_the_doors_they_were_among():
    """Drawers decoded among and below the doors: "three drawers across the top and two doors
    below them" gives the drawers the upper band and the doors the lower one, each group
    keeping its own layout; nothing overlaps."""
    parts = [_part("body_0", "body", -1, (0.5, 1.2, 1.0), (0, 0, 0.5))]
    for n, z in enumerate((0.15, 0.45, 0.75)):
        parts.append(_drawer(n, (0.05, -0.3, z), (0.4, 0.55, 0.25)))
    for n, y in enumerate((-0.3, 0.3)):
        parts.append(_part(f"door_{n}", "door", 0, (0.02, 0.55, 0.6), (0.24, y, 0.5),
                           Joint(JointType.REVOLUTE, (0.25, y + 0.27, 0.5), (0, 0, 1),
                                 r_range=(0, 1.6))))
    obj = ArticulatedObject(category="StorageFurniture", name="sideboard", parts=parts)
    _layout_same(obj, "a sideboard: three drawers across the top and two doors below them")
    assert is_above(spatial_summary(obj), "drawer", "door")
    boxes = [(p.bbox_center - p.bbox_size / 2, p.bbox_center + p.bbox_size / 2)
             for p in obj.parts[1:]]
    for a in range(len(boxes)):
        for b in range(a + 1, len(boxes)):
            (alo, ahi), (blo, bhi) = boxes[a], boxes[b]
            assert np.any(np.minimum(ahi, bhi) - np.maximum(alo, blo) <= 1e-9), (a, b)


def test_a_door_stated_on_the_left_between_drawer_columns_gets_the_left_band():
    """The README's example as the network lays it out: the door in the middle, drawers on
    both sides of it. "a door on the left" gives the door the left band of the front and the
    drawers the right band, one column there (they state no arrangement of their own; the
    network's two columns mapped into the band left one drawer beside two)."""
    obj = ArticulatedObject(category="StorageFurniture", name="kitchen", parts=[
        _part("body_0", "body", -1, (0.5, 1.2, 0.9), (0, 0, 0.45)),
        _door(0, (0.02, 0.4, 0.8), (0.24, 0.0, 0.45), (0.25, -0.2, 0.45)),
        _drawer(0, (0.05, -0.4, 0.6), (0.4, 0.35, 0.25)),
        _drawer(1, (0.05, 0.4, 0.6), (0.4, 0.35, 0.25)),
        _drawer(2, (0.05, 0.4, 0.3), (0.4, 0.35, 0.25)),
    ])
    _layout_same(obj, "a kitchen cabinet with three drawers and a door on the left")
    door_right = obj.parts[1].bbox_center[1] + obj.parts[1].bbox_size[1] / 2
    assert part_position(obj, 1)[0] == "left"
    assert all(p.bbox_center[1] - p.bbox_size[1] / 2 >= door_right - 1e-9 for p in obj.parts[2:])
    assert len({round(float(p.bbox_center[1]), 3) for p in obj.parts[2:]}) == 1   # a column
    tops = sorted(p.bbox_center[2] for p in obj.parts[2:])
    assert min(np.diff(tops)) > 0.2                                            # stacked


def test_a_door_beside_a_drawer_stack_it_was_decoded_under_gets_the_stacks_height():
    """Decoded as a door at the bottom and two full-width drawers above it; "two drawers
    stacked to the right of the door" puts the door on the left at the stack's height (the
    front's tiling would otherwise grow both back across the whole width)."""
    obj = ArticulatedObject(category="StorageFurniture", name="bedside", parts=[
        _part("body_0", "body", -1, (0.5, 1.0, 1.0), (0, 0, 0.5)),
        _door(0, (0.02, 0.95, 0.6), (0.24, 0.0, 0.35), (0.25, -0.47, 0.35)),
        _drawer(0, (0.05, 0.0, 0.9), (0.4, 0.95, 0.15)),
        _drawer(1, (0.05, 0.0, 0.75), (0.4, 0.95, 0.15)),
    ])
    _layout_same(obj, "small bedside cabinet with a door, and two drawers stacked to the right "
                 "of the door")
    sp = spatial_summary(obj)
    assert sp["door"]["hpos"] == ["left"] and sp["drawer"]["hpos"] == ["right"]
    assert sp["drawer"]["layout"] == "column"
    door = obj.parts[1]
    top = max(p.bbox_center[2] + p.bbox_size[2] / 2 for p in obj.parts[2:])
    bottom = min(p.bbox_center[2] - p.bbox_size[2] / 2 for p in obj.parts[2:])
    assert door.bbox_center[2] + door.bbox_size[2] / 2 == pytest.approx(top, abs=0.02)
    assert door.bbox_center[2] - door.bbox_size[2] / 2 == pytest.approx(bottom, abs=0.02)


def _locker_door(n, centre, size, axis=(0, 0, 1)):
    return _part(f"door_{n}", "door", 0, size, centre,
                 Joint(JointType.REVOLUTE, centre, axis, r_range=(0, 1.6)))


def test_a_stated_grid_gathers_doors_decoded_on_the_side_onto_the_front():
    """Ten locker doors, eight decoded on the front and two on the side face: "two rows of
    five" moves the two onto the front (depth and axis of a front door) and lays out 2 x 5;
    every door stays thinner than it is wide, so it keeps to the front face."""
    parts = [_part("body_0", "body", -1, (0.4, 0.6, 1.0), (0, 0, 0.5))]
    for n in range(8):
        parts.append(_locker_door(n, (0.21, -0.1 + 0.03 * n, 0.3 + 0.08 * n),
                                  (0.02 + 0.01 * (n % 3), 0.05, 0.25)))
    parts.append(_locker_door(8, (0.0, 0.31, 0.5), (0.3, 0.02, 0.25), axis=(0, 1, 0)))
    parts.append(_locker_door(9, (0.05, -0.31, 0.4), (0.25, 0.02, 0.3), axis=(1, 0, 0)))
    obj = ArticulatedObject(category="StorageFurniture", name="lockers", parts=parts)
    _layout_same(obj, "gym lockers -- 10 doors, two rows of five")
    doors = [i for i, p in enumerate(obj.parts) if p.label == "door"]
    assert _grid_of(obj, doors) == ("grid", 2, 5)
    for i in doors:
        p = obj.parts[i]
        assert p.bbox_center[0] > 0.19 and p.bbox_size[0] < min(p.bbox_size[1:])
        assert abs(p.joint.axis[2]) == pytest.approx(1.0)        # side-hinged on the front


def _safe_door_with_keypad(handle_z):
    parts = [_part("body_0", "body", -1, (0.36, 0.4, 0.5), (0, 0, 0.26)),
             _door(0, (0.03, 0.32, 0.24), (0.2, 0.0, 0.28), (0.21, -0.16, 0.28))]
    for n in range(9):
        c = (0.22, -0.06 + 0.012 * n, 0.2 + 0.01 * n)
        parts.append(_part(f"button_{n}", "button", 1, (0.01, 0.03, 0.03), c,
                           Joint(JointType.PRISMATIC, c, (-1, 0, 0), t_range=(0, 0.005))))
    parts.append(_part("handle_0", "handle", 1, (0.02, 0.12, 0.02), (0.22, -0.02, handle_z)))
    return ArticulatedObject(category="Safe", name="safe", parts=parts)


def test_a_handle_across_a_stated_keypad_moves_off_it():
    obj = _safe_door_with_keypad(handle_z=0.25)
    _layout(obj, "wall safe w/ keypad: 9 buttons, 3x3")
    buttons = list(range(2, 11))
    assert _grid_of(obj, buttons) == ("grid", 3, 3)
    h = obj.parts[-1]
    lo = np.min([obj.parts[i].bbox_center - obj.parts[i].bbox_size / 2 for i in buttons], 0)
    hi = np.max([obj.parts[i].bbox_center + obj.parts[i].bbox_size / 2 for i in buttons], 0)
    hlo, hhi = h.bbox_center - h.bbox_size / 2, h.bbox_center + h.bbox_size / 2
    assert np.any((hlo[1:] >= hi[1:] - 1e-9) | (hhi[1:] <= lo[1:] + 1e-9))
    assert min(obj.parts[i].bbox_size[2] for i in buttons) > 0.02   # none squashed


def test_a_keypads_keys_are_no_bigger_than_the_datas():
    """Keys decoded 6 cm across (the shipped model's safe keypads) are laid out in the stated
    grid at most KEY across, as the data's 2.2 cm keys are."""
    from model.refine.arrange import KEY
    obj = _safe_door_with_keypad(handle_z=0.4)
    for i in range(2, 11):
        obj.parts[i].bbox_size = np.array([0.01, 0.06, 0.06])
    _layout(obj, "a safe with a 3x3 keypad on its door")
    keys = [obj.parts[i] for i in range(2, 11)]
    assert _grid_of(obj, list(range(2, 11))) == ("grid", 3, 3)
    assert all(max(p.bbox_size[1:]) <= KEY + 1e-9 for p in keys)


def test_a_keypad_is_a_block_of_square_keys():
    """A hotel safe's nine keys decoded 1.6-2 cm across but spread 16 cm wide: laid out 3 x 3
    as a block of square keys PITCH of a key apart (they had been 1.6 x 2.9 cm, 7.3 cm
    apart: three bars across the door)."""
    from model.refine.arrange import PITCH
    obj = _safe_door_with_keypad(handle_z=0.4)
    for n, i in enumerate(range(2, 11)):
        obj.parts[i].bbox_center = np.array([0.22, -0.08 + 0.02 * n, 0.2 + 0.004 * n])
        obj.parts[i].bbox_size = np.array([0.01, 0.016 + 0.002 * (n % 2), 0.02 + 0.01 * (n % 3)])
    _layout(obj, "a hotel safe with a 3x3 keypad on its door")
    keys = [obj.parts[i] for i in range(2, 11)]
    assert _grid_of(obj, list(range(2, 11))) == ("grid", 3, 3)
    side = keys[0].bbox_size[1]
    assert all(p.bbox_size[1] == pytest.approx(p.bbox_size[2]) == pytest.approx(side)
               for p in keys)
    for ax in (1, 2):
        centres = sorted({round(float(p.bbox_center[ax]), 6) for p in keys})
        assert np.diff(centres) == pytest.approx([PITCH * side] * 2, rel=0.1)


@pytest.mark.parametrize("n, shape", [(9, (3, 3)), (4, (2, 2)), (6, (2, 3)), (3, (1, 3))])
def test_a_safes_buttons_no_prompt_arranges_are_a_keypad(n, shape):
    """Buttons scattered over a safe's door (an image request, "a safe with nine buttons")
    become a block of square keys, three to a row (two for four), as every safe of the data
    has them; the handle across the block moves off it."""
    from model.refine.arrange import KEY, PITCH
    obj = _safe_door_with_keypad(handle_z=0.25)
    rng = np.random.default_rng(n)
    del obj.parts[2 + n:11]
    for i in range(2, 2 + n):
        c = np.array([0.22, rng.uniform(-0.12, 0.12), rng.uniform(0.2, 0.36)])
        obj.parts[i].bbox_center = c
        obj.parts[i].joint.origin = c.copy()
    before = _structure(obj)
    assert safe_keypads(obj) == [f"button: keypad {shape[0]} x {shape[1]}"]
    assert _structure(obj) == before
    keys = list(range(2, 2 + n))
    layout, rows, cols = _grid_of(obj, keys)
    assert (rows, cols) == shape and layout in ("grid", "row", "column")
    side = obj.parts[2].bbox_size[1]
    assert side <= KEY + 1e-9
    for ax in (1, 2):
        centres = sorted({round(float(obj.parts[i].bbox_center[ax]), 6) for i in keys})
        assert np.diff(centres) == pytest.approx([PITCH * side] * (len(centres) - 1), rel=0.1)
    h = obj.parts[-1]
    lo = np.min([obj.parts[i].bbox_center - obj.parts[i].bbox_size / 2 for i in keys], 0)
    hi = np.max([obj.parts[i].bbox_center + obj.parts[i].bbox_size / 2 for i in keys], 0)
    hlo, hhi = h.bbox_center - h.bbox_size / 2, h.bbox_center + h.bbox_size / 2
    assert np.any((hlo[1:] >= hi[1:] - 1e-9) | (hhi[1:] <= lo[1:] + 1e-9))


def test_buttons_a_prompt_arranges_or_not_on_a_safe_keep_their_layout():
    obj = _safe_door_with_keypad(handle_z=0.4)
    assert safe_keypads(obj, {"button": {"layout": "row"}}) == []
    assert safe_keypads(obj, {"button": {"hpos": ["left"]}}) == []
    obj.category = "Oven"
    assert safe_keypads(obj) == []


def _range(knobs):
    parts = [_part("body_0", "body", -1, (0.5, 0.7, 0.8), (0, 0, 0.4)),
             _door(0, (0.04, 0.66, 0.56), (0.26, 0.0, 0.36), (0.27, 0.0, 0.08), axis=(0, 1, 0),
                   r_range=(0, 1.4))]
    for n, c in enumerate(knobs):
        parts.append(_part(f"knob_{n}", "knob", 0, (0.03, 0.05, 0.05), c,
                           Joint(JointType.CONTINUOUS, c, (1, 0, 0))))
    return ArticulatedObject(category="Oven", name="range", parts=parts)


def test_knobs_stated_above_a_drop_down_door_go_above_it_and_the_door_stays():
    """Two rows of three knobs decoded down across the door: they move into the strip above
    it, round, as rows; the door keeps its width and its top (it only fills down to the
    oven's bottom frame, and its top edge gives way to the swing clearance)."""
    from model.refine.siblings import CLEAR_SWING
    obj = _range([(0.29, y, z) for z in (0.7, 0.45) for y in (-0.2, 0.0, 0.2)])
    door = (obj.parts[1].bbox_center.copy(), obj.parts[1].bbox_size.copy())
    _layout(obj, "range with two rows of three knobs above the oven door")
    sp = spatial_summary(obj)
    assert is_above(sp, "knob", "door")
    assert (sp["knob"]["layout"], sp["knob"]["rows"], sp["knob"]["columns"]) == ("grid", 2, 3)
    d = obj.parts[1]
    assert d.bbox_center[1] == pytest.approx(door[0][1], abs=0.01)
    assert d.bbox_size[1] == pytest.approx(door[1][1], abs=0.03)               # not banded
    top = d.bbox_center[2] + d.bbox_size[2] / 2          # at most the swing clearance lower
    assert top == pytest.approx(door[0][2] + door[1][2] / 2, abs=CLEAR_SWING + 1e-6)
    assert d.bbox_center[2] - d.bbox_size[2] / 2 <= door[0][2] - door[1][2] / 2 + 1e-6
    for p in obj.parts[2:]:
        assert p.bbox_size[1] == pytest.approx(p.bbox_size[2])


def test_knobs_and_a_door_stated_on_opposite_sides_stand_side_by_side():
    """"door on the right, three knobs on the left", the knobs decoded in a row above a wide
    door: they become a column on the left, at their own size, as on a toaster oven; the
    door takes the right of the front and fills its height."""
    obj = _range([(0.29, y, 0.7) for y in (-0.2, 0.0, 0.2)])
    _layout(obj, "a countertop oven, door on the right side, three knobs on the left")
    door, knobs = obj.parts[1], obj.parts[2:]
    assert part_position(obj, 1)[0] == "right"
    assert {part_position(obj, i)[0] for i in range(2, 5)} == {"left"}
    assert np.ptp([k.bbox_center[1] for k in knobs]) < 1e-6           # one column
    assert np.ptp([k.bbox_center[2] for k in knobs]) > 0.1
    for k in knobs:
        assert np.allclose(k.bbox_size[1:], 0.05) and k.bbox_center[1] + 0.025 < \
            door.bbox_center[1] - door.bbox_size[1] / 2
    assert door.bbox_size[2] > 0.6


def test_a_stated_row_of_knobs_beside_a_door_stays_a_row():
    obj = _range([(0.29, y, 0.7) for y in (-0.2, 0.0, 0.2)])
    _layout(obj, "an oven with the door on the right and a row of three knobs on the left")
    assert spatial_summary(obj)["knob"]["layout"] == "row"
    assert part_position(obj, 1)[0] == "right"


def test_knobs_stated_on_the_left_leave_the_door_its_width():
    """"four knobs in a line on the left": the knobs come together on the left of the front;
    the door below them is not banded beside them."""
    obj = _range([(0.29, y, 0.7) for y in (-0.05, 0.05, 0.15, 0.25)])
    width = obj.parts[1].bbox_size[1]
    _layout(obj, "oven with four knobs in a line on the left")
    assert obj.parts[1].bbox_size[1] == pytest.approx(width, abs=0.03)
    assert {part_position(obj, i)[0] for i in range(2, 6)} == {"left"}
    assert spatial_summary(obj)["knob"]["layout"] == "row"


def test_two_columns_of_drawers_touching_stay_two_columns():
    """The fronts' tiling grows a drawer only up to a neighbour beyond it; two columns that
    touch (1 mm overlap) are still side by side, not grown across each other."""
    parts = [_part("body_0", "body", -1, (0.45, 1.1, 1.0), (0, 0, 0.5))]
    for n in range(6):
        parts.append(_drawer(n, (0.05, 0.25 if n % 2 else -0.25, 0.2 + 0.3 * (n // 2)),
                             (0.4, 0.501, 0.25)))
    obj = ArticulatedObject(category="StorageFurniture", name="chest", parts=parts)
    _layout(obj, "a chest with three pairs of drawers side by side")
    assert _grid_of(obj, list(range(1, 7))) == ("grid", 3, 2)


def test_a_door_stated_at_the_bottom_below_drawers_reaches_down_the_front():
    """Decoded with the door across the middle and the drawers over it: "two drawers on top,
    then one big door at the bottom" bands them over the front's whole height, so the door
    ends near the bottom instead of floating in the middle of an empty front."""
    obj = ArticulatedObject(category="StorageFurniture", name="filing", parts=[
        _part("body_0", "body", -1, (0.5, 0.9, 0.95), (0, 0, 0.49)),
        _door(0, (0.01, 0.8, 0.33), (0.23, 0.0, 0.54), (0.24, -0.4, 0.54)),
        _drawer(0, (0.05, 0.1, 0.65), (0.44, 0.72, 0.33)),
        _drawer(1, (0.03, 0.0, 0.63), (0.36, 0.72, 0.32)),
    ])
    _layout(obj, "A tall filing cabinet. Two drawers on top, stacked, then one big door at "
                 "the bottom.")
    sp = spatial_summary(obj)
    assert sp["door"]["vpos"] == ["bottom"] and is_above(sp, "drawer", "door")
    door = obj.parts[1]
    assert door.bbox_center[2] - door.bbox_size[2] / 2 < 0.1


def test_a_door_banded_below_a_drawer_does_not_touch_it():
    """Banded fronts are GAP apart: a door whose top touched the drawer above it carried the
    drawer's weight in MuJoCo, and friction held it shut."""
    from model.refine.layout import GAP
    obj = ArticulatedObject(category="StorageFurniture", name="bedside", parts=[
        _part("body_0", "body", -1, (0.45, 0.55, 0.5), (0, 0, 0.25)),
        _door(0, (0.02, 0.5, 0.3), (0.22, 0.0, 0.3), (0.23, 0.25, 0.3), r_range=(0, 1.5)),
        _drawer(0, (0.0, 0.0, 0.2), (0.42, 0.5, 0.2)),
    ])
    _layout(obj, "a small bedside table with one drawer on top and a door underneath")
    door, drawer = obj.parts[1], obj.parts[2]
    assert drawer.bbox_center[2] > door.bbox_center[2]
    gap = (drawer.bbox_center[2] - drawer.bbox_size[2] / 2) \
        - (door.bbox_center[2] + door.bbox_size[2] / 2)
    assert gap >= GAP - 1e-6


def test_a_drawer_decoded_on_the_side_is_turned_onto_the_front_to_be_banded():
    """"one drawer at the top and two doors below it", the drawer decoded on the cabinet's
    left side (its depth along the front, sliding sideways): it is turned onto the front,
    slides out of it, and sits above the doors."""
    obj = ArticulatedObject(category="StorageFurniture", name="kitchen", parts=[
        _part("body_0", "body", -1, (0.5, 0.9, 1.0), (0, 0, 0.5)),
        _door(0, (0.02, 0.85, 0.35), (0.24, 0.0, 0.3), (0.25, -0.42, 0.3)),
        _door(1, (0.02, 0.85, 0.35), (0.24, 0.0, 0.7), (0.25, -0.42, 0.7)),
        _part("drawer_0", "drawer", 0, (0.7, 0.4, 0.3), (0.0, -0.25, 0.5),
              Joint(JointType.PRISMATIC, (0.0, -0.25, 0.5), (0, -1, 0), t_range=(0, 0.3))),
    ])
    _layout_same(obj, "kitchen base cabinet with one drawer at the top and two doors below it")
    drawer = obj.parts[3]
    assert abs(drawer.joint.axis[0]) == pytest.approx(1.0) and drawer.joint.axis[0] > 0
    assert drawer.bbox_center[0] + drawer.bbox_size[0] / 2 == pytest.approx(0.25, abs=0.03)
    sp = spatial_summary(obj)
    assert sp["drawer"]["vpos"] == ["top"] and is_above(sp, "drawer", "door")


def test_a_drawer_stated_in_a_corner_goes_above_and_then_to_its_side():
    """"a detergent drawer at the top left": the drawer gets the band above the door, then
    moves left within it (a second, side-by-side band would stretch it back down)."""
    obj = ArticulatedObject(category="WashingMachine", name="washer", parts=[
        _part("body_0", "body", -1, (0.6, 0.6, 0.9), (0, 0, 0.45)),
        _door(0, (0.03, 0.45, 0.45), (0.3, 0.0, 0.45), (0.31, 0.22, 0.45)),
        _drawer(0, (0.15, 0.1, 0.5), (0.3, 0.2, 0.12)),
    ])
    _layout(obj, "a washing machine with a detergent drawer at the top left")
    sp = spatial_summary(obj)
    assert sp["drawer"]["vpos"] == ["top"] and sp["drawer"]["hpos"] == ["left"]
    assert is_above(sp, "drawer", "door")


def test_controls_stated_one_above_the_other_keep_their_size():
    """"A microwave with a keypad" (its facts: the door on the left, knobs and buttons in
    columns on the right, buttons below knobs): two 6 mm buttons decoded touching, 5 mm into
    the knob column above them, end up in their own band below the knobs with room between
    them; after the layout refinement none overlaps another or is cut under 5 mm."""
    def ctrl(n, label, size, z):
        return _part(f"{label}_{n}", label, 0, size, (0.1925, 0.17, z),
                     Joint(JointType.PRISMATIC if label == "button" else JointType.REVOLUTE,
                           (0.19, 0.17, z), (-1, 0, 0) if label == "button" else (1, 0, 0),
                           t_range=(0, 0.003), r_range=(0, 6.0)))
    obj = ArticulatedObject(category="Oven", name="o", parts=[
        _part("body_0", "body", -1, (0.38, 0.5, 0.3), (0, 0, 0.185)),
        _door(0, (0.021, 0.37, 0.186), (0.2005, -0.0045, 0.171), (0.211, -0.188, 0.171)),
        ctrl(0, "knob", (0.021, 0.015, 0.014), 0.301), ctrl(1, "knob", (0.019, 0.015, 0.014),
                                                            0.316),
        ctrl(0, "button", (0.005, 0.014, 0.006), 0.2955),
        ctrl(1, "button", (0.006, 0.012, 0.006), 0.2885)])
    facts = {"door": {"hinge": ["left"], "opens": ["sideways"], "hpos": ["left"]},
             "knob": {"hpos": ["right"], "layout": "column"},
             "button": {"hpos": ["right"], "layout": "column", "below": ["knob"]}}
    arrange_stated(obj, facts)
    ctrl_parts = [p for p in obj.parts if p.label in ("knob", "button")]
    lo = {p.name: p.bbox_center - p.bbox_size / 2 for p in ctrl_parts}
    hi = {p.name: p.bbox_center + p.bbox_size / 2 for p in ctrl_parts}
    assert max(hi[f"button_{k}"][2] for k in (0, 1)) <= min(lo[f"knob_{k}"][2] for k in (0, 1))
    assert lo["button_0"][2] - hi["button_1"][2] > 0.002          # room between the keys
    refine_layout(obj, stated=facts)
    for a in ctrl_parts:
        assert np.all(a.bbox_size[1:] >= 0.005), (a.name, a.bbox_size)
        for b in ctrl_parts:
            if a is not b:
                alo, ahi = a.bbox_center - a.bbox_size / 2, a.bbox_center + a.bbox_size / 2
                blo, bhi = b.bbox_center - b.bbox_size / 2, b.bbox_center + b.bbox_size / 2
                assert not np.all((alo < bhi - 1e-6) & (blo < ahi - 1e-6)), (a.name, b.name)


def test_a_stated_grid_gathers_members_the_network_put_under_the_body():
    """Twelve doors "6 across x 2 down", five decoded on the front and seven on the body's
    bottom face (no front holds most of them): all twelve go onto the front's grid."""
    parts = [_part("body_0", "body", -1, (0.4, 1.2, 0.6), (0, 0, 0.3))]
    for n in range(12):
        y = -0.5 + 0.2 * (n % 6)
        if n < 5:
            parts.append(_door(n, (0.02, 0.18, 0.25), (0.21, y, 0.45), (0.22, y - 0.09, 0.45)))
        else:
            parts.append(_door(n, (0.3, 0.18, 0.1), (0.0, y, -0.05), (0.0, y - 0.09, -0.1)))
    obj = ArticulatedObject(category="StorageFurniture", name="mail", parts=parts)
    _layout_same(obj, "mail-slot style cabinet w/ 12 small doors, 6 across x 2 down")
    doors = [i for i, p in enumerate(obj.parts) if p.label == "door"]
    assert _grid_of(obj, doors) == ("grid", 2, 6)


def test_a_left_door_and_a_right_door_are_side_by_side():
    """"A tall wardrobe with a left door and a right door": the network stacked the two doors
    (seeds 0-3). A group stated on as many sides as it has members is a row (a column for
    upper and lower); members already on those sides are left where they are."""
    def wardrobe(doors):
        return ArticulatedObject(category="StorageFurniture", name="w", parts=[
            _part("body_0", "body", -1, (0.5, 1.0, 1.8), (0, 0, 0.9)), *doors])
    stacked = wardrobe([_door(0, (0.02, 0.96, 0.85), (0.26, 0, 1.35), (0.27, -0.48, 1.35)),
                        _door(1, (0.02, 0.96, 0.85), (0.26, 0, 0.45), (0.27, -0.48, 0.45))])
    _layout_same(stacked, "a wardrobe with a left door and a right door")
    assert sorted(part_position(stacked, i)[0] for i in (1, 2)) == ["left", "right"]
    assert abs(stacked.parts[1].bbox_center[2] - stacked.parts[2].bbox_center[2]) < 0.01
    apart = wardrobe([_door(0, (0.02, 0.47, 1.7), (0.26, -0.25, 0.9), (0.27, -0.49, 0.9)),
                      _door(1, (0.02, 0.47, 1.7), (0.26, 0.25, 0.9), (0.27, 0.49, 0.9))])
    before = [p.bbox_center.copy() for p in apart.parts]
    assert arrange_stated(apart, parse_prompt("a left door and a right door").spatial) == []
    assert all(np.allclose(b, p.bbox_center) for b, p in zip(before, apart.parts))
    upper = wardrobe([_door(0, (0.02, 0.47, 1.7), (0.26, -0.25, 0.9), (0.27, -0.49, 0.9)),
                      _door(1, (0.02, 0.47, 1.7), (0.26, 0.25, 0.9), (0.27, 0.49, 0.9))])
    _layout_same(upper, "a cabinet with an upper door and a lower door")
    assert sorted(part_position(upper, i)[1] for i in (1, 2)) == ["bottom", "top"]


def test_drawers_stated_beside_a_door_are_one_column():
    """"an office cabinet with a door on the left and three drawers on the right" (seed 0):
    the network's drawers were one over two side by side, one of them 13 cm wide and 50 cm
    tall, already right of the door. Drawers stated on one side of the others with no
    arrangement of their own are one column of equal drawers in their band; a stated
    arrangement ("two drawers side by side on the right") is kept."""
    def office(drawers):
        return ArticulatedObject(category="StorageFurniture", name="o", parts=[
            _part("body_0", "body", -1, (0.51, 0.93, 1.07), (0, 0, 0.54)),
            _door(0, (0.02, 0.36, 0.94), (0.25, -0.26, 0.58), (0.26, -0.44, 0.58)), *drawers])
    messy = [_drawer(0, (0.05, 0.2, 0.84), (0.41, 0.48, 0.43)),
             _drawer(1, (0.05, 0.24, 0.36), (0.41, 0.40, 0.49)),
             _drawer(2, (0.05, -0.02, 0.37), (0.41, 0.13, 0.5))]
    obj = office(messy)
    _layout_same(obj, "an office cabinet with a door on the left and three drawers on the right")
    drawers = [2, 3, 4]
    assert _grid_of(obj, drawers) == ("column", 3, 1)
    assert all(part_position(obj, i)[0] == "right" for i in drawers)
    widths = [obj.parts[i].bbox_size[1] for i in drawers]
    assert max(widths) - min(widths) < 1e-6 and min(widths) > 0.3
    obj = office([_drawer(0, (0.05, 0.1, 0.3), (0.41, 0.2, 0.3)),
                  _drawer(1, (0.05, 0.35, 0.3), (0.41, 0.2, 0.3))])
    _layout_same(obj, "a cabinet with a door on the left and two drawers side by side on the "
                      "right")
    assert _grid_of(obj, [2, 3])[0] == "row"


def test_doors_banded_below_drawers_stand_side_by_side():
    """"two doors at the bottom and three drawers side by side above them, on a low
    sideboard": the network stacked the two doors, each the full width and 15 cm tall, under
    the drawers (seeds 0-2). Doors banded above or below another group with no arrangement
    of their own are one row in their band; a stated column is kept."""
    def sideboard():
        drawers = [_drawer(n, (0.08, y, 0.46), (0.37, 0.41, 0.27))
                   for n, y in enumerate((-0.42, 0.0, 0.41))]
        return ArticulatedObject(category="StorageFurniture", name="s", parts=[
            _part("body_0", "body", -1, (0.52, 1.29, 0.62), (0, 0, 0.31)),
            _door(0, (0.02, 1.24, 0.15), (0.25, 0, 0.25), (0.26, -0.62, 0.25)),
            _door(1, (0.02, 1.24, 0.15), (0.25, 0, 0.10), (0.26, -0.62, 0.10)), *drawers])
    obj = sideboard()
    _layout_same(obj, "two doors at the bottom and three drawers side by side above them, "
                      "on a low sideboard")
    assert _grid_of(obj, [1, 2]) == ("row", 1, 2)
    assert all(part_position(obj, i)[1] == "bottom" for i in (1, 2))
    assert _grid_of(obj, [3, 4, 5]) == ("row", 1, 3)
    obj = sideboard()
    _layout_same(obj, "two doors stacked at the bottom and three drawers side by side above "
                      "them")
    assert _grid_of(obj, [1, 2])[0] == "column"


def test_fronts_stated_at_the_bottom_keep_to_the_bottom_band():
    """"a bookcase with two doors at the bottom" (seed 0): the network's two doors covered 79 %
    of the front's height; moved down and tiled, they ended in its middle third, grown over
    the shelves above. Fronts stated at the top or bottom take that band of the face (the
    one they would take above or below another group) and grow only towards their edge."""
    obj = ArticulatedObject(category="StorageFurniture", name="b", parts=[
        _part("body_0", "body", -1, (0.44, 0.92, 1.12), (0, 0, 0.56)),
        _door(0, (0.02, 0.86, 0.73), (0.21, 0.0, 0.73), (0.22, -0.43, 0.73)),
        _door(1, (0.02, 0.86, 0.50), (0.21, 0.0, 0.47), (0.22, -0.43, 0.47))])
    _layout_same(obj, "a bookcase with two doors at the bottom")
    for i in (1, 2):
        top = obj.parts[i].bbox_center[2] + obj.parts[i].bbox_size[2] / 2
        assert part_position(obj, i)[1] == "bottom" and top < 0.5, (i, top)


def test_drawers_stated_on_the_right_are_a_column_in_the_right_band():
    """"a desk with three drawers on the right" (seed 0): the network's drawers spanned 90 %
    of the width, two side by side over a wide one, and the fill grew them back over the
    face. The face's only fronts stated on one side take that side's band as one column
    and grow only towards that edge, the rest of the face left open (a pedestal); with a
    door beside them the drawers keep their own width."""
    def desk(*extra):
        return ArticulatedObject(category="StorageFurniture", name="d", parts=[
            _part("body_0", "body", -1, (0.46, 0.97, 1.02), (0, 0, 0.51)),
            _drawer(0, (0.21, 0.24, 0.83), (0.03, 0.46, 0.31)),
            _drawer(1, (0.21, -0.23, 0.83), (0.03, 0.47, 0.31)),
            _drawer(2, (0.21, 0.0, 0.19), (0.03, 0.94, 0.31)), *extra])
    obj = desk()
    _layout_same(obj, "a desk with three drawers on the right")
    for i in (1, 2, 3):
        p = obj.parts[i]
        assert part_position(obj, i)[0] == "right", i
        assert p.bbox_center[1] - p.bbox_size[1] / 2 > 0.05, i      # the left half open
        assert p.bbox_size[1] < 0.45 * 0.97, i
    assert _grid_of(obj, [1, 2, 3]) == ("column", 3, 1)
    obj = desk(_door(3, (0.02, 0.3, 0.9), (0.22, -0.3, 0.5), (0.23, -0.45, 0.5)))
    _layout(obj, "a desk with a door and three drawers on the right")
    assert all(part_position(obj, i)[0] == "right" for i in (1, 2, 3))


def test_a_column_of_knobs_decoded_overlapping_gets_room_for_each():
    """"a microwave with a keypad on the right" (seed 3): two 13 mm knobs decoded 6 mm apart,
    laid out as a column over the span they covered, still overlapped (43 %: not sim-ready).
    A control's cell holds the control with GAP either side."""
    from model.refine.arrange import _lay_out
    from model.refine.layout import GAP

    def knob(n, z):
        return _part(f"knob_{n}", "knob", 0, (0.013, 0.013, 0.013), (0.197, 0.107, z),
                     Joint(JointType.CONTINUOUS, (0.19, 0.107, z), (1, 0, 0)))
    obj = ArticulatedObject(category="Oven", name="m", parts=[
        _part("body_0", "body", -1, (0.38, 0.5, 0.3), (0, 0, 0.15)), knob(0, 0.283),
        knob(1, 0.289)])
    assert _lay_out(obj, [1, 2], [1, 1])
    (a, b) = sorted(obj.parts[i].bbox_center[2] for i in (1, 2))
    assert b - a >= 0.013 + GAP - 1e-9
    assert all(np.allclose(obj.parts[i].bbox_size, 0.013) for i in (1, 2))


def _doors_under_drawers():
    """"a door on the left and a door on the right and two drawers in the middle" as decoded
    (seed 2): the two doors 22 x 6 cm slivers under a stack of two full-width drawers."""
    return ArticulatedObject(category="StorageFurniture", name="f", parts=[
        _part("body_0", "body", -1, (0.42, 0.48, 0.72), (0, 0, 0.36)),
        _door(0, (0.017, 0.218, 0.057), (0.2, -0.11, 0.25), (0.21, -0.22, 0.25)),
        _drawer(0, (0.025, 0.0, 0.6), (0.37, 0.44, 0.21)),
        _drawer(1, (0.025, 0.0, 0.39), (0.37, 0.44, 0.21)),
        _door(1, (0.017, 0.218, 0.057), (0.2, 0.11, 0.25), (0.21, 0.22, 0.25))])


def test_two_drawers_each_side_of_two_doors_are_stacks_in_the_side_columns():
    """"a TV cabinet with two drawers on the left, two doors in the middle and two drawers
    on the right" as the network laid it out: four drawers in a row across the top over the
    two doors. Four fronts stated left and right of a "middle" group: two to a side, each
    side column one stack, the doors the middle column; nothing overlaps."""
    obj = ArticulatedObject(category="StorageFurniture", name="tv", parts=[
        _part("body_0", "body", -1, (0.45, 1.5, 0.6), (0, 0, 0.3)),
        *[_drawer(k, (0.03, y, 0.48), (0.4, 0.34, 0.18)) for k, y in
          enumerate((-0.54, -0.18, 0.18, 0.54))],
        _door(0, (0.02, 0.7, 0.34), (0.215, -0.36, 0.2), (0.225, -0.71, 0.2), (0, 0, -1)),
        _door(1, (0.02, 0.7, 0.34), (0.215, 0.36, 0.2), (0.225, 0.71, 0.2))])
    _layout_same(obj, "a TV cabinet with two drawers on the left, two doors in the middle and "
                      "two drawers on the right")
    assert sorted(part_position(obj, i)[0] for i in (1, 2, 3, 4)) == \
        ["left", "left", "right", "right"]
    assert [part_position(obj, i)[0] for i in (5, 6)] == ["middle", "middle"]
    for side in ("left", "right"):
        group = [i for i in (1, 2, 3, 4) if part_position(obj, i)[0] == side]
        assert _grid_of(obj, group) == ("column", 2, 1)
    fronts = [obj.parts[i] for i in range(1, 7)]
    for a in fronts:
        for b in fronts:
            alo, ahi = a.bbox_center - a.bbox_size / 2, a.bbox_center + a.bbox_size / 2
            blo, bhi = b.bbox_center - b.bbox_size / 2, b.bbox_center + b.bbox_size / 2
            assert a is b or not np.all((alo < bhi) & (blo < ahi))


def test_doors_either_side_of_a_drawer_stack_are_three_columns():
    """"a storage cabinet with a door on the left and a door on the right and two drawers in
    the middle" (seed 2): the network put the two doors under the drawers as 22 x 6 cm
    slivers. Fronts stated left and right of another group's "middle" make three equal
    columns across the face, the middle group one stack; the layout refinement keeps them
    (the doors' group covers the drawers only as a whole, so nothing is cut)."""
    obj = _doors_under_drawers()
    _layout_same(obj, "a storage cabinet with a door on the left and a door on the right and "
                      "two drawers in the middle")
    assert [part_position(obj, i)[0] for i in (1, 2, 3, 4)] == \
        ["left", "middle", "middle", "right"]
    assert _grid_of(obj, [2, 3]) == ("column", 2, 1)
    widths = [obj.parts[i].bbox_size[1] for i in (1, 2, 4)]
    assert max(widths) - min(widths) < 0.01 and min(widths) > 0.12
    doors, drawers = [obj.parts[1], obj.parts[4]], [obj.parts[2], obj.parts[3]]
    assert min(d.bbox_size[2] for d in doors) > 0.4       # full height, not slivers
    for a in doors:
        for b in drawers:
            alo, ahi = a.bbox_center - a.bbox_size / 2, a.bbox_center + a.bbox_size / 2
            blo, bhi = b.bbox_center - b.bbox_size / 2, b.bbox_center + b.bbox_size / 2
            assert not np.all((alo < bhi) & (blo < ahi))
    # the middle group as the prompt arranges it ("in a row": it had come out a stack)
    row = _doors_under_drawers()
    _layout_same(row, "a TV console: 2 drawers in a row in the middle, with a door at each end")
    assert _grid_of(row, [2, 3]) == ("row", 1, 2)
    assert [part_position(row, i)[0] for i in (1, 4)] == ["left", "right"]


def _microwave(door_y, door_w, controls):
    """A 0.38 x 0.5 x 0.3 m microwave: a side-hinged door ``door_w`` wide at ``door_y`` with a
    handle, and ``controls`` = [(label, y, z)] on the front."""
    parts = [_part("body_0", "body", -1, (0.38, 0.5, 0.3), (0, 0, 0.15)),
             _part("door_0", "door", 0, (0.02, door_w, 0.22), (0.2, door_y, 0.14),
                   Joint(JointType.REVOLUTE, (0.2, door_y - door_w / 2, 0.14), (0, 0, -1),
                         r_range=(0, 1.6)))]
    parts.append(_part("handle_0", "handle", 1, (0.015, 0.01, 0.08),
                       (0.215, door_y + door_w / 2 - 0.01, 0.14)))
    for k, (lab, y, z) in enumerate(controls):
        joint = Joint(JointType.PRISMATIC, (0.19, y, z), (-1, 0, 0), t_range=(0, 0.003)) \
            if lab == "button" else Joint(JointType.REVOLUTE, (0.2, y, z), (1, 0, 0),
                                          r_range=(0, 3.0))
        parts.append(_part(f"{lab}_{k}", lab, 0, (0.02, 0.03, 0.03), (0.2, y, z), joint))
    return ArticulatedObject(parts=parts, category="Oven", name="microwave")


def test_a_microwave_door_fills_the_front_beside_its_control_column():
    """"a microwave with a pull handle and a column of buttons" had a 3 cm wide door between
    its controls, "... and six buttons" a column of buttons in the middle of the front: the
    controls go into one column at the far side from the door (the stated one: left), and
    the door fills the front up to it, hinged on its outer edge."""
    from model.data.spatial import hinge_side
    from model.refine import door_beside_controls
    usual = {"door": {"hpos": ["left"]}}
    obj = _microwave(-0.05, 0.03, [("knob", 0.05, 0.25), ("button", 0.05, 0.2),
                                   ("button", 0.05, 0.15)])
    assert door_beside_controls(obj, usual) == ["door_0: beside the controls"]
    door, ctrl = obj.parts[1], obj.parts[3:]
    assert all(c.bbox_center[1] == pytest.approx(0.25 - 0.03 - 0.015) for c in ctrl)
    assert [c.bbox_center[2] for c in ctrl] == [0.25, 0.2, 0.15]          # heights kept
    lo, hi = door.bbox_center - door.bbox_size / 2, door.bbox_center + door.bbox_size / 2
    assert lo[1] == pytest.approx(-0.25 + 0.03) and hi[1] == pytest.approx(-0.22 + 0.5 * 0.76 - 0.06)
    assert lo[2] == pytest.approx(0.03) and hi[2] == pytest.approx(0.27)
    assert part_position(obj, 1)[0] == "left" and hinge_side(obj, 1) == "left"
    h = obj.parts[2]                                   # the handle, still on the door
    assert lo[1] <= h.bbox_center[1] <= hi[1] and h.bbox_center[0] > hi[0] - 0.01
    # a door already filling its side, controls on both sides, or another front: left
    wide = _microwave(-0.07, 0.34, [("knob", 0.19, 0.25), ("button", 0.19, 0.2)])
    assert door_beside_controls(wide, usual) == []
    # ... unless it is so wide that it reads as in the middle: it keeps to its side
    centred = _microwave(-0.04, 0.38, [("knob", 0.19, 0.25), ("button", 0.19, 0.2)])
    assert part_position(centred, 1)[0] == "middle"
    assert door_beside_controls(centred, usual) == ["door_0: beside the controls"]
    assert part_position(centred, 1)[0] == "left"
    split = _microwave(0.0, 0.05, [("knob", -0.2, 0.25), ("knob", 0.2, 0.25)])
    assert door_beside_controls(split) == []
    cab = _microwave(-0.05, 0.03, [("knob", 0.05, 0.25)])
    cab.category = "StorageFurniture"
    assert door_beside_controls(cab, usual) == []
