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
    out = gen.export(res, tmp_path / "cabinet", preview=False)
    root = etree.parse(out.urdf_path).getroot()
    from model.export.urdf import link_name
    assert root.findall(f"link[@name='{link_name(body)}']/collision/geometry/box")
    rep = check_urdf(out.urdf_path, obj)
    assert rep.ok, rep.summary()
