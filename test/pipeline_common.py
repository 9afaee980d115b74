"""A tiny end-to-end model for pipeline / node tests: the shape stages trained for a few
seconds by the real `artformer train` commands on primitive parts (so decoded SDFs have a
surface), and a tiny random-weight transformer wired to them (test_metrics_common)."""
from __future__ import annotations

from pathlib import Path


def make_trained_tiny(folder, seed: int = 1, sdf_steps: int = 150, prior_steps: int = 20) -> Path:
    from model.cli import main
    from model.geometry.data import make_primitive_dataset
    from test_metrics_common import make_tiny_checkpoints

    folder = Path(folder)
    ckpt = make_tiny_checkpoints(folder / "ckpt", seed=seed)
    data = make_primitive_dataset(folder / "prim", 6, n_points=256, n_sdf=1024, seed=seed)
    common = ["--preset", "tiny", "--no-progress", "--threads", "1"]
    assert main(["train", "sdf", "--data", str(data), "--out", str(folder / "sdf"),
                 "--steps", str(sdf_steps), *common]) == 0
    assert main(["train", "prior", "--data", str(data), "--out", str(folder / "prior"),
                 "--sdf", str(folder / "sdf" / "ckpt.pt"), "--steps", str(prior_steps),
                 *common]) == 0
    (ckpt / "sdf.pt").write_bytes((folder / "sdf" / "ckpt.pt").read_bytes())
    (ckpt / "prior.pt").write_bytes((folder / "prior" / "ckpt.pt").read_bytes())
    return ckpt
