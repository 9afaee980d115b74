"""The shipped small geometry weights load alone and produce closed part meshes."""
import torch

from model.geometry.api import DEFAULT_PRIOR, DEFAULT_SDF, ShapeModel

torch.set_num_threads(1)


def test_shipped_weights_decode_and_sample():
    assert DEFAULT_SDF.exists() and DEFAULT_PRIOR.exists(), "model/weights/*_small.pt missing"
    shape = ShapeModel.load()
    bank = shape.bank
    assert bank["latents"].shape[1] == shape.ae.cfg.z_dim
    # a training part's latent decodes to a closed mesh filling its box frame
    z = bank["latents"][:2].float()
    for m in shape.decode_meshes(z, resolution=32):
        assert m.metadata["surface"] == "ok" and m.is_watertight
        assert (m.extents > 1.5).all()
    texts = ["storage furniture, drawer", "storage furniture, handle"]
    g = torch.Generator().manual_seed(0)
    zs = shape.sample_for_labels(texts, steps=20, generator=g)
    assert zs.shape == (2, shape.ae.cfg.z_dim) and torch.isfinite(zs).all()
    assert sum(m.metadata["surface"] == "ok" for m in shape.decode_meshes(zs, resolution=32)) >= 1


def test_turned_auto_encoder_decodes_as_the_shipped_one(tmp_path):
    """scripts/code_space_check.py rotate: the shipped auto-encoder with its latent space
    turned by a random orthogonal matrix encodes every part to the turned latent and decodes
    it to the same SDF, so it is a clean test bed for `train prior --codes-from`."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / "scripts" / "code_space_check.py"
    spec = importlib.util.spec_from_file_location("code_space_check", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = tmp_path / "turned.pt"
    assert mod.rotate(str(DEFAULT_SDF), str(out), 0) < 1e-3
    turned = ShapeModel.load(out, need_prior=False)
    shipped = ShapeModel.load(need_prior=False)
    pts = torch.rand(2, 1024, 3) * 1.6 - 0.8
    z, zt = shipped.encode(pts), turned.encode(pts)
    assert (z - zt).abs().max() > 0.1                  # another latent space ...
    assert torch.allclose(z.norm(dim=-1), zt.norm(dim=-1), rtol=1e-3, atol=1e-4)   # ... turned
