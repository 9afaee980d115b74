"""Bottles as solids of revolution (model/refine/revolve.py)."""
import math

import numpy as np
import pytest
import trimesh

from model.core import meshops
from model.refine.meshes import manifolds_of
from model.refine.revolve import revolve_vessels, revolved


def _slatted_cap(slats: int = 12, cover: float = 0.5):
    """A 5 cm screw cap as the shape prior decodes one: a 2 mm top disc over a skirt of
    ``slats`` separate 2 mm slats covering ``cover`` of its circumference, 11 mm long."""
    top = meshops.cylinder(0.025, 0.002, (0, 0, 0.014), segments=64)
    width = cover * 2 * math.pi * 0.024 / slats
    pieces = [top]
    for a in np.arange(slats) * 2 * math.pi / slats:
        slat = trimesh.creation.box([0.002, width, 0.0115])
        slat.apply_transform(trimesh.transformations.rotation_matrix(a, (0, 0, 1)) @
                             trimesh.transformations.translation_matrix((0.024, 0, 0.0075)))
        pieces.append(meshops.to_manifold(slat))
    return meshops.union_manifolds(pieces)


def _inside(man, points) -> np.ndarray:
    return meshops.to_trimesh(man).contains(np.asarray(points, dtype=np.float64))


def test_a_slatted_cap_closes_into_one_round_shell_with_its_bore_open():
    cap = _slatted_cap()
    assert len(cap.decompose()) == 1 and float(cap.volume()) > 0
    new = revolved(cap, (0, 0, 0), (0, 0, 1))
    assert new is not None and len(new.decompose()) == 1
    lo, hi = np.asarray(new.bounding_box()).reshape(2, 3)
    assert hi[0] - lo[0] == pytest.approx(hi[1] - lo[1], rel=0.01)     # round
    assert lo[2] == pytest.approx(0.002, abs=5e-4) and hi[2] == pytest.approx(0.015, abs=5e-4)
    # the gap between two slats (half way round from a slat) is skirt now; the bore is open
    gap = math.pi / 12
    assert _inside(new, [(0.024 * math.cos(gap), 0.024 * math.sin(gap), 0.007)]).all()
    assert not _inside(new, [(0, 0, 0.007), (0.015, 0, 0.005)]).any()
    assert float(new.volume()) > 1.3 * float(cap.volume())


def test_a_rippled_body_comes_out_round_with_its_girth():
    """An eight-sided 20 cm body (as every decoded bottle body has been) becomes a cylinder
    between its flats and its corners; an off-axis block (rays from the axis rarely meet
    it) is refused."""
    body = meshops.cylinder(0.04, 0.2, (0, 0, 0.1), segments=8)
    new = revolved(body, (0, 0, 0.1), (0, 0, 1))
    assert new is not None and len(new.decompose()) == 1
    v = trimesh.sample.sample_surface(meshops.to_trimesh(new), 4000, seed=0)[0]
    r = np.linalg.norm(v[np.abs(v[:, 2] - 0.1) < 0.05, :2], axis=1)
    apothem = 0.04 * math.cos(math.pi / 8)
    assert r.size and apothem - 1e-3 < r.min() and r.max() < 0.04 + 1e-3
    assert np.ptp(r) < 1e-3
    assert float(new.volume()) == pytest.approx(float(body.volume()), rel=0.05)
    off = meshops.box((0.02, 0.02, 0.02), (0.1, 0, 0))
    assert revolved(off, (0, 0, 0), (0, 0, 1)) is None


def test_a_bottles_body_and_screw_cap_are_rebuilt_about_the_caps_axis_and_nothing_else():
    from model.core.example import example_bottle, example_cabinet
    obj = example_bottle()
    cap = obj.parts[1]
    slats = _slatted_cap().translate((0.0, 0.0, 0.2))
    cap.mesh = meshops.to_trimesh(slats)
    mans = manifolds_of(obj)
    assert revolve_vessels(obj, mans) == ["body", "cap"]
    assert len(mans[1].decompose()) == 1 and float(mans[1].volume()) > 1.3 * float(slats.volume())
    assert float(mans[0].volume()) == pytest.approx(float(obj.parts[0].mesh.volume), rel=0.05)
    cab = example_cabinet()
    mans = manifolds_of(cab)
    before = {i: float(m.volume()) for i, m in mans.items()}
    assert revolve_vessels(cab, mans) == []
    assert {i: float(m.volume()) for i, m in mans.items()} == before
