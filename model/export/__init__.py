"""Export: ArticulatedObject ↔ URDF folder (meshes, metadata, preview), simulator checks.

Heavy dependencies (trimesh, yourdfpy, lxml, pybullet, mujoco) are imported inside the
functions that need them.
"""
from __future__ import annotations

__all__ = ["export_object", "import_urdf", "check_urdf", "render_views", "write_preview",
           "URDFImportError", "CollisionConfig", "collision_pieces"]


def __getattr__(name):
    if name == "export_object":
        from .urdf import export_object
        return export_object
    if name in ("CollisionConfig", "collision_pieces"):
        from . import collision
        return getattr(collision, name)
    if name in ("import_urdf", "URDFImportError"):
        from . import importer
        return getattr(importer, name)
    if name == "check_urdf":
        from .simcheck import check_urdf
        return check_urdf
    if name in ("render_views", "write_preview"):
        from . import render
        return getattr(render, name)
    raise AttributeError(name)
