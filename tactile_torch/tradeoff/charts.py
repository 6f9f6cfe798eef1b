"""The trade-off's charts: accuracy (with what the data say about a new unit) against one cost per chart.

:func:`draw_chart` is made to be read at 5 to 60 candidates: colour is the classifier, the marker the
feature family, window and subset size (:func:`feature_family`: ``21 features, W = 200`` and ``W = 800``
apart, ``top 3`` and ``top 7`` apart), a hollow marker an int8 variant and a red cross on it one that
lost more than its float model's interval. Every point sits at its measured cost: candidates that share
one (every candidate of one window on the time-to-a-decision chart, the ones behind one large feature
graph on the size chart) are shown side by side in a zoomed panel of that range (:func:`dense_ranges`:
up to :data:`ZOOMS`), never moved. Interval bars are drawn where they tell something, for the Pareto
front and the two chosen candidates (the 95 % prediction interval for a new unit, or the range over the
units); the y axis spans them (chance and the trivial baseline, when far below, are named in the legend
rather than drawn at the bottom of an empty plot). The recommended candidate is ringed, the runner-up
boxed: two shapes that stay apart when the points are close.
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
DENSE = 0.03
"""Candidates whose costs lie within this share of the x axis form a dense range..."""
DENSE_MIN = 5
"""...when there are at least this many of them: the range gets a zoomed panel."""
ZOOMS = 2
"""At most this many zoomed panels per chart (the densest ranges)."""


def feature_family(features: str) -> str:
    """The feature set's family for a chart's markers: the subset size dropped, the window kept.

    >>> feature_family("top 7 of 21, W = 800"), feature_family("21 features, W = 200"), feature_family("per-frame 1200")
    ('top 7, W = 800', 'all features, W = 200', 'per-frame')
    """
    window = re.search(r"W = \d+", features)
    text = re.sub(r",?\s*W = \d+", "", features).strip()
    if text.startswith("top "):
        family = " ".join(text.split()[:2])
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
    bars += " (Pareto front and chosen two)"
    return f"point: accuracy, mean over {over}; {bars}"


def dense_ranges(x: np.ndarray, *, log: bool) -> list[np.ndarray]:
    """Return the indices of the candidates in each dense range of costs ``x`` (module notes), densest first.

    A range holds the candidates within :data:`DENSE` of the axis' span of one another, at least
    :data:`DENSE_MIN` of them; at most :data:`ZOOMS` ranges, disjoint.
    """
    t = np.log10(x) if log else x.astype(np.float64)
    span = float(t.max() - t.min())
    if span == 0 or len(t) < DENSE_MIN:
        return []
    order = np.argsort(t, kind="stable")
    taken = np.zeros(len(t), dtype=bool)
    out = []
    while len(out) < ZOOMS:
        best = None
        for a in range(len(order)):
            if taken[order[a]]:
                continue
            b = a
            while (
                b + 1 < len(order)
                and not taken[order[b + 1]]
                and t[order[b + 1]] - t[order[a]] <= DENSE * span
            ):
                b += 1
            if best is None or b - a > best[1] - best[0]:
                best = (a, b)
        if best is None or best[1] - best[0] + 1 < DENSE_MIN:
            break
        members = order[best[0] : best[1] + 1]
        taken[members] = True
        out.append(members)
    return out


def charted(rows: list[dict], field: str) -> list[dict]:
    """The rows a chart of ``field`` draws: measured on it, with a full accuracy (not stopped early)."""
    return [
        r for r in rows if r.get(field) is not None and r.get("accuracy") is not None and not r.get("stopped")
    ]


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
    cost); horizontal lines mark chance, the trivial baseline and the target when they lie within the
    candidates' accuracies. The x axis is logarithmic only when the costs span a decade or more, with
    plain tick labels. Candidates stopped early (no full accuracy) are left out.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from .selection import pareto_front

    _, field, label = CHARTS[which]
    rows = charted(rows, field)
    if not rows:
        raise ValueError(f"no candidate has a {field} to chart")
    raw = np.array([r[field] for r in rows], dtype=np.float64)
    divisor, unit = _axis_scale(field, raw)
    x = raw / divisor
    log = bool(x.min() > 0 and x.max() / x.min() >= 10)
    acc = np.array([r["accuracy"] for r in rows])
    low = np.array([r["accuracy_low"] for r in rows])
    high = np.array([r["accuracy_high"] for r in rows])
    front = pareto_front(acc, raw)
    chosen = {recommended: "recommended", runner_up: "runner-up"}
    barred = front | np.array([r["name"] in chosen for r in rows])
    zooms = dense_ranges(x, log=log)
    style = _Style(rows)
    widths = [3.0] + [1.6] * len(zooms)
    fig, axes = plt.subplots(
        1,
        1 + len(zooms),
        figsize=(5.6 + 2.6 * len(zooms) if zooms else 8.0, 5.0),
        sharey=True,
        width_ratios=widths,
        squeeze=False,
    )
    axes = list(axes[0])
    floor = float(min(low[barred].min(), acc.min()))
    bottom = max(0.0, floor - max(0.02, 0.08 * (1.0 - floor)))
    for k, ax in enumerate(axes):
        members = np.arange(len(rows)) if k == 0 else zooms[k - 1]
        offset, scale, xlabel = 0.0, 1.0, f"{label} ({unit})"
        if k > 0 and which == "decision":  # a window's decisions differ by the latency: show it in ms
            offset = float(np.floor(x[members].min() * 10) / 10)
            scale, xlabel = 1e3, f"ms past {offset:g} s"
        elif k > 0:
            xlabel = f"{unit} (zoom)"
        xs = (x - offset) * scale
        for i in members:
            style.point(ax, rows[i], xs[i], acc[i], low[i], high[i], bar=bool(barred[i]), many=len(rows) > 15)
        on = np.flatnonzero(front)
        on = on[np.argsort(x[on], kind="stable")]
        ax.step(xs[on], acc[on], where="post", color="0.3", lw=1.2, zorder=2)
        for i, r in enumerate(rows):
            if r["name"] in chosen and i in set(members.tolist()):
                shape = "o" if chosen[r["name"]] == "recommended" else "s"
                ax.plot(xs[i], acc[i], shape, ms=16 if shape == "o" else 13, mfc="none", mec="black",
                        mew=1.6 if shape == "o" else 1.1, ls="none", zorder=4)  # fmt: skip
        _x_axis(ax, xs[members], log=log and k == 0, bins=5 if k == 0 else 3)
        if k > 0:
            lo, hi = float(xs[members].min()), float(xs[members].max())
            pad = (hi - lo) * 0.12 or max(abs(hi) * 0.01, 1e-6)
            ax.set_xlim(lo - pad, hi + pad)
            ax.set_title(f"zoom: {len(members)} candidates", fontsize=8.5, loc="left")
            axes[0].axvspan(x[members].min(), x[members].max(), color="0.85", zorder=0, lw=0)
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
    handles = [Line2D([], [], color="0.3", lw=1.2, label=f"Pareto front (accuracy vs {which})")]
    lines = [(chance, ":", "chance"), (baseline, "--", "majority class"), (target, "-.", "target")]
    if chance is not None and baseline is not None and abs(chance - baseline) < 5e-3:  # one line, both names
        lines = [(baseline, "--", "chance = majority class"), (target, "-.", "target")]
    for value, ls, text in lines:
        if value is None:
            continue
        colour = "0.45" if text != "target" else "tab:red"
        shown = value >= bottom
        for ax in axes:
            if shown:
                ax.axhline(value, ls=ls, color=colour, lw=1, zorder=0)
        handles.append(
            Line2D(
                [], [], ls=ls, color=colour, label=f"{text} {value:.2f}{'' if shown else ' (below the axis)'}"
            )
        )
    title = []
    for name, role in chosen.items():
        hit = [r for r in rows if r["name"] == name]
        if name is None or not hit:
            continue
        shape = "thick ring" if role == "recommended" else "box"
        title.append(f"{role} ({shape}): {name}, {hit[0]['accuracy']:.3f}")
        handles.append(Line2D([], [], ls="none", marker="o" if role == "recommended" else "s", ms=10, mfc="none",
                              mec="black", mew=1.4, label=role))  # fmt: skip
    handles += style.handles()
    if zooms:
        handles.append(Line2D([], [], ls="none", label="grey band: the zoomed range"))
    axes[0].set_ylabel(f"accuracy (mean over {rows[0].get('unit') or 'unit'}s)")
    axes[0].set_ylim(bottom, 1.0 + 0.03 * (1.0 - bottom))
    axes[-1].legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    fig.suptitle("\n".join([*title, what_is_drawn(rows)]), fontsize=8.5, x=0.01, ha="left")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


class _Style:
    """Colour by classifier, marker by feature family (module notes), hollow for int8."""

    MARKERS = "osD^vPXh<>*pd"

    def __init__(self, rows: list[dict]) -> None:
        import matplotlib.pyplot as plt

        self.colours = plt.get_cmap("tab10")
        self.classifiers = list(dict.fromkeys(r["classifier"] for r in rows))
        self.families = list(dict.fromkeys(feature_family(r["features"]) for r in rows))
        self.int8 = any(r.get("quantisation") for r in rows)
        self.degraded = any(r.get("int8_degraded") for r in rows)

    def colour(self, row: dict) -> object:
        return self.colours(self.classifiers.index(row["classifier"]) % 10)

    def marker(self, row: dict) -> str:
        return self.MARKERS[self.families.index(feature_family(row["features"])) % len(self.MARKERS)]

    def point(
        self, ax, row: dict, x: float, a: float, lo: float, hi: float, *, bar: bool, many: bool
    ) -> None:
        c = self.colour(row)
        int8 = row.get("quantisation") is not None
        ms = 5 if many else 7
        if bar:
            ax.plot([x, x], [lo, hi], "-", color=c, lw=0.9, alpha=0.6, zorder=1)
        # A filled marker's edge in its own colour, a hollow one larger with an edge thin for its size.
        ax.plot(x, a, self.marker(row), color=c, ms=1.3 * ms if int8 else ms, mfc="white" if int8 else c, mec=c,
                mew=ms / 6 if int8 else 0.5, zorder=3)  # fmt: skip
        if row.get("int8_degraded"):
            ax.plot(x, a, "x", color="tab:red", ms=9 if many else 11, mew=1.6, zorder=5)

    def handles(self) -> list:
        from matplotlib.lines import Line2D

        out = [
            Line2D([], [], ls="none", marker="s", color=self.colours(i % 10), label=clf)
            for i, clf in enumerate(self.classifiers)
        ]
        out += [
            Line2D([], [], ls="none", marker=self.MARKERS[j % len(self.MARKERS)], color="0.4", label=f)
            for j, f in enumerate(self.families)
        ]
        if self.int8:
            out.append(
                Line2D([], [], ls="none", marker="o", mfc="white", mec="0.4", mew=1.3, label="hollow: int8")
            )
        if self.degraded:
            out.append(
                Line2D(
                    [],
                    [],
                    ls="none",
                    marker="x",
                    color="tab:red",
                    mew=1.6,
                    label="int8 below its float interval",
                )
            )
        out.append(Line2D([], [], color="0.5", lw=0.9, label="bar: Pareto front and the chosen two"))
        return out


def _x_axis(ax, xs: np.ndarray, *, log: bool, bins: int = 5) -> None:
    from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator

    if log:
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_minor_locator(LogLocator(subs="auto"))
        ax.xaxis.set_minor_formatter(FuncFormatter(lambda v, _: ""))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        return
    ax.xaxis.set_major_locator(MaxNLocator(bins, steps=[1, 2, 2.5, 5, 10]))
    pad = (xs.max() - xs.min()) * 0.08 or max(abs(xs.max()) * 0.05, 1e-3)
    ax.set_xlim(max(0.0, xs.min() - pad) if xs.min() >= 0 else xs.min() - pad, xs.max() + pad)


__all__ = [
    "CHARTS",
    "DENSE",
    "DENSE_MIN",
    "ZOOMS",
    "charted",
    "dense_ranges",
    "draw_chart",
    "feature_family",
    "what_is_drawn",
]
