"""Rebuild only the held-out splits of a procedural dataset, for evaluation without the
hours that the training split costs.

    python scripts/heldout_data.py --n 10000 --seed 0 --version synth-v6 \
        --synth data/synth/v6 --out data/prepared/v6 --splits val,test

``artformer data synth --n N`` writes objects ``000000 .. N-1`` and ``artformer data prepare``
splits them by the sorted ids and the seed (``assign_splits``); every object is drawn from
``(seed, index)`` alone. So the objects of a split, and their records, come out byte for byte
as the full recipe makes them, given that the full synth run had no rejected indices (the
manifest of the full run lists 0 errors). The manifest written here lists only the splits
asked for; training needs the full recipe (scripts/recipe_geometry.sh, stage data).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=10000, help="objects of the full dataset")
    ap.add_argument("--seed", type=int, default=0, help="synth, split and sampling seed")
    ap.add_argument("--version", default="synth-v6", help="data_version of the manifest")
    ap.add_argument("--synth", default="data/synth/v6")
    ap.add_argument("--out", default="data/prepared/v6")
    ap.add_argument("--splits", default="val,test")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)

    import multiprocessing as mp

    from model.data import preprocess as pp
    from model.data.synth.config import SynthConfig
    from model.data.synth.dataset import _synth_one

    want = [s.strip() for s in a.splits.split(",") if s.strip()]
    ids = [f"{i:06d}" for i in range(a.n)]
    splits = pp.assign_splits(ids, a.seed)
    todo = [k for k, i in enumerate(ids) if splits[i] in want]
    t0 = time.time()
    cfg = SynthConfig(seed=a.seed)
    with mp.get_context("fork").Pool(a.workers) as pool:
        res = pool.map(_synth_one, [(a.synth, a.seed, k, cfg) for k in todo], chunksize=4)
    bad = {r["index"]: r["error"] for r in res if "error" in r}
    if bad:
        print(f"rejected indices {sorted(bad)[:10]}: the split would differ from the full run",
              file=sys.stderr)
        return 1
    t_synth = time.time() - t0
    pcfg = pp.PrepareConfig(src=a.synth, out=a.out, seed=a.seed, workers=a.workers,
                            data_version=a.version)
    jobs = [(str(Path(a.synth) / ids[k]), ids[k], splits[ids[k]], pcfg, k) for k in todo
            if not pp._is_done(Path(a.out), ids[k])]
    with mp.get_context("fork").Pool(a.workers) as pool:
        res = pool.map(pp._worker, jobs, chunksize=2)
    errors = {r["id"]: r["error"] for r in res if "error" in r}
    done = [ids[k] for k in todo if pp._is_done(Path(a.out), ids[k])]
    pp.write_manifest(pcfg, splits, done, errors, processed=len(jobs),
                      seconds=time.time() - t0, extra={"heldout_only": want})
    print(f"{len(done)} objects ({', '.join(want)}) in {a.out}: synth {t_synth:.0f} s, "
          f"total {time.time() - t0:.0f} s, {len(errors)} prepare errors")
    return 0


if __name__ == "__main__":
    sys.exit(main())
