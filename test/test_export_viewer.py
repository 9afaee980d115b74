"""Web viewer and studio in a real browser: headless Chromium (Debian's `chromium`) driven by
Playwright. The view page renders the object (not a blank canvas) and its openness slider
moves it; the studio shows errors for an empty prompt and a non-image upload, generates
from a typed prompt, and offers the object folder as a zip download. The browser may reach
127.0.0.1 only (every other request is aborted and recorded)."""
import io
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser")
playwright = pytest.importorskip("playwright.sync_api")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
if CHROMIUM is None:
    pytest.skip("chromium is not installed (Debian package `chromium`)", allow_module_level=True)

from PIL import Image  # noqa: E402

from model.core.example import example_objects  # noqa: E402
from model.export.urdf import export_object  # noqa: E402

ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox",
        "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(args, tmp_path):
    port = _free_port()
    log = open(tmp_path / f"server_{port}.log", "w")
    proc = subprocess.Popen([sys.executable, "-m", "model", *args, "--port", str(port)],
                            stdout=log, stderr=subprocess.STDOUT)
    t0 = time.time()
    while time.time() - t0 < 60:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=1):
                return proc, f"http://127.0.0.1:{port}"
        except OSError:
            assert proc.poll() is None, (tmp_path / f"server_{port}.log").read_text()
            time.sleep(0.3)
    proc.kill()
    raise AssertionError("the server did not start")


def _stop(proc):
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()             # a server that ignores SIGINT still ends here
        proc.wait(timeout=10)


@pytest.fixture(scope="module")
def browser():
    with playwright.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
        yield b
        b.close()


def _page(browser, url):
    page = browser.new_page(viewport={"width": 1200, "height": 800}, accept_downloads=True)
    outside = []

    def route(r):
        u = r.request.url
        if u.startswith(("http://127.0.0.1", "ws://127.0.0.1", "data:", "blob:")):
            r.continue_()
        else:
            outside.append(u)
            r.abort()

    page.route("**/*", route)
    page.goto(url)
    page.wait_for_selector("canvas", timeout=60000)
    return page, outside


def _object_pixels(png: bytes) -> np.ndarray:
    """Mask of warm (wood / beige) pixels in the 3D view: the object. The background is white,
    the grid grey; the panels (right) and notifications (left) are cut off."""
    a = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    view = a[180:, 320:880]
    return (view[..., 0] - view[..., 2]) > 12


def _wait_for_object(page, min_pixels=3000, timeout=60):
    t0 = time.time()
    while time.time() - t0 < timeout:
        mask = _object_pixels(page.screenshot())
        if mask.sum() >= min_pixels:
            time.sleep(1.0)                  # let the last meshes arrive
            return _object_pixels(page.screenshot())
        time.sleep(1.0)
    raise AssertionError(f"no object rendered (object pixels {mask.sum()})")


@pytest.mark.slow     # headless Chromium renders and drags the slider (~25-35 s on 2 busy cores)
def test_view_renders_the_object_and_the_openness_slider_moves_it(browser, tmp_path):
    export_object(example_objects()["cabinet"], tmp_path / "cabinet", preview=False)
    proc, url = _start(["view", str(tmp_path / "cabinet")], tmp_path)
    try:
        page, outside = _page(browser, url)
        closed = _wait_for_object(page)
        assert page.get_by_text("drawer_0_joint").count() == 1
        assert page.get_by_text("door_joint").count() == 1
        openness = page.locator("input[inputmode=decimal]").first   # openness: the first slider
        openness.fill("1")
        openness.press("Enter")
        time.sleep(3.0)
        opened = _object_pixels(page.screenshot())
        # the door swings out and the drawers slide out: the object's silhouette changes
        changed = np.logical_xor(closed, opened).sum()
        assert changed > 0.1 * closed.sum(), (changed, closed.sum())
        assert outside == []
        page.close()
    finally:
        _stop(proc)
    assert proc.returncode is not None


def test_view_of_a_missing_folder_is_an_error(tmp_path):
    out = subprocess.run([sys.executable, "-m", "model", "view", str(tmp_path / "nope")],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 1 and "does not exist" in out.stderr


def _dark_pixels(page) -> int:
    """Dark pixels in the middle of the page's 3D view (the rendered object)."""
    shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("L"))
    return int((shot[180:, 320:880] < 200).sum())


@pytest.mark.slow
def test_studio_errors_then_generates_and_downloads(browser, tiny_trained_model, tmp_path):
    proc, url = _start(["studio", "--checkpoint", str(tiny_trained_model), "--out", str(tmp_path / "out")],
                       tmp_path)
    try:
        page, outside = _page(browser, url)
        generate = page.get_by_role("button", name="Generate", exact=True)
        download = page.get_by_role("button", name="Download zip")
        assert download.is_disabled()
        empty = _dark_pixels(page)                           # the scene before any object
        generate.click()                                     # empty prompt
        page.get_by_text("Error: prompt is empty").first.wait_for(timeout=60000)
        page.locator("input[type=file]").set_input_files(
            files=[{"name": "notes.txt", "mimeType": "image/png", "buffer": b"not a picture"}])
        page.get_by_text("is not an image").first.wait_for(timeout=60000)
        assert proc.poll() is None                           # still serving
        page.get_by_role("textbox").fill("a cabinet with one door")
        generate.click()
        page.get_by_role("button", name="Download zip").and_(
            page.locator(":enabled")).wait_for(timeout=120000)
        page.get_by_text("parts:").first.wait_for(timeout=10000)
        # the scene streams to the page after the answer: poll the canvas until the object
        # shows (a tiny random model's object can be small: more drawn than the empty scene)
        drawn = 0
        for _ in range(40):
            drawn = _dark_pixels(page) - empty
            if drawn > 200:
                break
            page.wait_for_timeout(500)
        assert drawn > 200, (drawn, empty)
        with page.expect_download(timeout=60000) as dl:
            download.click()
        data = Path(dl.value.path()).read_bytes()
        names = zipfile.ZipFile(io.BytesIO(data)).namelist()
        assert dl.value.suggested_filename.endswith(".zip")
        assert any(n.endswith(".urdf") for n in names) and any("/meshes/" in n for n in names)
        folder = next((tmp_path / "out").iterdir())
        assert any(n.endswith("metadata.json") for n in names) and folder.is_dir()
        assert outside == []
        page.close()
    finally:
        _stop(proc)
    assert os.path.isdir(tmp_path / "out")
