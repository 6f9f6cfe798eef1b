"""Writing a trade-off study: ``tradeoff.json``, ``tradeoff.md`` and the charts."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .summary import TradeoffResult

COST = (
    "decision_s: seconds of sensor data one decision needs (W / rate for vibration, the exploration's length "
    "for images, 0 for features) plus the median latency of the exported ONNX pipeline at batch 1; ties by size"
)
RULE = (
    "with target=ACC: the cheapest candidate (by decision_s) whose interval's lower end reaches ACC; without: "
    "the cheapest candidate on the Pareto front of accuracy against decision_s whose mean accuracy over units is "
    "within one standard error of the best, among those significantly above the trivial baseline (majority "
    "class); none: no recommendation"
)
INTERVAL = (
    "accuracy = mean over the data's units (session, recording, group, time block or fold); interval = 95 % "
    "prediction interval for the accuracy on one new unit, mean +- t(g-1) s sqrt(1 + 1/g) over the g units' "
    "out-of-fold accuracies; with fewer than 5 units the range over the units instead"
)
CHARTS = {
    "latency": ("accuracy-vs-latency.png", "latency_ms", "latency of the exported ONNX pipeline, batch 1"),
    "size": ("accuracy-vs-size.png", "size_bytes", "ONNX file size"),
    "decision": ("accuracy-vs-decision.png", "decision_s", "time to a decision"),
}
TIMING_DIR = "timing"
"""Where the per-candidate ONNX files go: fitted on the first training fold, for latency and size only."""


def _size(n: int | None) -> str:
    if n is None:
        return "-"
    return f"{n / 2**20:.1f} MiB" if n >= 2**20 else f"{n / 1024:.0f} KiB"


def _interval_text(row: dict) -> str:
    if row["interval"] == "range":
        return f"range over {row['n_units']} {row['unit']}s [{row['accuracy_low']:.3f}, {row['accuracy_high']:.3f}]"
    return f"95 % interval for a new {row['unit']} [{row['accuracy_low']:.3f}, {row['accuracy_high']:.3f}]"


def describe(row: dict) -> str:
    """One line: a candidate's accuracy with its interval (and unit), latency, size and time to a decision."""
    text = f"{row['name']}: accuracy {row['accuracy']:.3f}, {_interval_text(row)}"
    if row["latency_ms"] is None:
        return text
    return f"{text}, latency {row['latency_ms']:.2f} ms, {_size(row['size_bytes'])}, decision in {row['decision_s']:.3g} s"


def _baseline_text(result: TradeoffResult) -> str:
    base = max(result.baselines.values(), key=lambda b: b["accuracy"], default=None)
    text = f"chance {result.chance:.3f}"
    if base is not None:
        text += f", majority class {base['accuracy']:.3f}"
    return text


def summary_lines(result: TradeoffResult) -> list[str]:
    """The warnings, the recommendation and the runner-up (or why there is none), one line each."""
    lines = list(result.warnings)
    if result.status == "none exported":
        failed = sum(1 for r in result.rows if r["accuracy"] is not None and r["decision_s"] is None)
        return [
            *lines,
            f"no recommendation: no candidate could be fitted and exported ({failed} export failures; the notes "
            "in tradeoff.md say why)",
        ]
    if result.status == "none adequate":
        best = max((r for r in result.rows if r["accuracy"] is not None), key=lambda r: r["accuracy"])
        why = (
            f"no candidate's interval reaches the target {result.target:.3f}"
            if result.target is not None
            else f"no candidate is significantly above the trivial baseline ({_baseline_text(result)})"
        )
        return [*lines, f"no recommendation: {why}; the best: {describe(best)}"]
    lines.append(f"recommended: {describe(result.row(result.recommended))}")
    if result.runner_up is not None:
        lines.append(f"runner-up:   {describe(result.row(result.runner_up))}")
    lines.append(f"baselines:   {_baseline_text(result)}")
    for d in result.deployed:
        files = ", ".join(Path(p).name for p in (d["onnx"], d["model_file"]) if p)
        lines.append(f"deployed:    {d['name']} refitted on all {d['samples']} samples: {files}")
        lines += [f"note:        {n}" for n in d["notes"]]
    return lines


def feature_family(features: str) -> str:
    """The feature set's family for a chart's markers: sizes and window lengths dropped.

    >>> feature_family("top 7 of 21, W = 800"), feature_family("21 features, W = 200"), feature_family("per-frame 1200")
    ('top k', 'all features', 'per-frame')
    """
    text = re.sub(r",?\s*W = \d+", "", features).strip()
    if text.startswith("top "):
        return "top k"
    if re.fullmatch(r"(all )?\d+ features", text):
        return "all features"
    return re.sub(r"\s*\d+$", "", text) or text


def _axis_scale(field: str, values: np.ndarray) -> tuple[float, str]:
    """Divisor and unit of the x axis: sizes in KiB or MiB, latency in ms, decision in s."""
    if field == "size_bytes":
        return (2.0**20, "MiB") if values.max() >= 2**20 else (1024.0, "KiB")
    return 1.0, "ms" if field == "latency_ms" else "s"


def draw_chart(
    rows: list[dict],
    which: str,
    path: str | Path,
    *,
    recommended: str | None = None,
    runner_up: str | None = None,
    chance: float | None = None,
    baseline: float | None = None,
    target: float | None = None,
) -> Path:
    """Draw accuracy (with its interval) against one cost of ``rows`` (``tradeoff.json``'s candidates); return ``path``.

    Colour is the classifier, the marker the feature family (:func:`feature_family`); the line is the
    Pareto front of this chart's own axes (accuracy against this cost); horizontal lines mark chance,
    the trivial baseline and the target. The x axis is logarithmic only when the costs span a decade
    or more, with plain tick labels. The recommended and runner-up candidates are ringed and named
    under the axes, so their labels never overlap the points or each other.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator

    from .selection import pareto_front

    _, field, label = CHARTS[which]
    rows = [r for r in rows if r.get(field) is not None and r.get("accuracy") is not None]
    if not rows:
        raise ValueError(f"no candidate has a {field} to chart")
    raw = np.array([r[field] for r in rows], dtype=np.float64)
    divisor, unit = _axis_scale(field, raw)
    x = raw / divisor
    acc = np.array([r["accuracy"] for r in rows])
    low = np.array([r["accuracy_low"] for r in rows])
    high = np.array([r["accuracy_high"] for r in rows])
    classifiers = list(dict.fromkeys(r["classifier"] for r in rows))
    families = list(dict.fromkeys(feature_family(r["features"]) for r in rows))
    colours = plt.get_cmap("tab10")
    markers = "osD^vPXh<>"
    many = len(rows) > 15
    fig, ax = plt.subplots(figsize=(8.0, 5.0))
    for r, xi, a, lo, hi in zip(rows, x, acc, low, high, strict=True):
        c = colours(classifiers.index(r["classifier"]) % 10)
        m = markers[families.index(feature_family(r["features"])) % len(markers)]
        ax.plot([xi, xi], [lo, hi], "-", color=c, lw=0.8, alpha=0.35 if many else 0.6, zorder=1)
        ax.plot(xi, a, m, color=c, ms=5 if many else 7, mec="white", mew=0.5, zorder=3)
    front = np.flatnonzero(pareto_front(acc, raw))
    front = front[np.lexsort((-acc[front], x[front]))]
    ax.step(x[front], acc[front], where="post", color="0.3", lw=1.2, zorder=2)
    handles = [Line2D([], [], color="0.3", lw=1.2, label=f"Pareto front (accuracy vs {which})")]
    lines = [(chance, ":", "chance"), (baseline, "--", "majority class"), (target, "-.", "target")]
    if chance is not None and baseline is not None and abs(chance - baseline) < 5e-3:  # one line, both names
        lines = [(baseline, "--", "chance = majority class"), (target, "-.", "target")]
    for value, style, text in lines:
        if value is not None:
            ax.axhline(value, ls=style, color="0.45" if text != "target" else "tab:red", lw=1, zorder=0)
            handles.append(
                Line2D(
                    [],
                    [],
                    ls=style,
                    color="0.45" if text != "target" else "tab:red",
                    label=f"{text} {value:.2f}",
                )
            )
    chosen = []
    for name, ring, text in ((recommended, 16, "recommended"), (runner_up, 12, "runner-up")):
        hit = [i for i, r in enumerate(rows) if r["name"] == name]
        if not hit:
            continue
        i = hit[0]
        ax.plot(
            x[i],
            acc[i],
            "o",
            ms=ring,
            mfc="none",
            mec="black",
            mew=1.6 if text == "recommended" else 1.0,
            zorder=4,
        )
        chosen.append(f"{text} ({'thick' if text == 'recommended' else 'thin'} ring): {name}, {acc[i]:.3f}")
    handles += [
        Line2D([], [], ls="none", marker="s", color=colours(i % 10), label=clf)
        for i, clf in enumerate(classifiers)
    ]
    handles += [
        Line2D([], [], ls="none", marker=markers[j % len(markers)], color="0.4", label=f)
        for j, f in enumerate(families)
    ]
    spread = x.max() / max(x.min(), 1e-12)
    if x.min() > 0 and spread >= 10:
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_minor_locator(LogLocator(subs="auto"))
        ax.xaxis.set_minor_formatter(FuncFormatter(lambda v, _: ""))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    else:
        ax.xaxis.set_major_locator(MaxNLocator(6, steps=[1, 2, 2.5, 5, 10]))
        pad = (x.max() - x.min()) * 0.08 or max(x.max() * 0.05, 1e-3)
        ax.set_xlim(max(0.0, x.min() - pad), x.max() + pad)
    ax.set_xlabel(f"{label} ({unit})")
    ax.set_ylabel(f"accuracy (mean over {rows[0].get('unit') or 'unit'}s, 95 % interval)")
    floor = min(low.min(), chance if chance is not None else 1.0)
    ax.set_ylim(max(0.0, floor - 0.05), 1.02)
    ax.grid(alpha=0.3)
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    if chosen:
        ax.set_title("\n".join(chosen), fontsize=8.5, loc="left")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def _chart(result: TradeoffResult, which: str, path: Path) -> Path:
    base = max((b["accuracy"] for b in result.baselines.values()), default=None)
    return draw_chart(
        result.rows,
        which,
        path,
        recommended=result.recommended,
        runner_up=result.runner_up,
        chance=result.chance or None,
        baseline=base,
        target=result.target,
    )


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
    for kind in chart_kinds(result) if any(r["decision_s"] is not None for r in result.rows) else []:
        paths[kind] = _chart(result, kind, out / "figures" / CHARTS[kind][0])
    if result.touch_time:
        from .touch_time import draw_touch_time

        paths["touch"] = draw_touch_time(
            result.touch_time,
            out / "figures" / "accuracy-vs-time-into-touch.png",
            chance=result.chance or None,
        )
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
        "units": {k: {"unit": s.unit, "n_units": len(np.unique(s.units))} for k, s in result.inputs.items()},
        "interval": INTERVAL,
        "cost": COST,
        "rule": RULE,
        "target": result.target,
        "chance": result.chance,
        "baselines": result.baselines,
        "candidates": result.rows,
        "status": result.status,
        "recommended": result.recommended,
        "runner_up": result.runner_up,
        "deployed": _relative(result.deployed, out),
        "timing_files": f"{TIMING_DIR}/: each candidate fitted on the first training fold, for latency and size "
        "only; not for deployment",
        "warnings": result.warnings,
        "study_model": result.study_model,
        "notes": result.notes,
        "seconds": result.seconds,
        "breaking_points": result.breaking_points,  # see TradeoffResult.breaking_points
        "accuracy_vs_time": [c.to_json() for c in result.touch_time.values()],  # frame data (.touch_time)
    }
    paths["json"] = out / "tradeoff.json"
    paths["json"].write_text(json.dumps(doc, indent=1, default=_json_default) + "\n")
    paths["md"] = out / "tradeoff.md"
    paths["md"].write_text(
        markdown(
            result,
            command=command,
            figures={k: p.relative_to(out) for k, p in paths.items() if k in CHARTS or k == "touch"},
        )
    )
    return paths


def _relative(deployed: list[dict], out: Path) -> list[dict]:
    return [
        {k: Path(v).name if k in ("onnx", "model_file") and v else v for k, v in d.items()} for d in deployed
    ]


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
        interval = "-"
        if fitted:
            kind = "range" if r["interval"] == "range" else "95 %"
            interval = f"{kind} [{r['accuracy_low']:.3f}, {r['accuracy_high']:.3f}] per {r['unit']}"
        out.append(
            {
                "candidate": r["name"],
                "accuracy": r["accuracy"] if fitted else "fit failed",
                "interval (unit)": interval,
                "above baseline": "-"
                if r["above_baseline"] is None
                else ("yes" if r["above_baseline"] else "no"),
                "fit s": r["fit_s"] if fitted else "-",
                "of it tuning s": r.get("tune_s") if fitted and r.get("tune_s") is not None else "-",
                "latency ms": r["latency_ms"] if r["latency_ms"] is not None else "-",
                "size": _size(r["size_bytes"]),
                "decision s": r["decision_s"] if r["decision_s"] is not None else "-",
                "Pareto": "yes" if r["pareto"] else "",
                "choice": mark,
            }
        )
    for key, b in result.baselines.items():
        kind = "range" if b["interval"] == "range" else "95 %"
        out.append(
            {
                "candidate": f"trivial baseline: majority class ({key})",
                "accuracy": b["accuracy"],
                "interval (unit)": f"{kind} [{b['accuracy_low']:.3f}, {b['accuracy_high']:.3f}] per {b['unit']}",
            }
        )
    out.append({"candidate": "chance (1 / classes)", "accuracy": result.chance})
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
    lines += [
        f"Accuracy: {INTERVAL}.",
        "",
        f"Cost: {COST}.",
        "",
        f"Rule: {RULE} (docs/tradeoff.md says why).",
        "",
    ]
    lines += [
        f"`{TIMING_DIR}/*.onnx`: each candidate fitted on the first training fold, for its latency and size only (not "
        "for deployment); `recommended.onnx` is the recommended candidate refitted on all the data.",
        "",
    ]
    lines += _table(table_rows(result))
    figures = dict(figures or {})
    touch = figures.pop("touch", None)
    for kind, rel in figures.items():
        lines += [f"![accuracy vs {kind}]({rel.as_posix()})", ""]
    if result.touch_time:
        from .touch_time import touch_time_markdown

        lines += touch_time_markdown(result.touch_time, None if touch is None else touch.as_posix())
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


STAGING = ".{name}.partial-{pid}"
"""Name of the directory a run writes into, next to ``--out``, before it is moved into place."""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, not ours
        return True
    return True


@contextmanager
def staged_output(out_dir: str | Path):
    """Yield a fresh directory next to ``out_dir``; on success move it into place as ``out_dir``.

    Everything a run writes goes to the staging directory; only when the block ends without an
    error does it replace ``out_dir`` (the previous result is moved aside, then removed), so a run that
    is killed or fails leaves the previous result intact (or nothing, if there was none), never a mix.
    A failed run removes its staging directory; one left by a killed run is removed by the next run
    into the same ``out_dir`` (when its process is gone).
    """
    out = Path(out_dir).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    for stale in out.parent.glob(f".{out.name}.partial-*"):
        tail = stale.name.rsplit("-", 1)[-1]
        if tail.isdigit() and not _alive(int(tail)):
            shutil.rmtree(stale, ignore_errors=True)
    staging = out.parent / STAGING.format(name=out.name, pid=os.getpid())
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    try:
        yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    old = out.parent / f".{out.name}.previous-{os.getpid()}"
    if out.exists():
        if not out.is_dir():
            shutil.rmtree(staging, ignore_errors=True)
            raise ValueError(f"out: {out} exists and is not a directory")
        out.rename(old)
    staging.rename(out)
    shutil.rmtree(old, ignore_errors=True)


__all__ = [
    "COST",
    "INTERVAL",
    "RULE",
    "TIMING_DIR",
    "describe",
    "draw_chart",
    "feature_family",
    "markdown",
    "staged_output",
    "summary_lines",
    "table_rows",
    "write_outputs",
]
