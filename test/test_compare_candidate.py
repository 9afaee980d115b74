"""scripts/compare_candidate.py: the ship rule over the text recipe's validation files."""
import importlib.util
import json
from pathlib import Path

from model.metrics.audit_eval import ROWS

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("compare_candidate",
                                                  ROOT / "scripts" / "compare_candidate.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _write(runs: Path, who: str, align: float, raw: float, refined: float, collapsed: int):
    tail = "" if who == "candidate" else "_shipped"
    (runs / f"text_alignment_val{tail}.json").write_text(
        json.dumps({"prompt_alignment": align, "alignment": align - 0.05}))
    (runs / f"layout_val{tail}.json").write_text(json.dumps({"summary": {
        m: {"iou_mean": 0.2, "collapsed": collapsed} for m in ("raw", "refined")}}))
    (runs / f"audit_{who}").mkdir()
    objs = [{"worst_components": 1}] * 95 + [{"worst_components": 4}]
    (runs / f"audit_{who}" / "audit.json").write_text(json.dumps({   # keyed as eval audit's
        ROWS[row]: {"summary": {"sim_ready": v}, "objects": objs}
        for row, v in (("raw", raw), ("refined", refined))}))
    for name in ("freeform", "dev"):
        (runs / f"{name}_{who}.json").write_text(json.dumps(
            {"breakdown": {"all": {"alignment": 0.95, "spatial": 0.9}}}))
    (runs / f"bare_{who}.json").write_text(json.dumps({"with_moving_part": 1.0,
                                                       "fronts_on_front": 1.0}))


def test_the_ship_rule_wants_better_alignment_and_raw_audit_and_no_worse_refined(tmp_path):
    mod = _script()
    _write(tmp_path, "candidate", 0.90, 0.30, 0.97, 5)
    _write(tmp_path, "shipped", 0.85, 0.05, 0.979, 11)
    c, s = mod.measures(tmp_path, "candidate"), mod.measures(tmp_path, "shipped")
    assert c["audit refined: worst part <= 2 components"] == 95 / 96
    assert mod.verdict(c, s) == (True, [])          # refined 0.97 is within 1.5 points
    c["audit refined: sim-ready"] = 0.95             # 2.9 points fewer
    c["layout refined: collapsed sibling pairs (val)"] = 12
    ship, why = mod.verdict(c, s)
    assert not ship and why == ["worse: audit refined: sim-ready",
                                "worse: layout refined: collapsed sibling pairs (val)"]
    c["audit refined: sim-ready"] = 0.97
    c["layout refined: collapsed sibling pairs (val)"] = 5
    c["audit refined: worst part <= 2 components"] = 90 / 96     # five objects more shredded
    c["bare names: objects with a moving part"] = 0.5            # "a cabinet": an empty box
    c["bare names: doors and drawers on the front"] = 0.6        # ... or its doors below it
    assert mod.verdict(c, s)[1] == ["worse: audit refined: worst part <= 2 components",
                                    "worse: bare names: objects with a moving part",
                                    "worse: bare names: doors and drawers on the front"]
    c["template alignment, project metric (val)"] = None     # a missing file never ships
    assert "not better: template alignment, project metric (val)" in mod.verdict(c, s)[1]
    assert mod.main([str(tmp_path)]) == 0
