"""Shapes and behaviour of the shape-prior networks and the diffusion process (tiny preset)."""
import pytest
import torch

from model.geometry.autoencoder import SDFAutoEncoder, plane_cell_index, plane_coords
from model.geometry.config import PriorConfig, SDFConfig, config_from_dict, get_preset
from model.geometry.diffusion import DROP_BOTH, DROP_NONE, Diffusion
from model.geometry.prior import ShapePrior

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def tiny():
    return get_preset("tiny")


def test_presets_are_independent_copies_and_paper_sizes():
    a, b = get_preset("small"), get_preset("small")
    a.sdf.z_dim = 3
    assert b.sdf.z_dim == 256
    p = get_preset("paper")
    assert (p.sdf.plane_res, p.sdf.plane_channels, p.sdf.z_dim) == (64, 256, 768)
    assert (p.sdf.mlp_layers, p.sdf.mlp_hidden) == (9, 512)
    assert (p.prior.n_codebooks, p.prior.codebook_size, p.prior.code_dim) == (4, 128, 32)
    g, f = get_preset("small-grid8").sdf.validate(), get_preset("small-fine").sdf
    assert (g.latent_res, f.validate().latent_res) == (8, 4)
    assert (g.z_dim, g.plane_res) == (f.z_dim, f.plane_res)   # same z for the prior, same planes
    planes = SDFAutoEncoder(g).decode_planes(torch.zeros(2, g.z_dim))    # inference mode
    assert planes.shape == (2, 3, g.plane_channels, 64, 64)
    with pytest.raises(KeyError, match="unknown preset"):
        get_preset("huge")
    with pytest.raises(ValueError, match="unknown config keys"):
        config_from_dict(SDFConfig, {"nope": 1})


def test_planes_cover_the_whole_part_cube():
    cfg = SDFConfig()
    xyz = torch.tensor([[[0.99, 0.0, 0.0], [0.6, 0.0, 0.0], [-0.99, 0.0, 0.0]]])
    idx = plane_cell_index(plane_coords(xyz, cfg.bound), cfg.plane_res)   # (1, 3, 3)
    cols = idx[0, 0] % cfg.plane_res                                      # xy plane, x column
    assert cols[0] >= cfg.plane_res - 2 and cols[2] <= 1                  # near the plane edges
    assert cols[1] < cols[0] - 3                                          # 0.6 is not clipped to 0.99


def test_autoencoder_shapes(tiny):
    cfg = tiny.sdf
    ae = SDFAutoEncoder(cfg)
    B, P, N = 3, 100, 50
    pts, q = torch.rand(B, P, 3) * 2 - 1, torch.rand(B, N, 3) * 2 - 1
    planes = ae.pointnet(pts)
    assert planes.shape == (B, 3, cfg.plane_channels, cfg.plane_res, cfg.plane_res)
    z = ae.encode(pts)
    assert z.shape == (B, cfg.z_dim)
    pl = ae.decode_planes(z)
    assert pl.shape == planes.shape
    assert ae.query(pl, q).shape == (B, N)
    loss, stats = ae(pts, q, torch.rand(B, N))
    assert loss.ndim == 0 and loss.requires_grad and set(stats) == {"l1", "kl"}


def test_prior_shapes_and_code_distribution(tiny):
    cfg = tiny.prior
    pr = ShapePrior(cfg)
    B = 5
    z = torch.randn(B, cfg.z_dim)
    P = pr.code_distribution(z)
    assert P.shape == (B, cfg.n_codebooks, cfg.codebook_size)
    assert torch.allclose(P.sum(-1), torch.ones(B, cfg.n_codebooks), atol=1e-5)
    geo = pr.geo_tokens(P.clone())
    assert geo.shape == (B, cfg.n_codebooks, cfg.width)
    x0 = pr.denoiser(z, torch.randint(0, cfg.timesteps, (B,)), (geo, torch.randn(B, cfg.cs_dim)),
                     torch.zeros(B, dtype=torch.long))
    assert x0.shape == (B, cfg.z_dim)
    loss, stats = pr(z, torch.randn(B, cfg.text_dim), torch.Generator().manual_seed(0))
    assert loss.ndim == 0 and loss.requires_grad and "usage_kl" in stats
    loss.backward()
    assert pr.codebooks.grad is not None and pr.codebooks.grad.abs().sum() > 0


def test_dropping_both_conditions_ignores_them(tiny):
    cfg = tiny.prior
    den = ShapePrior(cfg).denoiser.eval()
    B = 4
    x, t = torch.randn(B, cfg.z_dim), torch.full((B,), 10)
    c1 = (torch.randn(B, cfg.n_codebooks, cfg.width), torch.randn(B, cfg.cs_dim))
    c2 = (torch.randn(B, cfg.n_codebooks, cfg.width), torch.randn(B, cfg.cs_dim))
    both = torch.full((B,), DROP_BOTH)
    keep = torch.full((B,), DROP_NONE)
    with torch.no_grad():
        assert torch.allclose(den(x, t, c1, both), den(x, t, c2, both))
        assert not torch.allclose(den(x, t, c1, keep), den(x, t, c2, keep))


def test_cosine_schedule_and_q_sample():
    d = Diffusion(1000)
    ab = d.alpha_bar
    assert ab.shape == (1000,) and ab[0] > 0.999 and ab[-1] < 1e-3
    assert torch.all(ab[1:] <= ab[:-1])
    x0, noise = torch.ones(2, 4), torch.zeros(2, 4)
    xt = d.q_sample(x0, torch.tensor([0, 999]), noise)
    assert xt[0, 0] > 0.99 and xt[1, 0] < 0.05


def test_ddim_deterministic_under_seed_and_cfg_path(tiny):
    torch.manual_seed(0)
    pr = ShapePrior(tiny.prior).eval()
    B = 6
    P = torch.randn(B, tiny.prior.n_codebooks, tiny.prior.codebook_size)
    cs = torch.randn(B, tiny.prior.cs_dim)

    def run(seed, **kw):
        return pr.sample_from_logits(P, cs, steps=10, generator=torch.Generator().manual_seed(seed), **kw)
    a, b, c = run(1), run(1), run(2)
    assert a.shape == (B, tiny.prior.z_dim)
    assert torch.equal(a, b)
    assert not torch.allclose(a, c)
    g1, g2 = run(1, guidance=3.0), run(1, guidance=3.0)
    assert torch.equal(g1, g2) and torch.isfinite(g1).all()
    assert not torch.allclose(g1, a)


def test_sample_from_logits_batch_rows_are_independent(tiny):
    torch.manual_seed(0)
    pr = ShapePrior(tiny.prior).eval()
    K, N = tiny.prior.n_codebooks, tiny.prior.codebook_size
    P = torch.randn(3, K, N)
    cs = torch.randn(3, tiny.prior.cs_dim)
    z = pr.sample_from_logits(P, cs, steps=5, generator=torch.Generator().manual_seed(0))
    assert z.shape == (3, tiny.prior.z_dim) and torch.isfinite(z).all()
    # a peaked code choice makes the geometry condition the chosen codebook entry
    peaked = torch.full((1, K, N), -1e4)
    peaked[:, :, 2] = 0
    from model.geometry.prior import gumbel_softmax
    w = gumbel_softmax(peaked, 0.5, torch.Generator().manual_seed(0))
    assert torch.allclose(w[0, :, 2], torch.ones(K))


def test_encode_is_frame_independent(tiny):
    """Points in the iso unit cube and the same points in the box frame give the same z."""
    from model.geometry.data import box_frame
    ae = SDFAutoEncoder(tiny.sdf)
    p = torch.rand(2, 300, 3) * torch.tensor([0.2, 0.9, 0.5]) + 0.1
    c, s = box_frame(p)
    box = (p - c[:, None]) * s[:, None]
    assert torch.allclose(box.amax(1) - box.amin(1), torch.full((2, 3), 1.9), atol=1e-5)
    assert torch.allclose(ae.encode(p), ae.encode(box), atol=1e-4)
