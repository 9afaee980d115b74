"""Batch generation: one folder per job, manifest.jsonl, a failing prompt recorded while the
batch goes on, resume after an interruption without redoing finished jobs."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from model.pipeline.batch import (BatchError, plan_jobs, read_manifest, read_prompts,
                                  run_batch)

LONG = "a cabinet " * 300            # over the 2000-character prompt limit: a failing job


@pytest.fixture(scope="module")
def tiny(tiny_trained_model):
    return tiny_trained_model


def _config(tiny):
    from model.pipeline.api import GenerationConfig
    return GenerationConfig(checkpoint=str(tiny), resolution=24, steps=4, threads=1)


def _lines(path):
    return [json.loads(x) for x in Path(path).read_text().splitlines() if x.strip()]


def test_read_prompts_and_plan(tmp_path):
    f = tmp_path / "p.txt"
    f.write_text("a cabinet\n\n  # a comment\n  a   bottle with a cap \n")
    assert read_prompts(f) == ["a cabinet", "a bottle with a cap"]
    jobs = plan_jobs(["a cabinet", "a bottle with a cap"], 2, 5)
    assert [j.id for j in jobs] == ["0000_0", "0000_1", "0001_0", "0001_1"]
    assert [j.seed for j in jobs] == [5, 6, 5, 6]
    assert jobs[3].folder == "0001_a_bottle_with_a_cap_s6"
    (tmp_path / "e.txt").write_text("# nothing\n\n")
    with pytest.raises(BatchError, match="no prompts"):
        read_prompts(tmp_path / "e.txt")
    with pytest.raises(BatchError, match="does not exist"):
        read_prompts(tmp_path / "missing.txt")
    (tmp_path / "b.bin").write_bytes(b"\xff\xfe\x00bad")
    with pytest.raises(BatchError, match="UTF-8"):
        read_prompts(tmp_path / "b.bin")


def test_torn_manifest_line_is_ignored(tmp_path):
    m = tmp_path / "manifest.jsonl"
    m.write_text(json.dumps({"id": "0000_0", "status": "ok"}) + "\n" + '{"id": "0000_1", "sta')
    assert list(read_manifest(m)) == ["0000_0"]


def test_batch_records_failures_and_resumes(tiny, tmp_path):
    out = tmp_path / "b"
    prompts = ["a cabinet with one door", LONG, "a bottle"]
    seen = []
    s = run_batch(prompts, out, samples=2, workers=1, config=_config(tiny), preview=False,
                  progress=lambda e, summ: seen.append(e["id"]))
    assert (s.total, s.skipped, s.done, s.failed) == (6, 0, 4, 2)
    assert s.per_minute > 0 and sorted(seen) == sorted(j.id for j in plan_jobs(prompts, 2, 0))
    entries = _lines(out / "manifest.jsonl")
    assert [e["id"] for e in entries] == ["0000_0", "0000_1", "0001_0", "0001_1", "0002_0", "0002_1"]
    for e in entries:
        assert set(e) >= {"prompt", "seed", "status", "urdf", "out_dir", "timings_s", "seconds",
                          "audit", "error"}
        assert e["audit"] is None
        if e["index"] == 1:
            assert e["status"] == "error" and "characters" in e["error"] and e["urdf"] is None
        else:
            assert e["status"] == "ok" and e["error"] is None
            assert (out / e["urdf"]).is_file() and (out / e["meshes"]).is_dir()
            assert e["seed"] == e["sample"] and e["timings_s"]["export"] >= 0
    # an interruption: the last two jobs never finished, one of them mid-line, and one
    # object folder is half-written
    kept = (out / "manifest.jsonl").read_text().splitlines()[:4]
    (out / "manifest.jsonl").write_text("\n".join(kept) + '\n{"id": "0002_0", "st')
    (out / ".0002_x.tmp-abc").mkdir()
    s2 = run_batch(prompts, out, samples=2, workers=1, config=_config(tiny), preview=False)
    assert (s2.skipped, s2.done, s2.failed) == (4, 2, 0)
    after = _lines(out / "manifest.jsonl")
    assert [e["id"] for e in after] == [e["id"] for e in entries]
    assert after[:4] == entries[:4]                          # finished jobs were not redone
    assert not (out / ".0002_x.tmp-abc").exists()
    # failures are redone only when asked
    s3 = run_batch(prompts, out, samples=2, workers=1, config=_config(tiny), preview=False)
    assert (s3.skipped, s3.done, s3.failed) == (6, 0, 0)
    s4 = run_batch(prompts, out, samples=2, workers=1, config=_config(tiny), preview=False,
                   retry_failed=True)
    assert (s4.skipped, s4.done, s4.failed) == (4, 0, 2)
    assert len(_lines(out / "manifest.jsonl")) == 6
    # other prompts for the same folder: refused, nothing written
    with pytest.raises(BatchError, match="same prompts file"):
        run_batch(["a lamp", LONG, "a bottle"], out, config=_config(tiny))


def test_audit_verdict_in_the_manifest(tiny, tmp_path):
    pytest.importorskip("model.export.simready")
    s = run_batch(["a cabinet with one door"], tmp_path / "a", config=_config(tiny), preview=False,
                  audit=True)
    [e] = _lines(tmp_path / "a" / "manifest.jsonl")
    assert s.done == 1 and e["status"] == "ok"
    assert isinstance(e["audit"]["sim_ready"], bool) and isinstance(e["audit"]["failures"], list)
    assert e["audit"]["sim_ready"] == (not e["audit"]["failures"] and "error" not in e["audit"])
    assert e["timings_s"]["audit"] > 0


@pytest.mark.slow
def test_cli_interrupted_with_two_workers_then_resumed(tiny, tmp_path):
    prompts = tmp_path / "p.txt"
    prompts.write_text("a cabinet with one door\na bottle\na table with a drawer\n")
    out = tmp_path / "cli"
    cmd = [sys.executable, "-m", "model", "generate", "--prompts", str(prompts), "--samples", "3",
           "--workers", "2", "--out", str(out), "--checkpoint", str(tiny), "--resolution", "24",
           "--steps", "4", "--no-preview"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    manifest = out / "manifest.jsonl"
    t0 = time.time()
    while time.time() - t0 < 240 and not (manifest.exists() and len(_lines(manifest)) >= 2):
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)          # a kill: the batch stops its workers too
    _, err = proc.communicate(timeout=60)
    first = len(_lines(manifest))
    assert proc.returncode == 130 and "resume" in err and 2 <= first < 9
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert f"{first} already done, {9 - first} generated, 0 failed" in done.stdout
    assert "objects/min" in done.stdout
    entries = _lines(manifest)
    assert len(entries) == 9 and len({e["id"] for e in entries}) == 9
    assert all(e["status"] == "ok" and (out / e["urdf"]).is_file() for e in entries)
    # no worker outlived the batch
    pids = {e["worker"] for e in entries}
    time.sleep(1.0)
    for pid in pids:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)
