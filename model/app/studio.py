"""Studio (viser): a page that generates objects from a prompt or an image, on top of the
object viewer (model.export.viewer).

    artformer studio [--port 8080] [--out out/studio] [--checkpoint DIR]

It serves a page at http://HOST:PORT with a prompt box, a Generate button and an image
upload. Requests run one at a time on the model (the shipped one by default), and a progress
bar and status line show the stage. The result replaces the object shown, and "Download zip"
sends its folder (URDF with relative mesh paths, meshes, metadata, preview). A bad request
(an empty prompt, a file that is not an image, a model without an image stage) shows its
error in the page and the server keeps serving. No ROS is needed.
"""
from __future__ import annotations

import io
import logging
import os
import re
import tempfile
import threading
import zipfile
from pathlib import Path
from typing import Callable, Optional

from model.export.viewer import ObjectView, run_server, server_args, viser_server
from model.pipeline.api import GenerationConfig, GenerationError

log = logging.getLogger(__name__)


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
    from model.pipeline.generator import Generator

    server = viser_server(host, port)
    studio = Studio(server, out_dir, lambda: Generator.load(GenerationConfig(checkpoint=checkpoint)))
    if show is not None:
        studio._show(Path(show))
    return server, studio


def main(argv: list[str]) -> int:
    import argparse
    rest = argv[1:] if argv[:1] == ["studio"] else argv
    p = argparse.ArgumentParser(prog="artformer studio",
                                description="Generate objects from a prompt or an image in the browser.")
    p.add_argument("--out", default="out/studio", help="where generated objects are saved")
    p.add_argument("--checkpoint", default=None, help="model folder (default: shipped)")
    server_args(p)
    a = p.parse_args(rest)
    return run_server("studio", a, lambda: serve_studio(host=a.host, port=a.port, out_dir=a.out,
                                                        checkpoint=a.checkpoint))
