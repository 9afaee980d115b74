"""The one training loop every trainer runs (text and image transformer, image trunk, count
head, SDF auto-encoder, shape prior).

A trainer supplies a model, an optimizer and three callbacks; the loop owns the rest:

* the learning rate (``lr_at``: linear warm-up, then cosine to ``floor`` of the peak by the
  step budget or by the wall-clock budget, whichever comes first; a param group's
  ``lr_mult`` scales it);
* the step budget and the wall-clock budget (``minutes``, counted over resumed runs), and
  ``chunk_minutes``: this process stops (writing its checkpoint) after that long without
  touching the schedule, so a long run goes in resumable chunks;
* gradient clipping, progress bars (tqdm; off with ``progress=False``), log lines;
* validation every ``val_every`` steps and at the end (rank 0), a JSON line per validation
  in ``OUT/log.jsonl`` and the history kept in the state for the checkpoint;
* checkpoints every ``ckpt_every`` steps and at the end (rank 0; the trainer's ``save_fn``
  writes them atomically with ``LoopState.entries()`` so ``--resume`` continues);
* DDP: under ``torchrun --nproc_per_node N`` (RANK / WORLD_SIZE set) the model is wrapped in
  DistributedDataParallel over gloo (CPU); gradients are averaged over the processes, each
  process trains on its own share of the data (``Dist.shard`` or its own random stream) and
  only rank 0 validates, logs and writes files.
"""
from __future__ import annotations

import json
import logging
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

import torch

log = logging.getLogger(__name__)


def lr_at(step: int, peak: float, warmup: int, steps: int, floor: float = 0.1,
          time_share: float = 0.0) -> float:
    """Linear warm-up over ``warmup`` steps, then cosine from ``peak`` to ``floor * peak`` by
    ``steps`` or by ``time_share`` (elapsed / wall-clock budget) reaching 1, whichever first."""
    if step < warmup:
        return peak * (step + 1) / warmup
    prog = min(1.0, (step - warmup) / max(1, steps - warmup))
    prog = max(prog, min(1.0, time_share))
    return peak * (floor + (1.0 - floor) * 0.5 * (1 + math.cos(math.pi * prog)))


def resolve_device(name: str) -> torch.device:
    """``cpu``, ``cuda`` or ``auto`` (CUDA when torch sees a GPU, else the CPU) as a device;
    ``cuda`` on a machine without one is a clear error, not a silent CPU run."""
    if name not in ("cpu", "cuda", "auto"):
        raise ValueError(f"--device must be cpu, cuda or auto, got {name!r}")
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("--device cuda: torch sees no CUDA device here (this torch build or "
                         "machine has none); use --device cpu or auto")
    return torch.device(name)


class Dist:
    """The torchrun environment (or a single process)."""

    def __init__(self):
        self.world = int(os.environ.get("WORLD_SIZE", "1"))
        self.rank = int(os.environ.get("RANK", "0"))
        self.active = self.world > 1
        if self.active:
            import torch.distributed as dist
            if not dist.is_initialized():
                dist.init_process_group("gloo")

    @property
    def main(self) -> bool:
        return self.rank == 0

    def wrap(self, model: torch.nn.Module, unused: bool = False) -> torch.nn.Module:
        """DistributedDataParallel around ``model`` when distributed; ``unused``: some
        parameters get no gradient in a step (e.g. another condition modality's projection)."""
        if not self.active:
            return model
        from torch.nn.parallel import DistributedDataParallel
        return DistributedDataParallel(model, find_unused_parameters=unused)

    def shard(self, items: list) -> list:
        """This process's share of a list every process built the same way (one item of it
        when there are fewer items than processes)."""
        if not self.active or not items:
            return items
        return items[self.rank::self.world] or [items[self.rank % len(items)]]

    def any(self, flag: bool) -> bool:
        """True on every process when it is true on one (e.g. the time budget is spent)."""
        if not self.active:
            return flag
        import torch.distributed as dist
        t = torch.tensor([1.0 if flag else 0.0])
        dist.all_reduce(t, op=dist.ReduceOp.MAX)
        return bool(t.item() > 0)

    def barrier(self) -> None:
        if self.active:
            import torch.distributed as dist
            dist.barrier()

    def close(self) -> None:
        if self.active:
            import torch.distributed as dist
            if dist.is_initialized():
                dist.destroy_process_group()


@dataclass
class LoopConfig:
    steps: int                      # step budget (optimizer steps, counted over resumes)
    lr: float                       # peak learning rate
    warmup: int = 0
    floor: float = 0.1              # final learning rate as a share of the peak
    minutes: float = 0.0            # wall-clock budget over resumes (0 = none)
    chunk_minutes: float = 0.0      # stop this process after this long (0 = never); the
                                    # schedule is untouched: --resume continues the run
    val_every: int = 0              # validate every N steps (0 = only at the end)
    ckpt_every: int = 0             # run checkpoint every N steps (0 = only at the end)
    grad_clip: float = 0.0          # per param group (0 = none)
    progress: bool = True
    desc: str = "train"
    log_every: int = 25             # log line every N steps when there is no progress bar
    log_dir: Optional[str] = None   # OUT folder for log.jsonl (rank 0)


@dataclass
class LoopState:
    """What a run checkpoint must hold to continue: steps done, seconds trained, the history
    of validations."""
    step: int = 0
    elapsed: float = 0.0
    history: list = field(default_factory=list)
    running: dict = field(default_factory=dict)       # smoothed training losses

    def entries(self) -> dict:
        return {"step": self.step, "elapsed": self.elapsed, "history": list(self.history)}

    @classmethod
    def of(cls, ckpt: dict) -> "LoopState":
        return cls(step=int(ckpt.get("step", 0)), elapsed=float(ckpt.get("elapsed", 0.0)),
                   history=list(ckpt.get("history", [])))


def seed_all(seed: int) -> "np.random.Generator":
    """Seed torch's global generator; -> a numpy generator with the same seed."""
    import numpy as np
    torch.manual_seed(seed)
    return np.random.default_rng(seed)


StepFn = Callable[[torch.nn.Module, int], tuple]      # (net, step) -> (loss, {name: float})


class _Run:
    """One call of ``train_loop``: its clock, progress bar and records."""

    def __init__(self, cfg: LoopConfig, state: LoopState, dist: Dist):
        self.cfg, self.state, self.dist = cfg, state, dist
        self.t0, self.base = time.time(), state.elapsed
        self.bar = None
        if dist.main and cfg.progress:
            from tqdm import tqdm
            self.bar = tqdm(total=cfg.steps, initial=state.step, desc=cfg.desc, unit="step",
                            dynamic_ncols=True)

    def elapsed(self) -> float:
        return self.base + time.time() - self.t0

    def over_budget(self) -> bool:
        c = self.cfg
        spent = c.minutes > 0 and self.elapsed() > c.minutes * 60
        chunk = c.chunk_minutes > 0 and time.time() - self.t0 > c.chunk_minutes * 60
        return bool(self.dist.any(spent or chunk))

    def lr(self) -> float:
        c = self.cfg
        share = self.elapsed() / (c.minutes * 60) if c.minutes > 0 else 0.0
        return lr_at(self.state.step, c.lr, c.warmup, c.steps, c.floor, share)

    def tick(self, loss: float, stats: dict) -> None:
        run = self.state.running
        for k, v in {"loss": loss, **stats}.items():
            run[k] = 0.98 * run.get(k, v) + 0.02 * float(v)
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix({k: f"{v:.4f}" for k, v in list(run.items())[:4]})
        elif self.dist.main and self.state.step % max(1, self.cfg.log_every) == 0:
            log.info("%s step %d loss %.4f", self.cfg.desc, self.state.step, run["loss"])

    def validate(self, model: torch.nn.Module, val_fn, lr: float) -> None:
        st = self.state
        rec = {"step": st.step, "train": dict(st.running), "lr": lr,
               "time_min": round(self.elapsed() / 60, 3)}
        if val_fn is not None:
            was = model.training
            model.eval()
            rec["val"] = val_fn()
            model.train(was)
        st.history.append(rec)
        val = rec.get("val")
        shown = val.get("total", val.get("loss")) if isinstance(val, dict) else val
        line = f"step {st.step}: train {st.running.get('loss', float('nan')):.4f}" + \
            (f"  val {shown:.4f}" if isinstance(shown, (int, float)) else "")
        if self.bar is not None:
            self.bar.write(line)
        log.info("%s %s", self.cfg.desc, line)
        if self.cfg.log_dir:
            Path(self.cfg.log_dir).mkdir(parents=True, exist_ok=True)
            with open(Path(self.cfg.log_dir) / "log.jsonl", "a") as f:
                f.write(json.dumps(rec, default=float) + "\n")


def train_loop(model: torch.nn.Module, opt: torch.optim.Optimizer, cfg: LoopConfig,
               step_fn: StepFn, *, val_fn: Optional[Callable[[], object]] = None,
               save_fn: Optional[Callable[[LoopState, bool], None]] = None,
               state: Optional[LoopState] = None, dist: Optional[Dist] = None,
               unused_params: bool = False) -> LoopState:
    """Optimise ``model`` until ``cfg.steps`` (or ``cfg.minutes``) are spent.

    ``step_fn(net, step) -> (loss, stats)``: the loss of one batch (``net`` is the DDP wrapper
    under torchrun, else ``model``); ``val_fn() -> float | dict`` on rank 0, model in eval
    mode; ``save_fn(state, final)`` writes the run checkpoint on rank 0 (``final`` at the
    end); ``state``: where a resumed run stands. Returns the final state."""
    dist = dist or Dist()
    state = state or LoopState()
    net = dist.wrap(model, unused_params)
    run = _Run(cfg, state, dist)
    model.train()
    # a resumed run whose last validation was at its current step (say, a finished run run
    # once more to export it) is not validated again
    validated = state.history[-1].get("step", -1) if state.history else -1
    lr = cfg.lr
    while state.step < cfg.steps:
        if run.over_budget():
            log.info("%s: time budget reached at step %d (%.1f min trained)", cfg.desc,
                     state.step, run.elapsed() / 60)
            break
        lr = run.lr()
        for g in opt.param_groups:
            g["lr"] = lr * g.get("lr_mult", 1.0)
        loss, stats = step_fn(net, state.step)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        if cfg.grad_clip:
            for g in opt.param_groups:
                torch.nn.utils.clip_grad_norm_(g["params"], cfg.grad_clip)
        opt.step()
        state.step += 1
        run.tick(float(loss.detach()), stats)
        if cfg.val_every and state.step % cfg.val_every == 0 and state.step < cfg.steps:
            if dist.main:
                run.validate(model, val_fn, lr)
                validated = state.step
            dist.barrier()
        if cfg.ckpt_every and state.step % cfg.ckpt_every == 0 and state.step < cfg.steps:
            state.elapsed = run.elapsed()
            if dist.main and save_fn is not None:
                save_fn(state, False)
    if run.bar is not None:
        run.bar.close()
    state.elapsed = run.elapsed()
    if dist.main:
        if validated != state.step:
            run.validate(model, val_fn, lr)
        if save_fn is not None:
            save_fn(state, True)
    dist.barrier()
    return state


__all__ = ["lr_at", "resolve_device", "Dist", "LoopConfig", "LoopState", "seed_all",
           "train_loop"]
