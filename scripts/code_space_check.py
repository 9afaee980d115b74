"""A controlled check of `artformer train prior --codes-from` (a prior in another prior's code
space): an auto-encoder whose latent space is the shipped one turned by a random orthogonal
matrix decodes every part exactly as the shipped one does, but the shipped prior cannot read
or make its latents. A prior trained for it with ``--codes-from`` the shipped prior should then
turn the shipped transformer's code predictions into shapes as well as a prior trained on the
same data and steps in its own code space does.

    python scripts/code_space_check.py rotate --out runs/code_space/sdf_rotated.pt [--seed 0]

writes that auto-encoder (fp32; z' = Q z: the rows of the posterior-mean head turned by Q,
the two layers that read z turned back by Q^T) and prints the largest SDF difference to the
shipped decoder on random latents and points.

    python scripts/code_space_check.py score --data data/prepared/v6 --split val \
        --pair SDF PRIOR [--pair SDF2 PRIOR2 ...] [--per-label 10]

scores shapes drawn from codes: held-out parts (at most N per label) are encoded by the
first pair's auto-encoder, their code distributions P read by its prior (the targets a
transformer learns for that prior), and every pair's prior samples a latent from (P, c_s) by
50-step DDIM, which its auto-encoder decodes; each is compared with its true part (F@1%,
Chamfer, true number of components), per label. Pairs after the first must read the first
one's code space (their own, or adopted with --codes-from). The recipe around it:
docs/geometry.md ("A new auto-encoder without retraining the transformer").
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def rotate(sdf: str, out: str, seed: int) -> float:
    """Write the turned auto-encoder to ``out``; -> max |SDF difference| on a random check."""
    from model.core.checkpoint import read_checkpoint
    from model.geometry.checkpoint import load_checkpoint
    ck = read_checkpoint(sdf, "sdf")
    sd = {k: v.float() for k, v in ck["state_dict"].items()}
    Z = int(ck["config"]["z_dim"])
    gen = torch.Generator().manual_seed(seed)
    Q, _ = torch.linalg.qr(torch.randn(Z, Z, generator=gen, dtype=torch.float64))
    Q = Q.float()
    w, b = sd["vae.to_stats.weight"], sd["vae.to_stats.bias"]        # rows: [mu | logvar]
    w[:Z], b[:Z] = Q @ w[:Z], Q @ b[:Z]
    for name in ("vae.from_z.weight", "global_code.weight"):         # (out, Z): read z = Q^T z'
        sd[name] = sd[name] @ Q.T
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    extra = {**(ck.get("extra") or {}), "rotated_from": str(sdf), "rotation_seed": int(seed)}
    torch.save({**ck, "state_dict": sd, "extra": extra}, out)
    a, _ = load_checkpoint(sdf, "sdf")
    r, _ = load_checkpoint(out, "sdf")
    pts = torch.rand(4, 2048, 3, generator=gen) * 1.8 - 0.9
    z = torch.randn(4, Z, generator=gen)
    za, zr = a.encode(pts), r.encode(pts)
    q = torch.rand(4, 4096, 3, generator=gen) * 2 - 1
    err = max(float((a.query(a.decode_planes(z), q) - r.query(r.decode_planes(z @ Q.T), q))
                    .abs().max()),
              float((zr - za @ Q.T).abs().max()))
    return err


def score(data: str, split: str, pairs: list, per_label: int, seed: int) -> list[dict]:
    """One summary per pair of shapes sampled from the first pair's codes (module doc)."""
    from model.core.checkpoint import CheckpointError
    from model.geometry.api import ShapeModel
    from model.geometry.data import load_parts
    from model.geometry.eval_metrics import (encode_parts, per_label as by_label, select_parts,
                                             summarise)
    from model.geometry.eval_samples import reconstruct
    parts = load_parts(data, split, with_sdf=False)
    idx = select_parts(parts, per_label=per_label, max_parts=None, seed=seed)
    shapes = [ShapeModel.load(sdf, prior) for sdf, prior in pairs]
    space = shapes[0].info["fingerprint"]
    for (sdf, prior), sh in zip(pairs[1:], shapes[1:]):
        if space not in sh.info["accepts"]:
            raise CheckpointError(f"{prior} does not read the code space of {pairs[0][1]}")
    P = shapes[0].code_distribution(encode_parts(shapes[0], parts, idx, seed))
    texts = [parts.texts[i] for i in idx]
    truth: dict = {}
    out = []
    for (sdf, prior), sh in zip(pairs, shapes):
        z = sh.sample_from_logits(P.clamp_min(1e-8).log(), sh.semantic_condition(texts),
                                  steps=50, generator=torch.Generator().manual_seed(seed))
        rows = reconstruct(sh, parts, idx, seed=seed, truth=truth, z=z, iou=False)
        out.append({"sdf": sdf, "prior": prior, **summarise(rows), "labels": by_label(rows)})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("rotate", help="write the turned auto-encoder")
    r.add_argument("--sdf", default="model/weights/sdf_small.pt")
    r.add_argument("--out", required=True)
    r.add_argument("--seed", type=int, default=0)
    s = sub.add_parser("score", help="shapes sampled from the first pair's codes, per label")
    s.add_argument("--data", required=True)
    s.add_argument("--split", default="val")
    s.add_argument("--pair", nargs=2, action="append", required=True, metavar=("SDF", "PRIOR"))
    s.add_argument("--per-label", type=int, default=10)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--json", help="also write the summaries here")
    a = ap.parse_args(argv)
    torch.set_num_threads(2)
    if a.cmd == "rotate":
        err = rotate(a.sdf, a.out, a.seed)
        print(f"wrote {a.out}: max |difference| to {a.sdf} (latents turned, SDF) {err:.2e}")
        return 0 if err < 1e-3 else 1
    res = score(a.data, a.split, a.pair, a.per_label, a.seed)
    labels = sorted({k for r in res for k in r["labels"]})
    print("| label | " + " | ".join(f"pair {k + 1}: F@1% / CD mm / true #comp"
                                      for k in range(len(res))) + " |")
    print("|---|" + "---|" * len(res))
    for lab in labels + ["all"]:
        cells = []
        for r in res:
            x = r if lab == "all" else r["labels"].get(lab, {})
            cells.append(f"{x.get('fscore', float('nan')):.3f} / "
                         f"{x.get('chamfer_mm', float('nan')):.1f} / "
                         f"{x.get('true_components', float('nan')):.2f}")
        print(f"| {lab} | " + " | ".join(cells) + " |")
    if a.json:
        import json
        Path(a.json).write_text(json.dumps(res, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
