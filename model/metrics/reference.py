"""Reference objects and prompts from a prepared dataset (``model.data.format``), and the
retrieval baseline (the training object whose description embedding is nearest).
"""
from __future__ import annotations

import hashlib
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from model.core import ArticulatedObject
from model.data import format as fmt

log = logging.getLogger(__name__)

FREEFORM_PATH = Path(__file__).with_name("prompts_freeform.txt")
# the fixed workload of `artformer bench` (kept as it is, so speed figures stay comparable)
BENCH_PATH = Path(__file__).with_name("prompts_bench.txt")


def freeform_prompts(path: str | Path | None = None) -> list[str]:
    """The hand-written free-form prompts (one per line, '#' comments)."""
    lines = Path(path or FREEFORM_PATH).read_text().splitlines()
    return [l.strip() for l in lines if l.strip() and not l.lstrip().startswith("#")]


def load_object(root: str | Path, rec: fmt.ObjectRecord, *, meshes: bool = True) -> ArticulatedObject:
    """A dataset record as an ArticulatedObject, with its part meshes when they are stored
    (``ROOT/meshes/<id>/<k>.obj``, object frame). Parts without a stored mesh keep mesh=None."""
    obj = ArticulatedObject.from_tokens(np.asarray(rec.tokens, dtype=np.float64), rec.joint_types,
                                        rec.parents, rec.labels, category=rec.category,
                                        name=f"ref_{rec.id}")
    if rec.part_names and len(rec.part_names) == len(obj.parts) \
            and len(set(rec.part_names)) == len(rec.part_names):
        for p, nm in zip(obj.parts, rec.part_names):
            p.name = nm
    if meshes:
        import trimesh
        folder = Path(root) / "meshes" / rec.id
        for k, p in enumerate(obj.parts):
            f = folder / f"{k}.obj"
            if f.exists():
                p.mesh = trimesh.load(f, force="mesh", process=False)
    return obj


def pick_description(rec: fmt.ObjectRecord, index: int) -> str:
    """One description per record, rotating over the lengths so every length is evaluated."""
    lengths = [l for l in fmt.DESCRIPTION_LENGTHS if rec.descriptions.get(l)]
    lengths += [l for l in rec.descriptions if l not in lengths and rec.descriptions[l]]
    if not lengths:
        raise ValueError(f"record {rec.id} has no descriptions")
    texts = rec.descriptions[lengths[index % len(lengths)]]
    return texts[(index // len(lengths)) % len(texts)]


@dataclass
class Dataset:
    root: Path
    manifest: dict

    @classmethod
    def open(cls, root: str | Path) -> "Dataset":
        return cls(Path(root), fmt.load_manifest(root))

    def ids(self, split: str) -> list[str]:
        return list(self.manifest["splits"].get(split, []))

    def record(self, obj_id: str) -> fmt.ObjectRecord:
        return fmt.load_record(self.root, obj_id)

    def object(self, obj_id: str) -> ArticulatedObject:
        return load_object(self.root, self.record(obj_id))


def cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "artformer" / "retrieval"


class Retriever:
    """Nearest training object by cosine similarity of pooled description embeddings
    (every description of every length of every training record is a key).

    Embedding ~10k training descriptions costs minutes on a CPU, so the keys are cached in
    ``~/.cache/artformer/retrieval/<sha256 of encoder + texts>.npz`` (``cache=False`` to skip).
    """

    def __init__(self, data: Dataset, split: str = "train", encoder: str = "all-minilm-l6-v2",
                 batch: int = 64, cache: bool = True):
        from model.encoders.text import get_text_encoder
        self.data = data
        self.encoder = get_text_encoder(encoder)
        texts, owners = [], []
        for oid in data.ids(split):
            rec = data.record(oid)
            for _, ts in sorted(rec.descriptions.items()):
                for t in ts:
                    texts.append(t)
                    owners.append(oid)
        if not texts:
            raise ValueError(f"{data.root}: split {split!r} has no descriptions to retrieve from")
        self.owners = owners
        h = hashlib.sha256(encoder.encode())
        for t in texts:
            h.update(b"\0" + t.encode())
        path = cache_dir() / f"{h.hexdigest()[:24]}.npz"
        if cache and path.exists():
            with np.load(path) as z:
                self.keys = z["keys"]
            log.info("retrieval keys from cache %s", path)
        else:
            self.keys = self._embed(texts, batch)             # (T, D) unit rows
            if cache:
                import io
                buf = io.BytesIO()
                np.savez(buf, keys=self.keys)
                fmt.atomic_write_bytes(path, buf.getvalue())

    def _embed(self, texts: list[str], batch: int = 64) -> np.ndarray:
        out = []
        for i in range(0, len(texts), batch):
            e = self.encoder.encode(texts[i:i + batch]).pooled.float().numpy()   # (b, D)
            out.append(e / np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-12))
        return np.concatenate(out)

    def nearest(self, prompts: list[str]) -> list[str]:
        """Training object id per prompt."""
        q = self._embed(prompts)                               # (P, D)
        best = (q @ self.keys.T).argmax(axis=1)                # (P,)
        return [self.owners[i] for i in best]
