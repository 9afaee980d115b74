"""Shared helpers of the metrics tests: a tiny prepared dataset in the real format, and tiny
random-weight checkpoints of the three generation stages (for eval / bench smoke runs)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from model.data import format as fmt


def build_prepared(root: Path, n_train: int = 6, n_test: int = 3, seed: int = 11) -> Path:
    """A minimal prepared dataset (records + meshes) from the procedural generator."""
    from model.data.describe import describe
    from model.data.synth import generate_object
    ids = {"train": [], "val": [], "test": []}
    for i in range(n_train + n_test):
        obj = generate_object(seed=seed, index=i)
        split = "train" if i < n_train else "test"
        oid = f"obj{i:03d}"
        toks, types, parents, labels = obj.tokens()
        order = obj.topological_order()
        rec = fmt.ObjectRecord(id=oid, category=obj.category, split=split, labels=labels,
                               parents=parents.tolist(), joint_types=types.tolist(),
                               tokens=toks.tolist(),
                               descriptions=describe(obj, np.random.default_rng(i)),
                               summary=obj.summary(),
                               part_names=[obj.parts[k].name for k in order])
        fmt.save_record(root, rec)
        mdir = root / "meshes" / oid
        mdir.mkdir(parents=True, exist_ok=True)
        for k, j in enumerate(order):
            obj.parts[j].mesh.export(mdir / f"{k}.obj")
        ids[split].append(oid)
    fmt.atomic_write_json(root / "manifest.json", {
        "format": fmt.FORMAT_VERSION, "data_version": "test", "source": "synth", "seed": seed,
        "splits": ids, "labels": [], "categories": []})
    return root


def make_tiny_checkpoints(folder, seed: int = 0, end_bias: float = -1.0,
                          ablation: str = "none", count_labels: tuple = ()) -> Path:
    """transformer.pt / sdf.pt / prior.pt with random weights at the tiny presets, wired so
    the pipeline's Generator loads them (codebooks and c_s sizes agree across stages).
    ``end_bias`` keeps random trees small (a negative END logit bias = few children)."""
    import torch

    from model.articulation.checkpoint import save_checkpoint as save_art
    from model.articulation.config import preset
    from model.articulation.network import ArticulationTransformer
    from model.data import vocab
    from model.geometry.autoencoder import SDFAutoEncoder
    from model.geometry.checkpoint import save_checkpoint as save_geo
    from model.geometry.config import get_preset
    from model.geometry.prior import ShapePrior

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(seed)
    geo = get_preset("tiny")
    ae = SDFAutoEncoder(geo.sdf)
    _octahedron_decoder(ae.decoder)
    save_geo(folder / "sdf.pt", "sdf", ae)
    save_geo(folder / "prior.pt", "prior", ShapePrior(geo.prior))
    cfg, _ = preset("tiny", ablation, codebook_size=geo.prior.codebook_size,
                    num_codebooks=1 if ablation == "one_codebook" else geo.prior.n_codebooks,
                    cs_dim=geo.prior.cs_dim)
    cfg.count_labels = list(count_labels)      # plan labels (child counts, START plan head)
    net = ArticulationTransformer(cfg)
    with torch.no_grad():
        net.head_end.bias.fill_(end_bias)
    pairs = [(c, lab) for c in vocab.CATEGORIES for lab in ("body", "drawer", "door", "handle", "cap")]
    g = np.random.default_rng(seed)
    # token statistics of plausible furniture-sized parts (metres), so random outputs are sane
    stats = {"tok_mean": np.r_[[0.4] * 3, [0, 0, 0.3], [0] * 3, [0, 0, 1], [0, 0.2, 0, 1.0]
                              ].astype(np.float32),
             "tok_std": np.full(16, 0.1, np.float32),
             "cs_mean": np.zeros(cfg.cs_dim, np.float32), "cs_std": np.ones(cfg.cs_dim, np.float32)}
    table = {"categories": [c for c, _ in pairs], "labels": [lab for _, lab in pairs],
             "cs": g.normal(size=(len(pairs), cfg.cs_dim)).astype(np.float32)}
    save_art(folder / "transformer.pt", net, stats=stats, label_table=table,
             text_encoder="all-minilm-l6-v2", data_version="tiny", seed=seed, command="test",
             step=0)
    return folder


def _octahedron_decoder(dec) -> None:
    """Set the SDF MLP to |x| + |y| + |z| - 0.6 (plane features ignored): random decoders
    may produce no surface at all, which would make the smoke runs depend on the init."""
    import torch
    with torch.no_grad():
        for layer in list(dec.layers) + [dec.out]:
            layer.weight.zero_()
            layer.bias.zero_()
        signs = torch.tensor([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
        dec.layers[0].weight[:6, :3] = signs          # relu(+-x), relu(+-y), relu(+-z)
        for layer in list(dec.layers)[1:]:
            layer.weight[:6, :6] = torch.eye(6)       # carried through (skip input appended after)
        dec.out.weight[0, :6] = 1.0
        dec.out.bias.fill_(-0.6)
