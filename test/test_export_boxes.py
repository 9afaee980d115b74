"""Collision boxes from an occupancy grid (generated parts) and how the exporter writes them."""
from pathlib import Path

import numpy as np
import pytest
import trimesh
from lxml import etree

from model.core import ArticulatedObject, Joint, JointType, Part
from model.export import check_urdf, export_object
from model.export.collision import is_box, occupancy_boxes


def carcass_grid(n=40, wall=3, open_front=True):
    """A hollow box open at +x with one shelf: six slabs."""
    occ = np.zeros((n, n, n), bool)
    occ[:wall] = True                      # back
    occ[:, :wall] = occ[:, -wall:] = True  # sides
    occ[:, :, :wall] = occ[:, :, -wall:] = True
    occ[:, :, n // 2:n // 2 + wall] = True  # shelf
    if not open_front:
        occ[-wall:] = True
    return occ


def cells_of(boxes, lo, hi, shape):
    """Which grid cells the boxes cover (bool grid)."""
    cover = np.zeros(shape, bool)
    cell = (np.asarray(hi) - np.asarray(lo)) / np.asarray(shape)
    for b in boxes:
        a = np.round((b.bounds[0] - lo) / cell).astype(int)
        c = np.round((b.bounds[1] - lo) / cell).astype(int)
        cover[a[0]:c[0], a[1]:c[1], a[2]:c[2]] = True
    return cover


def test_carcass_becomes_its_slabs_and_keeps_the_opening():
    occ = carcass_grid()
    lo, hi = np.array([-0.2, -0.4, 0.0]), np.array([0.2, 0.4, 0.9])
    boxes, cov = occupancy_boxes(occ, lo, hi)
    assert all(is_box(b) for b in boxes)
    assert 5 <= len(boxes) <= 7 and cov == 1.0
    cover = cells_of(boxes, lo, hi, occ.shape)
    assert np.array_equal(cover, occ)                  # exactly the solid: no empty cell covered
    for b in boxes:                                    # inside the grid's box
        assert np.all(b.bounds[0] >= lo - 1e-9) and np.all(b.bounds[1] <= hi + 1e-9)


def test_layer_fill_bridges_holes_but_not_openings():
    occ = carcass_grid()
    rng = np.random.default_rng(0)
    holes = occ & (rng.random(occ.shape) < 0.08)       # a wavy learned wall has pinholes
    boxes_strict, cov_strict = occupancy_boxes(occ & ~holes, [0] * 3, [1] * 3)
    boxes, cov = occupancy_boxes(occ & ~holes, [0] * 3, [1] * 3, layer_fill=0.8)
    assert cov > 0.95 and len(boxes) < len(boxes_strict)
    cover = cells_of(boxes, np.zeros(3), np.ones(3), occ.shape)
    n = occ.shape[0]
    assert not cover[n // 3:, n // 4:-n // 4, n // 8:n // 2 - 2].any()   # the compartment stays open


def test_empty_and_caps():
    assert occupancy_boxes(np.zeros((8, 8, 8), bool), [0] * 3, [1] * 3) == ([], 0.0)
    blobs = np.zeros((30, 30, 30), bool)
    for k in range(8):                                 # 8 separate 3-cell cubes
        i, j = 3 * (k % 4) * 2, 3 * (k // 4) * 2
        blobs[i:i + 3, j:j + 3, 10:13] = True
    boxes, cov = occupancy_boxes(blobs, [0] * 3, [1] * 3, max_boxes=5)
    assert len(boxes) == 5 and cov == pytest.approx(5 / 8)
    speck = np.zeros((10, 10, 10), bool)
    speck[3, 3, 3] = True                              # single cells are not worth a box
    assert occupancy_boxes(speck, [0] * 3, [1] * 3)[0] == []


def test_exporter_writes_part_boxes_as_urdf_primitives(tmp_path):
    body = trimesh.creation.box(extents=[0.4, 0.6, 0.8])
    body.apply_translation([0, 0, 0.4])
    door = trimesh.creation.box(extents=[0.02, 0.6, 0.8])
    door.apply_translation([0.21, 0, 0.4])
    occ = carcass_grid(open_front=False)
    boxes, _ = occupancy_boxes(occ, [-0.2, -0.3, 0.0], [0.2, 0.3, 0.8])
    obj = ArticulatedObject(name="crate", category="storage", parts=[
        Part("body", "body", -1, bbox_center=[0, 0, 0.4], bbox_size=[0.4, 0.6, 0.8], mesh=body,
             collision=boxes),
        Part("door", "door", 0, bbox_center=[0.21, 0, 0.4], bbox_size=[0.02, 0.6, 0.8], mesh=door,
             joint=Joint(JointType.REVOLUTE, origin=[0.22, -0.3, 0.4], axis=[0, 0, 1],
                         r_range=[0, 1.5]))])
    out = export_object(obj, tmp_path / "crate", preview=False)
    root = etree.parse(out.urdf_path).getroot()
    body_link = root.find("link[@name='body']")
    sizes = [c.find("geometry/box").get("size") for c in body_link.findall("collision")]
    assert len(sizes) == len(boxes) and all(s is not None for s in sizes)
    assert not list(Path(out.out_dir, "meshes").glob("body_collision_*"))   # no files for boxes
    assert list(Path(out.out_dir, "meshes").glob("door_collision_*"))        # derived as before
    rep = check_urdf(out.urdf_path, obj)
    assert rep.ok, rep.summary()


def test_explicit_method_overrides_part_boxes(tmp_path):
    from model.export import CollisionConfig
    body = trimesh.creation.box(extents=[0.4, 0.4, 0.4])
    boxes, _ = occupancy_boxes(np.ones((4, 4, 4), bool), [-0.2] * 3, [0.2] * 3)
    obj = ArticulatedObject(name="cube", category="storage", parts=[
        Part("body", "body", -1, bbox_size=[0.4] * 3, mesh=body, collision=boxes)])
    out = export_object(obj, tmp_path / "c", preview=False, collision=CollisionConfig(method="hull"))
    root = etree.parse(out.urdf_path).getroot()
    assert root.find("link/collision/geometry/mesh") is not None
    assert root.find("link/collision/geometry/box") is None


@pytest.mark.parametrize("n", [0, 1, 3])
def test_torch_threads_restores(n):
    import torch

    from model.core.runtime import torch_threads
    before = torch.get_num_threads()
    with torch_threads(n):
        if n >= 1:
            assert torch.get_num_threads() == n
    assert torch.get_num_threads() == before
