"""Web viewer (viser): an object folder in 3D with a slider per joint.

    artformer view out/cabinet [--port 8080] [--host 127.0.0.1]

It serves a page at http://HOST:PORT (three.js in the browser; the meshes are sent over a
websocket). No ROS is needed. The page shows the URDF's visual meshes with a grid at the
object's foot. It has one slider per moving joint (range = the URDF limits; continuous joints
-pi..pi) and an openness slider that sets every joint to the same share of its range.

The studio page that generates objects from a prompt or an image builds on this viewer and
lives above the pipeline it drives: model.app.studio (`artformer studio`).
"""
from __future__ import annotations

import logging
import math
import os
import time
from typing import Callable

import numpy as np


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


def viser_server(host: str, port: int):
    import viser
    return viser.ViserServer(host=host, port=port, label="artformer", verbose=False)


def serve_view(folder: os.PathLike, *, host: str = "127.0.0.1", port: int = 8080):
    """Start a viser server showing ``folder``; returns (server, ObjectView)."""
    loaded = load_urdf(folder)                  # a clear error before a server starts
    server = viser_server(host, port)
    return server, ObjectView(server, folder, loaded=loaded)


def server_args(p) -> None:
    """The options every viser page command takes (host, port, verbosity)."""
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (127.0.0.1)")
    p.add_argument("--port", type=int, default=8080)
    p.add_argument("-v", "--verbose", action="store_true")


def run_server(cmd: str, a, start: Callable) -> int:
    """Start a page with ``start()`` -> (server, ...) and serve it until Ctrl-C; a folder that
    is no object, or a port in use, is reported as ``artformer CMD: ...`` (exit 1)."""
    import sys

    from .urdfmodel import ConvertError
    logging.basicConfig(level=logging.INFO if a.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        server, _ = start()
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


def main(argv: list[str]) -> int:
    import argparse
    rest = argv[1:] if argv[:1] == ["view"] else argv
    p = argparse.ArgumentParser(prog="artformer view",
                                description="Show an object folder in the browser (viser).")
    p.add_argument("folder", help="object folder (or its .urdf)")
    server_args(p)
    a = p.parse_args(rest)
    return run_server("view", a, lambda: serve_view(a.folder, host=a.host, port=a.port))
