"""Process-level runtime helpers: per-stage torch thread counts, returning freed heap.

On a 2-core CPU the token-sized networks (text encoder, articulation decoding, the 50 DDIM
steps of the shape prior) run fastest on one thread: waking a second OpenMP thread for a
64 x 128 matrix costs more than the product (measured: 50-step DDIM over 8 parts 98 ms on
one thread, 287 ms on two, `python -m model.metrics.bench` / `artformer bench geometry`).
SDF meshing evaluates ~10^5 points per part and gains from every core. ``torch_threads``
sets the count for one stage and restores the previous one.

``keep_heap_mapped`` stops glibc from mapping and unmapping the multi-MB buffers of every
meshing chunk (page faults on each fresh buffer); ``release_free_memory`` returns the heap
after each request instead. ``proc_memory_kb`` reads a process's current and peak resident
memory.
"""
from __future__ import annotations

import contextlib
import sys
from typing import Iterator

_malloc_trim = None
_heap_kept = None

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3          # glibc mallopt parameters


@contextlib.contextmanager
def torch_threads(n: int | None) -> Iterator[None]:
    """Run the body with ``torch.set_num_threads(n)`` (None or < 1: leave it as it is)."""
    import torch
    if n is None or int(n) < 1:
        yield
        return
    before = torch.get_num_threads()
    if before == int(n):
        yield
        return
    torch.set_num_threads(int(n))
    try:
        yield
    finally:
        torch.set_num_threads(before)


def keep_heap_mapped() -> bool:
    """glibc only, once per process: serve allocations up to 32 MB (the cap glibc accepts)
    from the heap instead of fresh ``mmap`` pages, and do not shrink the heap on every free.
    Meshing allocates 8 MB activations per 32k-point chunk; with the default dynamic
    thresholds many of them come back as new pages to fault in (measured, one part at 64³ on
    2 threads: 88.5-88.9 ms median kept, 100.7-136.9 ms default, `artformer bench geometry
    [--default-heap]`). Freed heap is handed back by ``release_free_memory`` after each
    request. ``ARTFORMER_KEEP_HEAP=0`` leaves the allocator alone. Returns whether it is set."""
    import os
    global _heap_kept
    if _heap_kept is None:
        _heap_kept = False
        if os.environ.get("ARTFORMER_KEEP_HEAP", "1") != "0":
            try:
                import ctypes
                libc = ctypes.CDLL("libc.so.6")
                _heap_kept = bool(libc.mallopt(M_MMAP_THRESHOLD, 32 << 20)
                                  and libc.mallopt(M_TRIM_THRESHOLD, 1 << 30))
            except (OSError, AttributeError):
                pass
    return _heap_kept


def release_free_memory() -> None:
    """After a request: collect reference cycles, then hand freed heap pages back to the OS
    (glibc ``malloc_trim``). trimesh meshes sit in reference cycles (their caches), so a
    finished request's meshes are garbage only the cycle collector frees; its full pass runs
    rarely on its own (measured: RSS +50 MB per request without ``gc.collect``, flat with
    it). Meshing, export and rendering also leave hundreds of MB of free but mapped heap."""
    import gc
    gc.collect()
    global _malloc_trim
    if _malloc_trim is None:
        try:
            import ctypes

            _malloc_trim = ctypes.CDLL("libc.so.6").malloc_trim
        except (OSError, AttributeError):
            _malloc_trim = False
    if _malloc_trim:
        _malloc_trim(0)


def settle_after_load() -> None:
    """For serving processes, once the model is loaded: collect, then move every object alive
    now (the model, the encoders, the libraries: ~420k objects) to the collector's permanent
    generation, so the full collection after each request looks at that request's objects
    only (measured: 9 ms instead of 400 ms). Frozen objects are never collected, which is
    what a loaded model wants; libraries that load a model and then unload it should not
    call this."""
    import gc
    gc.collect()
    gc.freeze()


def _one_torch_thread() -> None:
    """Pool initializer: a forked worker runs torch on one thread. Once the parent has run a
    parallel torch op, its OpenMP pool's threads do not exist in the child, and the child's
    first parallel op waits for them forever; the workers already share the cores."""
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)


def map_jobs(fn, jobs: list, workers: int = 1, chunksize: int = 4) -> Iterator:
    """``fn`` over ``jobs``: results in completion order from ``workers`` forked processes (one
    torch thread each), or in order in this process when one worker (or one job) is enough."""
    if workers > 1 and len(jobs) > 1:
        import multiprocessing as mp
        with mp.get_context("fork").Pool(workers, initializer=_one_torch_thread) as pool:
            yield from pool.imap_unordered(fn, jobs, chunksize=chunksize)
    else:
        yield from map(fn, jobs)


def proc_memory_kb(pid="self") -> dict[str, int]:
    """VmRSS (current) and VmHWM (peak) of a process in kB, from /proc (Linux)."""
    out = {}
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith(("VmRSS:", "VmHWM:")):
                key, value = line.split(":", 1)
                out[key] = int(value.split()[0])
    return out
