"""The shipped model end to end: a text becomes a URDF whose generated parts collide through
box primitives from their SDFs, and which yourdfpy, pybullet and MuJoCo load and move."""
import numpy as np
import pytest
from lxml import etree

from model.pipeline.api import GenerationConfig


@pytest.fixture(scope="module")
def gen():
    from model.pipeline.generator import Generator
    return Generator.load(GenerationConfig(resolution=48))


def test_cabinet_collision_boxes_and_simulators(gen, tmp_path):
    from model.export import check_urdf
    [res] = gen.generate("a storage cabinet with two drawers and a door on the left", seed=0)
    obj = res.obj
    labels = [p.label for p in obj.parts]
    assert labels.count("drawer") == 2 and "door" in labels
    body = obj.parts[0]
    assert body.collision, "the carcass should collide as boxes, not as a hull over its openings"
    # the carcass's boxes leave the drawer compartments open: no box contains a drawer's centre
    for p in obj.parts:
        if p.label == "drawer":
            c = p.bbox_center
            assert not any(np.all(b.bounds[0] <= c) and np.all(c <= b.bounds[1])
                           for b in body.collision)
    # the data's frame: standing on z = 0, the body centred on the z axis
    rest = np.concatenate([m.vertices for m in obj.posed_meshes().values()])
    assert abs(rest[:, 2].min()) < 0.003
    np.testing.assert_allclose(body.bbox_center[:2], 0.0, atol=0.003)
    out = gen.export(res, tmp_path / "cabinet", preview=False)
    root = etree.parse(out.urdf_path).getroot()
    from model.export.urdf import link_name
    assert root.findall(f"link[@name='{link_name(body)}']/collision/geometry/box")
    rep = check_urdf(out.urdf_path, obj)
    assert rep.ok, rep.summary()


@pytest.mark.slow     # loads the shipped image model (~15 s); the image path is also checked fast
# on tiny checkpoints (test_imaging_train) and on the shipped file by test_metrics_eval's bench
def test_shipped_image_model_reads_rendered_examples(gen, tmp_path):
    """The shipped image model on the project's own renders of the two built-in example
    objects (never in its training data): the bottle's exact structure from every view, the
    cabinet's category from every view, and an image request through the whole generator
    gives a URDF the simulators load and move."""
    from PIL import Image
    from model.core.example import example_bottle, example_cabinet
    from model.export import check_urdf
    from model.imaging.render import render_view, sample_views
    from model.imaging.model import load_image_model
    im = load_image_model(None)          # the shipped model/weights/image_small.pt
    paths = {}
    for name, obj in (("bottle", example_bottle()), ("cabinet", example_cabinet())):
        for k, view in enumerate(sample_views(f"example_{name}", [p.label for p in obj.parts], 4)):
            path = tmp_path / f"{name}_{k}.png"
            Image.fromarray(render_view(obj, view)).save(path)
            paths.setdefault(name, []).append(path)
            s = im.decode_image(str(path), samples=1, seed=0, temperature=0.0)[0].summary()
            assert s["category"] == obj.category, (name, k, s)
            if name == "bottle":
                assert s["counts"] == {"body": 1, "cap": 1}, (k, s)
                assert s["joint_types"]["cap"] == ["screw"], (k, s)
    [res] = gen.generate(image=str(paths["bottle"][0]), seed=0)
    assert res.obj.category == "Bottle"
    out = gen.export(res, tmp_path / "from_image", preview=False)
    rep = check_urdf(out.urdf_path, res.obj)
    assert rep.ok, rep.summary()


def test_carved_parts_are_written_closed(tmp_path):
    """The screw cap's sweep carves the bottle's body; exact booleans leave coincident
    vertices and needle faces there, which the export collapses so the written OBJ reads
    back closed. (A swivel cap, fitted to its stick, no longer carves it.)"""
    import trimesh

    from model.pipeline.generator import Generator
    g = Generator.load(GenerationConfig())
    try:
        [res] = g.generate("a water bottle with a screw cap", seed=0)
        assert "body_0" in res.obj.metadata["refine"]["meshes"]["carved"]
        out = g.export(res, tmp_path / "bottle", preview=False)
        for p in res.obj.parts:
            back = trimesh.load(tmp_path / "bottle" / "meshes" / f"{p.name}.obj", force="mesh")
            assert back.is_watertight, p.name
        assert out.urdf_path
    finally:
        g.close()


def test_a_chest_of_five_drawers_is_a_stack_of_one_drawer_meshed_once(gen):
    """A stated stack: refinement stacks the drawers as equal drawers, which share the first
    one's shape: each drawer's mesh and collision boxes are the first one's moved to its box,
    and the grids decoded are one per distinct part."""
    calls = []
    decode = gen.shape.decode_grids

    def counted(z, **kw):
        calls.append(len(z))
        return decode(z, **kw)
    gen.shape.decode_grids = counted
    try:
        [res] = gen.generate("a chest of five drawers stacked one above the other", seed=1)
    finally:
        gen.shape.decode_grids = decode
    drawers = [p for p in res.obj.parts if p.label == "drawer"]
    assert len(drawers) == 5
    zs = sorted(p.bbox_center[2] for p in drawers)
    assert all(b - a > 0.9 * drawers[0].bbox_size[2] for a, b in zip(zs, zs[1:]))   # stacked
    first = drawers[0]
    for p in drawers[1:]:
        assert np.allclose(p.bbox_size, first.bbox_size, atol=1e-3)
        assert np.array_equal(p.latent, first.latent)
        shift = p.bbox_center - first.bbox_center
        assert np.allclose(np.asarray(p.mesh.bounds), np.asarray(first.mesh.bounds) + shift,
                           atol=1e-3)
        assert len(p.mesh.faces) == len(first.mesh.faces)
    assert calls and calls[0] < len(res.obj.parts) - 3


def test_a_microwave_keypad_is_a_column_of_controls_beside_its_door(gen):
    """"A microwave with a keypad": at least two buttons (the stated lower bound holds though
    the network alone reads a washer), and every knob and button in one column right of the
    door, knobs above buttons, none overlapping another, none squeezed under 5 mm."""
    for seed in range(6):       # seeds 3-5 had a button cut to 3 mm by a knob above it
        trees, *_ = gen.decode_trees("a microwave with a keypad", seed=seed)
        obj = gen.layout(trees[0])
        parts = obj.parts
        ctrl = [p for p in parts if p.label in ("knob", "button")]
        door = next(p for p in parts if p.label == "door")
        assert sum(p.label == "button" for p in ctrl) >= 2, seed
        lo = {id(p): p.bbox_center - p.bbox_size / 2 for p in ctrl + [door]}
        hi = {id(p): p.bbox_center + p.bbox_size / 2 for p in ctrl + [door]}
        for a in ctrl:
            assert lo[id(a)][1] >= hi[id(door)][1], seed          # right of the door
            assert np.all(a.bbox_size[1:] >= 0.005), (seed, a.label, a.bbox_size)
            for b in ctrl:
                if a is not b:
                    assert not np.all((lo[id(a)] < hi[id(b)] - 1e-6)
                                      & (lo[id(b)] < hi[id(a)] - 1e-6)), seed
        knobs = [p.bbox_center[2] for p in ctrl if p.label == "knob"]
        buttons = [p.bbox_center[2] for p in ctrl if p.label == "button"]
        assert not knobs or min(knobs) > max(buttons), seed


def test_a_safes_keypad_is_a_three_by_three_grid_on_its_door(gen):
    """"A safe with a keypad and a door": the usual keypad of the data, nine buttons on the
    door in three rows of three, none overlapping (seeds 0-2)."""
    for seed in range(3):
        trees, *_ = gen.decode_trees("a safe with a keypad and a door", seed=seed)
        obj = gen.layout(trees[0])
        keys = [p for p in obj.parts if p.label == "button"]
        assert len(keys) == 9 and all(obj.parts[p.parent].label == "door" for p in keys), seed
        for ax in (1, 2):                                  # three columns and three rows
            assert len(np.unique(np.round([p.bbox_center[ax] for p in keys], 4))) == 3, seed



def test_a_safe_door_on_one_side_covers_the_front_hinged_there(gen):
    """"A safe with a keypad and a door on the right" had its door moved to the right half of
    the front (seeds 0-5: 0.175 m of a 0.44 m wide body), the rest of the safe open. The door
    covers the front and turns on its right edge (the viewer's right: +y)."""
    for seed in range(2):
        trees, *_ = gen.decode_trees("a safe with a keypad and a door on the right", seed=seed)
        obj = gen.layout(trees[0])
        body, [door] = obj.parts[0], [p for p in obj.parts if p.label == "door"]
        assert door.bbox_size[1] > 0.7 * body.bbox_size[1], (seed, door.bbox_size)   # walls
        assert door.joint.origin[1] > door.bbox_center[1] + 0.4 * door.bbox_size[1], seed


def test_doors_in_the_top_row_and_drawers_in_the_bottom_row(gen):
    """"Four doors in the top row and four drawers in the bottom row" came out as four
    full-height doors with the drawers in a column on the cabinet's side (seeds 0-2): every
    door now sits above every drawer, each row side by side."""
    for seed in range(2):
        trees, *_ = gen.decode_trees("a long cabinet with four doors in the top row and four "
                                     "drawers in the bottom row", seed=seed)
        obj = gen.layout(trees[0])
        rows = {lab: [p for p in obj.parts if p.label == lab] for lab in ("door", "drawer")}
        assert len(rows["door"]) == 4 and len(rows["drawer"]) == 4, seed
        lowest_door = min(p.bbox_center[2] - p.bbox_size[2] / 2 for p in rows["door"])
        highest_drawer = max(p.bbox_center[2] + p.bbox_size[2] / 2 for p in rows["drawer"])
        assert lowest_door >= highest_drawer - 1e-3, (seed, lowest_door, highest_drawer)
        for parts in rows.values():
            zs = [p.bbox_center[2] for p in parts]
            assert max(zs) - min(zs) < 0.01, (seed, zs)                   # one row each


def test_a_locker_is_tall_and_a_filing_cabinet_one_narrow_column_of_drawers(gen):
    """The data calls a body a locker only over 1.2 m tall and under 0.65 m wide, and a
    filing cabinet only one column of drawers under 0.6 m wide: "a locker" decoded under
    1.2 m in 7 of 8 seeds, "a filing cabinet with four drawers" in two or three columns
    0.8-1 m wide in 5 of 8."""
    for seed in range(4):
        trees, *_ = gen.decode_trees("a locker", seed=seed)
        body = gen.layout(trees[0]).parts[0]
        assert body.bbox_size[2] > 1.2 and body.bbox_size[1] < 0.65, (seed, body.bbox_size)
        trees, *_ = gen.decode_trees("a filing cabinet with four drawers", seed=seed)
        obj = gen.layout(trees[0])
        drawers = [p for p in obj.parts if p.label == "drawer"]
        assert len(drawers) == 4 and obj.parts[0].bbox_size[1] < 0.6, seed
        ys = [p.bbox_center[1] for p in drawers]
        assert max(ys) - min(ys) < 0.01, (seed, ys)                    # one column


def test_size_words_give_the_body_its_size_and_seeds_still_vary_it(gen):
    """"a tall bathroom cabinet" decoded 0.46-0.56 m tall with seeds 0-3 (storage furniture
    is 0.74-1.52 m tall between its quartiles): the network does not read size words. The
    body goes into the matching quarter of the data's sizes for its category."""
    from model.data.prompt_size import SIZE_SPREAD
    heights = []
    for seed in range(4):
        trees, *_ = gen.decode_trees("a tall bathroom cabinet", seed=seed)
        body = gen.layout(trees[0]).parts[0]
        heights.append(round(float(body.bbox_size[2]), 3))
        assert body.bbox_size[2] >= SIZE_SPREAD["StorageFurniture"]["height"][2] - 1e-3, seed
        trees, *_ = gen.decode_trees("a compact oven with two knobs", seed=seed)
        size = np.prod(gen.layout(trees[0]).parts[0].bbox_size) ** (1 / 3)
        assert size <= SIZE_SPREAD["Oven"]["size"][1] + 1e-3, (seed, size)
    assert len(set(heights)) >= 3, heights


def test_a_hutch_has_two_rows_of_doors_and_a_thermos_a_bottles_size(gen):
    """"a hutch with two upper doors and two lower doors" came out with three doors stacked
    and the fourth on the body's top or bottom face, over an open band (seeds 0-3); "a
    thermos with a screw-on cap" as a bottle 35-57 cm wide (seeds 0-2), "a small safe with a
    digital keypad" 2.5 cm tall (seed 3)."""
    from model.data.prompt_size import SIZE_SPREAD
    from model.data.spatial import arrangement, body_box, part_position
    for seed in range(4):
        trees, *_ = gen.decode_trees("a hutch with two upper doors and two lower doors",
                                     seed=seed)
        obj = gen.layout(trees[0])
        doors = [i for i, p in enumerate(obj.parts) if p.label == "door"]
        got = arrangement(obj, doors)
        assert (got["layout"], got["rows"], got["columns"]) == ("grid", 2, 2), (seed, got)
        low = min(obj.parts[i].bbox_center[2] - obj.parts[i].bbox_size[2] / 2 for i in doors)
        assert low - (body_box(obj)[0][2] - body_box(obj)[1][2] / 2) < 0.05, seed
        assert sorted(part_position(obj, i)[1] for i in doors) == \
            ["bottom", "bottom", "top", "top"], seed
    for seed in range(3):
        for text, cat in (("a thermos with a screw-on cap", "Bottle"),
                          ("a small safe with a digital keypad", "Safe")):
            trees, *_ = gen.decode_trees(text, seed=seed + 1)
            size = gen.layout(trees[0]).parts[0].bbox_size
            for ax, dim in enumerate(("depth", "width", "height")):
                lo, *_, hi = SIZE_SPREAD[cat][dim]
                assert lo - 1e-3 <= size[ax] <= hi + 1e-3, (text, seed, size)


def test_knobs_on_a_nightstands_drawers_are_round_knob_pulls(gen):
    """"a nightstand with two drawers and a small knob on each" had 15 cm bar handles with
    every seed: now a round knob 3.2 cm across on each drawer."""
    for res in gen.generate("a nightstand with two drawers and a small knob on each", seed=0,
                            samples=2):
        hs = [p for p in res.obj.parts if p.label == "handle"]
        assert len(hs) == 2
        for h in hs:
            lo, hi = h.mesh.bounds
            size = hi - lo
            assert size[1] < 0.04 and size[2] < 0.04, size               # not a bar
            assert size[1] == pytest.approx(size[2], rel=0.1)           # round
            assert res.obj.parts[h.parent].label == "drawer"
        assert res.obj.metadata["refine"]["meshes"]["revolved"] == [h.name for h in hs]
    [plain] = gen.generate("a nightstand with two drawers", seed=0)
    assert "knob_handles" not in plain.obj.metadata
