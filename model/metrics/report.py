"""Markdown tables and PNG figures of `artformer eval` / `artformer bench` results."""
from __future__ import annotations

import logging
from pathlib import Path

log = logging.getLogger(__name__)


def _f(x, scale: float = 1.0, digits: int = 4) -> str:
    return "–" if x is None else f"{x * scale:.{digits}f}"


def results_markdown(results: dict) -> str:
    """The results table (ours and baselines, then the published anchors)."""
    cfg = results.get("config", {})
    lines = [
        f"Prompts: {results['n_test']} test-split descriptions + {results['n_freeform']} "
        f"free-form. ID: {results.get('id_poses')} poses × {results.get('id_points')} points, "
        f"Chamfer in m². POR over {cfg.get('por_states')} openness states.",
        "",
        "| method | POR ×10⁻² ↓ | POR max ×10⁻² | MMD ↓ | COV ↑ | 1-NNA (0.5 best) | "
        "align test ↑ | align free ↑ | diversity ↑ | validity ↑ | failed |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results["rows"]:
        lines.append("| " + " | ".join([
            r["name"], _f(r.get("por"), 100, 3), _f(r.get("por_max"), 100, 3),
            _f(r.get("mmd")), _f(r.get("cov"), 1, 3), _f(r.get("nna"), 1, 3),
            _f(r.get("alignment_test"), 1, 3), _f(r.get("alignment_freeform"), 1, 3),
            _f(r.get("diversity")), _f(r.get("validity"), 1, 3),
            f"{r.get('n_failed', 0)}/{r.get('n_prompts', 0)}"]) + " |")
    for name, p in results.get("published", {}).items():
        lines.append("| " + " | ".join([
            f"*{name}*", _f(p.get("por"), 100, 3), "–", _f(p.get("mmd")), _f(p.get("cov"), 1, 4),
            _f(p.get("nna"), 1, 4), "–", "–", "–", "–", "–"]) + " |")
    for sk in results.get("skipped_rows", []):
        lines.append(f"\nSkipped: {sk}.")
    lines.append("")
    lines.append("Published anchors are on PartNet-Mobility with the authors' scale "
                 "normalisation; ours are on the procedural dataset in metres — compare "
                 "orders of magnitude and rankings, not digits.")
    return "\n".join(lines) + "\n"


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _bars(ax, names, vals, title, anchors=None, ylabel=""):
    xs = list(range(len(names)))
    bars = ax.bar(xs, [0 if v is None else v for v in vals], color="#4c72b0")
    ax.bar_label(bars, labels=["" if v is None else f"{v:.3g}" for v in vals], fontsize=6)
    for x, v in zip(xs, vals):
        if v is None:
            ax.text(x, 0, "n/a", ha="center", va="bottom", fontsize=7)
    for (label, val), style in zip((anchors or {}).items(), ("--", ":", "-.")):
        if val is not None:
            ax.axhline(val, color="#c44e52", ls=style, lw=1, label=label)
    ax.set_xticks(xs)
    ax.set_xticklabels(names, rotation=30, ha="right", fontsize=7)
    ax.set_title(title, fontsize=9)
    ax.set_ylabel(ylabel, fontsize=8)
    ax.tick_params(axis="y", labelsize=7)
    if anchors:
        ax.legend(fontsize=6)


def results_plots(results: dict, out_dir) -> list[str]:
    """One PNG per DESIGN §7 metric; returns the file paths."""
    plt = _plt()
    out_dir = Path(out_dir)
    rows = results["rows"]
    names = [r["name"] for r in rows]
    pub = results.get("published", {})
    files = []

    def save(fig, name):
        path = out_dir / name
        fig.tight_layout()
        fig.savefig(path, dpi=90)
        plt.close(fig)
        files.append(str(path))

    fig, ax = plt.subplots(figsize=(5, 3.2))
    _bars(ax, names, [None if r.get("por") is None else r["por"] * 100 for r in rows],
          "Part Overlapping Ratio (lower is better)",
          {f"{k} {v['por'] * 100:.3f}": v["por"] * 100 for k, v in pub.items() if "por" in v},
          "POR ×10⁻²")
    save(fig, "por.png")

    fig, axes = plt.subplots(1, 3, figsize=(9, 3.2))
    for ax, key, title in zip(axes, ("mmd", "cov", "nna"),
                              ("MMD ↓ (ID)", "COV ↑", "1-NNA (0.5 best)")):
        keep = [r for r in rows if r.get(key) is not None]
        anchors = {f"{k} {v[key]:.4f}": v[key] for k, v in pub.items() if key in v}
        if key == "nna":
            anchors["ideal 0.5"] = 0.5
        _bars(ax, [r["name"] for r in keep], [r[key] for r in keep], title, anchors)
    save(fig, "id_set_metrics.png")

    fig, ax = plt.subplots(figsize=(5, 3.2))
    keep = [r for r in rows if r.get("alignment") is not None]
    xs = range(len(keep))
    w = 0.38
    ax.bar([x - w / 2 for x in xs], [r.get("alignment_test") or 0 for r in keep], w,
           label="test prompts", color="#4c72b0")
    ax.bar([x + w / 2 for x in xs], [r.get("alignment_freeform") or 0 for r in keep], w,
           label="free-form prompts", color="#55a868")
    ax.set_xticks(list(xs))
    ax.set_xticklabels([r["name"] for r in keep], rotation=30, ha="right", fontsize=7)
    ax.set_ylim(0, 1)
    ax.set_title("Alignment: share of prompts with the structure asked for", fontsize=9)
    ax.legend(fontsize=7)
    save(fig, "alignment.png")

    fig, ax = plt.subplots(figsize=(5, 3.2))
    keep = [r for r in rows if r.get("diversity") is not None]
    _bars(ax, [r["name"] for r in keep], [r["diversity"] for r in keep],
          "Diversity: mean pairwise ID among samples of a prompt", ylabel="ID (m²)")
    save(fig, "diversity.png")

    fig, ax = plt.subplots(figsize=(5, 3.2))
    keep = [r for r in rows if r.get("validity") is not None]
    _bars(ax, [r["name"] for r in keep], [r["validity"] for r in keep],
          "Validity: loads in yourdfpy + pybullet + MuJoCo, joints move")
    ax.set_ylim(0, 1.05)
    save(fig, "validity.png")
    return files


def bench_markdown(bench: dict) -> str:
    kind = bench.get("requests", "prompts")
    lines = [f"{bench['n']} {kind}, checkpoint `{bench.get('checkpoint') or 'shipped'}`, "
             f"{bench.get('threads')} threads, {bench.get('cpu', '')}", "",
             "| stage | median s | p95 s | mean s |", "|---|---|---|---|"]
    for stage, s in bench["stages"].items():
        lines.append(f"| {stage} | {s['median']:.3f} | {s['p95']:.3f} | {s['mean']:.3f} |")
    by = bench.get("to_urdf_by_parts") or {}
    if by:
        lines.append("")
        lines.append(("Image" if kind == "images" else "Text")
                     + " -> URDF + meshes on disk (`to_urdf`), median by part count: "
                     + ", ".join(f"{k} parts {v['to_urdf_median']:.2f} s (n={v['n']})"
                                 for k, v in by.items()) + ".")
    lines.append("")
    lines.append(f"Model load: {bench['load_seconds']:.2f} s. Peak memory (RSS high-water "
                 f"mark of the benchmark process): {bench['peak_rss_mb']:.0f} MB "
                 f"(after load: {bench.get('rss_after_load_mb', 0):.0f} MB).")
    if bench.get("mesh_workers"):
        lines.append(f"Meshing helpers: {bench['mesh_workers']}, peak "
                     f"{bench.get('helpers_peak_rss_mb', 0):.0f} MB together; with the "
                     f"benchmark process {bench['peak_rss_mb'] + bench.get('helpers_peak_rss_mb', 0):.0f} MB.")
    return "\n".join(lines) + "\n"
