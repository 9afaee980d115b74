"""The core package imports without ROS, the CLI answers --help without heavy imports, and
the packages of model/ import one way along a declared layer order (no cycles).

    python test/test_core_package.py     # prints the package import graph and its cycles
"""
import ast
import subprocess
import sys
from pathlib import Path

MODEL = Path(__file__).resolve().parents[1] / "model"

# The packages of model/, lowest first: a module may import its own package and the layers
# below it, never one above. Along the product's flow (text -> tree -> latents -> meshes ->
# URDF -> topic) with two deviations the code needs: export (URDF / MJCF / USD readers and
# writers, rendering, simulator checks, the sim-ready verdict: functions of a
# core.ArticulatedObject) sits right above core because the data, geometry, refine and imaging
# layers read URDFs, render, carve collision shapes and gate objects with it; and geometry (the shape prior) sits below articulation,
# whose training targets are the prior's latents. "app" holds the commands, servers and
# benches that tie several layers together; "model" is the package root (model/__init__.py,
# model/cli.py); artformer_ros (the topic) sits above all of it and is never imported here.
LAYERS = ("core", "export", "data", "encoders", "geometry", "articulation", "refine", "imaging",
          "pipeline", "metrics", "app", "model")


def _module_name(path: Path) -> tuple[str, bool]:
    """model/a/b.py -> ("model.a.b", False); model/a/__init__.py -> ("model.a", True)."""
    parts = path.relative_to(MODEL.parent).with_suffix("").parts
    return (".".join(parts[:-1]), True) if parts[-1] == "__init__" else (".".join(parts), False)


def _layer(module: str) -> str:
    """The package of model/ a module name falls in ("model" for the root modules)."""
    parts = module.split(".")
    if len(parts) > 1 and (MODEL / parts[1] / "__init__.py").exists():
        return parts[1]
    return "model"


def _imported(node, module: str, is_package: bool) -> list[str]:
    """Absolute names an import statement reaches: the module and, for `from M import x`,
    M.x as well (x may be a submodule)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if node.level:
        base = module.split(".")[: len(module.split(".")) - (0 if is_package else 1)]
        base = base[: len(base) - (node.level - 1)]
        src = ".".join(base + ([node.module] if node.module else []))
    else:
        src = node.module or ""
    return [src] + [f"{src}.{a.name}" for a in node.names]


def import_graph() -> dict[str, dict[str, list[str]]]:
    """package -> imported package -> ["model/x/y.py:LINE imports NAME", ...], from the AST of
    every module under model/, imports inside functions and try blocks included."""
    graph: dict[str, dict[str, list[str]]] = {}
    for path in sorted(MODEL.rglob("*.py")):
        module, is_package = _module_name(path)
        src = _layer(module)
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            for name in _imported(node, module, is_package):
                top = name.split(".")[0]
                if top == "artformer_ros":
                    dst = top
                elif top != "model" or name == "model" and isinstance(node, ast.ImportFrom):
                    continue      # `from model import x`: x counts (a package or the root)
                else:
                    dst = _layer(name)
                if dst != src:
                    where = f"{path.relative_to(MODEL.parent)}:{node.lineno} imports {name}"
                    graph.setdefault(src, {}).setdefault(dst, []).append(where)
    return graph


def cycles(graph: dict[str, dict]) -> list[list[str]]:
    """Every elementary cycle of the package graph, each from its smallest package."""
    out = []

    def walk(start, node, path):
        for nxt in sorted(graph.get(node, {})):
            if nxt == start:
                out.append(path + [start])
            elif nxt > start and nxt not in path:
                walk(start, nxt, path + [nxt])
    for start in sorted(graph):
        walk(start, start, [start])
    return out


def test_packages_of_model_import_one_way_without_cycles():
    graph = import_graph()
    packages = {p.parent.name for p in MODEL.glob("*/__init__.py")}
    assert packages <= set(LAYERS), f"place the new packages in LAYERS: {packages - set(LAYERS)}"
    assert "artformer_ros" not in {d for deps in graph.values() for d in deps}, graph
    upward = [w for src, deps in graph.items() for dst, where in deps.items()
              if LAYERS.index(dst) > LAYERS.index(src) for w in where]
    found = cycles(graph)
    assert not found and not upward, (
        f"{len(found)} import cycles between packages, e.g. "
        + "; ".join(" -> ".join(c) for c in found[:5])
        + "\nimports of a higher layer:\n" + "\n".join(upward))


def test_import_graph_sees_imports_in_functions_and_relative_ones():
    """The graph builder itself: a function-level import, a relative one and
    `from model import <package>` all count."""
    tree = ast.parse("from ...pipeline import api\n"
                     "def f():\n    from model import metrics\n    import model.export.urdf\n")
    names = [n for node in ast.walk(tree) if isinstance(node, (ast.Import, ast.ImportFrom))
             for n in _imported(node, "model.data.synth", True)]
    assert "model.pipeline.api" in names and "model.metrics" in names
    assert {_layer(n) for n in names if n.startswith("model.")} >= {"pipeline", "metrics", "export"}
    [node] = ast.parse("from .urdfmodel import find_urdf").body
    assert _imported(node, "model.export.viewer", False)[0] == "model.export.urdfmodel"
    assert cycles({"a": {"b": []}, "b": {"c": []}, "c": {"a": []}}) == [["a", "b", "c", "a"]]
    assert cycles({"a": {"b": []}, "b": {}}) == []


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


def test_map_jobs_workers_run_torch_after_the_parent_did():
    """A parent that has run a parallel torch op forks workers whose OpenMP pool has no
    threads: a parallel op there waited forever (load_parts(workers=2) after loading a
    model). The workers get one torch thread each."""
    import os
    import signal
    code = ("import torch\n"
            "from model.core.runtime import map_jobs\n"
            "def job(n):\n"
            "    a = torch.ones(300, 300)\n"
            "    return n, torch.get_num_threads(), float((a @ a)[0, 0])\n"
            "torch.set_num_threads(2)\n"
            "a = torch.randn(800, 800); (a @ a).sum()\n"
            "print(sorted(map_jobs(job, list(range(4)), workers=2, chunksize=1)))\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=90)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise AssertionError("map_jobs' workers hung in their first parallel torch op")
    assert proc.returncode == 0, err
    assert out.strip() == str([(n, 1, 300.0) for n in range(4)])


if __name__ == "__main__":
    g = import_graph()
    for pkg in sorted(g, key=lambda p: LAYERS.index(p) if p in LAYERS else -1):
        print(f"{pkg:13} -> {', '.join(sorted(g[pkg]))}")
    for c in cycles(g):
        print("cycle:", " -> ".join(c))
    for src, deps in g.items():
        for dst, where in deps.items():
            if dst not in LAYERS or LAYERS.index(dst) > LAYERS.index(src):
                print(f"upward {src} -> {dst}:", *where, sep="\n  ")
