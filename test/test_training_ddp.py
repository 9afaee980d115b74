"""The shared training loop (model.core.training): schedule, budgets, resume, and DDP with two
processes over gloo on localhost."""
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from model.core.training import Dist, LoopConfig, LoopState, lr_at, train_loop

ROOT = Path(__file__).resolve().parents[1]


def test_lr_schedule_warmup_cosine_floor_and_time_budget():
    assert lr_at(0, 1.0, 10, 100) == pytest.approx(0.1)
    assert lr_at(9, 1.0, 10, 100) == pytest.approx(1.0)
    assert lr_at(10, 1.0, 10, 100) == pytest.approx(1.0)
    assert lr_at(100, 1.0, 10, 100, floor=0.05) == pytest.approx(0.05)
    assert lr_at(55, 1.0, 10, 100, floor=0.0) == pytest.approx(0.5)
    # a run that spent its wall-clock budget has annealed, whatever its step
    assert lr_at(20, 1.0, 10, 100, floor=0.1, time_share=1.0) == pytest.approx(0.1)


def _regression(seed: int = 0):
    torch.manual_seed(seed)
    x = torch.randn(64, 3)
    y = x @ torch.tensor([1.0, -2.0, 0.5]) + 0.3
    return x, y


def test_loop_steps_validates_saves_and_resumes(tmp_path):
    x, y = _regression()
    model = torch.nn.Linear(3, 1)
    opt = torch.optim.SGD(model.parameters(), lr=0.1)
    saved = []

    def step_fn(net, step):
        i = torch.arange(step * 8, step * 8 + 8) % 64
        return torch.nn.functional.mse_loss(net(x[i]).squeeze(1), y[i]), {}

    def val_fn():
        with torch.no_grad():
            return float(torch.nn.functional.mse_loss(model(x).squeeze(1), y))

    cfg = LoopConfig(steps=40, lr=0.1, warmup=2, val_every=10, ckpt_every=15, progress=False,
                     log_dir=str(tmp_path))
    st = train_loop(model, opt, cfg, step_fn, val_fn=val_fn,
                    save_fn=lambda s, final: saved.append((s.step, final)))
    assert st.step == 40 and [h["step"] for h in st.history] == [10, 20, 30, 40]
    assert st.history[-1]["val"] < 0.1 * st.history[0]["val"]
    assert saved == [(15, False), (30, False), (40, True)]
    assert len((tmp_path / "log.jsonl").read_text().splitlines()) == 4
    # resuming from the state continues to the new budget with the history kept
    cfg.steps = 50
    st2 = train_loop(model, opt, cfg, step_fn, val_fn=val_fn, state=LoopState.of(st.entries()))
    assert st2.step == 50 and len(st2.history) == 5 and st2.elapsed >= st.elapsed
    # a finished run resumed at its end (to export it) is not validated a second time
    st3 = train_loop(model, opt, cfg, step_fn, val_fn=val_fn, state=LoopState.of(st2.entries()))
    assert st3.step == 50 and len(st3.history) == 5
    assert len((tmp_path / "log.jsonl").read_text().splitlines()) == 5


def test_wall_clock_budget_stops_and_counts_resumed_time():
    model = torch.nn.Linear(1, 1)
    opt = torch.optim.SGD(model.parameters(), lr=0.1)
    calls = []

    def step_fn(net, step):
        calls.append(step)
        return net(torch.ones(1, 1)).sum(), {}

    # 1 s of budget, of which the resumed run already spent 2 s: no step is taken
    cfg = LoopConfig(steps=1000, lr=0.1, minutes=1 / 60, progress=False)
    st = train_loop(model, opt, cfg, step_fn, state=LoopState(step=3, elapsed=2.0))
    assert calls == [] and st.step == 3


def test_chunks_stop_and_resume_to_the_uninterrupted_result():
    """--chunk-minutes stops a process early without bending the schedule: chunks resumed
    to the end give the weights of one uninterrupted run."""
    import time
    x, y = _regression()

    def run(chunks: bool):
        torch.manual_seed(0)
        model = torch.nn.Linear(3, 1)
        opt = torch.optim.SGD(model.parameters(), lr=0.1)

        def step_fn(net, step):
            time.sleep(0.02)
            i = torch.arange(step * 8, step * 8 + 8) % 64
            return torch.nn.functional.mse_loss(net(x[i]).squeeze(1), y[i]), {}

        cfg = LoopConfig(steps=16, lr=0.1, warmup=2, progress=False,
                         chunk_minutes=0.1 / 60 if chunks else 0.0)
        st, stops = LoopState(), []
        while st.step < cfg.steps:
            st = train_loop(model, opt, cfg, step_fn, state=LoopState.of(st.entries()))
            stops.append(st.step)
        return model, stops

    whole, one = run(False)
    chunked, stops = run(True)
    assert one == [16] and len(stops) >= 2 and stops[-1] == 16
    assert torch.allclose(whole.weight, chunked.weight) and torch.allclose(whole.bias, chunked.bias)


def test_shard_splits_and_never_leaves_a_process_empty():
    d = Dist.__new__(Dist)                     # a rank of a 2-process run, without gloo
    d.world, d.active = 2, True
    d.rank = 1
    assert d.shard([0, 1, 2, 3, 4]) == [1, 3]
    assert d.shard(["only"]) == ["only"]       # fewer batches than processes: one repeats
    d.rank = 0
    assert d.shard([0, 1, 2, 3, 4]) == [0, 2, 4]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _batch(items: list, step: int) -> list:
    return items[(step * 4) % len(items):][:4]


def _ddp_worker(rank: int, world: int, port: int, out: str) -> None:
    os.environ.update(RANK=str(rank), WORLD_SIZE=str(world), MASTER_ADDR="127.0.0.1",
                      MASTER_PORT=str(port), LOCAL_RANK=str(rank))
    torch.set_num_threads(1)
    from model.core.checkpoint import CheckpointMeta, write_checkpoint
    dist = Dist()
    x, y = _regression()
    torch.manual_seed(0)                       # the same initial weights on both ranks
    model = torch.nn.Linear(3, 1)
    opt = torch.optim.SGD(model.parameters(), lr=0.1)
    mine = dist.shard(list(range(64)))         # every rank its own half of the data

    def step_fn(net, step):
        i = torch.tensor(_batch(mine, step))
        return torch.nn.functional.mse_loss(net(x[i]).squeeze(1), y[i]), {}

    def save_fn(st, final):
        assert dist.rank == 0
        write_checkpoint(Path(out) / "ckpt.pt", CheckpointMeta(kind="sdf", step=st.step),
                         {"config": {}, "state_dict": model.state_dict(), **st.entries()})

    train_loop(model, opt, LoopConfig(steps=6, lr=0.1, val_every=3, progress=False), step_fn,
               val_fn=lambda: 0.0, save_fn=save_fn, dist=dist)
    torch.save(model.state_dict(), Path(out) / f"rank{rank}.pt")
    dist.close()


def test_ddp_two_processes_average_gradients_and_rank0_writes(tmp_path):
    import torch._dynamo  # noqa: F401  - the optimizers import it on their first step: once
    import torch.multiprocessing as mp       # here, not in each worker (fork shares it)
    from model.core.checkpoint import read_checkpoint
    mp.start_processes(_ddp_worker, args=(2, _free_port(), str(tmp_path)), nprocs=2, join=True,
                       start_method="fork")
    ck = read_checkpoint(tmp_path / "ckpt.pt", "sdf")
    assert ck["step"] == 6 and len(ck["history"]) == 2
    r0, r1 = (torch.load(tmp_path / f"rank{r}.pt", weights_only=True) for r in (0, 1))
    assert all(torch.equal(r0[k], r1[k]) for k in r0)          # gradients were averaged
    assert all(torch.equal(r0[k], ck["state_dict"][k]) for k in r0)
    # = one process on both ranks' batches at once (equal batch sizes: the mean of the two
    # gradients is the gradient of the mean loss)
    x, y = _regression()
    torch.manual_seed(0)
    one = torch.nn.Linear(3, 1)
    halves = [list(range(64))[r::2] for r in (0, 1)]

    def step_fn(net, step):
        i = torch.tensor(_batch(halves[0], step) + _batch(halves[1], step))
        return torch.nn.functional.mse_loss(net(x[i]).squeeze(1), y[i]), {}

    train_loop(one, torch.optim.SGD(one.parameters(), lr=0.1),
               LoopConfig(steps=6, lr=0.1, progress=False), step_fn)
    assert torch.allclose(one.weight, r0["weight"], atol=1e-6)
    assert torch.allclose(one.bias, r0["bias"], atol=1e-6)


@pytest.mark.slow     # two processes each load the text encoder (~25 s)
def test_torchrun_two_processes_train_the_text_transformer(tmp_path):
    torchrun = Path(sys.executable).parent / "torchrun"
    if not torchrun.exists():
        pytest.skip("torchrun not installed in this environment")
    sys.path.insert(0, str(Path(__file__).parent))
    from helpers import write_toy_dataset
    write_toy_dataset(tmp_path / "data", n=10)
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    cmd = [str(torchrun), "--standalone", "--nproc_per_node", "2", "-m", "model", "train",
           "transformer", "--data", str(tmp_path / "data"), "--prior", "none", "--preset", "tiny",
           "--out", str(tmp_path / "run"), "--steps", "6", "--no-progress", "--threads", "1"]
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    from model.articulation.checkpoint import read_checkpoint
    from model.articulation.decode import ArticulationModel
    ck = read_checkpoint(tmp_path / "run" / "transformer.pt")
    assert ck["step"] == 6 and "val" in ck["history"][-1]
    am = ArticulationModel.load(tmp_path / "run" / "transformer.pt")
    cond, mask = am.encode_text(["a cabinet with two drawers"])
    assert am.decode(cond, mask, seed=0, max_nodes=6)[0].num_nodes >= 1
