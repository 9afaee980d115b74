"""Candidate text model against the shipped one, from the files the text recipe's text-eval
stage writes (scripts/recipe_text.sh): one table of the issue's measures on validation data
and the hand-written prompt sets, each row marked where the candidate is better, and the
ship rule's verdict.

    python scripts/compare_candidate.py runs/text_v5 [--markdown OUT.md]

Ship rule (decided on these validation figures; test and held-out are scored once, after):
the candidate ships when it is better on template alignment (the project metric) and on
the raw audit, and no worse than the shipped model on the refined audit's sim-ready share and
its objects whose worst part has at most 2 connected components (1.5 % of the objects
allowed each), free-form and dev alignment (1 point allowed), collapsed sibling pairs and
bare names decoded with a moving part and with their doors and drawers on the front
(scripts/bare_names.py).

The audit runs 6 seeds (288 objects). The component row mostly measures the shape prior,
which a candidate may share with the shipped model; at 96 objects a difference of 2 objects
is within one standard error of the difference of two shares near 96 %, so a smaller sample
decides on noise.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _load(path: Path):
    return json.loads(path.read_text()) if path.exists() else None


def _audit(d, row: str):
    """The summary of one row ("raw", "refined") of an audit.json, whose keys are the rows'
    titles (model.metrics.audit_eval.ROWS: "raw model", "refined")."""
    from model.metrics.audit_eval import ROWS
    row = ROWS[row]
    if d is None or row not in d:
        return None
    objs = d[row]["objects"]
    return {"sim_ready": d[row]["summary"]["sim_ready"],
            "worst_le2": sum(o.get("worst_components", 99) <= 2 for o in objs) / max(len(objs), 1),
            "objects": len(objs)}


def measures(runs: Path, who: str) -> dict:
    """who: "candidate" or "shipped" -> {measure: value (None where the file is missing)}."""
    tail = "" if who == "candidate" else "_shipped"
    out: dict = {}
    al = _load(runs / f"text_alignment_val{tail}.json") or {}
    out["template alignment, project metric (val)"] = al.get("prompt_alignment")
    out["template alignment, strict (val)"] = al.get("alignment")
    lay = (_load(runs / f"layout_val{tail}.json") or {}).get("summary", {})
    for mode in ("raw", "refined"):
        m = lay.get(mode) or {}
        out[f"layout {mode}: box IoU mean (val)"] = m.get("iou_mean")
        out[f"layout {mode}: collapsed sibling pairs (val)"] = m.get("collapsed")
    audit = _load(runs / f"audit_{who}" / "audit.json")
    for row in ("raw", "refined"):
        a = _audit(audit, row)
        out[f"audit {row}: sim-ready"] = a and a["sim_ready"]
        out[f"audit {row}: worst part <= 2 components"] = a and a["worst_le2"]
    for name in ("freeform", "dev"):
        b = ((_load(runs / f"{name}_{who}.json") or {}).get("breakdown") or {}).get("all", {})
        out[f"{name} prompts: alignment"] = b.get("alignment")
        out[f"{name} prompts: spatial facts"] = b.get("spatial")
    bare = _load(runs / f"bare_{who}.json") or {}
    out["bare names: objects with a moving part"] = bare.get("with_moving_part")
    out["bare names: doors and drawers on the front"] = bare.get("fronts_on_front")
    return out


LOWER_IS_BETTER = ("collapsed",)
SLACK = {"audit refined: sim-ready": 0.015,
         "audit refined: worst part <= 2 components": 0.015,
         "freeform prompts: alignment": 0.01, "dev prompts: alignment": 0.01}


def verdict(c: dict, s: dict) -> tuple[bool, list[str]]:
    """The ship rule (module docstring) -> (ship, reasons it does not)."""
    why = []

    def better(key):
        return c.get(key) is not None and s.get(key) is not None and c[key] > s[key]

    def not_worse(key):
        if c.get(key) is None or s.get(key) is None:
            return False
        if any(w in key for w in LOWER_IS_BETTER):
            return c[key] <= s[key]
        return c[key] >= s[key] - SLACK.get(key, 0.0)

    for key in ("template alignment, project metric (val)", "audit raw: sim-ready"):
        if not better(key):
            why.append(f"not better: {key}")
    for key in ("audit refined: sim-ready", "audit refined: worst part <= 2 components",
                "freeform prompts: alignment", "dev prompts: alignment",
                "layout refined: collapsed sibling pairs (val)",
                "bare names: objects with a moving part",
                "bare names: doors and drawers on the front"):
        if not not_worse(key):
            why.append(f"worse: {key}")
    return not why, why


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", help="the text recipe's RUNS folder (e.g. runs/text_v5)")
    ap.add_argument("--markdown", help="also write the table to this file")
    args = ap.parse_args(argv)
    runs = Path(args.runs)
    c, s = measures(runs, "candidate"), measures(runs, "shipped")

    def fmt(v):
        return "–" if v is None else (f"{v:.3f}" if isinstance(v, float) else str(v))

    lines = ["| measure | candidate | shipped | |", "|---|---|---|---|"]
    for key in c:
        mark = ""
        if c[key] is not None and s[key] is not None and c[key] != s[key]:
            low = any(w in key for w in LOWER_IS_BETTER)
            mark = "better" if (c[key] < s[key]) == low else "worse"
        lines.append(f"| {key} | {fmt(c[key])} | {fmt(s[key])} | {mark} |")
    ship, why = verdict(c, s)
    lines.append("")
    lines.append("ship: yes" if ship else "ship: no (" + "; ".join(why) + ")")
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
