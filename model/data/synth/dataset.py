"""Writing a procedural dataset to disk as PartNet-Mobility folders (resumable, parallel)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np

from .config import GENERATOR_VERSION, GenerationRejected, SynthConfig
from .generate import generate_object

# =============================================================================================
# dataset on disk
# =============================================================================================
def _synth_one(args) -> dict:
    out, seed, index, cfg = args
    from model.data.describe import describe
    from model.data.partnet_writer import write_partnet
    folder = Path(out) / f"{index:06d}"
    if (folder / "descriptions.json").exists():
        return {"index": index, "skipped": True}
    try:
        obj = generate_object(seed, index, cfg)
    except GenerationRejected as e:
        return {"index": index, "error": str(e)}
    texts = describe(obj, np.random.default_rng([seed, index, 7]))
    # descriptions.json is written last by write_partnet: it marks the folder complete
    write_partnet(obj, folder, descriptions=texts, extra_meta={"seed": seed, "index": index})
    return {"index": index, "category": obj.category, "parts": len(obj.parts),
            "movable": len(obj.movable_parts())}


def synthesize_dataset(out: str, n: int, seed: int = 0, workers: int = 2, config: Optional[SynthConfig] = None,
                       progress: bool = True) -> dict:
    """Write objects 0..n-1 of ``seed`` as PartNet-Mobility folders ``out/<index:06d>``.

    Resumable (complete folders are skipped), parallel over objects; writes ``out/synth.json``.
    """
    import time
    cfg = config or SynthConfig(seed=seed)
    Path(out).mkdir(parents=True, exist_ok=True)
    jobs = [(out, seed, i, cfg) for i in range(n)]
    t0 = time.time()
    results = []
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=n, desc="synth", unit="obj")
    if workers > 1 and n > 1:
        import multiprocessing as mp
        with mp.get_context("fork").Pool(workers) as pool:
            for r in pool.imap_unordered(_synth_one, jobs, chunksize=4):
                results.append(r)
                if bar:
                    bar.update(1)
    else:
        for j in jobs:
            results.append(_synth_one(j))
            if bar:
                bar.update(1)
    if bar:
        bar.close()
    errors = {r["index"]: r["error"] for r in results if "error" in r}
    info = {"generator": GENERATOR_VERSION, "seed": seed, "n": n, "errors": errors,
            "seconds_last_run": round(time.time() - t0, 1), "config": {
                "states": cfg.states, "attach_distance": cfg.attach_distance,
                "collision_abs_tol": cfg.collision_abs_tol, "collision_depth_tol": cfg.collision_depth_tol,
                "categories": cfg.categories}}
    from model.data.format import atomic_write_json
    atomic_write_json(Path(out) / "synth.json", info)
    return info
