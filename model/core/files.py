"""Small helpers every layer shares: atomic file writes, conversion to strict JSON, and
file-name-safe slugs."""
from __future__ import annotations

import json
import math
import os
import re
import tempfile
from pathlib import Path
from typing import Any, Optional

import numpy as np


def atomic_write_bytes(path: os.PathLike, data: bytes) -> None:
    """Write to a temp file in the same folder, then rename: readers never see half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_torch_save(path: os.PathLike, obj: Any) -> None:
    """``torch.save`` through atomic_write_bytes (serialised in memory first)."""
    import io

    import torch
    buf = io.BytesIO()
    torch.save(obj, buf)
    atomic_write_bytes(path, buf.getvalue())


def atomic_write_text(path: os.PathLike, text: str) -> None:
    atomic_write_bytes(path, text.encode())


def atomic_write_json(path: os.PathLike, obj: Any) -> None:
    atomic_write_bytes(path, json.dumps(obj, indent=1).encode())


def jsonable(x: Any, *, nan_as_null: bool = True) -> Any:
    """``x`` as plain JSON values: numpy scalars and arrays become Python numbers and lists,
    tuples lists, dict keys strings, anything else (a path) its string; NaN / inf become null
    unless ``nan_as_null`` is False (then ``json.dumps`` writes them as NaN / Infinity)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v, nan_as_null=nan_as_null) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v, nan_as_null=nan_as_null) for v in x]
    if isinstance(x, (np.ndarray, np.generic)):
        return jsonable(x.tolist(), nan_as_null=nan_as_null)
    if isinstance(x, float) and not math.isfinite(x):
        return None if nan_as_null else x
    if x is None or isinstance(x, (str, int, float, bool)):
        return x
    return str(x)


def slug(text: str, *, default: str, keep: str = "", sep: str = "_", lower: bool = False,
         collapse: bool = False, max_length: Optional[int] = None) -> str:
    """A file-name-safe version of ``text``: every character other than an ASCII letter, a
    digit or one of ``keep`` becomes ``sep`` (a run of them one ``sep`` with ``collapse``),
    ``sep`` trimmed from both ends; ``default`` when nothing is left."""
    text = str(text).strip()
    if lower:
        text = text.lower()
    bad = f"[^A-Za-z0-9{re.escape(keep)}]" + ("+" if collapse else "")
    s = re.sub(bad, sep, text).strip(sep)[:max_length]
    return s or default
