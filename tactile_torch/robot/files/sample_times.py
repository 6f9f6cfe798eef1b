"""The sample rate and the gaps of a recording's time stamps (NumPy only): one rule for files and the stream.

A logger's time stamps are rarely exact multiples of the sample period: rounded to 0.1 ms, the
steps of an 800 Hz sensor alternate between 1.2 and 1.3 ms (rounded to 1 ms, between 1 and 2 ms), and
a recording may hold gaps (samples lost, a paused logger). :func:`time_base` reads both from the
time stamps:

- **gaps**: a step longer than ``(1 + GAP_TOLERANCE)`` sample periods plus the time stamps'
  resolution is a gap (at least one sample lost). :data:`GAP_TOLERANCE` is the rule of the live
  stream too (:mod:`tactile_torch.robot.stream.sequencer`), so a file and a serial line split at the same
  steps; no window ever spans a gap;
- **the period**: the slope of ``t`` against the sample index, fitted by least squares within the
  stretches between gaps (one slope shared by all stretches), so that neither the rounding of the
  stamps nor a gap biases it. The median step is only the first guess (with stamps rounded to
  0.1 ms it is 1.2 or 1.3 ms, 4 % off an 800 Hz sensor's 1.25 ms);
- **irregular steps**: the largest deviation of a step (gaps aside) from the period, beyond the
  resolution, as a share of the period; the readers warn above :data:`IRREGULAR_TOLERANCE`.

Examples
--------
>>> import numpy as np
>>> t = np.round(np.arange(1000) * 1.25, 1)  # 800 Hz in ms, rounded to 0.1 ms: steps 1.2 and 1.3
>>> base = time_base(t, resolution=0.1)
>>> rate_hz(base.period * 1e-3, base.period_error), base.gaps.size, base.irregular
(800.0, 0, 0.0)
>>> base = time_base(np.concatenate([t[:500], t[500:] + 1000.0]), resolution=0.1)  # a 1 s gap
>>> base.gaps, round(base.longest_gap, 1)
(array([500]), 1001.2)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

GAP_TOLERANCE = 0.5
"""A step of ``t`` longer than ``(1 + GAP_TOLERANCE)`` sample periods (plus the time stamps'
resolution) is a gap: at least one sample lost. The stream's rule and the files'."""
RATE_TOLERANCE = 0.05
"""Rates that differ by more than this share disagree: a stated rate and the time stamps', or (in the
stream) a window's ``t`` span and the bundle's rate."""
IRREGULAR_TOLERANCE = 0.05
"""Steps (gaps aside) further than this share of the period from it, beyond the time stamps'
resolution, make the readers warn that the samples are taken as uniformly spaced."""


@dataclass(frozen=True)
class TimeBase:
    """What the time stamps of one recording say (in the unit of the stamps).

    Attributes
    ----------
    period : float
        The sample period: the least-squares slope of ``t`` against the sample index within the
        stretches between gaps.
    gaps : ndarray (K,) int64
        Indices of the samples that start a new stretch after a gap (``t[i] - t[i - 1]`` is a gap),
        increasing; empty when there is none.
    longest_gap : float
        The longest gap step (0 when there is none).
    irregular : float
        Largest deviation of a step that is not a gap from ``period``, beyond the resolution, as a
        share of ``period`` (0: every step is the period within the resolution).
    period_error : float
        Standard error of ``period`` relative to it, from the residuals of the fit (0 for a stated
        period); :func:`rate_hz` rounds the rate to it.
    longest_gap_at : float
        Where the longest gap starts: its first stamp's time since the recording's first one (0 when
        there is no gap).
    """

    period: float
    gaps: np.ndarray
    longest_gap: float
    irregular: float
    period_error: float = 0.0
    longest_gap_at: float = 0.0


def _pooled_slope(t: np.ndarray, gap: np.ndarray) -> tuple[float, float]:
    """Least-squares slope of ``t`` against the index, one slope shared by the stretches between gaps,
    and its standard error relative to it (NaN, NaN when every stretch is one sample)."""
    segment = np.concatenate([[0], np.cumsum(gap)])
    index = np.arange(len(t), dtype=np.float64)
    count = np.bincount(segment).astype(np.float64)
    di = index - (np.bincount(segment, index) / count)[segment]
    dt = t - (np.bincount(segment, t) / count)[segment]
    denominator = float(np.dot(di, di))
    if denominator == 0.0:
        return float("nan"), float("nan")
    slope = float(np.dot(di, dt) / denominator)
    freedom = len(t) - 2 * len(count)
    residual = dt - slope * di
    error = np.sqrt(float(np.dot(residual, residual)) / max(freedom, 1) / denominator)
    return slope, float(error / abs(slope)) if slope else float("nan")


def time_base(t: np.ndarray, *, resolution: float = 0.0, period: float | None = None) -> TimeBase:
    """Return the period, the gaps and the irregularity of strictly increasing time stamps ``t``.

    Parameters
    ----------
    t : ndarray (n,), n >= 2
        Time stamps, strictly increasing (the caller checks), in any unit.
    resolution : float
        The stamps' resolution in the same unit (0.1 for milliseconds written with one decimal):
        steps may be off the period by this much without being a gap or irregular.
    period : float, optional
        The period, when it is known (a stated sample rate): only the gaps and the irregularity are
        read then.

    Returns
    -------
    TimeBase
    """
    t = np.asarray(t, dtype=np.float64)
    dt = np.diff(t)
    resolution = float(resolution)
    error = 0.0
    if period is None:
        estimate = float(np.median(dt))
        for _ in range(2):  # the median step (biased by rounding) finds the gaps, the slope the period
            slope, slope_error = _pooled_slope(t, dt > (1.0 + GAP_TOLERANCE) * estimate + resolution)
            if not (np.isfinite(slope) and slope > 0):
                break
            estimate, error = slope, slope_error
        period = estimate
    gap = dt > (1.0 + GAP_TOLERANCE) * period + resolution
    regular = dt[~gap]
    excess = np.abs(regular - period) - resolution if regular.size else np.zeros(1)
    longest = int(np.argmax(np.where(gap, dt, -np.inf))) if gap.any() else 0
    return TimeBase(
        period=float(period),
        gaps=(np.flatnonzero(gap) + 1).astype(np.int64),
        longest_gap=float(dt[longest]) if gap.any() else 0.0,
        irregular=float(max(0.0, excess.max()) / period),
        period_error=error,
        longest_gap_at=float(t[longest] - t[0]) if gap.any() else 0.0,
    )


def rate_hz(period_s: float, relative_error: float = 0.0) -> float:
    """Return ``1 / period_s`` rounded to the significant digits its relative error supports (3 to 9).

    An 800 Hz log whose fitted period is off by 2e-7 of itself (stamps rounded to 0.1 ms, a few
    thousand samples) gives 800.0, not 799.99984: the digits beyond the fit's precision are noise.

    >>> rate_hz(1.25e-3 * (1 + 2e-7), 1e-6), rate_hz(1 / 769.2307692, 0.0)
    (800.0, 769.230769)
    """
    rate = 1.0 / float(period_s)
    error = float(relative_error) if np.isfinite(relative_error) and relative_error > 0 else 1e-9
    digits = int(np.clip(np.ceil(-np.log10(3.0 * error)), 3, 9))
    return float(f"{rate:.{digits}g}")


def stamp_resolution(texts: np.ndarray) -> float:
    """Return the resolution of decimal time stamps as written (``"1700000000001.3"`` → 0.1, ``"12"`` → 1).

    The last digit written, ``10 ** (exponent - decimals)``, the finest over all stamps (a logger
    that drops trailing zeros writes ``0.005`` next to ``0.00625``).

    >>> stamp_resolution(np.array(["0", "0.00125", "0.0025", "0.005"]))
    1e-05
    >>> stamp_resolution(np.array(["1700000000001.3", "1700000000002.5"]))
    0.1
    """
    text = np.char.lower(np.char.strip(np.asarray(texts, dtype=str)))
    mantissa, _, exponent = np.char.partition(text, "e").T
    _, dot, decimals = np.char.partition(mantissa, ".").T
    digits = np.where(dot == ".", np.char.str_len(decimals), 0)
    power = np.where(np.char.str_len(exponent) > 0, exponent, "0").astype(np.int64) - digits
    return float(10.0 ** int(power.min()))


def describe_duration(seconds: float) -> str:
    """Return a duration as people read it: ``"40 ms"``, ``"0.4 s"``, ``"12.3 s"``, ``"2 min 5 s"``, ``"3 h 02 min"``.

    Three significant digits below a minute; minutes and seconds below an hour; hours and minutes below
    two days, then days and hours; non-finite or beyond a century: the seconds as a number.

    >>> [describe_duration(s) for s in (0.0004, 0.04, 0.4, 12.34, 125, 10_920, 3 * 86400 + 7200)]
    ['0.4 ms', '40 ms', '0.4 s', '12.3 s', '2 min 5 s', '3 h 02 min', '3 d 2 h']
    """
    s = float(seconds)
    if not math.isfinite(s) or abs(s) >= 100 * 365.25 * 86400:
        return f"{s:.3g} s"
    if abs(s) < 0.1:
        return f"{s * 1e3:.3g} ms"
    if abs(s) < 60:
        return f"{s:.3g} s"
    whole = round(abs(s))
    sign = "-" if s < 0 else ""
    if whole < 3600:
        return f"{sign}{whole // 60} min {whole % 60} s"
    if whole < 2 * 86400:
        return f"{sign}{whole // 3600} h {whole % 3600 // 60:02d} min"
    return f"{sign}{whole // 86400} d {whole % 86400 // 3600} h"


def describe_gap(gap_s: float, at_s: float, where: str) -> str:
    """Return where a gap is, as people read it: ``"a 0.4 s gap 12.3 s into day2/felt.csv"``.

    ``gap_s``: how long the step of the time stamps lasted; ``at_s``: when it started, in seconds since
    the recording's (or the stream's) first stamp; ``where``: the file or the stream. Never two epoch
    times side by side (``1.76243e+09 to 1.76243e+09``, which read the same).

    >>> describe_gap(0.4, 12.34, "day2/felt.csv")
    'a 0.4 s gap 12.3 s into day2/felt.csv'
    """
    return f"a {describe_duration(gap_s)} gap {describe_duration(at_s)} into {where}"


def describe_timing(found: Sequence[tuple[str, TimeBase, float]], *, what: str = "file") -> list[str]:
    """Return the readers' warnings about the time stamps of several recordings: at most one per finding.

    ``found``: ``(name, time base, seconds per unit of t)`` of each recording. A command reading 24
    files whose stamps are rounded warns once, naming how many files and the worst, not 24 times.
    """
    lines = []
    gappy = [(name, base, s) for name, base, s in found if base.gaps.size]
    if gappy:
        name, base, seconds = max(gappy, key=lambda item: item[1].longest_gap * item[2])
        total = sum(int(b.gaps.size) for _, b, _ in gappy)
        lines.append(
            f"{total} gap(s) in the time stamps of {len(gappy)} of {len(found)} {what}(s) (steps longer than "
            f"{1 + GAP_TOLERANCE:g} sample periods; the longest, "
            f"{describe_gap(base.longest_gap * seconds, base.longest_gap_at * seconds, name)}): "
            "no window spans a gap"
        )
    odd = [(name, base) for name, base, _ in found if base.irregular > IRREGULAR_TOLERANCE]
    if odd:
        name, base = max(odd, key=lambda item: item[1].irregular)
        lines.append(
            f"time steps vary by up to {base.irregular:.0%} of the sample period in {len(odd)} of {len(found)} "
            f"{what}(s) (the most in {name}), beyond the time stamps' resolution; the samples are taken as "
            "uniformly spaced"
        )
    return lines


__all__ = [
    "GAP_TOLERANCE",
    "IRREGULAR_TOLERANCE",
    "RATE_TOLERANCE",
    "TimeBase",
    "describe_duration",
    "describe_gap",
    "describe_timing",
    "rate_hz",
    "stamp_resolution",
    "time_base",
]
