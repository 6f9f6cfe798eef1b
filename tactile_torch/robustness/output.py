"""A sweep as a table (:func:`breaking_table`) and as files: charts and rows (:func:`breaking_summary`),
and ``breaking_points.md`` / ``.json`` (:func:`write_breaking_points`)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from .charts import plot_factor
from .results import Curve, SweepResult


def breaking_table(curves: Iterable[Curve]) -> list[dict[str, Any]]:
    """Return one row per curve: factor, model, clean accuracy with its interval, the halfway
    threshold, the breaking level with its 95 % interval, and a note."""
    return [
        {
            "factor": c.factor.name,
            "model": c.model,
            "clean accuracy [95 % CI]": f"{c.clean:.3f} [{c.clean_low:.3f}, {c.clean_high:.3f}]",
            "halfway to chance": round(c.breaking.threshold, 3),
            "breaks at [95 % CI]": c.breaking.text,
            "note": c.note,
        }
        for c in curves
    ]


def breaking_summary(result: SweepResult | Sequence[Curve], out_dir: str | Path) -> dict[str, Any]:
    """Write one chart per factor to ``out_dir`` (``breaking-<factor>.png``) and return
    ``{"rows": breaking_table(...), "figures": [paths], "skipped": [...], "failed": [...]}``: what a results file such as
    ``tactile-torch tradeoff``'s ``tradeoff.json`` / ``tradeoff.md`` holds about breaking points."""
    import matplotlib.pyplot as plt

    if not isinstance(result, SweepResult):
        result = SweepResult(curves=list(result))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = []
    for name, curves in result.by_factor().items():
        slug = "".join(ch if ch.isalnum() else "-" for ch in name.lower()).strip("-")
        fig = plot_factor(curves)
        figures.append(out / f"breaking-{slug}.png")
        fig.savefig(figures[-1], dpi=110, bbox_inches="tight")
        plt.close(fig)
    return {
        "rows": breaking_table(result.curves),
        "figures": [str(p) for p in figures],
        "skipped": [list(s) for s in result.skipped],
        "failed": [list(s) for s in result.failed],
    }


def write_breaking_points(
    result: SweepResult | Sequence[Curve], out_dir: str | Path, *, title: str = "Breaking points"
) -> Path:
    """Write a sweep's table and charts to ``out_dir``; return the path of the markdown file.

    ``result`` is a :class:`SweepResult` or the curves of :func:`breaking_points`. Writes
    ``breaking_points.md`` (the table of :func:`breaking_table`, the skipped factors and one chart per
    factor, see :func:`breaking_summary`), ``breaking_points.json`` (every curve: levels, accuracies,
    intervals, breaking point) and ``breaking-<factor>.png``.
    """
    import json

    if not isinstance(result, SweepResult):
        result = SweepResult(curves=list(result))
    out = Path(out_dir)
    summary = breaking_summary(result, out)
    rows = summary["rows"]
    columns = list(rows[0]) if rows else []
    folds = f"{result.n_splits} grouped folds; " if result.n_splits else ""
    lines = [f"# {title}", "", f"{folds}95 % cluster-bootstrap intervals.", ""]
    if rows:
        lines += ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
        lines += ["| " + " | ".join(str(r[c]).replace("|", "\\|") for c in columns) + " |" for r in rows]
    lines += [""] + [f"- not swept: {name} ({why})" for name, why in result.skipped]
    lines += [f"- **failed** (a bug, please report it): {name}: {why}" for name, why in result.failed]
    lines += ["", *(f"![{Path(p).stem}]({Path(p).name})" for p in summary["figures"])]
    md = out / "breaking_points.md"
    md.write_text("\n".join(lines) + "\n")
    curves = [
        {
            "factor": c.factor.name,
            "unit": c.factor.unit,
            "model": c.model,
            "levels": [list(v) if isinstance(v, tuple) else v for v in c.levels],
            "accuracy": c.accuracy.tolist(),
            "low": c.low.tolist(),
            "high": c.high.tolist(),
            "clean": [c.clean, c.clean_low, c.clean_high],
            "chance": c.chance,
            "breaking": {
                "status": c.breaking.status,
                "text": c.breaking.text,
                "level": c.breaking.level,
                "threshold": c.breaking.threshold,
            },
            "note": c.note,
        }
        for c in result.curves
    ]
    (out / "breaking_points.json").write_text(
        json.dumps({"curves": curves, "skipped": result.skipped, "failed": result.failed}, indent=1)
    )
    return md
