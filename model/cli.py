"""`artformer` command line. Subcommands live beside the code they drive and are imported
only when used, so `artformer --help` stays fast (no torch import)."""
from __future__ import annotations

import importlib
import sys

# (words...) -> module with `main(argv: list[str]) -> int`; argv keeps the route words.
ROUTES: dict[tuple[str, ...], tuple[str, str]] = {
    ("export",): ("model.export.commands", "export the built-in example object(s) to URDF folders"),
    ("convert",): ("model.export.convert", "convert an object folder to MJCF / USD / a ROS package"),
    ("view",): ("model.export.viewer", "show an object folder in the browser (viser)"),
    ("studio",): ("model.app.studio", "generate objects from a prompt or image in the browser"),
    ("data", "render"): ("model.imaging.commands", "render dataset objects for image conditioning"),
    ("data", "partmaps"): ("model.imaging.commands", "part-centre maps of the rendered views"),
    ("data", "features"): ("model.imaging.commands", "cache encoder features of the rendered views"),
    ("data",): ("model.data.commands", "synth / prepare / stats of the articulated-object dataset"),
    ("train", "sdf"): ("model.geometry.commands", "train the tri-plane SDF auto-encoder"),
    ("train", "prior"): ("model.geometry.commands", "train the codebook diffusion shape prior"),
    ("train", "transformer"): ("model.app.train_transformer", "train the articulation transformer"),
    ("train", "image"): ("model.app.train_image", "train the image-conditioned transformer"),
    ("train", "image-counts"): ("model.imaging.commands", "train the image model's count head"),
    ("train", "image-trunk"): ("model.imaging.commands", "fine-tune the image encoder trunk to count parts"),
    ("generate",): ("model.pipeline.commands", "text or image -> URDF + meshes"),
    ("edit",): ("model.pipeline.commands", "remove parts of a URDF and regenerate them from text"),
    ("eval", "audit"): ("model.metrics.audit_eval", "sim-ready audit of generated objects, raw and refined"),
    ("eval", "geometry"): ("model.geometry.commands", "shape-prior reconstruction / sample quality"),
    ("bench", "geometry"): ("model.geometry.commands", "shape-prior meshing and DDIM speed"),
    ("eval",): ("model.metrics.commands", "evaluate a checkpoint (POR, MMD/COV/1-NNA, alignment...)"),
    ("bench",): ("model.metrics.commands", "per-stage speed and memory benchmark"),
    ("audit",): ("model.metrics.commands", "physical sim-ready audit of URDF folders"),
}


def _usage() -> str:
    lines = ["usage: artformer <command> [...]", "", "commands:"]
    for words, (_, help_) in ROUTES.items():
        lines.append(f"  {' '.join(words):<18} {help_}")
    lines.append("")
    lines.append("`artformer <command> --help` for the options of one command.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0
    for n in (2, 1):
        key = tuple(argv[:n])
        if key in ROUTES:
            module = importlib.import_module(ROUTES[key][0])
            return int(module.main(argv) or 0)
    print(f"artformer: unknown command {' '.join(argv[:2])!r}\n\n{_usage()}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
