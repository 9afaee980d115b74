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
