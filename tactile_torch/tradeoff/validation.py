"""The checks of a trade-off study's data and options that run before any work: one line naming what is
wrong (``ValueError``), rather than an error, or a study of nothing, minutes later."""

from __future__ import annotations

import numpy as np

from .inputs import Samples, TradeoffData

FLOAT32_MAX = float(np.finfo(np.float32).max)
"""A sample at float32's largest magnitude is an overflow a reader saturated (1e308 read as float32), not a
measurement: refused as a non-finite one is."""


MAX_ACCELERATION_G = 1e15
"""A vibration sample beyond this many g is no measurement (accelerometers read at most thousands of g) and
its window's features overflow float32 (spectral powers of 1e25 g are inf): refused even with
``--sensor-range inf``, in one line, before any work."""


def _not_finite(values: np.ndarray, limit: float = FLOAT32_MAX) -> np.ndarray:
    """Where ``values`` are NaN, infinite, or at least ``limit`` in magnitude (default: saturated at
    float32's range, :data:`FLOAT32_MAX`)."""
    values = np.asarray(values)
    return ~np.isfinite(values) | (np.abs(values) >= limit)


def check_two_classes(data: TradeoffData) -> None:
    """One class: nothing to choose between (one line naming the class, before any work)."""
    labels = data.recordings.labels if data.kind == "vibration" else data.labels
    present = np.unique(np.asarray(labels))
    if len(present) < 2:
        which = ", ".join(repr(data.class_names[int(c)]) for c in present) or "none"
        where = data.description.partition(":")[0]
        raise ValueError(
            f"data: {where} holds a single class ({which}); comparing classifiers needs recordings of at "
            "least two classes (surfaces): add the other classes' files"
        )


def check_finite(data: TradeoffData) -> None:
    """A sample that is not a finite number (NaN, or an overflow such as 1e308 read as float32) would make
    every candidate fail after minutes: one line naming where, before any work. A value saturated at
    float32's range (a reader that clips 1e308 to 3.4e38 rather than overflowing to inf) is refused too:
    its features overflow all the same."""
    where = data.description.partition(":")[0]
    if data.kind == "vibration":
        rec = data.recordings
        for r, signal in enumerate(rec.signals):
            bad = _not_finite(signal, MAX_ACCELERATION_G)
            if bad.any():
                row, axis = np.argwhere(bad)[0]
                session = "" if rec.session is None else f", session {rec.session[r]}"
                files = getattr(
                    rec, "sources", None
                )  # the CSV file or bag of each recording, when read from one
                raise ValueError(
                    f"data: {where}: {'' if not files else f'{files[r]}: '}the recording of {rec.class_names[int(rec.labels[r])]!r}{session} holds "
                    f"{int(bad.sum())} value(s) that are not finite numbers (first: sample {row}, axis "
                    f"{'xyz'[axis]}: {float(np.asarray(signal)[row, axis]):.3g}; NaN, inf, or beyond "
                    f"{MAX_ACCELERATION_G:.0e} g, which no accelerometer reads and whose features overflow); every "
                    "window must be finite: fix or drop them (a finite sensor range, sensor_range_g=, refuses such values)"
                )
    elif data.raw is not None and np.issubdtype(data.raw.dtype, np.floating) and _not_finite(data.raw).any():
        first = np.argwhere(_not_finite(data.raw))[0]
        raise ValueError(
            f"data: {where}: sample {first[0]} holds values that are not finite numbers; every sample must be finite"
        )


def check_folds_fit(n_folds: int, inputs: dict[str, Samples]) -> None:
    """``n_folds`` asked for more folds than the data allow: one line, rather than silently fewer.

    The default (5) may drop to what small data allow (the folds' description says how many); a number
    the user gave above every input's count of samples (or groups) per class is a mistake."""
    for s in inputs.values():
        counts = np.bincount(s.y)
        most = int(counts[counts > 0].min())
        if s.groups is not None:
            most = min(len(np.unique(s.groups[s.y == c])) for c in np.unique(s.y))
        if n_folds > max(most, 5):
            raise ValueError(
                f"n_folds must be at most {max(most, 5)} here (the rarest class of {s.key} has {most} "
                f"{'groups' if s.groups is not None else 'samples'}), got {n_folds}"
            )


def check_target(target: float | None) -> None:
    """Raise ``ValueError`` unless ``target`` is ``None`` or an accuracy in (0, 1]."""
    if target is None:
        return
    if isinstance(target, bool) or not isinstance(target, int | float | np.number) or not 0 < target <= 1:
        raise ValueError(f"target must be an accuracy in (0, 1], got {target!r}")


__all__ = ["check_finite", "check_folds_fit", "check_target", "check_two_classes"]
