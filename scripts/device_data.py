"""Build a training subset of the procedural data on a many-core accelerator machine, in time.

The full recipe's data (10,000 objects, 14 GB) cannot travel to a lent GPU machine, so the
auto-encoder's data is rebuilt there: only objects of the full dataset's *train* split (the
list comes from ``assign_splits`` of the 10,000 ids, seed 0), so the validation and test
objects of the full dataset stay unseen and the local evaluation is clean. Object i is a
pure function of (seed, i), so these are the same objects as in the full dataset.

    python scripts/device_data.py IDS_FILE OUT_DIR SECONDS WORKERS

synthesises the listed objects in order until SECONDS have passed (unfinished folders are
removed), then prepares them into OUT_DIR/prepared with 95 % train / 5 % val.
"""
from __future__ import annotations

import multiprocessing as mp
import shutil
import sys
import time
from pathlib import Path

from model.data.synth import GENERATOR_VERSION


def synth_until(ids: list[int], out: Path, seconds: float, workers: int) -> int:
    from model.data.synth import SynthConfig
    from model.data.synth.dataset import _synth_one
    cfg = SynthConfig(seed=0)
    out.mkdir(parents=True, exist_ok=True)
    t0, done = time.time(), 0
    pool = mp.get_context("fork").Pool(workers)
    try:
        for r in pool.imap_unordered(_synth_one, [(str(out), 0, i, cfg) for i in ids], chunksize=2):
            done += "error" not in r
            if time.time() - t0 > seconds:
                break
    finally:
        pool.terminate()
        pool.join()
    for f in out.iterdir():   # a folder is complete once descriptions.json is written
        if f.is_dir() and not (f / "descriptions.json").exists():
            shutil.rmtree(f)
    n = sum(1 for f in out.iterdir() if f.is_dir())
    print(f"synth: {n} objects in {time.time() - t0:.0f} s ({workers} workers)", flush=True)
    return n


def main() -> None:
    ids_file, out = sys.argv[1], Path(sys.argv[2])
    seconds, workers = float(sys.argv[3]), int(sys.argv[4])
    ids = [int(x) for x in Path(ids_file).read_text().split()]
    synth_until(ids, out / "synth", seconds, workers)
    from model.data.preprocess import PrepareConfig, prepare_dataset
    t0 = time.time()
    prepare_dataset(PrepareConfig(src=str(out / "synth"), out=str(out / "prepared"),
                                  workers=workers, split=(0.95, 0.05, 0.0),
                                  data_version=f"{GENERATOR_VERSION}-train-subset", seed=0),
                    progress=False)
    print(f"prepare: {time.time() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
