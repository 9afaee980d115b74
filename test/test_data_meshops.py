"""Exact booleans of model.core.meshops and the vocabulary tables."""
import numpy as np
import pytest
import trimesh

from model.core import meshops
from model.data import vocab


def _box(size, at=(0, 0, 0)):
    m = trimesh.creation.box(size)
    m.apply_translation(at)
    return m


def test_volume_intersection_iou_union():
    a, b = _box([1, 1, 1]), _box([1, 1, 1], (0.5, 0, 0))
    assert meshops.volume(a) == pytest.approx(1.0)
    assert meshops.intersection_volume(a, b) == pytest.approx(0.5)
    assert meshops.volume_iou(a, b) == pytest.approx(0.5 / 1.5)
    assert meshops.union([a, b]).volume == pytest.approx(1.5)
    assert meshops.difference(a, b).volume == pytest.approx(0.5)
    assert meshops.volume_iou(a, a.copy()) == pytest.approx(1.0)


def test_touching_faces_is_zero_and_disjoint_skipped():
    a, c = _box([1, 1, 1]), _box([1, 1, 1], (1.0, 0, 0))
    assert meshops.intersection_volume(a, c) == pytest.approx(0.0, abs=1e-9)
    far = _box([1, 1, 1], (5, 0, 0))
    M = meshops.pairwise_intersection_volumes([a, c, far])
    assert M.shape == (3, 3) and np.allclose(np.diag(M), 1.0) and abs(M[0, 1]) < 1e-9
    iou = meshops.pairwise_iou([a, _box([1, 1, 1], (0.5, 0, 0))])
    assert iou[0, 1] == pytest.approx(1 / 3)


def test_open_sheet_raises_or_hull_fallback():
    sheet = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                            faces=[[0, 1, 2], [0, 2, 3]])  # two triangles, cannot be closed by repair
    with pytest.raises(meshops.NotWatertightError):
        meshops.volume(sheet)
    assert meshops.volume(sheet, fallback="hull") == pytest.approx(1 / 6)


def test_primitives_are_closed():
    cyl = meshops.to_trimesh(meshops.cylinder(0.1, 1.0, axis="x", segments=64))
    assert cyl.is_watertight
    assert np.allclose(cyl.bounds, [[-0.5, -0.1, -0.1], [0.5, 0.1, 0.1]], atol=1e-6)
    assert meshops.volume(cyl) == pytest.approx(np.pi * 0.01, rel=0.01)


def test_vocab_tables():
    assert len(set(vocab.LABELS)) == len(vocab.LABELS)
    assert set(vocab.CATEGORIES) == {"StorageFurniture", "Safe", "Oven", "WashingMachine", "Bottle", "USB"}
    for table in (vocab.PART_SYNONYMS, vocab.MOTION_SYNONYMS):
        assert all(len(v) >= 3 for v in table.values())
    assert all(len(vocab.CATEGORY_SYNONYMS[c]) >= 3 for c in vocab.CATEGORIES)
    assert vocab.lookup_label("pull-out drawers") == "drawer"
    assert vocab.lookup_label("hinged doors") == "door"
    assert vocab.lookup_category("washers") == "WashingMachine"
    assert vocab.map_partnet_label("rotation_door") == "door"
    assert vocab.map_partnet_label("furniture_body") == "body"
    assert vocab.map_partnet_label("mystery") == "other"
    assert vocab.semantic_text("StorageFurniture", "drawer") == "storage furniture, drawer"


def test_drop_degenerate_removes_zero_area_slivers_and_keeps_clean_meshes():
    import trimesh

    from model.core.meshops import drop_degenerate
    box = trimesh.creation.box(extents=(1.0, 0.5, 0.2))
    assert drop_degenerate(box) is box                      # nothing to drop: the same mesh
    v = np.vstack([box.vertices, (box.vertices[0] + box.vertices[1]) / 2])
    f = np.vstack([box.faces, [[0, 1, len(v) - 1]]])        # a zero-area face on an edge
    sliver = trimesh.Trimesh(v, f, process=False)
    assert not sliver.is_watertight
    clean = drop_degenerate(sliver)
    assert len(clean.faces) == 12 and clean.is_watertight
    assert clean.volume == pytest.approx(0.1)


def test_sheets_touching_along_an_edge_stay_closed_once_written():
    """Two cubes meeting along one edge, each closed, vertices not shared: merged by
    position (as a file reader does) the shared edge has four faces and the mesh is open;
    separate_coincident keeps them a couple of micrometres apart, closed, same volume."""
    import trimesh
    from model.core.meshops import separate_coincident
    a = trimesh.creation.box((1, 1, 1))
    b = trimesh.creation.box((1, 1, 1))
    b.apply_translation((1, 1, 0))
    both = trimesh.Trimesh(np.vstack([a.vertices, b.vertices]),
                           np.vstack([a.faces, b.faces + len(a.vertices)]), process=False)
    merged = both.copy()
    merged.merge_vertices()
    assert not merged.is_watertight
    apart = separate_coincident(both)
    merged = apart.copy()
    merged.merge_vertices()
    assert merged.is_watertight and merged.volume == pytest.approx(2.0, rel=1e-4)
    assert np.abs(apart.vertices - both.vertices).max() < 1e-5
