"""What a prompt asks for (``ExpectedStructure``: category, counts, joint types, spatial facts)
and the annotated free-form prompt file, where each prompt is followed by its structure as a
``#> ...`` line (``ExpectedStructure.to_line`` / ``from_line``). model.metrics.prompt_parse
reads an ExpectedStructure from a prompt; the alignment metric checks objects against it.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from model.data import vocab

# Spatial facts a prompt can state, and their values (model.data.spatial.spatial_summary).
SIDES = ("left", "right", "top", "bottom", "back", "front", "side")   # "side": left or right
SPATIAL_KEYS: dict[str, tuple[str, ...]] = {
    "hinge": SIDES,
    "opens": ("down", "up", "sideways"),
    "layout": ("row", "column", "grid"),
    "rows": ("int",),
    "columns": ("int",),
    "hpos": ("left", "middle", "right"),
    "vpos": ("top", "middle", "bottom"),
    "above": (),    # values: part labels
    "below": (),
    "beside": (),   # side by side with them, either way round ("a drawer beside a door")
    "per_row": ("ints",),   # parts per row, top row first ("2/1/1": two on top of a column)
}
SPATIAL_KINDS = {"hinge": "hinge", "opens": "opening", "layout": "arrangement",
                 "rows": "arrangement", "columns": "arrangement", "hpos": "position",
                 "vpos": "position", "above": "position", "below": "position", "beside": "position",
                 "per_row": "arrangement"}
ARRANGEMENT_KEYS = frozenset(k for k, kind in SPATIAL_KINDS.items() if kind == "arrangement")
POSITION_KEYS = frozenset(k for k, kind in SPATIAL_KINDS.items() if kind == "position")
RELATION_KEYS = ("above", "below", "beside")   # facts whose values are other part labels


@dataclass
class ExpectedStructure:
    """What a prompt asks for. Labels not mentioned are unconstrained."""
    category: str | None = None
    counts: dict[str, int] = field(default_factory=dict)       # exact counts
    min_counts: dict[str, int] = field(default_factory=dict)   # lower bounds (no exact count)
    joint_types: dict[str, list[str]] = field(default_factory=dict)  # acceptable types
    # spatial facts per label (see SPATIAL_KEYS): {"door": {"hinge": ["left"]}, ...}
    spatial: dict[str, dict] = field(default_factory=dict)
    # the body's stated dimensions in metres (model.data.prompt_size): {"width": 0.6, ...}
    size: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict:
        out = {"category": self.category, "counts": dict(self.counts),
               "min_counts": dict(self.min_counts),
               "joint_types": {k: list(v) for k, v in self.joint_types.items()}}
        if self.spatial:
            out["spatial"] = {k: dict(v) for k, v in self.spatial.items()}
        if self.size:
            out["size"] = dict(self.size)
        return out

    @property
    def is_empty(self) -> bool:
        return not (self.category or self.counts or self.min_counts or self.joint_types
                    or self.spatial or self.size)

    @property
    def num_parts(self) -> int:
        """Countable parts the prompt asks for (exact counts, else lower bounds)."""
        return sum(self.counts.values()) + sum(v for k, v in self.min_counts.items()
                                               if k not in self.counts)

    # -- the free-form file's annotation line ---------------------------------------------------
    def to_line(self) -> str:
        """``CATEGORY drawer=3 knob>=2 door:revolute door.hinge=left drawer.layout=column``."""
        items = [self.category or "-"]
        items += [f"{k}={v}" for k, v in self.counts.items()]
        items += [f"{k}>={v}" for k, v in self.min_counts.items()]
        items += [f"{k}:{'/'.join(v)}" for k, v in self.joint_types.items()]
        for lab, facts in self.spatial.items():
            for key, v in facts.items():
                val = "/".join(str(x) for x in v) if isinstance(v, (list, tuple)) else str(v)
                items.append(f"{lab}.{key}={val}")
        items += [f"size.{k}={v:g}" for k, v in self.size.items()]
        return " ".join(items)

    @classmethod
    def from_line(cls, line: str) -> "ExpectedStructure":
        """Inverse of :meth:`to_line`; a clear ValueError on anything it does not know."""
        items = line.split()
        if not items:
            raise ValueError("empty structure line")
        cat = None if items[0] == "-" else items[0]
        if cat is not None and cat not in vocab.CATEGORIES:
            raise ValueError(f"unknown category {cat!r} (one of {list(vocab.CATEGORIES)} or -)")
        out = cls(category=cat)
        labels = set(vocab.COUNTABLE_LABELS)
        for it in items[1:]:
            m = re.fullmatch(r"size\.(width|height|depth|length)=(\d+(?:\.\d+)?)", it)
            if m:
                out.size[m.group(1)] = float(m.group(2))
                continue
            m = re.fullmatch(r"([a-z]+)\.([a-z_]+)=([a-z0-9/]+)", it)
            if m:
                lab, key, val = m.groups()
                if lab not in labels or key not in SPATIAL_KEYS:
                    raise ValueError(f"{it!r}: label must be one of {sorted(labels)}, fact one "
                                     f"of {list(SPATIAL_KEYS)}")
                vals = val.split("/")
                bad = [v for v in vals if v not in SPATIAL_KEYS[key] and not
                       (SPATIAL_KEYS[key] in (("int",), ("ints",)) and v.isdigit())
                       and not (key in RELATION_KEYS and v in labels)]
                if bad:
                    raise ValueError(f"{it!r}: {bad} not among {SPATIAL_KEYS[key]}")
                fact = int(vals[0]) if SPATIAL_KEYS[key] == ("int",) else \
                    [int(v) for v in vals] if SPATIAL_KEYS[key] == ("ints",) else \
                    (vals[0] if key == "layout" else sorted(vals))
                out.spatial.setdefault(lab, {})[key] = fact
                continue
            m = re.fullmatch(r"([a-z]+)(=|>=|:)([a-z0-9/]+)", it)
            if not m or m.group(1) not in labels:
                raise ValueError(f"cannot read {it!r} (label=N, label>=N, label:type/type or "
                                 f"label.fact=value; labels {sorted(labels)})")
            lab, op, val = m.groups()
            if op == ":":
                types = val.split("/")
                bad = [t for t in types if t not in vocab.MOTION_SYNONYMS]
                if bad:
                    raise ValueError(f"{it!r}: unknown joint types {bad}")
                out.joint_types[lab] = sorted(types)
            elif not val.isdigit():
                raise ValueError(f"{it!r}: a count must be a whole number")
            elif op == "=":
                out.counts[lab] = int(val)
            else:
                out.min_counts[lab] = int(val)
        return out


def read_annotated_prompts(path=None) -> list[tuple[str, ExpectedStructure]]:
    """(prompt, expected structure) of every prompt of a free-form file: each prompt line is
    followed by its ``#> ...`` structure line (``ExpectedStructure.from_line``). Default: the
    shipped ``prompts_freeform.txt``. A prompt without a structure line, or a structure line
    without a prompt, is a ValueError naming the line."""
    from pathlib import Path
    path = Path(path) if path else Path(__file__).parents[1] / "metrics" / "prompts_freeform.txt"
    out: list[tuple[str, ExpectedStructure]] = []
    pending: tuple[int, str] | None = None
    for no, raw in enumerate(path.read_text().splitlines(), 1):
        line = raw.strip()
        if line.startswith("#>"):
            if pending is None:
                raise ValueError(f"{path}:{no}: structure line without a prompt above it")
            try:
                out.append((pending[1], ExpectedStructure.from_line(line[2:].strip())))
            except ValueError as e:
                raise ValueError(f"{path}:{no}: {e}") from None
            pending = None
        elif not line or line.startswith("#"):
            continue
        else:
            if pending is not None:
                raise ValueError(f"{path}:{pending[0]}: prompt without a '#> ...' structure line")
            pending = (no, line)
    if pending is not None:
        raise ValueError(f"{path}:{pending[0]}: prompt without a '#> ...' structure line")
    return out
