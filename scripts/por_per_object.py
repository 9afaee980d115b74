"""POR of every exported URDF under a folder, one line per object (which objects carry the
averaged worst state that `--pipeline` reports).

    python scripts/por_per_object.py /tmp/artformer_image_pipeline_XXXX
"""
import sys
from pathlib import Path

from model.export.importer import import_urdf
from model.metrics.por import part_overlap_ratio


def main(root: Path) -> None:
    means, worsts = [], []
    for d in sorted(p for p in root.iterdir() if p.is_dir()):
        urdfs = sorted(d.glob("*.urdf"))
        if not urdfs:
            print(f"{d.name}: no URDF")
            continue
        obj = import_urdf(urdfs[0])
        r = part_overlap_ratio(obj)
        means.append(r.mean)
        worsts.append(r.max)
        print(f"{d.name} {urdfs[0].stem:24s} parts {len(obj.parts):2d}  POR ×1e-2 mean {100 * r.mean:6.3f}"
              f"  worst state {100 * r.max:6.3f}  worst pair {r.worst_pair} IoU {r.worst_iou:.3f}")
    if means:
        print(f"{len(means)} objects: POR ×1e-2 mean {100 * sum(means) / len(means):.3f}, worst states averaged "
              f"{100 * sum(worsts) / len(worsts):.3f}, {sum(w > 0.01 for w in worsts)} over 1e-2")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(Path(sys.argv[1]))
