"""Builders shared by the test modules (through the fixtures in conftest.py or imported by
name): the one tiny model every pipeline / node / metrics test loads, small prepared
datasets in the real format, procedural objects as the builder makes them, and the
hand-written wheel URDF."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from model.data import format as fmt

# -- the tiny model ----------------------------------------------------------------------------
SHAPES = ("octahedron", "sphere", "trained")


def build_tiny_model(folder, *, seed: int = 0, shape: str = "octahedron", image: bool = False,
                     end_bias: float = -1.0, ablation: str = "none", count_labels=(),
                     sdf_steps: int = 150, prior_steps: int = 20) -> Path:
    """A checkpoint folder the pipeline's Generator loads: transformer.pt / sdf.pt / prior.pt
    at the tiny presets (codebooks and c_s sizes agree across stages), plus image.pt when
    ``image``. The transformer has random weights; ``end_bias`` keeps its trees small (a
    negative END logit bias = few children). ``shape`` decides the shape stages:

    - "octahedron": random prior, SDF decoder set by hand to |x|+|y|+|z|-0.6 (instant);
    - "sphere": random prior, SDF decoder fitted to a sphere for latents of any scale (~2 s);
    - "trained": auto-encoder and prior trained for a few seconds by the real
      `artformer train` commands on primitive parts, so decoded SDFs follow the latents.

    A random decoder may produce no surface at all, so every shape gives each part a surface.
    """
    import torch

    from model.articulation.checkpoint import read_checkpoint, save_checkpoint as save_art, save_dict
    from model.articulation.config import preset
    from model.articulation.network import ArticulationTransformer
    from model.core.checkpoint import shape_prior_fingerprint
    from model.data import vocab
    from model.geometry.autoencoder import SDFAutoEncoder
    from model.geometry.checkpoint import save_checkpoint as save_geo
    from model.geometry.config import get_preset
    from model.geometry.prior import ShapePrior
    from model.imaging.model import ImageExtras

    if shape not in SHAPES:
        raise ValueError(f"shape must be one of {SHAPES}, got {shape!r}")
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
    # the shape stages are final before the transformer records their fingerprint
    if shape == "sphere":
        _sphere_decoder(folder / "sdf.pt")
    elif shape == "trained":
        _train_shape_stages(folder, seed, sdf_steps, prior_steps)
    save_art(folder / "transformer.pt", net, stats=stats, label_table=table,
             text_encoder="all-minilm-l6-v2", data_version="tiny", seed=seed, command="test",
             step=0, prior=shape_prior_fingerprint(folder / "sdf.pt", folder / "prior.pt"))
    if image:
        # an image checkpoint is a transformer checkpoint with an image condition and the
        # frozen EfficientNet-Lite0 config (the defaults)
        ck = read_checkpoint(folder / "transformer.pt")
        save_dict(folder / "image.pt", {**ck, **ImageExtras(encoder={}).entries()})
    return folder


def _octahedron_decoder(dec) -> None:
    """Set the SDF MLP to |x| + |y| + |z| - 0.6 (plane features ignored)."""
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


def _sphere_decoder(path) -> None:
    """Fit the SDF decoder to a sphere (radius 0.6 of the part cube) for latents of any scale."""
    import torch

    from model.geometry.checkpoint import load_checkpoint, save_checkpoint

    ae, _ = load_checkpoint(path, "sdf")
    gen = torch.Generator().manual_seed(0)
    zs = torch.cat([torch.randn(4, ae.cfg.z_dim, generator=gen) * s for s in (0.25, 1.0, 4.0)])
    planes = ae.decode_planes(zs).clone()              # (12, 3, C, R, R), out of inference mode
    opt = torch.optim.Adam(ae.decoder.parameters(), lr=3e-3)
    for _ in range(200):
        xyz = torch.rand(len(zs), 1024, 3, generator=gen) * 2 - 1        # (12, 1024, 3)
        loss = (ae.decoder(planes, xyz) - (xyz.norm(dim=-1) - 0.6)).abs().mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.05, loss.item()
    save_checkpoint(path, "sdf", ae)


def _train_shape_stages(folder: Path, seed: int, sdf_steps: int, prior_steps: int) -> None:
    """Replace sdf.pt / prior.pt by ones the real CLI trains on primitive parts (the training
    runs in a temporary folder, so only the checkpoints land in ``folder``)."""
    import tempfile

    from model.cli import main
    from model.geometry.data import make_primitive_dataset

    common = ["--preset", "tiny", "--no-progress", "--threads", "1"]
    with tempfile.TemporaryDirectory(prefix="tiny_shape_") as tmp:
        work = Path(tmp)
        data = make_primitive_dataset(work / "prim", 6, n_points=256, n_sdf=1024, seed=seed)
        assert main(["train", "sdf", "--data", str(data), "--out", str(work / "sdf"),
                     "--steps", str(sdf_steps), *common]) == 0
        assert main(["train", "prior", "--data", str(data), "--out", str(work / "prior"),
                     "--sdf", str(work / "sdf" / "ckpt.pt"), "--steps", str(prior_steps),
                     *common]) == 0
        (folder / "sdf.pt").write_bytes((work / "sdf" / "ckpt.pt").read_bytes())
        (folder / "prior.pt").write_bytes((work / "prior" / "ckpt.pt").read_bytes())


# -- procedural objects ------------------------------------------------------------------------
def built_object(seed: int, index: int, category: str | None = None):
    """``synth.generate_object`` without the sim-ready audit that dataset generation adds
    (its MuJoCo drop is ~98 % of the time: 3.7 s against 0.08 s for a cabinet): the
    builder's object, collision- and attachment-checked over its motion. For tests of what
    the builder and the describer guarantee of every object they make; the audit's own tests
    use the generator as the dataset does."""
    from model.data import synth
    return synth.generate_object(seed, index, synth.SynthConfig(seed=seed, audit=False),
                                 category=category)


# -- prepared datasets -------------------------------------------------------------------------
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


def write_prepared(root, objects: dict, splits: dict, version: str = "test"):
    """A minimal prepared dataset (manifest, records, prepared meshes) of hand-built objects."""
    import trimesh
    fmt.atomic_write_json(root / "manifest.json", {
        "format": 1, "data_version": version, "source": "example", "seed": 0, "splits": splits,
        "labels": sorted({p.label for o in objects.values() for p in o.parts}),
        "categories": sorted({o.category for o in objects.values()})})
    for split, ids in splits.items():
        for oid in ids:
            obj = objects[oid]
            toks, types, parents, labels = obj.tokens()
            order = obj.topological_order()
            fmt.save_record(root, fmt.ObjectRecord(
                id=oid, category=obj.category, split=split, labels=labels,
                parents=parents.tolist(), joint_types=types.tolist(), tokens=toks.tolist(),
                summary=obj.summary()))
            (root / "meshes" / oid).mkdir(parents=True, exist_ok=True)
            pts = []
            for k, i in enumerate(order):
                mesh = obj.parts[i].mesh
                mesh.export(root / "meshes" / oid / f"{k}.obj")
                p = np.asarray(trimesh.sample.sample_surface(mesh, 256, seed=k)[0], np.float64)
                pts.append((p - p.mean(0)) / max(np.ptp(p, axis=0).max(), 1e-6) * 1.9)
            fmt.save_part_arrays(root, oid, points=np.stack(pts).astype(np.float16))


# toy articulation dataset: simple cabinets and bottles whose descriptions state the structure
WORDS = ["zero", "one", "two", "three", "four"]


def _cabinet(rng, n_drawers: int, door: bool):
    labels, parents, jts, toks = ["body"], [-1], [0], []
    w, d, h = 0.6, 0.5, 0.3 + 0.15 * n_drawers
    toks.append([w, d, h, 0, 0, h / 2, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0])
    for k in range(n_drawers):
        z = h - 0.15 * (k + 0.5)
        labels.append("drawer"); parents.append(0); jts.append(2)
        toks.append([0.45, 0.5, 0.12, 0, 0, z, 0.25, 0, z, 1, 0, 0, 0, 0.3, 0, 0])
        labels.append("handle"); parents.append(len(labels) - 2); jts.append(0)
        toks.append([0.02, 0.1, 0.02, 0.27, 0, z, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0])
    if door:
        labels.append("door"); parents.append(0); jts.append(1)
        toks.append([0.02, 0.3, 0.15, 0.26, 0.1, 0.1, 0.26, -0.05, 0.1, 0, 0, 1, 0, 0, 0, 1.57])
    toks = np.asarray(toks) * (1 + 0.05 * rng.normal(size=(len(toks), 16)))
    return "StorageFurniture", labels, parents, jts, toks


def _bottle(rng):
    toks = np.array([[0.08, 0.08, 0.25, 0, 0, 0.125, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0],
                     [0.03, 0.03, 0.02, 0, 0, 0.26, 0, 0, 0.26, 0, 0, 1, 0, 0.02, 0, 6.28]])
    toks = toks * (1 + 0.05 * rng.normal(size=toks.shape))
    return "Bottle", ["body", "cap"], [-1, 0], [0, 4], toks


def _texts(cat, labels, door):
    if cat == "Bottle":
        return {"detailed": ["A bottle whose cap screws on and off the body."],
                "sentences": ["A bottle. It has a screw cap."],
                "sentence": ["A bottle with a twist-off cap."],
                "words": ["screw cap bottle"]}
    n = labels.count("drawer")
    extra = " and a hinged door" if door else ""
    return {"detailed": [f"A storage cabinet with {WORDS[n]} sliding drawers{extra}; "
                         f"every drawer has a handle."],
            "sentences": [f"A cabinet. It has {WORDS[n]} drawers{extra}."],
            "sentence": [f"A cabinet with {WORDS[n]} drawers{extra}."],
            "words": [f"{WORDS[n]} drawer cabinet" + (" door" if door else "")]}


def write_toy_dataset(root, n: int = 24, seed: int = 0, points: int = 64,
                      version: str = "toy1", wordings: int = 1) -> list[str]:
    """Write n objects (train/val/test = 60/20/20 %) to ``root``; returns the ids. With
    ``wordings`` > 1 every description length gets that many wordings (numbered copies)."""
    rng = np.random.default_rng(seed)
    ids, splits = [], {"train": [], "val": [], "test": []}
    for i in range(n):
        kind = i % 4
        if kind == 3:
            cat, labels, parents, jts, toks = _bottle(rng)
            door = False
        else:
            door = kind == 2
            cat, labels, parents, jts, toks = _cabinet(rng, 1 + (i // 4) % 3, door)
        oid = f"toy_{i:03d}"
        split = "train" if i < 0.6 * n else ("val" if i < 0.8 * n else "test")
        splits[split].append(oid)
        rec = fmt.ObjectRecord(id=oid, category=cat, split=split, labels=labels,
                               parents=parents, joint_types=jts, tokens=toks.tolist(),
                               descriptions={k: v + [f"{v[0]} ({j + 2})" for j in range(wordings - 1)]
                                             for k, v in _texts(cat, labels, door).items()})
        fmt.save_record(root, rec)
        K = len(labels)
        pts = rng.uniform(-0.95, 0.95, size=(K, points, 3)) * rng.uniform(0.3, 1, size=(K, 1, 3))
        fmt.save_part_arrays(root, oid, points=pts.astype(np.float16),
                             normals=np.zeros_like(pts, dtype=np.float16),
                             sdf=np.zeros((K, 8, 4), np.float16),
                             center=np.zeros((K, 3), np.float32), scale=np.ones(K, np.float32))
        ids.append(oid)
    fmt.atomic_write_json(f"{root}/manifest.json", {
        "format": fmt.FORMAT_VERSION, "data_version": version, "source": "test", "seed": seed,
        "splits": splits, "labels": sorted({"body", "drawer", "handle", "door", "cap"}),
        "categories": ["Bottle", "StorageFurniture"]})
    return ids


# -- a hand-written URDF with a continuous joint and primitive geometry -------------------------
WHEEL_URDF = """<robot name="cart">
  <link name="base">
    <inertial><mass value="2"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><box size="0.4 0.2 0.1"/></geometry>
      <material name="grey"><color rgba="0.5 0.5 0.5 1"/></material></visual>
    <collision><geometry><box size="0.4 0.2 0.1"/></geometry></collision>
  </link>
  <link name="wheel">
    <inertial><origin xyz="0 0 0" rpy="0.3 0 0"/><mass value="0.5"/>
      <inertia ixx="0.01" iyy="0.02" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><origin rpy="1.5707963 0 0"/><geometry><cylinder radius="0.05" length="0.02"/></geometry></visual>
    <collision><origin rpy="1.5707963 0 0"/><geometry><cylinder radius="0.05" length="0.02"/></geometry></collision>
  </link>
  <joint name="wheel_joint" type="continuous">
    <parent link="base"/><child link="wheel"/>
    <origin xyz="0.2 0.12 -0.05" rpy="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit effort="5" velocity="10"/>
  </joint>
</robot>
"""
