"""`artformer eval geometry`: metrics (F-score, Chamfer, components, floaters), the per-label
evaluation end to end with an oracle shape model that decodes the true parts, the table,
the contact sheets and the cause analysis's building blocks."""
import numpy as np
import pytest
import torch
import trimesh

from model.geometry import evaluate as ev
from model.geometry.meshing import components, keep_largest_components, mesh_sdf_batch

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def prim(tmp_path_factory):
    from model.geometry.data import load_parts, make_primitive_dataset
    root = make_primitive_dataset(tmp_path_factory.mktemp("geo_eval") / "data", 6,
                                  n_points=512, n_sdf=512, seed=5,
                                  splits=(0.0, 0.0))
    return root, load_parts(root, "test", with_sdf=False)


class _OracleAE:
    """encode/decode stand-ins: z is the part index; planes carry it through."""
    def __init__(self, parts):
        self.parts = parts


class OracleShape:
    """Decodes z = [part index] to the exact SDF of that held-out part in its box frame, so
    every metric of a reconstruction should be (nearly) perfect."""

    def __init__(self, parts, sabotage: bool = False):
        self.parts = parts
        self.sabotage = sabotage
        self.ae = _OracleAE(parts)
        self.prior = object()
        self.bank = {}

    def decode(self, z, resolution=64, **kw):
        out = []
        for zi in z:
            i = int(zi[0])
            tp = ev.true_part(self.parts, i)
            box, _ = ev._to_frame(tp, self.parts, i, "box")
            fn = ev._igl_sdf(box)
            if self.sabotage:   # a bubble inside the part: a second, inner shell (meshed
                base = fn           # without island removal, which fills enclosed voids)
                fn = lambda x, base=base: torch.maximum(  # noqa: E731
                    base(x), 0.1 - x.norm(dim=-1))
                kw = {**kw, "min_island": 0}
            out += mesh_sdf_batch(fn, 1, resolution, **kw)
        return out

    def sample_for_labels(self, texts, steps=50, generator=None):
        return torch.tensor([[float(self.parts.texts.index(t))] for t in texts])


def test_components_and_floaters():
    a = trimesh.creation.box(extents=(1, 1, 1))
    b = trimesh.creation.icosphere(radius=0.1)
    b.apply_translation((3, 0, 0))
    m = trimesh.util.concatenate([a, b])
    n, lab = components(m)
    assert n == 2 and len(lab) == len(m.faces)
    assert ev.floater_faces(m, 1) == len(b.faces)
    assert ev.floater_faces(m, 2) == 0
    big = keep_largest_components(m, 1)
    assert components(big)[0] == 1 and len(big.faces) == len(a.faces)
    assert big.is_watertight


def test_fscore_is_point_to_surface():
    a = trimesh.creation.box(extents=(1, 1, 1))
    pa, pb = ev._surface_points(a, 4000, 0), ev._surface_points(a, 4000, 1)
    f, c = ev.fscore_chamfer(a, pa, a, pb, tau=0.01)
    assert f == 1.0 and c < 1e-6          # two samplings of one surface: no sampling floor
    b = a.copy()
    b.apply_translation((0.05, 0, 0))
    f2, c2 = ev.fscore_chamfer(b, ev._surface_points(b, 4000, 0), a, pb, tau=0.01)
    assert f2 < 0.9 and c2 > 0.005


def test_level_offset_dilates():
    sph = lambda x: x.norm(dim=-1) - 0.5  # noqa: E731
    r0 = mesh_sdf_batch(sph, 1, 32)[0].mesh
    r1 = mesh_sdf_batch(sph, 1, 32, level=0.1)[0]
    assert r1.ok and r1.mesh.is_watertight
    rad = np.linalg.norm(r1.mesh.vertices, axis=1).mean()
    assert rad == pytest.approx(0.6, abs=0.01)
    assert np.linalg.norm(r0.vertices, axis=1).mean() == pytest.approx(0.5, abs=0.01)
    assert r1.inside.sum() > mesh_sdf_batch(sph, 1, 32)[0].inside.sum()


def test_select_parts_caps(prim):
    _, parts = prim
    idx = ev.select_parts(parts, per_label=1, max_parts=None, seed=0)
    labels = [ev.part_label(parts.texts[i]) for i in idx]
    assert len(labels) == len(set(labels)) == len({ev.part_label(t) for t in parts.texts})
    assert len(ev.select_parts(parts, per_label=None, max_parts=3, seed=0)) == 3
    assert ev.select_parts(parts, per_label=None, max_parts=None, seed=1) == list(range(len(parts)))


def test_oracle_reconstruction_is_near_perfect(prim):
    _, parts = prim
    shape = OracleShape(parts)
    idx = list(range(min(4, len(parts))))
    z = torch.tensor([[float(i)] for i in idx])
    rows = ev.reconstruct(shape, parts, idx, resolution=64, z=z)
    assert len(rows) == len(idx)
    for r in rows:       # the metric frame round trip is exact
        assert r["fscore"] > 0.97, r
        assert r["iou"] > 0.9
        assert r["components"] == r["true_components"] == 1
        assert r["floater_faces"] == 0 and r["watertight"]
    s = ev.summarise(rows)
    assert s["true_components"] == 1.0 and s["with_floaters"] == 0.0
    bad = ev.reconstruct(OracleShape(parts, sabotage=True), parts, idx, resolution=64, z=z)
    sb = ev.summarise(bad)
    assert sb["true_components"] == 0.0 and sb["with_floaters"] == 1.0
    assert all(r["floater_faces"] > 0 for r in bad)


def test_prior_rows_table_and_sheets(prim, tmp_path):
    _, parts = prim
    shape = OracleShape(parts)
    texts = sorted(set(parts.texts))[:2]
    rows = ev.prior_samples(shape, parts, n=2, steps=1, seed=0, resolution=32, texts=texts)
    assert len(rows) == 4 and {r["text"] for r in rows} == set(texts)
    for r in rows:   # the oracle "samples" a part of that text: its nearest true part fits
        assert r["fscore"] > 0.8 and r["components"] == 1
    res = {"reconstruction": {**ev.summarise(rows), "labels": ev.per_label(rows)},
           "prior": {**ev.summarise(rows), "labels": ev.per_label(rows)}}
    table = ev.format_table(res)
    for t in texts:
        assert f"| {ev.part_label(t)} |" in table
    assert table.count("\n") == 2 + len({ev.part_label(t) for t in texts})
    ev.samples_sheet(tmp_path / "s.png", rows)
    rec = ev.reconstruct(shape, parts, [0, 1], resolution=32,
                         z=torch.tensor([[0.0], [1.0]]))
    ev.worst_sheet(tmp_path / "w.png", rec, k=2)
    from PIL import Image
    for name in ("s.png", "w.png"):
        im = np.asarray(Image.open(tmp_path / name).convert("RGB"))
        assert im.shape[0] > 100 and (im < 200).any()      # something was drawn
    js = ev._json_rows(rec)
    assert "mesh" not in js[0] and "true" not in js[0] and js[0]["fscore"] == rec[0]["fscore"]


def test_render_marks_extra_components_red():
    a = trimesh.creation.box(extents=(1, 1, 1))
    b = trimesh.creation.box(extents=(0.4, 0.4, 0.4))
    b.apply_translation((0, 1.2, 0))
    img = ev.render_mesh(trimesh.util.concatenate([a, b]), 96).astype(int)
    red = (img[..., 0] > 150) & (img[..., 2] < 120)
    assert red.sum() > 20
    one = ev.render_mesh(a, 96).astype(int)
    assert ((one[..., 0] > 150) & (one[..., 2] < 120)).sum() == 0


def test_wall_thickness_of_a_plate():
    plate = trimesh.creation.box(extents=(1.0, 1.0, 0.1))
    _, _, t = ev.wall_thickness(plate, 400, 0, step=0.005, steps=80)
    # most samples are on the two big faces: thickness 0.1 along the normal
    assert np.median(t) == pytest.approx(0.1, abs=0.006)


def test_diagnose_runs_on_an_untrained_model(prim):
    """The cause analysis end to end (tiny untrained auto-encoder: every number must be a
    well-formed share, whatever the shapes look like)."""
    from model.geometry.api import ShapeModel
    from model.geometry.autoencoder import SDFAutoEncoder
    from model.geometry.config import get_preset
    root, parts = prim
    torch.manual_seed(0)
    shape = ShapeModel(SDFAutoEncoder(get_preset("tiny").sdf))
    out = ev.diagnose(shape, str(root), per_label_cap=1, max_parts=2, resolutions=(16, 32),
                      progress=False)
    assert out["parts"] == 2 and set(out["a_ae_resolution"]) == {"16", "32"}
    assert set(out["a_true_sdf_box"]) == {"32", "64", "128"}
    for r in out["a_true_sdf_box"].values():          # the exact SDF keeps the primitives whole
        assert r["fscore"] > 0.9 and r["true_components"] == 1.0
    for b in out["b_wall_midpoints_outside"]:
        assert b["decoded_outside"] is None or 0.0 <= b["decoded_outside"] <= 1.0
    assert sum(b["points"] for b in out["b_wall_midpoints_outside"]) == 2 * 512
    thick = out["c_wall_thickness_cells"]
    assert thick["box"]["median"] >= thick["iso"]["median"]   # the box frame never thins walls
    assert "d_retrieval_64" not in out                        # no bank: no retrieval row
    assert out["e_remedies_64"]["largest_component_only"]["n"] == 2
