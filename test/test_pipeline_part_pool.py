"""Meshing lanes (model.pipeline.part_pool): the helper's parts equal the caller's, the split
is deterministic, and a helper that dies or fails costs a warning, never a part."""
import numpy as np
import pytest
import torch

from model.core import meshops
from model.geometry.meshing import evaluate_grids
from model.geometry.surface import SdfGrid
from model.pipeline.part_finish import PartTask, finish_parts
from model.pipeline.part_pool import PartPool, split_by_cost


def _tasks(n=4):
    def field(k):
        c = torch.tensor([0.1 * k, 0.0, -0.05 * k])
        return lambda x: torch.maximum((x - c).abs().max(-1).values - 0.6,      # a box with
                                       0.25 - (x - c)[..., :2].norm(dim=-1))   # a hole through
    out = []
    for k in range(n):
        [g] = evaluate_grids(field(k), 1, 32)
        out.append(PartTask(k, g, np.array([0.0, 0.2 * k, 0.3]), np.array([0.4, 0.3, 0.5 + k / 10])))
    return out


def _same(a, b):
    assert [d.index for d in a] == [d.index for d in b]
    for x, y in zip(a, b):
        assert x.status == y.status and x.evaluations == y.evaluations
        assert np.array_equal(x.vertices, y.vertices) and np.array_equal(x.faces, y.faces)
        assert len(x.boxes) == len(y.boxes)
        for (e1, t1), (e2, t2) in zip(x.boxes, y.boxes):
            assert np.array_equal(e1, e2) and np.array_equal(t1, t2)
        assert len(x.prepared.steps) == len(y.prepared.steps)
        for p, q in zip((x.prepared.whole,) + x.prepared.steps,
                        (y.prepared.whole,) + y.prepared.steps):
            assert (p is None) == (q is None)
            if p is not None:
                assert np.array_equal(p[0], q[0]) and np.array_equal(p[1], q[1])


def test_split_by_cost_is_balanced_and_deterministic():
    tasks = _tasks(4)
    lanes = split_by_cost(tasks, 2)
    assert sorted(t.index for lane in lanes for t in lane) == [0, 1, 2, 3]
    assert [[t.index for t in lane] for lane in lanes] == \
        [[t.index for t in lane] for lane in split_by_cost(tasks, 2)]
    assert all(lane for lane in lanes)


def test_helper_gives_the_callers_parts_and_survives_a_dead_helper(caplog):
    tasks = _tasks(4)
    here = finish_parts(tasks)
    assert all(d.ok and d.prepared is not None for d in here)
    man = meshops.unpack(here[0].prepared.whole)
    assert man.volume() == pytest.approx(here[0].mesh().volume, rel=1e-6)
    pool = PartPool(1).start()
    try:
        _same(pool.finish(tasks), here)
        assert pool.failures == 0
        pool._helpers[0].proc.kill()                 # dies between objects
        pool._helpers[0].proc.wait()
        _same(pool.finish(tasks), here)              # a new helper starts
        assert pool.failures == 0
        # a part that fails in the helper: warned, retried here, where it fails again
        grid = SdfGrid(np.zeros((3, 3)), 0)
        bad = PartTask(9, grid, tasks[0].center, tasks[0].size)
        big = PartTask(0, tasks[0].grid, tasks[0].center, tasks[0].size)
        big.grid.evaluations = 10 ** 9                      # lane 0 (here); bad goes out
        with pytest.raises(Exception):
            pool.finish([big, bad])
        assert pool.failures == 1 and "meshing helper" in caplog.text
        _same(pool.finish(tasks[1:]), here[1:])
        # ... and one that fails here while the helper works: its answer is not left over
        bad.grid.evaluations = 10 ** 9
        with pytest.raises(Exception):
            pool.finish([bad] + tasks[1:])
        _same(pool.finish(tasks[1:]), here[1:])
    finally:
        pool.close()
    assert pool._helpers == [None]


def test_an_instance_is_its_first_part_moved_to_its_box():
    from model.core import ArticulatedObject, Part
    from model.pipeline.generator import instances
    [t] = _tasks(1)
    t.center = np.array([0.0, 0.0, 0.3])
    t.size = np.array([0.4, 0.3, 0.5])
    [d] = finish_parts([t])
    offset = np.array([0.0, 0.25, -0.1])
    moved = d.moved(7, offset)
    t.center = t.center + offset                   # what meshing the copy itself would give
    [own] = finish_parts([t])
    own.index, own.evaluations = 7, 0
    assert moved.index == 7 and moved.ok
    assert np.allclose(moved.vertices, own.vertices) and np.array_equal(moved.faces, own.faces)
    for (e1, t1), (e2, t2) in zip(moved.boxes, own.boxes):
        assert np.allclose(e1, e2) and np.allclose(t1, t2)
    assert moved.prepared.manifold(0).volume() == pytest.approx(d.prepared.manifold(0).volume())
    assert np.allclose(np.array(moved.prepared.manifold().bounding_box()),
                       np.array(own.prepared.manifold().bounding_box()))

    def part(label, size):
        return Part(name=label, label=label, parent=0, bbox_center=(0, 0, 0), bbox_size=size)
    obj = ArticulatedObject(category="StorageFurniture", name="x", parts=[
        Part(name="body", label="body", parent=-1, bbox_center=(0, 0, 0), bbox_size=(1, 1, 1)),
        part("drawer", (0.4, 0.8, 0.1)), part("drawer", (0.4, 0.8, 0.10005)),
        part("drawer", (0.4, 0.8, 0.2)), part("handle", (0.4, 0.8, 0.1)),
        part("drawer", (0.4, 0.8, 0.2))])
    assert instances(obj, [1, 2, 3, 4, 5]) == {2: 1, 5: 3}
    assert instances(obj, [2, 3, 4]) == {}
