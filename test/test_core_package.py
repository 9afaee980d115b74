"""The core package imports without ROS, and the CLI answers --help without heavy imports."""
import subprocess
import sys


def test_import_model_does_not_import_rclpy():
    code = ("import sys, model, model.core, model.cli; "
            "bad = [m for m in ('rclpy', 'rclpy._rclpy_pybind11') if m in sys.modules]; "
            "assert not bad, bad; print('ok')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_cli_help_is_light():
    code = ("import sys, model.cli; model.cli.main(['--help']); "
            "assert 'torch' not in sys.modules, 'torch imported by --help'")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "generate" in out.stdout


def test_keep_heap_mapped_sets_glibc_thresholds_once_and_can_be_turned_off():
    """The pipeline asks glibc to keep meshing buffers on the heap (mallopt); a fresh
    process reports it set, ARTFORMER_KEEP_HEAP=0 leaves the allocator alone, and a large
    allocation then comes from the heap: freeing it does not shrink the process's mappings."""
    import os
    code = ("import sys; from model.core import runtime as r\n"
            "ok = r.keep_heap_mapped(); assert r.keep_heap_mapped() == ok\n"
            "import numpy as np\n"
            "def maps(): return sum(1 for _ in open('/proc/self/maps'))\n"
            "a = np.ones(2 << 20); before = maps(); del a; after = maps()\n"
            "print(ok, before - after)")
    out = {}
    for flag in ("1", "0"):
        env = {**os.environ, "ARTFORMER_KEEP_HEAP": flag}
        res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                             timeout=120)
        assert res.returncode == 0, res.stderr
        out[flag] = res.stdout.split()
    assert out["1"][0] == "True" and out["0"][0] == "False"
    # 16 MB from the heap: no mapping disappears on free; by default it is its own mmap
    assert out["1"][1] == "0" and int(out["0"][1]) >= 1


def test_half_state_stores_floats_as_fp16_copies_and_keeps_other_tensors():
    import torch

    from model.core.state import half_state
    w = torch.tensor([1.0, 2.5], requires_grad=True)
    h16 = torch.tensor([0.5], dtype=torch.float16)
    steps = torch.tensor([7], dtype=torch.long)
    out = half_state({"w": w, "h": h16, "n": steps})
    assert out["w"].dtype == torch.float16 and out["w"].tolist() == [1.0, 2.5]
    assert not out["w"].requires_grad
    assert out["n"].dtype == torch.long and out["n"].tolist() == [7]
    # copies, never views of the live weights: a later in-place update must not leak in
    with torch.no_grad():
        w.add_(1.0)
    h16.add_(1.0)
    steps.add_(1)
    assert out["w"].tolist() == [1.0, 2.5] and out["h"].tolist() == [0.5] and out["n"].tolist() == [7]


def test_map_jobs_gives_every_result_in_one_process_or_several():
    from model.core.runtime import map_jobs
    jobs = [-5, 3, -1, 4, -2]
    assert list(map_jobs(abs, jobs, workers=1)) == [5, 3, 1, 4, 2]        # in order
    assert sorted(map_jobs(abs, jobs, workers=2, chunksize=1)) == [1, 2, 3, 4, 5]
    assert list(map_jobs(abs, [], workers=2)) == []
