"""Figures of breaking-point curves: one factor (:func:`plot_factor`), every factor (:func:`plot_factors`),
and a grid factor as a heat map (:func:`plot_grid`)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from .degradations import Degradation
from .results import Curve

_AXIS_TITLES = {
    "feature SNR": "feature SNR (dB)",
    "image noise": "image noise (mean, variance)",
    "frames": "frames per exploration",
    "sensel grid": "sensel size (times the sensor's)",
    "erosion / pitch": "erosion square (texture pitches)",
    "window": "window (samples)",
    "sensor noise": "sensor noise (g, standard deviation)",
    "quantisation": "quantisation step (g)",
    "saturation": "sensor range (± g)",
    "sample rate": "sample rate (times lower)",
    "training samples": "training samples per class",
    "drift": "test segment centre (share of the recording)",
}


def axis_title(f: Degradation) -> str:
    """Return the x-axis title of a factor's chart: the quantity and its unit, said once (the tick
    labels are bare numbers)."""
    if f.name in _AXIS_TITLES:
        return _AXIS_TITLES[f.name]
    return f.name if not f.unit or f.unit in f.name else f"{f.name} ({f.unit})"


def _tick(level: Any) -> str:
    if isinstance(level, tuple):
        return "(" + ", ".join(f"{v:.3g}" for v in level) + ")"
    return f"{level:.3g}" if isinstance(level, int | float) else str(level)


def _legend_handles(models: Sequence[str]) -> tuple[list, list[str]]:
    """Legend entries shared by the factor charts: one line per model, then what the marks mean."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=f"C{i}", marker="o", ms=3) for i in range(len(models))]
    labels = list(models)
    handles += [
        Line2D([], [], color="grey", ls="--", lw=0.8),
        Line2D([], [], color="k", ls=":", lw=0.8),
        Line2D([], [], color="k", marker="v", ls="", ms=7),
    ]
    labels += ["chance", "halfway to chance (model's colour)", "breaking point"]
    return handles, labels


def plot_factor(
    curves: Sequence[Curve], *, ax: Any = None, legend: bool = True, models: Sequence[str] | None = None
) -> Any:
    """Return a figure of accuracy against level for every curve of one factor.

    Lines are the accuracies along the breaking path with their 95 % bands; the clean accuracy is the
    first point (at the left, marked "clean"), dotted lines the halfway thresholds, the dashed grey line
    chance, and triangles the breaking levels. Severity grows to the right. The x-axis title gives the
    quantity and its unit; the ticks are the levels. ``legend=False`` leaves the legend to the caller
    (:func:`plot_factors` draws one for all panels); ``models`` fixes each model's colour (its index).
    """
    import matplotlib.pyplot as plt

    if not curves:
        raise ValueError("curves must hold at least one curve, got none")
    f = curves[0].factor
    models = list(models) if models is not None else list(dict.fromkeys(c.model for c in curves))
    fig = ax.figure if ax is not None else plt.subplots(figsize=(6.4, 3.8))[0]
    ax = ax if ax is not None else fig.axes[0]
    longest = max(curves, key=lambda c: len(c.path()[0]))
    labels = ["clean"] + [_tick(v) for v in longest.path()[0]]
    for c in curves:
        _, acc, low, high = c.path()
        x = np.arange(len(acc) + 1)
        colour = f"C{models.index(c.model)}"
        ax.plot(x, np.r_[c.clean, acc], marker="o", ms=3, color=colour)
        ax.fill_between(x, np.r_[c.clean_low, low], np.r_[c.clean_high, high], color=colour, alpha=0.15)
        ax.axhline(c.breaking.threshold, color=colour, ls=":", lw=0.8)
        if c.breaking.status == "reached":
            ax.plot([c.breaking.position], [c.breaking.threshold], marker="v", ms=8, color=colour)
    ax.axhline(curves[0].chance, color="grey", ls="--", lw=0.8)
    crowded = len(labels) * max(len(t) for t in labels) > 36  # about what a 4-inch axis holds at 8 pt
    ax.set_xticks(
        np.arange(len(labels)),
        labels,
        rotation=45 if crowded else 0,
        ha="right" if crowded else "center",
        fontsize=8,
    )
    ax.set_xlabel(axis_title(f))
    ax.set_ylabel("accuracy")
    ax.set_ylim(0.0, 1.02)
    ax.set_title(f.name, fontsize=9)
    if legend:
        ax.legend(*_legend_handles(models), fontsize=7, loc="lower left")
    ax.grid(alpha=0.3)
    return fig


def plot_factors(curves: Iterable[Curve], *, columns: int = 4) -> Any:
    """Return one figure with a panel per factor (:func:`plot_factor`), every candidate's curve in each,
    and one legend for all panels (the models keep their colour from panel to panel)."""
    import matplotlib.pyplot as plt

    by: dict[str, list[Curve]] = {}
    for c in curves:
        by.setdefault(c.factor.name, []).append(c)
    if not by:
        raise ValueError("curves must hold at least one curve, got none")
    models = list(dict.fromkeys(c.model for group in by.values() for c in group))
    rows = -(-len(by) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.4 * rows + 0.6), squeeze=False)
    for ax, group in zip(axes.flat, by.values(), strict=False):
        plot_factor(group, ax=ax, legend=False, models=models)
    for ax in list(axes.flat)[len(by) :]:
        ax.set_visible(False)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.6 / (3.4 * rows + 0.6)))
    handles, labels = _legend_handles(models)
    fig.legend(handles, labels, loc="upper center", ncol=min(len(labels), 6), fontsize=8, frameon=False)
    return fig


def plot_grid(curve: Curve, means: Sequence[float], variances: Sequence[float]) -> Any:
    """Return a heat map of a grid factor's accuracies (Table 4: rows mean, columns variance); cells at
    or below the halfway threshold are hatched."""
    import matplotlib.pyplot as plt

    acc = {lvl: a for lvl, a in zip(curve.levels, curve.accuracy, strict=True)}
    grid = np.array([[acc.get((m, v), np.nan) for v in variances] for m in means])
    fig, ax = plt.subplots(figsize=(4.6, 3.8))
    image = ax.imshow(grid, vmin=curve.chance, vmax=1.0, cmap="viridis", origin="upper")
    for i, j in np.ndindex(grid.shape):
        if np.isfinite(grid[i, j]):
            broken = grid[i, j] <= curve.breaking.threshold
            ax.text(
                j, i, f"{grid[i, j]:.2f}", ha="center", va="center", fontsize=7, color="w" if broken else "k"
            )
            if broken:
                ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, hatch="//", ec="w", lw=0))
    ax.set_xticks(range(len(variances)), [f"{v:g}" for v in variances])
    ax.set_yticks(range(len(means)), [f"{m:g}" for m in means])
    ax.set_xlabel("noise variance")
    ax.set_ylabel("noise mean")
    ax.set_title(
        f"{curve.model}: clean {curve.clean:.2f}, halfway {curve.breaking.threshold:.2f}", fontsize=8
    )
    fig.colorbar(image, ax=ax, label="accuracy")
    return fig
