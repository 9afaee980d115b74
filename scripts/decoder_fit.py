"""Can the shape prior's decoder hold thin walls? Fit the shipped auto-encoder's decoder alone
(latents frozen) to a few held-out parts of one label and count their connected components
before and after (docs/geometry.md, "How good it is, and why walls break").

    python scripts/decoder_fit.py --label body --parts 24 --steps 600
    python scripts/decoder_fit.py --label body --parts 24 --steps 1500 --lr 1e-3 --inside-weight 4

A decoder that cannot fit 24 parts it is trained on cannot generalise to them either: if
their components stay wrong, the representation (the tri-plane's resolution), not the
amount of training, is what limits them. Nothing is saved; the weights on disk are untouched.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch


def score(shape, parts, idx) -> tuple[float, float, list[int]]:
    """Mean F@1 %, share with the true number of components, and the component counts."""
    from model.geometry.eval_samples import reconstruct
    rows = reconstruct(shape, parts, idx, iou=False)
    ok = [r["components"] == r["true_components"] for r in rows]
    return (float(np.mean([r["fscore"] for r in rows])), float(np.mean(ok)),
            [r["components"] for r in rows])


def weighted_l1(pred, sdf, clamp: float, inside_weight: float) -> torch.Tensor:
    """The training loss (clamped L1), with samples inside the true part weighted up."""
    t = sdf.clamp(-clamp, clamp)
    done = (sdf.abs() >= clamp) & (pred * torch.sign(sdf) >= clamp)
    err = torch.where(done, torch.zeros_like(pred), (pred - t).abs())
    return (err * (1 + (inside_weight - 1) * (sdf < 0).float())).mean()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="data/prepared/v6")
    ap.add_argument("--split", default="val")
    ap.add_argument("--objects", type=int, default=160, help="first N objects of the split")
    ap.add_argument("--label", default="body")
    ap.add_argument("--parts", type=int, default=24)
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--lr", type=float, default=3e-4)
    ap.add_argument("--inside-weight", type=float, default=1.0)
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    from model.geometry.api import load_shape_model
    from model.geometry.data import load_parts, sample_batch
    from model.geometry.eval_metrics import part_label
    # the parts first: their exact SDF samples are drawn before torch starts its threads
    parts = load_parts(a.data, a.split, max_objects=a.objects)
    torch.set_num_threads(a.threads)
    shape = load_shape_model()
    ae = shape.ae.float()
    idx = [i for i in range(len(parts)) if part_label(parts.texts[i]) == a.label][:a.parts]
    if not idx:
        raise SystemExit(f"no {a.label!r} parts in the first {a.objects} {a.split} objects")
    f, comp, counts = score(shape, parts, idx)
    print(f"before: {len(idx)} {a.label} parts, F@1% {f:.3f}, true #components {comp:.3f}, "
          f"components {counts}")
    rows = torch.tensor(idx)
    with torch.no_grad():   # the posterior of each part, from the same 512 points throughout
        mu, logvar = ae.vae.encode(ae.plane_net(ae.pointnet(parts.points[rows, :512].float())))
    decoder = [ae.vae.from_z, ae.vae.dec, ae.plane_out, ae.global_code, ae.decoder]
    for p in ae.parameters():
        p.requires_grad_(False)
    params = [p for m in decoder for p in m.parameters()]
    for p in params:
        p.requires_grad_(True)
    opt = torch.optim.Adam(params, lr=a.lr)
    gen = torch.Generator().manual_seed(0)
    ae.train()
    t0 = time.time()
    for step in range(a.steps):
        b = torch.randint(0, len(idx), (a.batch,), generator=gen)
        _, q, sdf = sample_batch(parts, rows[b], 1, 2048, gen)
        z = mu[b] + torch.randn(mu[b].shape, generator=gen) * (0.5 * logvar[b]).exp()
        loss = weighted_l1(ae.decoder(ae._planes(z), q), sdf, ae.cfg.sdf_clamp, a.inside_weight)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if step % 100 == 0 or step == a.steps - 1:
            print(f"step {step}: loss {loss.item():.5f} ({time.time() - t0:.0f} s)")
    ae.eval()
    f, comp, counts = score(shape, parts, idx)
    print(f"after:  F@1% {f:.3f}, true #components {comp:.3f}, components {counts}")


if __name__ == "__main__":
    main()
