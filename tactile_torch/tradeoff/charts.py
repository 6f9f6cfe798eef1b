"""The trade-off's charts: accuracy (with what the data say about a new unit) against one cost per chart.

:func:`draw_chart` is made to be read at 5 to 60 candidates: colour is the classifier, the marker the
feature family and window (:func:`feature_family`: ``21 features, W = 200`` and ``W = 800`` apart), a
hollow marker an int8 variant and a red cross on it one that lost more than its float model's interval.
The bars say what they are (the 95 % prediction interval for a new unit, or the range over the units),
the y axis spans the candidates (chance and the trivial baseline, when far below, are named in the
legend rather than drawn at the bottom of an empty plot), and candidates that share one cost (every
candidate of one window on the time-to-a-decision chart) are spread sideways in the order of their
latency, so that none hides another.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

CHARTS = {
    "latency": ("accuracy-vs-latency.png", "latency_ms", "latency of the exported ONNX pipeline, batch 1"),
    "size": ("accuracy-vs-size.png", "size_bytes", "ONNX file size"),
    "decision": ("accuracy-vs-decision.png", "decision_s", "time to a decision"),
}
"""The charts: file name, the cost field of ``tradeoff.json`` and the x axis' quantity."""
SPREAD = 0.012
"""Candidates whose costs lie closer than this share of the x axis are spread sideways."""


def feature_family(features: str) -> str:
    """The feature set's family for a chart's markers: the subset size dropped, the window kept.

    >>> feature_family("top 7 of 21, W = 800"), feature_family("21 features, W = 200"), feature_family("per-frame 1200")
    ('top k, W = 800', 'all features, W = 200', 'per-frame')
    """
    window = re.search(r"W = \d+", features)
    text = re.sub(r",?\s*W = \d+", "", features).strip()
    if text.startswith("top "):
        family = "top k"
    elif re.fullmatch(r"(all )?\d+ features", text):
        family = "all features"
    else:
        family = re.sub(r"\s*\d+$", "", text) or text
    return f"{family}, {window[0]}" if window else family


def _axis_scale(field: str, values: np.ndarray) -> tuple[float, str]:
    """Divisor and unit of the x axis: sizes in KiB or MiB, latency in ms, decision in s."""
    if field == "size_bytes":
        return (2.0**20, "MiB") if values.max() >= 2**20 else (1024.0, "KiB")
    return 1.0, "ms" if field == "latency_ms" else "s"


def what_is_drawn(rows: list[dict]) -> str:
    """One line: what a point and its bar are, in the data's unit (and the units' names when few)."""
    unit = rows[0].get("unit") or "unit"
    n = max((r.get("n_units") or 0) for r in rows)
    names = list(dict.fromkeys(u["unit"] for r in rows for u in r.get("unit_accuracy") or []))
    over = f"{n} {unit}s" if n else f"the {unit}s"
    if names and len(names) <= 6:
        over += f" ({', '.join(names)})"
    kinds = {r.get("interval") for r in rows}
    if kinds == {"range"}:
        bars = f"bar: lowest to highest {unit}"
    elif kinds == {"prediction"}:
        bars = f"bar: 95 % prediction interval for a new {unit}"
    else:
        bars = f"bar: 95 % prediction interval for a new {unit}, or the range where fewer than 5"
    return f"point: accuracy, mean over {over}; {bars}"


def spread_sideways(x: np.ndarray, order: np.ndarray, *, log: bool) -> tuple[np.ndarray, bool]:
    """Return the x positions with candidates that share a cost spread sideways, and whether any were.

    Candidates closer than :data:`SPREAD` of the axis form a group; a group's members are placed
    evenly around its mean cost in the order of ``order`` (their latency), at most half the distance to
    the next group away, so that no group reaches into another."""
    t = np.log10(x) if log else x.astype(np.float64)
    span = float(t.max() - t.min()) or max(abs(float(t.max())), 1.0) * 0.5
    ranked = np.argsort(t, kind="stable")
    groups, current = [], [ranked[0]]
    for i in ranked[1:]:
        if t[i] - t[current[-1]] < SPREAD * span:
            current.append(i)
        else:
            groups.append(current)
            current = [i]
    groups.append(current)
    centres = [float(np.mean(t[g])) for g in groups]
    out = t.copy()
    moved = False
    for k, group in enumerate(groups):
        if len(group) < 2:
            continue
        gaps = [abs(centres[k] - centres[j]) for j in (k - 1, k + 1) if 0 <= j < len(groups)]
        half = min([0.4 * g for g in gaps] + [0.006 * span * len(group)])
        members = sorted(group, key=lambda i: (order[i], i))
        out[members] = centres[k] + np.linspace(-half, half, len(members))
        moved = True
    return (10.0**out if log else out), moved


def draw_chart(  # noqa: PLR0915
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
    """Draw accuracy (with its interval or range) against one cost of ``rows`` (``tradeoff.json``'s candidates); return ``path``.

    See the module notes. The line is the Pareto front of this chart's own axes (accuracy against this
    cost, at the candidates' true costs); horizontal lines mark chance, the trivial baseline and the
    target when they lie within the candidates' accuracies. The x axis is logarithmic only when the costs
    span a decade or more, with plain tick labels. The recommended and runner-up candidates are ringed
    and named above the axes, so their labels never overlap the points or each other.
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
    x_true = raw / divisor
    log = bool(x_true.min() > 0 and x_true.max() / x_true.min() >= 10)
    latency = np.array([r.get("latency_ms") or 0.0 for r in rows])
    x, spread = spread_sideways(x_true, latency, log=log)
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
        int8 = r.get("quantisation") is not None
        ms = 5 if many else 7
        ax.plot([xi, xi], [lo, hi], "-", color=c, lw=0.8, alpha=0.35 if many else 0.6, zorder=1)
        # A filled marker's edge in its own colour, a hollow one larger with an edge thin for its size: a
        # white edge on a float plus ("P", the networks) left a thin cross, and a thick edge on an int8 plus
        # filled it, so at 5 points the two read the wrong way round.
        ax.plot(
            xi,
            a,
            m,
            color=c,
            ms=1.3 * ms if int8 else ms,
            mfc="white" if int8 else c,
            mec=c,
            mew=ms / 6 if int8 else 0.5,
            zorder=3,
        )
        if r.get("int8_degraded"):
            ax.plot(xi, a, "x", color="tab:red", ms=9 if many else 11, mew=1.6, zorder=5)
    front = np.flatnonzero(pareto_front(acc, raw))
    front = front[np.lexsort((-acc[front], x_true[front]))]
    ax.step(x_true[front], acc[front], where="post", color="0.3", lw=1.2, zorder=2)
    floor = float(low.min())
    bottom = max(0.0, floor - max(0.02, 0.08 * (1.0 - floor)))
    handles = [Line2D([], [], color="0.3", lw=1.2, label=f"Pareto front (accuracy vs {which})")]
    lines = [(chance, ":", "chance"), (baseline, "--", "majority class"), (target, "-.", "target")]
    if chance is not None and baseline is not None and abs(chance - baseline) < 5e-3:  # one line, both names
        lines = [(baseline, "--", "chance = majority class"), (target, "-.", "target")]
    for value, style, text in lines:
        if value is None:
            continue
        colour = "0.45" if text != "target" else "tab:red"
        shown = value >= bottom
        if shown:
            ax.axhline(value, ls=style, color=colour, lw=1, zorder=0)
        below = "" if shown else " (below the axis)"
        handles.append(Line2D([], [], ls=style, color=colour, label=f"{text} {value:.2f}{below}"))
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
    if any(r.get("quantisation") for r in rows):
        handles.append(
            Line2D([], [], ls="none", marker="o", mfc="white", mec="0.4", mew=1.3, label="hollow: int8")
        )
    if any(r.get("int8_degraded") for r in rows):
        handles.append(
            Line2D(
                [], [], ls="none", marker="x", color="tab:red", mew=1.6, label="int8 below its float interval"
            )
        )
    if spread:
        handles.append(
            Line2D([], [], ls="none", label="equal costs: spread sideways\nin the order of latency")
        )
    if log:
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
    ax.set_ylabel(f"accuracy (mean over {rows[0].get('unit') or 'unit'}s)")
    ax.set_ylim(bottom, 1.0 + 0.03 * (1.0 - bottom))
    ax.grid(alpha=0.3)
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.set_title("\n".join([*chosen, what_is_drawn(rows)]), fontsize=8.5, loc="left")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


__all__ = ["CHARTS", "SPREAD", "draw_chart", "feature_family", "spread_sideways", "what_is_drawn"]
