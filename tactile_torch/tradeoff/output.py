"""Writing a trade-off study: ``tradeoff.json``, ``tradeoff.md`` and the charts (drawn by :mod:`.charts`)."""

from __future__ import annotations

import json
import math
import os
import shutil
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .charts import CHARTS, charted, draw_chart, feature_family
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
    if row.get("int8_degraded"):
        text += f" (int8 loses {row['int8_loss']:.3f} against its float model, beyond its interval)"
    if row["latency_ms"] is None:
        return text
    text += f", latency {row['latency_ms']:.3g} ms"
    if row.get("touch_ms") is not None:
        text += f" ({row['touch_ms']:.3g} ms per touch at most)"
    text += f", {_size(row['size_bytes'])}, decision in {row['decision_s']:.3g} s"
    if row.get("measured_on"):
        text += f" (measured on {row['measured_on']})"
    return text


def whole_range(row: dict) -> bool:
    """Whether a row's interval (or range) is the whole [0, 1]: it says nothing about the next unit."""
    return (
        row["accuracy_low"] is not None and row["accuracy_low"] <= 5e-4 and row["accuracy_high"] >= 1 - 5e-4
    )


def why_whole_range(row: dict) -> str:
    """Why a row's interval is the whole [0, 1], in words, from its units' accuracies."""
    values = [u["accuracy"] for u in row.get("unit_accuracy") or []]
    unit, n = row["unit"], row["n_units"]
    spread = f"its {n} {unit}s score {min(values):.2f} to {max(values):.2f}" if values else f"its {n} {unit}s"
    if row["interval"] == "range":
        what = f"{spread}, and fewer than 5 {unit}s give their range, not an interval"
    else:
        what = f"{spread}: too spread for {n} {unit}s to say what a new one scores"
    return (
        f"its {'range' if row['interval'] == 'range' else '95 % interval'} is the whole [0, 1] ({what}); it is "
        f"chosen because it beats the majority class {unit} by {unit} (p = {row['baseline_p']:.2g}), not "
        f"because a new {unit} will go well: more {unit}s narrow it"
    )


def _baseline_text(result: TradeoffResult) -> str:
    base = max(result.baselines.values(), key=lambda b: b["accuracy"], default=None)
    text = f"chance {result.chance:.3f}"
    if base is not None:
        text += f", majority class {base['accuracy']:.3f}"
    return text


def incomplete_lines(result: TradeoffResult) -> list[str]:
    """One line per late stage that failed (an internal error): what is missing, and that the rest is written."""
    return [
        f"internal error in {i['stage']}: {i['error']} (that part is missing; everything else is written; "
        "please report it)"
        for i in result.incomplete
    ]


FAILURES = ("fit failed: ", "ONNX export failed: ", "no ONNX export: ")
"""How a candidate's notes begin when it could not be fitted or exported."""


def none_exported_line(result: TradeoffResult) -> str:
    """One line when no candidate could be fitted and exported: how many failed where, and the cause most
    of them share (e.g. ``windows must be finite``), so that the cause is not only in ``tradeoff.md``."""
    from collections import Counter

    fit = sum(1 for r in result.rows if r["accuracy"] is None)
    export = sum(1 for r in result.rows if r["accuracy"] is not None and r["decision_s"] is None)
    causes = Counter(
        next((n for n in r["notes"] if n.startswith(FAILURES)), "no note")
        for r in result.rows
        if r["decision_s"] is None
    )
    line = (
        f"no recommendation: no candidate could be fitted and exported ({fit} could not be fitted, {export} not "
        "exported)"
    )
    if causes:
        cause, count = causes.most_common(1)[0]
        line += f"; {'all' if count == len(result.rows) else f'{count} of {len(result.rows)}'}: {cause}"
    return line


def summary_lines(result: TradeoffResult) -> list[str]:
    """The warnings, the recommendation and the runner-up (or why there is none), one line each."""
    lines = list(result.warnings)
    if result.status == "none exported":
        return [*lines, none_exported_line(result)]
    if result.status == "none adequate":
        best = max((r for r in result.rows if r["accuracy"] is not None), key=lambda r: r["accuracy"])
        why = (
            f"no candidate's interval reaches the target {result.target:.3f}"
            if result.target is not None
            else f"no candidate is significantly above the trivial baseline ({_baseline_text(result)})"
        )
        return [*lines, f"no recommendation: {why}; the best: {describe(best)}"]
    chosen = result.row(result.recommended)
    if whole_range(chosen):  # the rule's choice, but no recommendation on this evidence alone
        lines.append(f"chosen:      {describe(chosen)}")
        lines.append(f"caution:     not a recommendation on this evidence: {why_whole_range(chosen)}")
    else:
        lines.append(f"recommended: {describe(chosen)}")
    for variant in _variants(result, chosen):
        lines.append(f"  variant:   {describe(variant)}")
    if result.runner_up is not None:
        lines.append(f"runner-up:   {describe(result.row(result.runner_up))}")
    lines.append(f"baselines:   {_baseline_text(result)}")
    for d in result.deployed:
        files = ", ".join(Path(p).name for p in (d["onnx"], d["model_file"]) if p)
        count = (
            f"all {d['samples']}"
            if d.get("available", d["samples"]) == d["samples"]
            else f"{d['samples']} of {d['available']} (evenly spaced)"
        )
        lines.append(f"deployed:    {d['name']} refitted on {count} samples: {files}")
        lines += [f"note:        {n}" for n in d["notes"]]
    return lines


def _variants(result: TradeoffResult, row: dict) -> list[dict]:
    """The other variants of ``row``'s model (its int8 copy, or its float twin), shown beside it."""
    model = row.get("variant_of") or row["name"]
    return [
        r
        for r in result.rows
        if r["name"] != row["name"]
        and (r.get("variant_of") or r["name"]) == model
        and r["decision_s"] is not None
    ]


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
    drawn = charted(result.rows, "decision_s")
    if result.rows and not drawn:  # every candidate stopped early (none can reach the target): no chart
        result.notes.append(
            "no cost charts: every candidate stopped early, so none has a full accuracy to draw"
        )
    for kind in chart_kinds(result) if drawn else []:
        try:
            paths[kind] = _chart(result, kind, out / "figures" / CHARTS[kind][0])
        except Exception as err:  # a chart that fails leaves the results (and the other charts) written
            result.mark_incomplete(f"chart {CHARTS[kind][0]}", err)
    if result.touch_time:
        from .touch_time import draw_touch_time

        try:
            paths["touch"] = draw_touch_time(
                result.touch_time,
                out / "figures" / "accuracy-vs-time-into-touch.png",
                chance=result.chance or None,
            )
        except Exception as err:  # as above: the results stay written
            result.mark_incomplete("chart accuracy-vs-time-into-touch.png", err)
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
        "units": {
            k: {
                "unit": s.unit,
                "n_units": len(np.unique(s.units)),
                "names": [s.unit_name(i) for i in np.unique(s.units)],
            }
            for k, s in result.inputs.items()
        },
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
        "complete": not result.incomplete,
        "incomplete": result.incomplete,
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
            ("chosen (interval [0, 1])" if whole_range(r) else "recommended")
            if r["name"] == result.recommended
            else "runner-up"
            if r["name"] == result.runner_up
            else f"stopped after {r['folds']} folds"
            if r.get("stopped")
            else ""
        )
        frames = any(x.get("touch_ms") is not None for x in result.rows)
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
                **(
                    {"per touch ms (at most)": r["touch_ms"] if r.get("touch_ms") is not None else "-"}
                    if frames
                    else {}
                ),
                "size": _size(r["size_bytes"]),
                "decision s": r["decision_s"] if r["decision_s"] is not None else "-",
                "Pareto": "yes" if r["pareto"] else "",
                "int8 loss": "-"
                if r.get("int8_loss") is None
                else f"{r['int8_loss']:.3f}" + (" (beyond the float interval)" if r["int8_degraded"] else ""),
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
    if result.incomplete:
        lines += [
            "**Incomplete**: a late stage failed (an internal error, please report it); the rest is below.",
            "",
        ]
        lines += [f"- {i['stage']}: {i['error']}" for i in result.incomplete] + [""]
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
        points = result.breaking_points
        lines += [
            "## Breaking points",
            "",
            "Each factor is swept with its own cross-validation (fewer folds, every sample pooled, a "
            "cluster-bootstrap interval of that accuracy), so its clean accuracy differs from the study's "
            "above (the mean over units, with the prediction interval for a new unit). A breaking point is "
            "`level [low, high]`, the ends in numeric order; an end outside the levels swept says so.",
            "",
            *_table(points.get("rows") or []),
        ]
        lines += [f"- {n}" for n in points.get("notes") or []]
        lines += [f"- not swept: {name}: {why}" for name, why in points.get("skipped") or []]
        lines += [
            f"- **failed** (a bug, please report it): {name}: {why}"
            for name, why in points.get("failed") or []
        ]
        lines.append("")
        lines += [
            f"![breaking point]({Path(p).as_posix()})" for p in result.breaking_points.get("figures") or []
        ]
        lines.append("")
    issues = grouped_notes(result.rows)
    agreement = [r for r in result.rows if r["onnx_agreement"] is not None and r["onnx_agreement"] < 1.0]
    if result.notes or issues or agreement:
        lines += ["## Notes", ""]
        lines += [f"- {n}" for n in result.notes]
        lines += [f"- {line}" for line in issues]
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


def grouped_notes(rows: list[dict]) -> list[str]:
    """The candidates' notes, each said once: ``"<note> (3 candidates: A, B, C)"`` or ``"<name>: <note>"``."""
    by_note: dict[str, list[str]] = {}
    for r in rows:
        for note in r["notes"]:
            by_note.setdefault(note, []).append(r["name"])
    out = []
    for note, names in by_note.items():
        if len(names) == 1:
            out.append(f"{names[0]}: {note}")
        else:
            shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
            out.append(f"{note} ({len(names)} candidates: {shown})")
    return out


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
    "CHARTS",
    "COST",
    "INTERVAL",
    "RULE",
    "TIMING_DIR",
    "describe",
    "draw_chart",
    "feature_family",
    "grouped_notes",
    "incomplete_lines",
    "markdown",
    "staged_output",
    "summary_lines",
    "table_rows",
    "write_outputs",
]
