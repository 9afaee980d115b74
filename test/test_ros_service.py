"""GenerationService (queue, worker, folders, stop) with a scripted in-process backend."""
import json
import os
import threading
import time

import pytest

from artformer_ros.params import NodeSettings
from artformer_ros.service import (OWNER_MARKER, PARTIAL_MARKER, RESULT_FILE, FAILED, READY,
                                   GenerationService, Job, owned_folders)
from model.pipeline.api import ExportResult, GeneratedObject, GenerationError

URDF = '<robot name="r"><link name="base"/></robot>'


class ScriptedBackend:
    """generate() waits on ``gate`` when set; ``fail`` maps a prompt to an exception."""
    name = "scripted"

    def __init__(self):
        self.gate = None
        self.started = threading.Event()
        self.fail = {}
        self.export_fail = {}
        self.calls = []

    def generate(self, *, text, image, seed, samples):
        self.calls.append((text, seed, samples))
        self.started.set()
        if self.gate is not None:
            assert self.gate.wait(10)
        if text in self.fail:
            raise self.fail[text]
        return [GeneratedObject(obj=None, prompt=text or "<image>", seed=seed + k,
                                timings={"stage": 0.001}) for k in range(samples)]

    def export(self, result, out_dir):
        if result.prompt in self.export_fail:
            os.makedirs(out_dir)
            open(os.path.join(out_dir, "half.obj"), "w").close()
            raise self.export_fail[result.prompt]
        os.makedirs(os.path.join(out_dir, "meshes"))
        with open(os.path.join(out_dir, "r.urdf"), "w") as f:
            f.write(URDF)
        mesh = os.path.join(out_dir, "meshes", "base.obj")
        open(mesh, "w").close()
        return ExportResult(out_dir=out_dir, urdf_path=os.path.join(out_dir, "r.urdf"),
                            mesh_paths={"base": mesh}, metadata_path="")


class Harness:
    def __init__(self, tmp_path, backend=None, load_gate=None, load_error=None, **settings):
        self.backend = backend or ScriptedBackend()
        self.settings = NodeSettings(backend="example", output_dir=str(tmp_path / "out"),
                                     **settings)
        self.answers = []
        self.lock = threading.Lock()

        def load():
            if load_gate is not None:
                assert load_gate.wait(10)
            if load_error is not None:
                raise load_error
            return self.backend

        def emit(result, urdf):
            with self.lock:
                self.answers.append((result, urdf))

        self.svc = GenerationService(self.settings, load, emit)

    def wait_answers(self, n, timeout=10.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self.lock:
                if len(self.answers) >= n:
                    return list(self.answers)
            time.sleep(0.005)
        raise AssertionError(f"only {len(self.answers)} of {n} answers: {self.answers}")

    def by_id(self):
        return {r["id"]: (r, u) for r, u in self.answers}


def test_done_result_writes_a_complete_folder(tmp_path):
    h = Harness(tmp_path, seed=7)
    h.svc.start()
    assert h.svc.wait_ready(5)
    assert h.svc.submit(Job("a", "text", text="a cabinet"))
    (res, urdf), = h.wait_answers(1)
    assert res["status"] == "done" and res["id"] == "a" and res["seed"] == 7
    assert urdf == URDF
    assert res["urdf_path"].startswith(res["output_dir"])
    assert set(res["timings"]) >= {"queue_wait", "generate", "export", "total", "stages"}
    folder = res["output_dir"]
    assert sorted(os.listdir(folder)) == sorted([OWNER_MARKER, RESULT_FILE, "sample_0"])
    assert h.svc.stop(1)


def test_requests_during_the_load_wait_and_are_served_once_ready(tmp_path):
    gate = threading.Event()
    h = Harness(tmp_path, load_gate=gate, queue_size=2)
    h.svc.start()
    assert h.svc.state == "loading"
    accepted = [h.svc.submit(Job(f"early{i}", "text", text="x")) for i in range(3)]
    assert accepted == [True, True, False]     # the bounded queue applies while loading too
    (res, urdf), = h.wait_answers(1)
    assert res["id"] == "early2" and res["status"] == "rejected" and "queue full" in res["message"]
    time.sleep(0.1)
    assert len(h.answers) == 1 and h.svc.queue_length() == 2   # no answer before the model
    gate.set()
    assert h.svc.wait_ready(5)
    h.wait_answers(3)
    ids = h.by_id()
    for rid in ("early0", "early1"):
        res, urdf = ids[rid]
        assert res["status"] == "done" and urdf == URDF and os.path.isfile(res["urdf_path"])
        assert res["timings"]["queue_wait"] >= 0.1          # waited for the model
    h.svc.stop(1)


def test_failed_load_answers_every_request_with_the_reason(tmp_path):
    gate = threading.Event()
    h = Harness(tmp_path, load_gate=gate,
                load_error=FileNotFoundError("no checkpoint at /nowhere"))
    h.svc.start()
    assert h.svc.submit(Job("queued", "text", text="x"))     # waits for the load ...
    gate.set()
    assert not h.svc.wait_ready(5)
    assert h.svc.state == FAILED
    h.svc.submit(Job("r", "text", text="x"))                 # ... and after the failure
    answers = h.wait_answers(2)
    assert sorted(r["id"] for r, _ in answers) == ["queued", "r"]
    for res, urdf in answers:
        assert res["status"] == "error" and urdf is None
        assert res["message"] == ("model failed to load: FileNotFoundError: no checkpoint at "
                                  "/nowhere")
    assert h.svc.stop(1)


def test_full_queue_rejects_at_once_and_every_request_is_answered(tmp_path):
    h = Harness(tmp_path, queue_size=2, retention=50)
    h.backend.gate = threading.Event()
    h.svc.start()
    assert h.svc.wait_ready(5)
    h.svc.submit(Job("run", "text", text="x"))
    assert h.backend.started.wait(5)   # the worker holds "run"; the queue is empty
    accepted = [h.svc.submit(Job(f"q{i}", "text", text="x")) for i in range(5)]
    assert accepted == [True, True, False, False, False]
    rejected = h.wait_answers(3)
    assert all(r["status"] == "rejected" and "queue full" in r["message"] for r, _ in rejected)
    h.settings.queue_size = 3            # a live parameter change takes effect at once
    assert h.svc.submit(Job("q5", "text", text="x"))
    h.backend.gate.set()
    h.wait_answers(7)
    ids = h.by_id()
    assert len(h.answers) == 7 and len(ids) == 7
    assert [ids[k][0]["status"] for k in ("run", "q0", "q1", "q5")] == ["done"] * 4
    h.svc.stop(1)


def test_retention_keeps_the_newest_folders_only(tmp_path):
    h = Harness(tmp_path, retention=2)
    foreign = tmp_path / "out" / "not_ours"
    foreign.mkdir(parents=True)
    h.svc.start()
    h.svc.wait_ready(5)
    for i in range(5):
        h.svc.submit(Job(f"r{i}", "text", text="x"))
        h.wait_answers(i + 1)
    complete, partial = owned_folders(h.settings.output_path)
    assert partial == [] and len(complete) == 2
    assert [os.path.basename(p).rsplit("_", 1)[1] for p in complete] == ["r3", "r4"]
    assert foreign.exists()   # folders the node did not write are never touched
    h.svc.stop(1)


def test_generation_errors_become_error_results_and_serving_continues(tmp_path):
    h = Harness(tmp_path)
    h.backend.fail = {"nothing": GenerationError("no part produced a valid mesh"),
                      "crash": ZeroDivisionError("boom")}
    h.backend.export_fail = {"badexport": GenerationError("mesh extraction failed")}
    h.svc.start()
    h.svc.wait_ready(5)
    for rid in ("nothing", "crash", "badexport", "fine"):
        h.svc.submit(Job(rid, "text", text=rid))
    h.wait_answers(4)
    ids = h.by_id()
    assert ids["nothing"][0]["message"] == "generation failed: no part produced a valid mesh"
    assert ids["crash"][0]["message"] == "internal error: ZeroDivisionError: boom"
    assert "mesh extraction failed" in ids["badexport"][0]["message"]
    assert [ids[k][0]["status"] for k in ("nothing", "crash", "badexport")] == ["error"] * 3
    assert ids["fine"][0]["status"] == "done"
    complete, partial = owned_folders(h.settings.output_path)
    assert len(complete) == 1 and partial == []   # the failed export left nothing behind
    h.svc.stop(1)


def test_stop_during_the_model_load(tmp_path):
    gate = threading.Event()
    h = Harness(tmp_path, load_gate=gate)
    h.svc.start()
    assert h.svc.stop(timeout=0.2) is False    # the loader is still inside load_backend
    gate.set()
    h.svc._threads[0].join(5)
    assert h.svc.state == "stopping"           # a late load does not flip the state back
    assert not h.svc.submit(Job("x", "text", text="x"))
    assert h.wait_answers(1)[0][0]["status"] == "rejected"


def test_stale_partial_folders_are_removed_at_start(tmp_path):
    out = tmp_path / "out"
    stale = out / "20250101T000000.000Z_00001_x"
    stale.mkdir(parents=True)
    (stale / OWNER_MARKER).write_text("{}")
    (stale / PARTIAL_MARKER).write_text("")
    h = Harness(tmp_path)
    h.svc.start()
    assert not stale.exists()
    h.svc.stop(1)


def test_stop_rejects_queued_and_abandons_the_running_generation(tmp_path):
    h = Harness(tmp_path)
    h.backend.gate = threading.Event()
    h.svc.start()
    h.svc.wait_ready(5)
    h.svc.submit(Job("running", "text", text="x"))
    assert h.backend.started.wait(5)
    h.svc.submit(Job("queued", "text", text="x"))
    assert h.svc.stop(timeout=0.2) is False          # still inside generate()
    res = h.by_id()["queued"][0]
    assert res["status"] == "rejected" and "shutting down" in res["message"]
    assert not h.svc.submit(Job("after", "text", text="x"))
    assert h.by_id()["after"][0]["status"] == "rejected"
    h.backend.gate.set()                              # generate returns after the stop
    h.wait_answers(3)
    assert "abandoned" in h.by_id()["running"][0]["message"]
    assert owned_folders(h.settings.output_path) == ([], [])


@pytest.mark.parametrize("job_seed,node_seed,expect", [(5, 9, 5), (None, 9, 9), (None, -1, None)])
def test_seed_policy(tmp_path, job_seed, node_seed, expect):
    h = Harness(tmp_path, seed=node_seed)
    h.svc.start()
    h.svc.wait_ready(5)
    h.svc.submit(Job("s", "text", text="x", seed=job_seed))
    (res, _), = h.wait_answers(1)
    if expect is None:
        assert 0 <= res["seed"] <= 2**31 - 1
    else:
        assert res["seed"] == expect
    h.svc.stop(1)


def test_samples_are_exported_side_by_side(tmp_path):
    h = Harness(tmp_path, samples=3, seed=10)
    h.svc.start()
    h.svc.wait_ready(5)
    h.svc.submit(Job("m", "text", text="x"))
    (res, _), = h.wait_answers(1)
    assert [s["seed"] for s in res["samples"]] == [10, 11, 12]
    assert sorted(os.listdir(res["output_dir"])) == sorted(
        [OWNER_MARKER, RESULT_FILE, "sample_0", "sample_1", "sample_2"])
    assert h.svc.state == READY
    h.svc.stop(1)


class PreviewBackend(ScriptedBackend):
    """Records when previews are drawn relative to generations."""

    def __init__(self):
        super().__init__()
        self.events = []

    def generate(self, **kw):
        self.events.append(("generate", kw["text"]))
        return super().generate(**kw)

    def preview(self, result, exported, interrupt=None):
        self.events.append(("preview", result.prompt))
        path = os.path.join(exported.out_dir, "preview.png")
        with open(path, "wb") as f:
            f.write(b"png")
        return path


def test_previews_follow_the_answer_and_wait_for_queued_requests(tmp_path):
    h = Harness(tmp_path, backend=PreviewBackend(), preview=True, queue_size=8, retention=50)
    h.backend.gate = threading.Event()
    h.svc.start()
    assert h.svc.wait_ready(5)
    for k in range(3):
        assert h.svc.submit(Job(f"r{k}", "text", text=f"p{k}"))
    assert h.backend.started.wait(5)
    h.backend.gate.set()
    answers = h.wait_answers(3)
    for res, _ in answers:   # the picture does not exist yet: the answer does not name it
        assert res["preview_path"] is None and res["samples"][0]["preview_path"] is None
    end = time.monotonic() + 5
    while len(h.backend.events) < 5 and time.monotonic() < end:
        time.sleep(0.01)
    time.sleep(0.05)
    # the three queued requests ran back to back; the pictures came when the queue was
    # empty, for the newest MAX_PENDING_PREVIEWS (2) requests only: memory stays bounded
    assert h.backend.events == [("generate", "p0"), ("generate", "p1"), ("generate", "p2"),
                                ("preview", "p1"), ("preview", "p2")]
    # result.json names a picture once it is written (and only then)
    saved = [json.load(open(os.path.join(r["output_dir"], RESULT_FILE))) for r, _ in answers]
    assert saved[0]["preview_path"] is None
    for doc in saved[1:]:
        assert os.path.isfile(doc["preview_path"])
        assert doc["samples"][0]["preview_path"] == doc["preview_path"]
        assert doc["preview_path"].endswith(os.path.join("sample_0", "preview.png"))
    assert h.svc.stop(1)


def test_retention_never_deletes_the_folder_of_the_answer_going_out(tmp_path):
    h = Harness(tmp_path, retention=1)
    newer = tmp_path / "out" / "99991231T235959.999Z_99999_from-the-future"
    newer.mkdir(parents=True)                  # sorts after anything written today
    (newer / OWNER_MARKER).write_text("{}")
    h.svc.start()
    assert h.svc.wait_ready(5)
    h.svc.submit(Job("now", "text", text="x"))
    (res, _), = h.wait_answers(1)
    assert os.path.isfile(res["urdf_path"]) and not newer.exists()
    assert h.svc.stop(1)


def test_preview_failure_is_logged_and_serving_continues(tmp_path):
    backend = PreviewBackend()
    backend.preview = lambda result, exported, interrupt=None: (_ for _ in ()).throw(
        RuntimeError("no pixels"))
    h = Harness(tmp_path, backend=backend, preview=True)
    h.svc.start()
    assert h.svc.wait_ready(5)
    assert h.svc.submit(Job("a", "text", text="x"))
    h.wait_answers(1)
    time.sleep(0.1)
    assert h.svc.submit(Job("b", "text", text="y"))
    answers = h.wait_answers(2)
    assert [r["status"] for r, _ in answers] == ["done", "done"]
    assert h.svc.stop(1)


def test_a_preview_yields_to_a_request_that_arrives_while_it_is_drawn(tmp_path):
    class Slow(PreviewBackend):
        def preview(self, result, exported, interrupt=None):
            for view in range(3):           # like render_views: ask before each view
                if interrupt():
                    self.events.append(("preview-interrupted", result.prompt))
                    return None
                if result.prompt == "first" and view == 0 and not sent:
                    sent.append(1)
                    assert h.svc.submit(Job("second", "text", text="second"))
                time.sleep(0.01)
            return super().preview(result, exported)

    sent = []
    h = Harness(tmp_path, backend=Slow(), preview=True, retention=50)
    h.svc.start()
    assert h.svc.wait_ready(5)
    assert h.svc.submit(Job("first", "text", text="first"))
    h.wait_answers(2)
    end = time.monotonic() + 5
    while len(h.backend.events) < 5 and time.monotonic() < end:
        time.sleep(0.01)
    assert h.backend.events == [("generate", "first"), ("preview-interrupted", "first"),
                                ("generate", "second"), ("preview", "first"),
                                ("preview", "second")]
    assert h.svc.stop(1)


# -- structure requests (docs/ros.md) --------------------------------------------------------------
class StructureBackend(ScriptedBackend):
    """A backend that takes structures: records them, refuses {"drawer": 99} as a model would."""

    def generate(self, *, text, image, seed, samples, structure=None):
        self.calls.append((text, seed, samples, structure))
        if structure is not None and structure.get("drawer", {}).get("count") == 99:
            raise GenerationError("structure: 99 drawer parts: at most 20 per StorageFurniture")
        return [GeneratedObject(obj=None, prompt=text, seed=seed, timings={})]


def _refused(key, cases):
    """Each (bad value of ``key``, words) is an error of the request that sent it."""
    from artformer_ros.conversions import RequestError, parse_text_request
    for bad, words in cases:
        with pytest.raises(RequestError, match=words) as err:
            parse_text_request(json.dumps({"id": "r2", "text": "x", key: bad}),
                               max_length=100, assigned_id="t")
        assert err.value.request_id == "r2"


def test_json_structure_requests_reach_the_backend_and_bad_ones_get_error_results(tmp_path):
    from artformer_ros.conversions import parse_text_request
    req = parse_text_request(json.dumps({"id": "s1", "text": "a cabinet",
                                         "structure": {"drawer": 3, "door": {"hinge": "left"}}}),
                             max_length=100, assigned_id="text-1")
    assert req.structure == {"drawer": {"count": 3},
                             "door": {"count": 1, "joint": "revolute", "hinge": ["left"]}}
    assert parse_text_request("plain text", max_length=100, assigned_id="t").structure is None
    _refused("structure", ((["drawer"], "JSON object"), ('{"drawer": 3', "not valid JSON"),
                           ({"drawer": -2}, ">= 0"), ({"door": {"hinge": "north"}}, "hinge side")))

    h = Harness(tmp_path, backend=StructureBackend())
    h.svc.start()
    assert h.svc.wait_ready(5)
    h.svc.submit(Job("ok", "text", text="a cabinet", structure=req.structure))
    h.svc.submit(Job("big", "text", text="a cabinet", structure={"drawer": {"count": 99}}))
    h.svc.submit(Job("plain", "text", text="a cabinet"))
    h.wait_answers(3)
    ids = h.by_id()
    assert ids["ok"][0]["status"] == "done" and ids["ok"][0]["structure"] == req.structure
    assert ids["big"][0]["status"] == "error" and "at most 20" in ids["big"][0]["message"]
    assert ids["plain"][0]["status"] == "done" and "structure" not in ids["plain"][0]
    assert [c[3] for c in h.backend.calls] == [req.structure, {"drawer": {"count": 99}}, None]
    h.svc.stop(1)


class SizeBackend(StructureBackend):
    def generate(self, *, text, image, seed, samples, structure=None, size=None):
        self.calls.append((text, size))
        return [GeneratedObject(obj=None, prompt=text, seed=seed, timings={})]


def test_json_size_requests_reach_the_backend_and_bad_ones_get_error_results(tmp_path):
    from artformer_ros.backends import ExampleBackend
    from artformer_ros.conversions import parse_text_request
    req = parse_text_request(json.dumps({"id": "z1", "text": "a cabinet",
                                         "size": {"width": 0.6, "height": 1}}),
                             max_length=100, assigned_id="text-1")
    assert req.size == {"width": 0.6, "height": 1.0}
    _refused("size", (([0.6], "an object"), ({"wide": 0.6}, "unknown dimension"),
                      ({"width": 60}, "metres"), ({"width": True}, "metres")))
    h = Harness(tmp_path, backend=SizeBackend())
    h.svc.start()
    assert h.svc.wait_ready(5)
    h.svc.submit(Job("sized", "text", text="a cabinet", size=req.size))
    h.svc.submit(Job("plain", "text", text="a cabinet"))
    h.wait_answers(2)
    ids = h.by_id()
    assert ids["sized"][0]["status"] == "done" and ids["sized"][0]["size"] == req.size
    assert ids["plain"][0]["status"] == "done" and "size" not in ids["plain"][0]
    assert h.backend.calls == [("a cabinet", req.size), ("a cabinet", None)]
    h.svc.stop(1)
    backend = ExampleBackend(NodeSettings(backend="example", output_dir=str(tmp_path)))
    with pytest.raises(GenerationError, match="example backend.*size"):
        backend.generate(text="a cabinet", image=None, seed=0, samples=1, size=req.size)


def test_the_example_backend_honours_its_own_structures_and_refuses_others(tmp_path):
    from artformer_ros.backends import ExampleBackend
    from model.core.example import structure_mismatch
    backend = ExampleBackend(NodeSettings(backend="example", output_dir=str(tmp_path)))
    [cab] = backend.generate(text="a bottle", image=None, seed=0, samples=1,
                             structure={"drawer": 2, "door": {"count": 1, "hinge": "right"}})
    assert structure_mismatch(cab.obj, {"drawer": 2, "door": 1}) is None
    assert cab.obj.category == "StorageFurniture"      # the structure wins over the prompt
    [bottle] = backend.generate(text="a thing", image=None, seed=0, samples=1,
                                structure={"cap": {"count": 1, "joint": "screw"}})
    assert bottle.obj.category == "Bottle"
    for bad, words in (({"drawer": 3}, "2 drawer part"), ({"drawer": 2}, "1 door part"),
                       ({"drawer": 2, "door": {"count": 1, "hinge": "left"}}, "hinges are"),
                       ({"cap": {"count": 1, "joint": "revolute"}}, "revolute joints")):
        with pytest.raises(GenerationError, match="example backend.*" + words):
            backend.generate(text="a cabinet", image=None, seed=0, samples=1, structure=bad)
