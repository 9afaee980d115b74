"""Offscreen rendering: preview PNG and the reusable render_views."""
import numpy as np
import pytest

from model.core.example import example_bottle, example_cabinet
from model.export.render import RenderOptions, random_options, render_views, write_preview


@pytest.fixture(scope="module")
def cabinet():
    return example_cabinet()


def test_preview_png_written_and_not_blank(cabinet, tmp_path):
    from PIL import Image
    path = write_preview(cabinet, tmp_path / "preview.png", size=160)
    img = np.asarray(Image.open(path).convert("RGB"))
    assert img.shape == (160, 3 * 160 + 2 * 4, 3)
    views = [img[:, k * 164:k * 164 + 160] for k in range(3)]
    for v in views:
        covered = np.any(v < 250, axis=2).mean()
        assert 0.05 < covered < 0.9                       # an object, not empty, not a wall
        assert v.std() > 10                               # shaded, not one flat colour
    # Openness 0 and 1 differ (drawers out, door open), and wider at openness 1.
    assert np.abs(views[0].astype(int) - views[2].astype(int)).mean() > 2
    assert not list(tmp_path.glob(".*"))                  # written atomically


def test_render_views_shape_and_framing(cabinet):
    imgs = render_views(cabinet, (0.0, 1.0), (96, 128))
    assert imgs.shape == (2, 96, 128, 3) and imgs.dtype == np.uint8
    bg = np.array(RenderOptions().background) * 255
    for im in imgs:
        mask = np.any(np.abs(im.astype(float) - bg) > 3, axis=2)
        ys, xs = np.nonzero(mask)
        # Framed inside the image with a margin on every side.
        assert ys.min() > 0 and xs.min() > 0 and ys.max() < 95 and xs.max() < 127


def test_render_deterministic_and_seed_varies(cabinet):
    a = render_views(cabinet, (0.5,), 64, seed=3)
    b = render_views(cabinet, (0.5,), 64, seed=3)
    c = render_views(cabinet, (0.5,), 64, seed=4)
    assert np.array_equal(a, b)
    assert np.abs(a.astype(int) - c.astype(int)).mean() > 5
    o3, o4 = random_options(3), random_options(4)
    assert o3 == random_options(3) and o3 != o4 and o3.colour_mode == "random"


def test_render_occlusion_front_part_wins():
    """The cap must hide the neck from above: a z-buffer, not painter's order."""
    b = example_bottle()
    top = RenderOptions(azimuth=0.0, elevation=89.0, supersample=1)
    img = render_views(b, (0.0,), 64, options=top)[0]
    centre = img[28:36, 28:36].reshape(-1, 3).mean(axis=0)
    cap_colour = np.array([0.15, 0.35, 0.75])
    assert centre[2] > centre[0] + 30, centre                        # blue (the cap)
    assert cap_colour[2] > cap_colour[0]


def test_render_empty_object_gives_background():
    b = example_bottle()
    for p in b.parts:
        p.mesh = None
    img = render_views(b, (0.0,), 32, options=RenderOptions(background=(0.2, 0.4, 0.6)))[0]
    assert np.all(img == np.round(np.array([0.2, 0.4, 0.6]) * 255).astype(np.uint8))


def test_bad_colour_mode():
    with pytest.raises(ValueError, match="colour_mode"):
        render_views(example_bottle(), (0.0,), 16, options=RenderOptions(colour_mode="rainbow"))


def test_back_face_culling_keeps_inverted_and_open_meshes_visible():
    """Culling applies only to closed, outward-wound meshes: an inverted or open cap still
    renders exactly like the correct one."""
    import trimesh
    b = example_bottle()
    opts = RenderOptions(supersample=1)
    ref = render_views(b, (0.0,), 64, options=opts)[0]
    cap = b.parts[1].mesh
    for mesh in (trimesh.Trimesh(cap.vertices, cap.faces[:, ::-1]),      # inward winding
                 trimesh.Trimesh(cap.vertices, cap.faces[:-1])):         # one face missing
        b.parts[1].mesh = mesh
        img = render_views(b, (0.0,), 64, options=opts)[0]
        assert np.abs(img.astype(int) - ref.astype(int)).mean() < 1.0


def test_part_id_render_matches_the_colour_render(cabinet):
    """render_part_ids sees what render_views draws: the same silhouette (one sample per
    pixel, same camera) and, seen from the front with everything open, every part."""
    from model.export.render import render_part_ids
    opt = RenderOptions(azimuth=20.0, elevation=15.0, supersample=1, background=(1.0, 0.0, 1.0))
    for ratio in (0.0, 1.0):
        ids = render_part_ids(cabinet, ratio, (96, 128), options=opt)
        img = render_views(cabinet, (ratio,), (96, 128), options=opt)[0]
        assert ids.shape == (96, 128) and ids.min() == -1 and ids.max() < len(cabinet.parts)
        background = np.all(img == np.array([255, 0, 255]), axis=2)
        assert np.array_equal(ids == -1, background)
    px = np.bincount(ids[ids >= 0], minlength=len(cabinet.parts))
    assert np.all(px > 0), px


def test_part_id_render_knows_hidden_parts():
    """From straight above the bottle's cap covers the centre; from straight below the body
    hides it completely (0 pixels), which a colour render cannot tell apart from "small"."""
    from model.export.render import render_part_ids
    b = example_bottle()
    cap = [p.label for p in b.parts].index("cap")
    top = render_part_ids(b, 0.0, 64, options=RenderOptions(azimuth=0.0, elevation=89.0))
    assert top[32, 32] == cap
    below = render_part_ids(b, 0.0, 64, options=RenderOptions(azimuth=0.0, elevation=-89.0))
    assert (below == cap).sum() == 0 and (below == 1 - cap).sum() > 100
