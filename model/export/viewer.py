"""Web viewer (viser): an object folder in 3D with a slider per joint, and a studio page that
generates objects from a prompt or an image.

    artformer view out/cabinet [--port 8080] [--host 127.0.0.1]
    artformer studio [--port 8080] [--out out/studio] [--checkpoint DIR]

Both serve a page at http://HOST:PORT (three.js in the browser; the meshes are sent over a
websocket). No ROS is needed.

* **view** shows the URDF's visual meshes with a grid at the object's foot. It has one slider
  per moving joint (range = the URDF limits; continuous joints -pi..pi) and an openness
  slider that sets every joint to the same share of its range.
* **studio** adds a prompt box, a Generate button and an image upload. Requests run one at a
  time on the model (the shipped one by default), and a progress bar and status line show
  the stage. The result replaces the object shown, and "Download zip" sends its folder (URDF
  with relative mesh paths, meshes, metadata, preview). A bad request (an empty prompt, a
  file that is not an image, a model without an image stage) shows its error in the page
  and the server keeps serving.
"""
from __future__ import annotations

import io
import logging
import math
import os
import re
import tempfile
import threading
import time
import zipfile
from pathlib import Path
from typing import Callable, Optional

import numpy as np

log = logging.getLogger(__name__)


def load_urdf(folder: os.PathLike):
    """yourdfpy URDF of an object folder with its meshes (file://, package://, relative)."""
    import warnings

    import yourdfpy

    from .importer import resolve_mesh_path
    from .urdfmodel import find_urdf
    path = find_urdf(folder)
    with warnings.catch_warnings():      # yourdfpy 0.0.58 float()s 1-element arrays
        warnings.simplefilter("ignore", DeprecationWarning)
        return path, yourdfpy.URDF.load(
            str(path), build_scene_graph=True, load_meshes=True,
            filename_handler=lambda fname: str(resolve_mesh_path(fname, path.parent)))


class ObjectView:
    """One object in a viser server: meshes under ``/object``, a grid, joint sliders."""

    def __init__(self, server, folder: os.PathLike, gui_folder_label: str = "Joints",
                 loaded=None):
        from viser.extras import ViserUrdf

        self.server = server
        self.path, urdf = loaded or load_urdf(folder)
        self.urdf = ViserUrdf(server, urdf_or_path=urdf, root_node_name="/object")
        lo, hi = _bounds(urdf)
        size = float(np.linalg.norm(hi - lo)) or 1.0
        self.grid = server.scene.add_grid("/grid", width=max(2.0, 3 * size), height=max(2.0, 3 * size),
                                          cell_size=0.1, position=(0.0, 0.0, float(lo[2])))
        centre = (lo + hi) / 2.0
        server.initial_camera.look_at = tuple(float(x) for x in centre)
        server.initial_camera.position = tuple(float(x) for x in centre + np.array([1.6, -1.2, 0.9]) * size)
        for client in server.get_clients().values():
            client.camera.look_at = server.initial_camera.look_at
            client.camera.position = server.initial_camera.position
        limits = self.urdf.get_actuated_joint_limits()
        self.names = list(self.urdf.get_actuated_joint_names())
        self.ranges = {}
        for n in self.names:
            a, b = limits.get(n, (None, None))
            self.ranges[n] = (-math.pi, math.pi) if a is None or b is None else (float(a), float(b))
        self.folder = server.gui.add_folder(gui_folder_label)
        self.sliders = {}
        self._busy = False
        with self.folder:
            self.openness = server.gui.add_slider("openness", min=0.0, max=1.0, step=0.01,
                                                  initial_value=0.0)
            for n in self.names:
                a, b = self.ranges[n]
                rest = float(np.clip(0.0, a, b))
                s = server.gui.add_slider(n, min=a, max=b, step=max((b - a) / 200.0, 1e-4),
                                          initial_value=rest)
                s.on_update(lambda _e: self._from_sliders())
                self.sliders[n] = s
        self.openness.on_update(lambda _e: self._from_openness())
        self._from_sliders()

    def _from_sliders(self) -> None:
        if self._busy:
            return
        self.urdf.update_cfg(np.array([self.sliders[n].value for n in self.names], dtype=np.float64))

    def _from_openness(self) -> None:
        r = float(self.openness.value)
        self._busy = True                   # one scene update, not one per slider
        try:
            for n in self.names:
                a, b = self.ranges[n]
                self.sliders[n].value = a + r * (b - a)
        finally:
            self._busy = False
        self._from_sliders()

    def remove(self) -> None:
        self.urdf.remove()
        self.grid.remove()
        self.folder.remove()


def _bounds(urdf) -> tuple[np.ndarray, np.ndarray]:
    try:
        scene = urdf.scene
        if scene is not None and not scene.is_empty:
            b = np.asarray(scene.bounds, dtype=np.float64)
            return b[0], b[1]
    except Exception:  # no meshes: a unit box around the origin
        pass
    return -0.5 * np.ones(3), 0.5 * np.ones(3)


def _server(host: str, port: int):
    import viser
    return viser.ViserServer(host=host, port=port, label="artformer", verbose=False)


def serve_view(folder: os.PathLike, *, host: str = "127.0.0.1", port: int = 8080):
    """Start a viser server showing ``folder``; returns (server, ObjectView)."""
    loaded = load_urdf(folder)                  # a clear error before a server starts
    server = _server(host, port)
    return server, ObjectView(server, folder, loaded=loaded)


def zip_folder(folder: os.PathLike) -> bytes:
    """The object folder as a zip (paths under ``<folder name>/``), without dot files."""
    folder = Path(folder)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(folder.rglob("*")):
            rel = f.relative_to(folder)
            if f.is_file() and not any(p.startswith(".") for p in rel.parts):
                z.write(f, f"{folder.name}/{rel.as_posix()}")
    return buf.getvalue()


class Studio:
    """Prompt / image → object, on one generator, one request at a time."""

    STAGES = ("loading the model", "generating", "writing the folder", "done")

    def __init__(self, server, out_dir: os.PathLike, load_generator: Callable):
        self.server = server
        self.out_dir = Path(out_dir).expanduser().resolve()
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self._load_generator = load_generator
        self._gen = None
        self._lock = threading.Lock()
        self._count = 0
        self.view: Optional[ObjectView] = None
        self.current: Optional[Path] = None
        gui = server.gui
        with gui.add_folder("Generate"):
            self.prompt = gui.add_text("Prompt", initial_value="")
            self.go = gui.add_button("Generate")
            self.upload = gui.add_upload_button("Generate from an image", mime_type="image/*")
            self.progress = gui.add_progress_bar(0.0, animated=False)
            self.status = gui.add_markdown("Type a description of an object and press Generate.")
            self.download = gui.add_button("Download zip", disabled=True)
        self.go.on_click(lambda e: self._start(text=self.prompt.value, image=None))
        self.upload.on_upload(lambda e: self._start(text=None, image=self.upload.value))
        self.download.on_click(self._send_zip)

    # -- requests --------------------------------------------------------------------------
    def _start(self, text, image) -> None:
        if not self._lock.acquire(blocking=False):
            self._say("A request is running; wait for it to finish.", error=True)
            return
        threading.Thread(target=self._run, args=(text, image), daemon=True).start()

    def _run(self, text, image) -> None:
        from model.pipeline.api import GenerationError
        tmp = None
        try:
            self.go.disabled = True
            self._stage(0)
            if self._gen is None:
                self._gen = self._load_generator()
            self._stage(1)
            if image is not None:
                tmp = self._image_file(image)
                [res] = self._gen.generate(image=str(tmp), seed=self._count)
                label = f"image {image.name}"
            else:
                [res] = self._gen.generate(text, seed=self._count)
                label = res.prompt
            self._stage(2)
            self._count += 1
            slug = re.sub(r"[^a-z0-9]+", "_", (res.obj.category or "object").lower()).strip("_")
            out = self._gen.export(res, self.out_dir / f"{self._count:03d}_{slug or 'object'}",
                                   mesh_uri="relative")
            self._show(Path(out.out_dir))
            self._stage(3)
            parts = ", ".join(f"{p.label} ({p.joint.type.name.lower()})" for p in res.obj.parts)
            self.status.content = (f"**{res.obj.category or 'object'}** from {label!r}: "
                                   f"{len(res.obj.parts)} parts: {parts}. Saved to "
                                   f"`{out.out_dir}`.")
        except GenerationError as e:
            self._fail(str(e))
        except Exception as e:  # any failure of one request is shown; the server keeps serving
            log.exception("studio request failed")
            self._fail(f"{type(e).__name__}: {e}")
        finally:
            if tmp is not None:
                tmp.unlink(missing_ok=True)
            self.go.disabled = False
            self._lock.release()

    def _image_file(self, upload) -> Path:
        """The upload as a file for the generator; its bytes must be a picture PIL reads."""
        from PIL import Image, UnidentifiedImageError

        from model.pipeline.api import GenerationError
        content = upload.content
        try:
            with Image.open(io.BytesIO(content)) as im:
                im.verify()
        except (UnidentifiedImageError, OSError, ValueError):
            raise GenerationError(f"{upload.name!r} is not an image (PNG, JPEG, ... that PIL "
                                  f"can read)") from None
        suffix = Path(upload.name).suffix or ".png"
        fd, name = tempfile.mkstemp(suffix=suffix, prefix="studio_upload_")
        with os.fdopen(fd, "wb") as f:
            f.write(content)
        return Path(name)

    def _show(self, folder: Path) -> None:
        if self.view is not None:
            self.view.remove()
        self.view = ObjectView(self.server, folder)
        self.current = folder
        self.download.disabled = False

    def _send_zip(self, event) -> None:
        if self.current is None or event.client is None:
            return
        event.client.send_file_download(f"{self.current.name}.zip", zip_folder(self.current),
                                         save_immediately=True)

    # -- feedback --------------------------------------------------------------------------
    def _stage(self, k: int) -> None:
        self.progress.value = 100.0 * (k + 1) / len(self.STAGES)
        self.progress.animated = k < len(self.STAGES) - 1
        if k < len(self.STAGES) - 1:
            self.status.content = f"_{self.STAGES[k]}..._"

    def _fail(self, message: str) -> None:
        self.progress.value = 0.0
        self.progress.animated = False
        self._say(f"Error: {message}", error=True)

    def _say(self, message: str, error: bool = False) -> None:
        self.status.content = f"**{message}**" if error else message
        for client in self.server.get_clients().values():
            client.add_notification(title="artformer", body=message, auto_close_seconds=8.0,
                                    color="red" if error else None)


def serve_studio(*, host: str = "127.0.0.1", port: int = 8080, out_dir: os.PathLike = "out/studio",
                 checkpoint: Optional[str] = None, show: Optional[os.PathLike] = None):
    """Start the studio; the model loads on the first request. Returns (server, Studio)."""
    from model.pipeline.api import GenerationConfig
    from model.pipeline.generator import Generator

    server = _server(host, port)
    studio = Studio(server, out_dir, lambda: Generator.load(GenerationConfig(checkpoint=checkpoint)))
    if show is not None:
        studio._show(Path(show))
    return server, studio


def main(argv: list[str]) -> int:
    import argparse
    import sys

    from .urdfmodel import ConvertError
    cmd = argv[0] if argv and argv[0] in ("view", "studio") else "view"
    rest = argv[1:] if argv and argv[0] in ("view", "studio") else argv
    p = argparse.ArgumentParser(prog=f"artformer {cmd}",
                                description="Show an object folder in the browser (viser)."
                                if cmd == "view" else
                                "Generate objects from a prompt or an image in the browser.")
    if cmd == "view":
        p.add_argument("folder", help="object folder (or its .urdf)")
    else:
        p.add_argument("--out", default="out/studio", help="where generated objects are saved")
        p.add_argument("--checkpoint", default=None, help="model folder (default: shipped)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (127.0.0.1)")
    p.add_argument("--port", type=int, default=8080)
    p.add_argument("-v", "--verbose", action="store_true")
    a = p.parse_args(rest)
    logging.basicConfig(level=logging.INFO if a.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        if cmd == "view":
            server, _ = serve_view(a.folder, host=a.host, port=a.port)
        else:
            server, _ = serve_studio(host=a.host, port=a.port, out_dir=a.out,
                                     checkpoint=a.checkpoint)
    except (ConvertError, OSError) as e:
        print(f"artformer {cmd}: {e}", file=sys.stderr)
        return 1
    print(f"artformer {cmd}: http://{a.host}:{server.get_port()}  (Ctrl-C to stop)", flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        server.stop()
    return 0
