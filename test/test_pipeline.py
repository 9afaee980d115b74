"""End-to-end pipeline on tiny random-weight checkpoints: text -> tree -> latents -> meshes ->
URDF folder; determinism, editing, and clear errors for bad prompts and checkpoints."""
import json
from pathlib import Path

import numpy as np
import pytest

from model.pipeline.api import GenerationConfig, GenerationError


@pytest.fixture(scope="module")
def tiny(tiny_trained_model):
    return tiny_trained_model          # shared, read-only: copy files out before changing them


@pytest.fixture(scope="module")
def gen(tiny):
    from model.pipeline.generator import Generator
    return Generator.load(GenerationConfig(checkpoint=str(tiny), resolution=24, steps=4, threads=1))


def _signature(obj):
    return ([p.label for p in obj.parts], [int(p.joint.type) for p in obj.parts],
            np.round(np.stack([p.token() for p in obj.parts]), 6),
            [np.round(np.asarray(p.mesh.vertices).sum(0), 5) for p in obj.parts])


def test_generate_gives_meshed_valid_object_with_timings(gen):
    [res] = gen.generate("a cabinet with two drawers", seed=0)
    obj = res.obj.validate()
    assert obj.parts and all(p.mesh is not None and len(p.mesh.faces) for p in obj.parts)
    for p in obj.parts:   # meshes are fitted to the predicted boxes
        lo, hi = p.mesh.bounds
        assert np.allclose((lo + hi) / 2, p.bbox_center, atol=1e-6)
    assert {"text_encoding", "decoding", "diffusion", "meshing"} <= set(res.timings)
    assert res.prompt == "a cabinet with two drawers" and res.seed == 0


def test_same_seed_same_object_and_samples_use_consecutive_seeds(gen):
    a = gen.generate("a safe with a door", seed=5)[0]
    b = gen.generate("a safe with a door", seed=5)[0]
    sa, sb = _signature(a.obj), _signature(b.obj)
    assert sa[0] == sb[0] and sa[1] == sb[1]
    assert np.array_equal(sa[2], sb[2])
    assert all(np.array_equal(x, y) for x, y in zip(sa[3], sb[3]))
    many = gen.generate("a safe with a door", seed=5, samples=3)
    assert [r.seed for r in many] == [5, 6, 7]
    assert np.array_equal(_signature(many[0].obj)[2], sa[2])
    # different seeds differ (structure, boxes or at least the diffused part shapes)
    sigs = {(_signature(r.obj)[2].tobytes(), np.concatenate(_signature(r.obj)[3]).tobytes())
            for r in many}
    assert len(sigs) == 3


def test_export_writes_urdf_meshes_metadata_with_provenance(gen, tmp_path):
    res = gen.generate("a bottle with a screw cap", seed=2)[0]
    out = gen.export(res, tmp_path / "o", preview=False)
    xml = Path(out.urdf_path).read_text()
    assert "a bottle with a screw cap" in xml and "transformer.pt@" in xml
    assert all(Path(p).exists() for p in out.mesh_paths.values())
    meta = json.loads(Path(out.metadata_path).read_text())
    assert meta["provenance"]["seed"] == 2
    assert "export" in res.timings


@pytest.mark.parametrize("bad,msg", [("", "empty"), ("   \n\t ", "empty"),
                                     ("x" * 5000, "limit"), (b"\xff\xfe", "UTF-8"), (42, "string")])
def test_bad_prompts_fail_clearly(gen, bad, msg):
    with pytest.raises(GenerationError, match=msg):
        gen.generate(bad)


def test_text_and_image_are_exclusive_and_image_needs_an_image_stage(gen):
    with pytest.raises(GenerationError, match="exactly one"):
        gen.generate("a", image=np.zeros((8, 8, 3), np.uint8))
    if not gen.supports_image:
        with pytest.raises(GenerationError, match="image"):
            gen.generate(image=np.zeros((8, 8, 3), np.uint8))


def test_editing_keeps_parts_and_regrows(gen, tmp_path):
    from model.core.example import example_cabinet
    from model.pipeline.edit import remove_parts
    cab = example_cabinet()
    removable = [p.name for p in cab.parts if p.parent >= 0 and p.label == "drawer"][:1]
    kept = remove_parts(cab, removable)
    assert removable[0] not in [p.name for p in kept.parts]
    assert all(p.parent < len(kept.parts) for p in kept.parts)
    res = gen.generate("a cabinet with drawers", seed=0, keep=kept)[0]
    names = [p.name for p in res.obj.parts]
    for p in kept.parts:   # every kept part is still there with its own mesh
        assert p.name in names
        q = res.obj.parts[names.index(p.name)]
        assert np.allclose(q.mesh.vertices, p.mesh.vertices)
    with pytest.raises(ValueError, match="root"):
        remove_parts(cab, [cab.parts[cab.root].name])
    with pytest.raises(KeyError, match="no part named"):
        remove_parts(cab, ["nope"])


def test_checkpoint_folder_errors(tmp_path, tiny):
    from model.pipeline.generator import Generator, find_checkpoints
    with pytest.raises(GenerationError, match="does not exist"):
        find_checkpoints(tmp_path / "missing")
    (tmp_path / "half").mkdir()
    (tmp_path / "half" / "sdf.pt").write_bytes((Path(tiny) / "sdf.pt").read_bytes())
    with pytest.raises(GenerationError, match="no checkpoint for"):
        find_checkpoints(tmp_path / "half")
    bad = tmp_path / "bad"
    bad.mkdir()
    for f in ("sdf.pt", "prior.pt"):
        (bad / f).write_bytes((Path(tiny) / f).read_bytes())
    (bad / "transformer.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(GenerationError, match="could not load"):
        Generator.load(GenerationConfig(checkpoint=str(bad)))
    with pytest.raises(GenerationError, match="resolution"):
        Generator.load(GenerationConfig(checkpoint=str(tiny), resolution=3))
    # a one_codebook transformer (1 x C*N logits: same head size) beside a C x N prior is
    # refused at load time, naming the prior it needs, not by a shape error mid-generation
    import torch
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    for f in ("sdf.pt", "prior.pt"):
        (mixed / f).write_bytes((Path(tiny) / f).read_bytes())
    ck = torch.load(Path(tiny) / "transformer.pt", map_location="cpu", weights_only=False)
    c, n = ck["config"]["num_codebooks"], ck["config"]["codebook_size"]
    ck["config"].update(num_codebooks=1, codebook_size=c * n)
    torch.save(ck, mixed / "transformer.pt")
    with pytest.raises(GenerationError, match=f"1 x {c * n} codebook logits.*--codebooks 1"):
        Generator.load(GenerationConfig(checkpoint=str(mixed)))


def test_cli_generate_and_edit(tiny, tmp_path, capsys):
    from model.cli import main
    out = tmp_path / "cli"
    rc = main(["generate", "a cabinet with one door", "--checkpoint", str(tiny), "--out", str(out),
               "--resolution", "24", "--steps", "4", "--threads", "1", "--json", "--no-preview"])
    assert rc == 0
    row = json.loads(capsys.readouterr().out)
    assert Path(row["urdf"]).exists() and row["seed"] == 0
    link = [p.split(":")[0] for p in row["parts"]]
    rc = main(["edit", row["urdf"], "--remove", *link[1:2], "--text", "a cabinet with one door",
               "--checkpoint", str(tiny), "--out", str(tmp_path / "edited"), "--resolution", "24",
               "--steps", "4", "--threads", "1", "--no-preview"])
    assert rc == 0 if len(link) > 1 else rc == 1
    rc = main(["generate", "   ", "--checkpoint", str(tiny), "--out", str(tmp_path / "x")])
    assert rc == 1 and "empty" in capsys.readouterr().err


def test_generated_parts_get_collision_boxes_inside_their_box_and_load(gen, tmp_path):
    from lxml import etree
    res = gen.generate("a cabinet with two drawers", seed=1)[0]
    boxed = [p for p in res.obj.parts if p.collision]
    assert boxed, "no part got collision boxes from its SDF occupancy"
    for p in boxed:
        lo, hi = p.mesh.bounds
        cell = (hi - lo) / 24
        for b in p.collision:                  # within one grid cell of the fitted mesh
            assert np.all(b.bounds[0] >= lo - cell) and np.all(b.bounds[1] <= hi + cell)
    out = gen.export(res, tmp_path / "boxes", preview=True)
    root = etree.parse(out.urdf_path).getroot()
    n_boxes = len(root.findall("link/collision/geometry/box"))
    assert n_boxes == sum(len(p.collision) for p in boxed)
    assert Path(out.preview_path).is_file()
    assert {"export", "preview"} <= set(res.timings)     # the picture is timed on its own
    # (simulator loading of generated objects: test_shipped_pipeline.py; the tiny model's
    # parts all overlap, which no collision geometry makes simulable)


@pytest.mark.slow
def test_refine_switch_and_eval_audit_rows(tiny, tmp_path, capsys):
    """--no-refine exports the raw output (no refine timing); `artformer eval audit` writes
    a raw and a refined row for the same prompts."""
    from model.metrics import audit_eval
    from model.pipeline.generator import Generator
    raw = Generator.load(GenerationConfig(checkpoint=str(tiny), resolution=24, steps=4,
                                          threads=1, refine=False, face_budget=1500))
    [res] = raw.generate("a cabinet with two drawers", seed=0)
    assert "refine" not in res.timings and "refine" not in res.obj.metadata
    budget = res.obj.metadata["simplify"]      # raw output is simplified towards the budget
    assert budget["simplify_tolerance"] > 0
    assert budget["faces"] == sum(len(p.mesh.faces) for p in res.obj.parts)
    raw.config.face_budget = 0                 # ... and only when there is one
    [full] = raw.generate("a cabinet with two drawers", seed=0)
    assert "simplify" not in full.obj.metadata
    assert sum(len(p.mesh.faces) for p in full.obj.parts) > 1.5 * budget["faces"]
    prompts = tmp_path / "p.txt"
    prompts.write_text("a cabinet with two drawers\n")
    assert audit_eval.main(["eval", "audit", "--checkpoint", str(tiny), "--seeds", "1",
                            "--freeform-file", str(prompts), "--no-everyday",
                            "--rows", "floor,raw,refined,retrieval",
                            "--out", str(tmp_path / "ea")]) == 0
    data = json.loads((tmp_path / "ea" / "audit.json").read_text())
    assert set(data) == {"data floor", "raw model", "refined", "retrieval (refined)"}
    assert all(len(v["objects"]) == 1 for v in data.values())
    assert "sim-ready:" in capsys.readouterr().out


def test_a_transformer_trained_against_another_prior_is_refused(tiny_model_factory, tmp_path):
    import shutil

    from model.pipeline import GenerationConfig, Generator
    from model.pipeline.api import GenerationError

    a = tiny_model_factory("prior_a", seed=3)
    b = tiny_model_factory("prior_b", seed=4)          # another random shape prior
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    shutil.copy(a / "transformer.pt", mixed / "transformer.pt")
    for stage in ("sdf.pt", "prior.pt"):
        shutil.copy(b / stage, mixed / stage)
    Generator.load(GenerationConfig(checkpoint=str(a)))              # its own prior: loads
    with pytest.raises(GenerationError, match="another shape prior"):
        Generator.load(GenerationConfig(checkpoint=str(mixed)))


def test_image_model_runs_with_its_own_prior_from_image_prior_folder(tmp_path, tiny,
                                                                      tiny_image_model):
    """A folder whose text model was trained against a newer shape prior than its image model
    keeps image requests working: image_prior/ holds the image model's prior, which image
    requests (and only they) sample and decode with. Without it the image model is refused;
    a half-filled image_prior/ is an error."""
    import shutil

    from PIL import Image

    from model.pipeline.generator import Generator, find_checkpoints
    folder = tmp_path / "both"
    folder.mkdir()
    for f in ("transformer.pt", "sdf.pt", "prior.pt"):
        shutil.copy(Path(tiny) / f, folder / f)
    shutil.copy(Path(tiny_image_model) / "image.pt", folder / "image.pt")
    kw = dict(checkpoint=str(folder), resolution=16, steps=2, threads=1)
    assert not Generator.load(GenerationConfig(**kw)).supports_image   # another prior: refused
    (folder / "image_prior").mkdir()
    shutil.copy(Path(tiny_image_model) / "sdf.pt", folder / "image_prior" / "sdf.pt")
    with pytest.raises(GenerationError, match="both sdf"):
        find_checkpoints(folder)
    shutil.copy(Path(tiny_image_model) / "prior.pt", folder / "image_prior" / "prior.pt")
    gen = Generator.load(GenerationConfig(**kw))
    assert gen.supports_image and gen.image_shape is not gen.shape
    assert gen.image_shape.info["fingerprint"] != gen.shape.info["fingerprint"]
    used = []
    for name, shape in (("text", gen.shape), ("image", gen.image_shape)):
        decode = shape.decode_grids
        shape.decode_grids = lambda z, _d=decode, _n=name, **k: used.append(_n) or _d(z, **k)
    png = tmp_path / "photo.png"
    Image.new("RGB", (64, 64), (120, 90, 60)).save(png)
    assert gen.generate(image=str(png), seed=0)[0].obj.parts
    assert set(used) == {"image"}
    used.clear()
    assert gen.generate(text="a cabinet with two doors", seed=0)[0].obj.parts
    assert set(used) == {"text"}
