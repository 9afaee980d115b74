"""Where does the shape prior lose thin walls? Fit a few held-out parts of one label, from the
shipped decode, with more and more of the auto-encoder's decoding path made free, and count
components and F-score after each fit (docs/geometry.md, "How good it is, and why walls break").

    python scripts/plane_res_fit.py --label body --parts 24 --fit planes --res 64,128
    python scripts/plane_res_fit.py --label body --parts 24 --fit grid8    # or z, decoder, ...
    python scripts/plane_res_fit.py --label tray --parts 12 --res 64,128 --mesh-res 128

Every fit starts from the shipped auto-encoder's decode of each part's latent (planes
bilinearly resampled to a finer resolution give the same field) and fits the free parameters
to dense exact SDF samples of the true part in its box frame (libigl). Parameters fitted
freely per part are an upper bound on what training could produce there: a stage whose free
version cannot hold a part's walls cannot be trained to. The true SDF meshed the same way is
printed first (the ceiling of any fit). Nothing is saved; the weights on disk are untouched.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch
import torch.nn.functional as F


def dense_samples(tp, parts, i: int, n: int, h: float, seed: int) -> torch.Tensor:
    """(n, 4) exact SDF samples of true part ``i`` in its box frame: 45 % within a quarter cell
    of the surface, 45 % within two cells, 10 % uniform in the cube."""
    import trimesh
    from model.geometry.eval_diagnose import _igl_sdf, _to_frame
    m, _ = _to_frame(tp, parts, i, "box")
    rng = np.random.default_rng(seed)
    n_u = n // 10
    near, _ = trimesh.sample.sample_surface(m, n - n_u, seed=seed)
    sig = np.where(np.arange(len(near)) % 2 == 0, 0.25 * h, 2.0 * h)[:, None]
    q = np.concatenate([rng.uniform(-1.0, 1.0, (n_u, 3)),
                        near + rng.normal(0, 1, near.shape) * sig])
    q = torch.from_numpy(q).float()
    return torch.cat([q, _igl_sdf(m)(q[None])[0][:, None]], 1)


def score(decoder, planes, parts, idx, truth, mesh_res: int) -> tuple[float, float, list[int]]:
    """Mean F@1 %, share with the true number of components, and the component counts.
    ``decoder`` None meshes the exact SDF of the true part (the ceiling of any fit)."""
    from model.geometry.eval_diagnose import _igl_sdf, _to_frame
    from model.geometry.eval_metrics import box_to_metric, compare
    from model.geometry.meshing import evaluate_grids, mesh_grid
    f, ok, counts = [], [], []
    with torch.inference_mode():
        for j, i in enumerate(idx):
            if decoder is None:
                fn = _igl_sdf(_to_frame(truth[i], parts, i, "box")[0])
            else:
                fn = (lambda xyz, pl=planes[j:j + 1]: decoder(pl, xyz))
            g = evaluate_grids(fn, 1, mesh_res)[0]
            r = mesh_grid(g)
            row = compare(box_to_metric(r.mesh, parts, i), truth[i], iou=False) if r.ok else \
                {"fscore": 0.0, "components": 0}
            f.append(row["fscore"])
            ok.append(row["components"] == truth[i].components)
            counts.append(row["components"])
    return float(np.mean(f)), float(np.mean(ok)), counts


def report(what: str, decoder, planes, parts, idx, truth, mesh_res: int) -> None:
    f, comp, counts = score(decoder, planes, parts, idx, truth, mesh_res)
    print(f"{what}: F@1% {f:.3f}, true #components {comp:.3f}, components {counts}", flush=True)


class _FirstInputs(torch.nn.Module):
    """A layer applied to the first ``n`` inputs only (the global path of a widened z)."""

    def __init__(self, layer: torch.nn.Module, n: int):
        super().__init__()
        self.layer, self.n = layer, n

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        return self.layer(z[:, :self.n])


def fit_latents(a, ae, z, parts, idx, truth, samples, gen) -> None:
    """--fit z / decoder / z+decoder / z768+decoder: latents (from the encoder's means), the
    decoder, or both. ``z``: the encoder's means of the parts."""
    if a.fit.startswith("z768"):      # z widened: new inputs at 0, their weights small
        old = ae.vae.from_z
        wide = torch.nn.Linear(768, old.out_features)
        with torch.no_grad():
            wide.weight.normal_(0.0, 0.01)
            wide.weight[:, :old.in_features] = old.weight
            wide.bias.copy_(old.bias)
        ae.vae.from_z = wide
        ae.global_code = _FirstInputs(ae.global_code, old.in_features)
        z = torch.cat([z, torch.zeros(len(z), 768 - z.shape[1])], 1)
    z = torch.nn.Parameter(z.clone())
    for p in ae.parameters():
        p.requires_grad_(False)
    groups = [{"params": [z], "lr": a.lr}] if "z" in a.fit else []
    z.requires_grad_("z" in a.fit)
    if "decoder" in a.fit:
        mods = [ae.vae.from_z, ae.vae.dec, ae.plane_out, ae.global_code, ae.decoder]
        params = [p for m in mods for p in m.parameters()]
        for p in params:
            p.requires_grad_(True)
        groups.append({"params": params, "lr": a.lr / 10})
    _fit(a, a.fit, groups, lambda b: ae._planes(z[b]), len(idx), samples, gen, ae.cfg.sdf_clamp,
         ae.decoder)
    with torch.no_grad():
        planes = ae._planes(z.detach())
    report(f"fitted {a.fit}", ae.decoder, planes, parts, idx, truth, a.mesh_res)


def _fit(a, label: str, groups, planes_of, P, samples, gen, clamp, decoder) -> None:
    """Adam on ``groups`` for a.steps steps: clamped L1 of ``decoder(planes_of(rows), q)``
    against the exact samples of a.batch random parts."""
    opt = torch.optim.Adam(groups)
    t0 = time.time()
    for step in range(a.steps):
        b = torch.randint(0, P, (min(a.batch, P),), generator=gen)
        s = samples[b[:, None], torch.randint(0, a.samples, (len(b), a.queries), generator=gen)]
        loss = (decoder(planes_of(b), s[..., :3]) - s[..., 3].clamp(-clamp, clamp)).abs().mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        if step % 500 == 0 or step == a.steps - 1:
            print(f"  {label}: step {step} loss {loss.item():.5f} ({time.time() - t0:.0f} s)",
                  flush=True)


def fit_grid(a, ae, z, parts, idx, truth, samples, gen) -> None:
    """--fit gridN: the plane generator's N x N activations free per part; the generator's
    later layers, the plane head and the SDF MLP trained (lr / 10). ``z``: the encoder's
    means of the parts."""
    n = int(a.fit[4:])
    cut = 4 * (int(np.log2(n // ae.cfg.latent_res)))     # 4 modules per doubling
    with torch.no_grad():
        B, r, c = len(idx), ae.cfg.latent_res, ae.cfg.vae_channels[-1]
        h = ae.vae.from_z(z).reshape(B * 3, c, r, r)
        h = ae.vae.dec[:cut](h)
        g = ae.global_code(z) / 3.0
    grid = torch.nn.Parameter(h.reshape(B, 3, *h.shape[1:]).clone())
    tail = ae.vae.dec[cut:]
    for p in ae.parameters():
        p.requires_grad_(False)
    params = [p for m in (tail, ae.plane_out, ae.decoder) for p in m.parameters()]
    for p in params:
        p.requires_grad_(True)

    def planes_of(b):
        x = tail(grid[b].reshape(len(b) * 3, *grid.shape[2:]))
        return ae.plane_out(x.reshape(len(b), 3, *x.shape[1:])) + g[b][:, None, :, None, None]
    print(f"  free grids {tuple(grid.shape[2:])} per plane ({grid[0].numel()} floats per part)")
    _fit(a, a.fit, [{"params": [grid], "lr": a.lr}, {"params": params, "lr": a.lr / 10}],
         planes_of, B, samples, gen, ae.cfg.sdf_clamp, ae.decoder)
    with torch.no_grad():
        planes = planes_of(torch.arange(B))
    report(f"fitted {a.fit}", ae.decoder, planes, parts, idx, truth, a.mesh_res)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="data/prepared/v6")
    ap.add_argument("--split", default="val")
    ap.add_argument("--label", default="body")
    ap.add_argument("--parts", type=int, default=24)
    ap.add_argument("--fit", default="planes",
                    choices=["planes", "z", "decoder", "z+decoder", "z768+decoder", "grid4",
                             "grid8", "grid16"],
                    help="planes: free tri-planes per part at each --res; z: free latents, "
                         "the shipped decoder frozen; decoder: every decoder layer from z to "
                         "the SDF, z frozen at the encoder's means; z+decoder: both; z768+decoder: "
                         "z widened to 768 (the new inputs start at 0); gridN: "
                         "free N x N feature grids inside the plane generator and the layers "
                         "after them")
    ap.add_argument("--res", default="64,128", help="plane resolutions to fit (--fit planes)")
    ap.add_argument("--mesh-res", type=int, default=64, help="meshing grid (cells per side)")
    ap.add_argument("--samples", type=int, default=200_000, help="exact SDF samples per part")
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--queries", type=int, default=8192)
    ap.add_argument("--lr", type=float, default=1e-2, help="planes (the decoder gets lr / 10)")
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    from model.geometry.api import load_shape_model
    from model.geometry.data import load_parts
    from model.geometry.eval_metrics import encode_parts, part_label, true_part
    parts = load_parts(a.data, a.split, with_sdf=False)
    torch.set_num_threads(a.threads)
    idx = [i for i in range(len(parts)) if part_label(parts.texts[i]) == a.label]
    truth = {i: true_part(parts, i) for i in idx}
    idx = [i for i in idx if truth[i] is not None][:a.parts]
    if not idx:
        raise SystemExit(f"no {a.label!r} parts with a mesh in {a.data} {a.split}")
    shape = load_shape_model()
    ae = shape.ae.float()
    h = 2.0 / a.mesh_res
    t0 = time.time()
    samples = torch.stack([dense_samples(truth[i], parts, i, a.samples, h, k)
                           for k, i in enumerate(idx)])                     # (P, S, 4)
    print(f"{len(idx)} {a.label} parts, {a.samples} exact samples each ({time.time() - t0:.0f} s)",
          flush=True)
    report(f"true SDF meshed at {a.mesh_res}^3", None, None, parts, idx, truth, a.mesh_res)
    z = encode_parts(shape, parts, idx, 0).float()                          # the encoder's means
    base = ae.decode_planes(z).float()                                      # (P, 3, C, R0, R0)
    report(f"shipped decode (planes {base.shape[-1]})", ae.decoder, base, parts, idx, truth,
           a.mesh_res)
    gen = torch.Generator().manual_seed(0)
    if a.fit.startswith("grid"):
        fit_grid(a, ae, z, parts, idx, truth, samples, gen)
        return
    if a.fit != "planes":
        fit_latents(a, ae, z, parts, idx, truth, samples, gen)
        return
    for res in [int(r) for r in a.res.split(",")]:
        P, _, C, R0, _ = base.shape
        init = F.interpolate(base.reshape(P * 3, C, R0, R0), size=(res, res), mode="bilinear",
                             align_corners=False).reshape(P, 3, C, res, res)
        planes = torch.nn.Parameter(init.clone())
        decoder = type(ae.decoder)(ae.cfg)
        decoder.load_state_dict(ae.decoder.state_dict())
        groups = [{"params": [planes], "lr": a.lr},
                  {"params": decoder.parameters(), "lr": a.lr / 10}]
        _fit(a, f"planes {res}", groups, lambda b: planes[b], P, samples, gen, ae.cfg.sdf_clamp,
             decoder)
        report(f"fitted planes {res}", decoder, planes.detach(), parts, idx, truth, a.mesh_res)


if __name__ == "__main__":
    main()
