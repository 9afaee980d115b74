"""Shared helpers of model.core.files: atomic writes, strict JSON, slugs."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from model.core.files import atomic_write_json, atomic_write_text, jsonable, slug
from model.core.objects import rotation_matrix, rpy_matrix


def test_atomic_write_leaves_no_temp_file_and_replaces(tmp_path):
    p = tmp_path / "sub" / "a.json"
    atomic_write_json(p, {"a": 1})
    atomic_write_text(p, '{"a": 2}')
    assert json.loads(p.read_text()) == {"a": 2}
    assert [f.name for f in p.parent.iterdir()] == ["a.json"]


def test_atomic_write_failure_keeps_the_old_file(tmp_path):
    p = tmp_path / "a.json"
    atomic_write_json(p, {"a": 1})
    with pytest.raises(TypeError):
        atomic_write_json(p, {"a": object()})
    assert json.loads(p.read_text()) == {"a": 1}
    assert [f.name for f in tmp_path.iterdir()] == ["a.json"]


def test_jsonable_makes_strict_json():
    x = {1: np.float32(1.5), "a": (np.arange(2), float("nan")), "p": Path("/x"),
         "i": np.int64(3), "b": np.bool_(True)}
    out = jsonable(x)
    assert out == {"1": 1.5, "a": [[0, 1], None], "p": "/x", "i": 3, "b": True}
    json.dumps(out, allow_nan=False)
    assert math.isnan(jsonable([float("nan")], nan_as_null=False)[0])


@pytest.mark.parametrize("text,kw,want", [
    (" A kitchen, cabinet! ", dict(keep="_-"), "A_kitchen__cabinet"),
    ("Knob Dial", dict(lower=True), "knob_dial"),
    ("req id / 1", dict(keep="_-", sep="-", collapse=True), "req-id-1"),
    ("!!!", {}, "fallback"),
    ("abcdef", dict(max_length=3), "abc"),
    ("tür", {}, "t_r"),                       # ASCII only: file names every tool reads
])
def test_slug(text, kw, want):
    assert slug(text, default="fallback", **kw) == want


def test_rpy_matrix_is_urdf_fixed_axis_order():
    r, p, y = 0.3, -0.7, 1.1
    want = (rotation_matrix(np.array([0, 0, 1.0]), y) @ rotation_matrix(np.array([0, 1.0, 0]), p)
            @ rotation_matrix(np.array([1.0, 0, 0]), r))
    np.testing.assert_allclose(rpy_matrix([r, p, y]), want, atol=1e-12)
