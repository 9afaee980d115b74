"""`artformer eval diversity`: do seeds vary the layout within a prompt's structure?

For every prompt, the trees of seeds 0..S-1 (S = 8) are decoded as ``artformer generate``
decodes them (``Generator.decode_trees``: no shapes, no meshes, no refinement) and scored:

* ``distinct``: distinct layouts among the seeds. A layout is the part tree with every node's
  label, joint type and box (size and centre) rounded to ``cm`` (1 cm), children in a
  canonical order (``layout_key``), so two seeds differ only if a part is added, removed,
  relabelled, re-jointed or its box moves by about a centimetre.
* ``spread``: the mean pairwise box distance among the seeds that have the prompt's main
  structure (category + parts per label, handles aside), against ``data_spread``, the same
  among the training objects of that structure (``--data``'s train split): ``ratio`` = 1
  means the seeds vary the boxes as much as the data does for that structure. The box
  distance of two objects of one structure matches the parts of each label one to one
  (Hungarian, on the distance of their 6-vectors box centre + size, metres) and averages the
  matched distances (``box_distance``).
* ``room``: the structure leaves room when the training data has at least two objects of that
  structure and its first S of them (at most) all have distinct layouts (the generator draws
  every object's sizes, so any structure it made twice does); unknown (None) with fewer than
  two, and such prompts are left out of the share.

    artformer eval diversity --out eval_diversity.json       # free prompts (shipped model)
    artformer eval diversity --forced                         # each prompt's structure forced
    artformer eval diversity --structure '{"drawer": 2}' --prompts-file p.txt
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
from collections import Counter
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from .audit_eval import EVERYDAY

log = logging.getLogger(__name__)

PROMPTS = ("a cabinet with two drawers",) + EVERYDAY   # and the audit's 12 everyday prompts
# the structure each built-in prompt states, for --forced (decoding within an asked structure)
FORCED = {
    "a cabinet with two drawers": {"drawer": 2},
    "a kitchen cabinet with three drawers and a door on the left": {"drawer": 3, "door": 1},
    "a chest of four drawers": {"drawer": 4},
    "a wardrobe with two doors": {"door": 2},
    "a safe with a keypad and a door": {"door": 1, "button": 9},
    "an oven with four knobs and a door": {"door": 1, "knob": 4},
    "a front-loading washing machine with a dial": {"door": 1, "dial": 1},
    "a bottle with a screw cap": {"cap": {"count": 1, "joint": "screw"}},
    "a usb stick with a cap": {"cap": 1, "category": "USB"},
    "a storage cabinet with two drawers and a door": {"drawer": 2, "door": 1},
    "a nightstand with one drawer": {"drawer": 1, "category": "StorageFurniture"},
    "a microwave-sized safe with a turning knob": {"door": 1, "dial": 1, "category": "Safe"},
    "a top-loading washing machine with a lid": {"lid": 1, "category": "WashingMachine"},
}
UNCOUNTED = ("handle",)   # left out of a structure: they follow their doors and drawers


def _node_boxes(tokens) -> np.ndarray:
    t = np.asarray(tokens, dtype=np.float64).reshape(-1, 16)
    return t[:, :6]                                   # size (3), centre (3)


def layout_key(labels: Sequence[str], parents: Sequence[int], joint_types: Sequence[int],
               tokens, cm: float = 0.01) -> str:
    """Canonical text of a layout: tree, labels, joint types and boxes rounded to ``cm``."""
    boxes = np.round(_node_boxes(tokens) / cm).astype(np.int64)
    kids: dict[int, list[int]] = {}
    for k, p in enumerate(parents):
        kids.setdefault(int(p), []).append(k)

    def node(k: int) -> str:
        inner = ",".join(sorted(node(c) for c in kids.get(k, [])))
        return f"{labels[k]}:{int(joint_types[k])}:{boxes[k].tolist()}({inner})"
    return "|".join(sorted(node(r) for r in kids.get(-1, [])))


def structure_key(category: str, labels: Sequence[str]) -> tuple:
    """(category, ((label, count), ...)) without the UNCOUNTED labels."""
    c = Counter(lab for lab in labels if lab not in UNCOUNTED)
    return (category, tuple(sorted(c.items())))


def box_distance(a: tuple, b: tuple) -> Optional[float]:
    """Mean matched box distance (m) of two layouts ``(labels, tokens)`` of one structure
    (UNCOUNTED labels aside); None when their structures differ."""
    from scipy.optimize import linear_sum_assignment

    la, lb = list(a[0]), list(b[0])
    ba, bb = _node_boxes(a[1]), _node_boxes(b[1])
    total, n = 0.0, 0
    for lab in sorted(set(la) | set(lb)):
        if lab in UNCOUNTED:
            continue
        ia = [k for k, x in enumerate(la) if x == lab]
        ib = [k for k, x in enumerate(lb) if x == lab]
        if len(ia) != len(ib):
            return None
        d = np.linalg.norm(ba[ia][:, None, :] - bb[ib][None, :, :], axis=-1)
        r, c = linear_sum_assignment(d)
        total += float(d[r, c].sum())
        n += len(r)
    return total / n if n else 0.0


def mean_pairwise(items: Sequence[tuple], limit: int = 64) -> Optional[float]:
    """Mean box_distance over all pairs of the first ``limit`` items (None below 2)."""
    items = list(items)[:limit]
    d = [box_distance(items[i], items[j]) for i in range(len(items))
         for j in range(i + 1, len(items))]
    d = [x for x in d if x is not None]
    return float(np.mean(d)) if d else None


def data_pool(data_root: str, split: str = "train") -> dict[tuple, list[dict]]:
    """structure_key -> that structure's objects of a prepared dataset's split (labels,
    parents, joint types, tokens), in id order."""
    from model.data import format as fmt

    pool: dict[tuple, list[dict]] = {}
    for i in fmt.split_ids(data_root, split):
        rec = fmt.load_record(data_root, i)
        pool.setdefault(structure_key(rec.category, rec.labels), []).append(
            {"labels": rec.labels, "parents": rec.parents, "joint_types": rec.joint_types,
             "tokens": rec.tokens})
    return pool


def score_prompt(trees: Sequence, pool: dict[tuple, list[dict]], *, cm: float = 0.01) -> dict:
    """One prompt's row from its seeds' decoded trees (``DecodedTree``s, seed order)."""
    S = len(trees)
    keys = [layout_key(t.labels, t.parents, t.joint_types, t.tokens, cm) for t in trees]
    structs = [structure_key(t.category, t.labels) for t in trees]
    main, n_main = Counter(structs).most_common(1)[0]
    mine = [(t.labels, t.tokens) for t, s in zip(trees, structs) if s == main]
    data = pool.get(main, [])
    data_keys = {layout_key(d["labels"], d["parents"], d["joint_types"], d["tokens"], cm)
                 for d in data[:S]}
    spread = mean_pairwise(mine)
    data_spread = mean_pairwise([(d["labels"], d["tokens"]) for d in data])
    return {"distinct": len(set(keys)), "seeds": S, "structures": len(set(structs)),
            "main_structure": {"category": main[0], "counts": dict(main[1])},
            "main_share": n_main / S, "data_objects": len(data),
            "data_distinct": len(data_keys),
            "room": None if len(data) < 2 else len(data_keys) == min(len(data), S),
            "spread_m": spread, "data_spread_m": data_spread,
            "ratio": (spread / data_spread) if spread is not None and data_spread else None}


def summarise(rows: Sequence[dict], min_distinct: int = 6) -> dict:
    room = [r for r in rows if r.get("room")]
    ratios = [r["ratio"] for r in rows if r.get("ratio") is not None]
    return {"prompts": len(rows),
            "mean_distinct": float(np.mean([r["distinct"] for r in rows])) if rows else None,
            "room_prompts": len(room),
            f"share_room_with_{min_distinct}_distinct":
                float(np.mean([r["distinct"] >= min_distinct for r in room])) if room else None,
            "mean_ratio": float(np.mean(ratios)) if ratios else None,
            "all_main_structure": float(np.mean([r["main_share"] == 1.0 for r in rows]))
            if rows else None}


def run_diversity(gen, prompts: Sequence, pool: dict, *, seeds: int = 8,
                  structure=None, cm: float = 0.01, progress: bool = False) -> dict:
    """Rows for ``prompts`` (texts, or (text, structure) pairs) with a loaded
    ``model.pipeline.Generator`` (its config decides the decoding: temperature, plan,
    layout_sampling); ``structure`` is forced on the prompts that bring none."""
    from model.pipeline.api import parse_structure

    rows = []
    it = prompts
    if progress:
        from tqdm import tqdm
        it = tqdm(prompts, desc="diversity", unit="prompt")
    for item in it:
        prompt, own = (item, None) if isinstance(item, str) else item
        asked = own if own is not None else structure
        trees, *_ = gen.decode_trees(prompt, seed=0, samples=seeds, structure=asked)
        row = {"prompt": prompt, **score_prompt(trees, pool, cm=cm)}
        if asked is not None:
            row["structure"] = parse_structure(asked).to_dict()
        rows.append(row)
    c = gen.config
    return {"rows": rows, "summary": summarise(rows),
            "decoding": {"structure_temperature": c.structure_temperature,
                         "follow_plan": list(c.follow_plan), "sample_choices": c.sample_choices,
                         "layout_sampling": c.layout_sampling,
                         "structure": None if structure is None
                         else parse_structure(structure).to_dict(),
                         "seeds": f"0..{seeds - 1}", "cm": cm}}


def markdown(rep: dict) -> str:
    def f(x, fmt="{:.3f}"):
        return "–" if x is None else fmt.format(x)
    lines = ["| prompt | distinct / seeds | main structure (share) | room | spread (m) | "
             "data spread (m, n) | ratio |", "|---|---|---|---|---|---|---|"]
    for r in rep["rows"]:
        ms = r["main_structure"]
        st = ms["category"] + " " + ", ".join(f"{k} {v}" for k, v in ms["counts"].items())
        room = {True: "yes", False: "no", None: "–"}[r["room"]]
        lines.append(f"| {r['prompt']} | {r['distinct']} / {r['seeds']} | {st} "
                     f"({r['main_share']:.2f}) | {room} | {f(r['spread_m'])} | "
                     f"{f(r['data_spread_m'])} ({r['data_objects']}) | {f(r['ratio'], '{:.2f}')} |")
    s = rep["summary"]
    share = [v for k, v in s.items() if k.startswith("share_room")][0]
    lines.append("")
    lines.append(f"{s['prompts']} prompts: mean {f(s['mean_distinct'], '{:.2f}')} distinct layouts "
                 f"of {rep['rows'][0]['seeds'] if rep['rows'] else 0}; {s['room_prompts']} leave "
                 f"room, {f(share, '{:.0%}')} of them with >= 6; mean spread ratio "
                 f"{f(s['mean_ratio'], '{:.2f}')}")
    return "\n".join(lines)


def _matching_data(version: Optional[str]) -> Optional[str]:
    """A prepared dataset under ./data/prepared or the repository's whose data_version is the
    model's (the data it was trained on)."""
    if not version:
        return None
    roots = [Path.cwd() / "data" / "prepared",
             Path(__file__).resolve().parents[2] / "data" / "prepared"]
    for r in roots:
        for m in sorted(r.glob("*/manifest.json")) if r.is_dir() else []:
            try:
                if json.loads(m.read_text()).get("data_version") == version:
                    return str(m.parent)
            except (OSError, ValueError):
                continue
    return None


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(
        prog="artformer eval diversity",
        description="Distinct layouts among seeds 0..S-1 per prompt and their box spread "
                    "against the training data's spread for the same structure.")
    p.add_argument("--checkpoint", default=None, help="checkpoint folder (default: shipped)")
    p.add_argument("--data", default=None, help="prepared dataset whose train split gives "
                                                "the data's spread (default: newest under "
                                                "data/prepared)")
    p.add_argument("--prompts-file", default=None, help="one prompt per line (default: "
                                                        "'a cabinet with two drawers' + the "
                                                        "12 everyday prompts)")
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--structure", default=None, metavar="JSON",
                   help="decode every prompt with this structure forced")
    p.add_argument("--structure-temperature", type=float, default=None)
    p.add_argument("--sample-choices", action="store_true",
                   help="let the seed draw labels and plan counts too (GenerationConfig."
                        "sample_choices; off in the product)")
    p.add_argument("--layout-sampling", choices=("never", "structure", "always"), default=None,
                   help="Monte-Carlo dropout for the parts' boxes and joints (GenerationConfig."
                        "layout_sampling; default: the product's, 'structure')")
    p.add_argument("--no-prompt-structure", dest="prompt_structure", action="store_false",
                   help="decode free text with the network's own reading, without holding "
                        "the parts the prompt states (GenerationConfig.prompt_structure)")
    p.add_argument("--forced", action="store_true",
                   help="decode every built-in prompt with its structure (FORCED) forced")
    p.add_argument("--cm", type=float, default=1.0, help="layout rounding in cm (1)")
    p.add_argument("--out", default=None, help="write the report as JSON here")
    p.add_argument("--md", default=None, help="also write the markdown table here")
    a = p.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    from model.metrics.commands import _default_data
    from model.pipeline.api import GenerationConfig, GenerationError, parse_structure
    from model.pipeline.generator import Generator

    if not 2 <= a.seeds <= 16:
        p.error("--seeds must be in [2, 16]")
    prompts: list = [(t, FORCED[t]) for t in PROMPTS] if a.forced else list(PROMPTS)
    if a.prompts_file:   # one prompt per line, optionally <TAB> its structure as JSON
        prompts = [tuple(s.split("\t", 1)) if "\t" in s else s.strip()
                   for s in Path(a.prompts_file).read_text().splitlines()
                   if s.strip() and not s.startswith("#")]
    try:
        structure = None if a.structure is None else parse_structure(a.structure)
        cfg = GenerationConfig(checkpoint=a.checkpoint, sample_choices=a.sample_choices,
                               refine=False, prompt_structure=a.prompt_structure)
        if a.structure_temperature is not None:
            cfg.structure_temperature = a.structure_temperature
        if a.layout_sampling is not None:
            cfg.layout_sampling = a.layout_sampling
        gen = Generator.load(cfg)
        data = a.data or _matching_data(gen.articulation.meta.get("data_version")) \
            or _default_data()
        if not data:
            print("artformer eval diversity: give --data DIR (a prepared dataset)",
                  file=sys.stderr)
            return 2
        pool = data_pool(data)
        rep = run_diversity(gen, prompts, pool, seeds=a.seeds, structure=structure,
                            cm=a.cm / 100.0, progress=sys.stderr.isatty())
    except (GenerationError, FileNotFoundError, KeyError, ValueError) as e:
        print(f"artformer eval diversity: {e}", file=sys.stderr)
        return 1
    rep["data"] = str(data)
    md = markdown(rep)
    print(md)
    if a.out:
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(json.dumps(rep, indent=1))
        print(f"wrote {a.out}")
    if a.md:
        Path(a.md).write_text(md + "\n")
    return 0
