"""Writing a trade-off study: ``tradeoff.json``, ``tradeoff.md`` and the charts."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .runner import TradeoffResult

COST = (
    "decision_s: seconds of sensor data one decision needs (W / rate for vibration, the exploration's length "
    "for images, 0 for features) plus the median latency of the exported ONNX pipeline at batch 1; ties by size"
)
RULE = (
    "one-standard-error rule: the cheapest candidate (by decision_s) on the Pareto front of accuracy against "
    "decision_s whose mean fold accuracy is within one standard error of the best mean accuracy"
)
CHARTS = {
    "latency": (
        "accuracy-vs-latency.png",
        "latency_ms",
        "latency of the exported ONNX pipeline, batch 1 (ms)",
    ),
    "size": ("accuracy-vs-size.png", "size_bytes", "ONNX file size (bytes)"),
    "decision": ("accuracy-vs-decision.png", "decision_s", "time to a decision (s)"),
}


def _size(n: int | None) -> str:
    if n is None:
        return "-"
    return f"{n / 2**20:.1f} MiB" if n >= 2**20 else f"{n / 1024:.0f} KiB"


def describe(row: dict) -> str:
    """One line: a candidate's accuracy with its interval, latency, size and time to a decision."""
    return (
        f"{row['name']}: accuracy {row['accuracy']:.3f} [{row['accuracy_low']:.3f}, {row['accuracy_high']:.3f}], "
        f"latency {row['latency_ms']:.2f} ms, {_size(row['size_bytes'])}, decision in {row['decision_s']:.3g} s"
    )


def summary_lines(result: TradeoffResult) -> list[str]:
    """The recommendation and the runner-up, one line each."""
    if result.recommended is None:
        return ["no recommendation: no candidate could be exported (see the notes in tradeoff.md)"]
    lines = [f"recommended: {describe(result.row(result.recommended))}"]
    if result.runner_up is not None:
        lines.append(f"runner-up:   {describe(result.row(result.runner_up))}")
    return lines


def _chart(result: TradeoffResult, which: str, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    _, field, label = CHARTS[which]
    rows = [r for r in result.rows if r[field] is not None]
    classifiers = list(dict.fromkeys(r["classifier"] for r in rows))
    feature_names = list(dict.fromkeys(r["features"] for r in rows))
    colours = plt.get_cmap("tab10")
    markers = "osD^vP*Xhp<>"
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for r in rows:
        c = colours(classifiers.index(r["classifier"]) % 10)
        m = markers[feature_names.index(r["features"]) % len(markers)]
        err = [[r["accuracy"] - r["accuracy_low"]], [r["accuracy_high"] - r["accuracy"]]]
        ax.errorbar(r[field], r["accuracy"], yerr=err, fmt=m, color=c, ms=6, capsize=2, alpha=0.85)
    front = sorted((r for r in rows if r["pareto"]), key=lambda r: (r["decision_s"], -r["accuracy"]))
    if front:
        ax.plot(
            [r[field] for r in front],
            [r["accuracy"] for r in front],
            "-",
            color="0.35",
            lw=1,
            zorder=0,
            label="Pareto front (accuracy vs time to a decision)",
        )
    for name, style, text in ((result.recommended, "*", "recommended"), (result.runner_up, "o", "runner-up")):
        if name is None:
            continue
        r = result.row(name)
        if r[field] is None:
            continue
        ax.plot(
            r[field], r["accuracy"], style, ms=18 if style == "*" else 14, mfc="none", mec="black", mew=1.5
        )
        ax.annotate(
            f"{text}: {name}",
            (r[field], r["accuracy"]),
            xytext=(8, -14),
            textcoords="offset points",
            fontsize=7,
        )
    for i, clf in enumerate(classifiers):
        ax.plot([], [], "s", color=colours(i % 10), label=clf)
    for j, feats in enumerate(feature_names):
        ax.plot([], [], markers[j % len(markers)], color="0.5", label=feats)
    ax.set_xscale("log")
    ax.set_xlabel(label + " (log scale)")
    ax.set_ylabel("accuracy (mean over folds, 95 % interval)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=6.5, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def chart_kinds(result: TradeoffResult) -> list[str]:
    """The charts a study gets: latency and size always; time to a decision for vibration and whenever the
    candidates need different lengths of sensor data."""
    kinds = ["latency", "size"]
    acquisition = {
        round(r["decision_s"] - r["latency_ms"] / 1e3, 9) for r in result.rows if r["decision_s"] is not None
    }
    if result.data.kind == "vibration" or len(acquisition) > 1:
        kinds.append("decision")
    return kinds


def write_outputs(result: TradeoffResult, out_dir: str | Path, *, command: str = "") -> dict[str, Path]:
    """Write ``tradeoff.json``, ``tradeoff.md`` and the charts to ``out_dir``; return their paths by name."""
    from .. import __version__

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    for kind in chart_kinds(result):
        paths[kind] = _chart(result, kind, out / "figures" / CHARTS[kind][0])
    data = result.data
    doc = {
        "tactile_torch_version": __version__,
        "command": command,
        "data": {
            "description": data.description,
            "kind": data.kind,
            "classes": list(data.class_names),
            "rate_hz": data.rate_hz,
        },
        "splits": result.splits,
        "cost": COST,
        "rule": RULE,
        "candidates": result.rows,
        "recommended": result.recommended,
        "runner_up": result.runner_up,
        "study_model": result.study_model,
        "notes": result.notes,
        "seconds": result.seconds,
        "breaking_points": result.breaking_points,  # see TradeoffResult.breaking_points
    }
    paths["json"] = out / "tradeoff.json"
    paths["json"].write_text(json.dumps(doc, indent=1, default=_json_default) + "\n")
    paths["md"] = out / "tradeoff.md"
    paths["md"].write_text(
        markdown(
            result, command=command, figures={k: p.relative_to(out) for k, p in paths.items() if k in CHARTS}
        )
    )
    return paths


def _json_default(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return str(value)


def table_rows(result: TradeoffResult) -> list[dict]:
    """The candidates as report-table rows, cheapest first."""
    order = sorted(
        result.rows, key=lambda r: (r["decision_s"] is None, r["decision_s"] or 0.0, -(r["accuracy"] or 0.0))
    )
    out = []
    for r in order:
        mark = (
            "recommended"
            if r["name"] == result.recommended
            else "runner-up"
            if r["name"] == result.runner_up
            else ""
        )
        fitted = r["accuracy"] is not None
        out.append(
            {
                "candidate": r["name"],
                "accuracy": r["accuracy"] if fitted else "fit failed",
                "95 % interval": f"[{r['accuracy_low']:.3f}, {r['accuracy_high']:.3f}]" if fitted else "-",
                "fit s": r["fit_s"] if fitted else "-",
                "of it tuning s": r.get("tune_s") if fitted and r.get("tune_s") is not None else "-",
                "latency ms": r["latency_ms"] if r["latency_ms"] is not None else "-",
                "size": _size(r["size_bytes"]),
                "decision s": r["decision_s"] if r["decision_s"] is not None else "-",
                "Pareto": "yes" if r["pareto"] else "",
                "choice": mark,
            }
        )
    return out


def _table(rows: list[dict]) -> list[str]:
    """Markdown lines of a table given as dicts (columns: every key, in order of appearance)."""
    if not rows:
        return []
    columns = list(dict.fromkeys(k for r in rows for k in r))
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for r in rows:
        cells = (r.get(c, "") for c in columns)
        lines.append(
            "| "
            + " | ".join(
                format(v, ".4g") if isinstance(v, float) else str(v).replace("|", "\\|") for v in cells
            )
            + " |"
        )
    return [*lines, ""]


def markdown(result: TradeoffResult, *, command: str = "", figures: dict[str, Path] | None = None) -> str:
    """Return ``tradeoff.md``."""
    lines = ["# Speed against accuracy: which model this data needs", ""]
    if command:
        lines += ["Written by:", "", f"```\n{command}\n```", ""]
    lines += [f"Data: {result.data.description}.", ""]
    lines += [f"- `{key}`: {split}" for key, split in result.splits.items()]
    lines += ["", *(f"**{line}**  " for line in summary_lines(result))]
    if result.study_model is not None and result.row(result.study_model)["decision_s"] is not None:
        lines.append(f"the study's model: {describe(result.row(result.study_model))}")
    lines.append("")
    lines += [f"Cost: {COST}.", "", f"Rule: {RULE} (docs/tradeoff.md says why).", ""]
    lines += _table(table_rows(result))
    for kind, rel in (figures or {}).items():
        lines += [f"![accuracy vs {kind}]({rel.as_posix()})", ""]
    if result.breaking_points:
        lines += ["## Breaking points", "", *_table(result.breaking_points.get("rows") or [])]
        lines += [
            f"![breaking point]({Path(p).as_posix()})" for p in result.breaking_points.get("figures") or []
        ]
        lines.append("")
    issues = [(r["name"], n) for r in result.rows for n in r["notes"]]
    agreement = [r for r in result.rows if r["onnx_agreement"] is not None and r["onnx_agreement"] < 1.0]
    if result.notes or issues or agreement:
        lines += ["## Notes", ""]
        lines += [f"- {n}" for n in result.notes]
        lines += [f"- {name}: {n}" for name, n in issues]
        lines += [
            f"- {r['name']}: the ONNX file's labels agree with the pipeline's on {r['onnx_agreement']:.1%} of the "
            "held-out samples checked"
            for r in agreement
        ]
        lines.append("")
    lines.append(
        f"_{len(result.rows)} candidates in {result.seconds:.0f} s ({result.exports} ONNX exports)._"
    )
    return "\n".join(lines) + "\n"


__all__ = ["COST", "RULE", "describe", "markdown", "summary_lines", "table_rows", "write_outputs"]
