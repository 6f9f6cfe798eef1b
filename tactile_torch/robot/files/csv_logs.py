"""CSV accelerometer logs with their units, and the naming rule for classes and sessions (NumPy only).

A log is one recording: a time column and three accelerations, comma-separated, with or without a
header line. What varies between loggers is declared, never guessed silently:

===============  ==================================================================================
``columns``      which columns hold t, x, y, z: 4 names or 0-based indices (``"time,ax,ay,az"``,
                 ``"0,1,2,3"``), or 3 (x, y, z; the time column is then ``t`` or ``time``, else
                 the first); default ``t``/``time`` and ``x, y, z`` by name, or the first four
``units``        ``"g"`` (default) or ``"m/s2"`` (divided by 9.80665)
``scale``        units per count for integer sensor counts (``0.0039`` for the ADXL345 at full
                 resolution); integer-valued logs without a scale are refused
``time_unit``    ``"s"``, ``"ms"``, ``"us"``, or ``"auto"`` (default): seconds, unless the rate in
                 seconds is implausible (below 10 Hz or above 100 kHz) while another unit gives a
                 plausible one, which is refused in one line naming the unit to pass
===============  ==================================================================================

The naming rule for classes and sessions (``felt_3.csv`` → class ``felt``, session ``3``) is
:mod:`tactile_torch.robot.files.naming`'s.

Examples
--------
>>> from tactile_torch.robot.files.naming import class_and_session
>>> class_and_session("logs/felt_3.csv"), class_and_session("glass.csv")
(('felt', '3'), ('glass', 'glass'))
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...validation import saturate_float32
from .npz import _too_large, max_read_bytes
from .safe_write import write_atomic
from .sample_times import RATE_TOLERANCE, TimeBase, rate_hz, stamp_resolution, time_base

PathLike = str | os.PathLike

STANDARD_GRAVITY = 9.80665
UNITS = {"g": 1.0, "m/s2": 1.0 / STANDARD_GRAVITY}
"""Accepted ``units`` and their factor to g."""
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
"""Accepted ``time_unit`` and their factor to seconds (``"auto"`` picks seconds, see the module notes)."""
PLAUSIBLE_RATE_HZ = (10.0, 100_000.0)
"""Sample rates an accelerometer log is taken to have under ``time_unit="auto"``."""
_CSV_EXPANSION = 4  # bytes of parsed table per byte of CSV text, at most ("0,0,0,0\n": 8 bytes, 4 float64)


# ------------------------------------------------------------------------------------ CSV logs
def _column_spec(columns: str | Sequence[str | int] | None) -> list[str | int] | None:
    if columns is None:
        return None
    parts = columns.split(",") if isinstance(columns, str) else list(columns)
    spec = []
    for part in parts:
        text = str(part).strip()
        spec.append(int(text) if text.isdigit() else text.lower())
    if len(spec) not in (3, 4):
        raise ValueError(f"columns must name 4 columns (t, x, y, z) or 3 (x, y, z), got {list(parts)}")
    return spec


def _column_index(path: Path, header: list[str] | None, spec: list | None, n_columns: int) -> list[int]:
    """Indices of the t, x, y, z columns."""
    if spec is None:
        if header is None:
            return [0, 1, 2, 3]
        spec = ["time" if "time" in header else "t", "x", "y", "z"]
    if len(spec) == 3:
        time = 0
        if header is not None and ("t" in header or "time" in header):
            time = header.index("time" if "time" in header else "t")
        spec = [time, *spec]
    index = []
    for item in spec:
        if isinstance(item, int):
            if item >= n_columns:
                raise ValueError(f"{path}: column {item} does not exist (the file has {n_columns} columns)")
            index.append(item)
        elif header is None:
            raise ValueError(f"{path} has no header line, so column {item!r} cannot be found; give indices")
        elif item not in header:
            raise ValueError(
                f"{path}: no column {item!r} (header: {','.join(header)}); name the time and the three "
                f"acceleration columns with columns=, e.g. columns={_suggest(header)!r}"
            )
        else:
            index.append(header.index(item))
    return index


def _suggest(header: list[str]) -> str:
    time = next((h for h in header if h in ("t", "time", "timestamp", "stamp")), header[0])
    axes = [h for h in header if h != time and h.lower().startswith(("acc", "a"))][:3]
    return ",".join([time, *axes]) if len(axes) == 3 else "t,x,y,z"


_UNIT_NAMES = {"ms": "milliseconds", "us": "microseconds", "s": "seconds"}


def _seconds_per_tick(path: Path, period: float, time_unit: str, stated_rate_hz: float | None) -> float:
    """Seconds per unit of ``t``: the declared unit, or under ``"auto"`` the one the rate makes plausible.

    A declared unit is checked as ``"auto"`` is: one that makes the rate implausible while another
    unit makes it plausible is refused. With a stated rate, the unit is the one whose rate is
    nearest to it, and the two must agree within :data:`~tactile_torch.robot.files.sample_times.RATE_TOLERANCE`.
    """
    if time_unit != "auto" and time_unit not in TIME_UNITS:
        raise ValueError(f"time_unit must be one of {[*TIME_UNITS, 'auto']}, got {time_unit!r}")
    units = TIME_UNITS if time_unit == "auto" else {time_unit: TIME_UNITS[time_unit]}
    rates = {u: 1.0 / (period * f) for u, f in units.items()}
    if stated_rate_hz is not None:
        unit = min(rates, key=lambda u: abs(np.log(rates[u] / stated_rate_hz)))
        if abs(rates[unit] / stated_rate_hz - 1.0) > RATE_TOLERANCE:
            raise ValueError(
                f"{path}: the time stamps give {rates[unit]:.4g} Hz (t in {_UNIT_NAMES[unit]}), but "
                f"sample_rate_hz={stated_rate_hz:g} was stated; check the time column (columns=), its unit "
                "(time_unit=) and the rate"
            )
        return units[unit]
    low, high = PLAUSIBLE_RATE_HZ
    plausible = [u for u, f in TIME_UNITS.items() if low <= 1.0 / (period * f) <= high]
    if time_unit == "auto":
        if "s" in plausible:
            return 1.0
        if plausible:
            unit = plausible[0]
            raise ValueError(
                f"{path}: t looks like {_UNIT_NAMES[unit]}: a step of {period:g} s would be {1.0 / period:.3g} Hz; "
                f"pass time_unit={unit!r}, or time_unit='s' with sample_rate_hz= if the rate is right"
            )
    elif time_unit in plausible:
        return TIME_UNITS[time_unit]
    elif plausible:
        unit = plausible[0]
        raise ValueError(
            f"{path}: t in {_UNIT_NAMES[time_unit]} (time_unit={time_unit!r}) gives {rates[time_unit]:.4g} Hz, "
            f"not a plausible accelerometer rate ({low:g} Hz to {high:g} Hz); t looks like {_UNIT_NAMES[unit]} "
            f"({1.0 / (period * TIME_UNITS[unit]):.4g} Hz): pass time_unit={unit!r}, or state the rate with "
            "sample_rate_hz= if it is right"
        )
    raise ValueError(
        f"{path}: the time step {period:g} gives {1.0 / period:.3g} Hz in seconds, "
        f"{1e3 / period:.3g} Hz in ms and {1e6 / period:.3g} Hz in us, none a plausible accelerometer rate "
        f"({low:g} Hz to {high:g} Hz); check the time column (columns=), or state the rate with sample_rate_hz="
    )


def integer_counts_message(where: str, found: str) -> str:
    """The one message for accelerations given as integer counts without a declared scale (CSV and .npz)."""
    return (
        f"{where}: accelerations must be in g or m/s^2, got {found} (raw sensor counts?); declare the "
        "scale in units per count, scale=0.0039 for the ADXL345 at full resolution, "
        "or convert them to g first"
    )


@dataclass(frozen=True)
class CsvLog:
    """One CSV log as read by :func:`read_csv_log`.

    Attributes
    ----------
    signal : ndarray (n, 3) float32
        Accelerations in g.
    rate_hz : float
        The sample rate: stated, or from the time stamps (:func:`tactile_torch.robot.files.sample_times.time_base`).
    gaps : ndarray (K,) int64
        Samples that start a new stretch after a gap in the time stamps (no window spans a gap).
    timing : TimeBase
        What the time stamps say, in their unit; ``seconds`` converts it.
    seconds : float
        Seconds per unit of the time column.
    t : ndarray (n,) float64
        Each sample's time stamp in seconds, as logged (an epoch time stays one): what
        ``simulate-sensor`` plays back.
    """

    signal: np.ndarray
    rate_hz: float
    gaps: np.ndarray
    timing: TimeBase
    seconds: float
    t: np.ndarray


def read_csv_log(
    path: PathLike,
    *,
    columns: str | Sequence[str | int] | None = None,
    units: str = "g",
    scale: float | None = None,
    time_unit: str = "auto",
    sample_rate_hz: float | None = None,
) -> CsvLog:
    """Read one CSV log; return its samples in g, its rate, the gaps of its time stamps and the stamps.

    The one reader of a CSV log: :func:`tactile_torch.robot.files.formats.read_csv_recordings` reads
    several with it (classes and sessions, one rate, one warning for all), ``simulate-sensor`` plays
    one.

    The rate is the slope of ``t`` against the sample index between gaps (robust to stamps rounded
    to 0.1 ms or 1 ms, :func:`tactile_torch.robot.files.sample_times.time_base`), rounded to the digits the
    fit supports; ``sample_rate_hz`` states it instead (the stamps must agree within 5 %). Gaps (a
    step longer than 1.5 periods plus the stamps' resolution) are returned as ``gaps``; the caller
    warns (:func:`tactile_torch.robot.files.sample_times.describe_timing`). Values beyond float32's range
    (``1e308``) are kept as its largest value, beyond every sensor's range (refused or left out there).

    Raises
    ------
    ValueError
        One line naming the file: a missing column, a value that is not a finite number, fewer than
        2 rows, time stamps that do not strictly increase, a rate implausible for the time unit
        (declared or ``"auto"``) or off the stated one, integer counts without ``scale``, an unknown
        unit, text that is not UTF-8, or a file whose parsing would exceed the read bound
        (:func:`tactile_torch.robot.files.npz.max_read_bytes`, ``--max-read-mb``).
    """
    path = Path(path)
    if units not in UNITS:
        raise ValueError(f"units must be one of {list(UNITS)}, got {units!r}")
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a finite number > 0 (units per count), got {scale!r}")
    if sample_rate_hz is not None and not (np.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise ValueError(f"sample_rate_hz must be a finite number of Hz > 0, got {sample_rate_hz!r}")
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, expected a CSV log")
    limit = max_read_bytes()  # the readers' one bound (--max-read-mb, TACTILE_TORCH_MAX_READ_MB)
    if path.stat().st_size * _CSV_EXPANSION > limit:  # parsing takes up to ~4 bytes per byte of text
        raise _too_large(path, "parsing the CSV log", path.stat().st_size * _CSV_EXPANSION, limit)
    spec = _column_spec(columns)
    try:
        table, header, index = _read_table(path, spec)
    except UnicodeDecodeError as err:
        raise ValueError(
            f"{path}: not UTF-8 text (byte 0x{err.object[err.start]:02x} at offset {err.start}); a CSV log "
            "is text: t,x,y,z numbers, comma-separated"
        ) from None
    try:
        values = table.astype(np.float64)
    except ValueError as err:
        raise ValueError(f"{path}: every value of columns {index} must be a number ({err})") from None
    if len(values) < 2:
        raise ValueError(f"{path} must hold at least 2 samples, got {len(values)}")
    if not np.isfinite(values).all():
        bad = np.argwhere(~np.isfinite(values))[0]
        raise ValueError(
            f"{path} must hold finite values, got {int((~np.isfinite(values)).sum())} NaN/inf "
            f"(first at data row {bad[0] + 1}, column {_column_name(header, index[bad[1]])})"
        )
    dt = np.diff(values[:, 0])
    if (dt <= 0).any():
        raise ValueError(
            f"{path}: time stamps must strictly increase, data row {int(np.argmax(dt <= 0)) + 2} does not"
        )
    if (
        scale is None
        and not np.char.count(table[:, 1:], ".").any()
        and not np.char.count(np.char.lower(table[:, 1:]), "e").any()
    ):
        raise ValueError(integer_counts_message(str(path), "integers only"))
    resolution = stamp_resolution(table[:, 0])
    timing = time_base(values[:, 0], resolution=resolution)
    seconds = _seconds_per_tick(path, timing.period, time_unit, sample_rate_hz)
    if sample_rate_hz is None:
        rate = rate_hz(timing.period * seconds, timing.period_error)
    else:  # the gaps and the irregularity against the stated period
        rate = float(sample_rate_hz)
        timing = time_base(values[:, 0], resolution=resolution, period=1.0 / (rate * seconds))
    factor = (1.0 if scale is None else float(scale)) * UNITS[units]
    signal = saturate_float32(values[:, 1:] * factor)
    return CsvLog(signal, rate, timing.gaps, timing, seconds, values[:, 0] * seconds)


def _read_table(path: Path, spec: list | None) -> tuple[np.ndarray, list[str] | None, list[int]]:
    """The t, x, y, z columns as text ``(n, 4)``, the header (or None) and the columns' indices."""
    import warnings

    with path.open(newline="", encoding="utf-8") as f:
        first = next(csv.reader(f), None)
    if first is None:
        raise ValueError(f"{path}: empty file, expected a CSV log with columns t,x,y,z")
    try:
        [float(v) for v in first]
        header = None
    except ValueError:
        header = [h.strip().lower() for h in first]
    if header is None and spec is None and len(first) < 4:
        raise ValueError(f"{path}: rows must have 4 columns t,x,y,z, the first has {len(first)}")
    index = _column_index(path, header, spec, len(first))
    try:
        with warnings.catch_warnings():  # a blank line or a header-only file: numpy warns; we say it below
            warnings.simplefilter("ignore", UserWarning)
            table = np.loadtxt(
                path,
                delimiter=",",
                skiprows=0 if header is None else 1,
                usecols=index,
                ndmin=2,
                dtype=str,
                encoding="utf-8",
            )
    except UnicodeDecodeError:
        raise
    except ValueError as err:
        raise ValueError(f"{path}: every row must have the columns {index} ({err})") from None
    return table, header, index


def _column_name(header: list[str] | None, column: int) -> str:
    return f"{column} ({header[column]})" if header is not None and column < len(header) else str(column)


def write_csv_recording(path: PathLike, signal: np.ndarray, rate_hz: float) -> Path:
    """Write one recording ``(n, 3)`` in g as a CSV log with the header ``t,x,y,z``; return the path.

    Times are ``i / rate_hz`` seconds; values keep float32 precision (9 significant digits), so
    :func:`read_csv_log` gives the same samples and rate back.
    """
    signal = np.asarray(signal)
    if signal.ndim != 2 or signal.shape[1] != 3:
        raise ValueError(f"signal must have shape (n, 3), got {signal.shape}")
    if not rate_hz > 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz!r}")
    table = np.column_stack([np.arange(len(signal)) / float(rate_hz), signal.astype(np.float64)])
    buffer = io.StringIO()
    np.savetxt(buffer, table, delimiter=",", fmt="%.9g", header="t,x,y,z", comments="")
    text = buffer.getvalue().encode("ascii")
    return write_atomic(path, lambda f: f.write(text))


__all__ = [
    "PLAUSIBLE_RATE_HZ",
    "TIME_UNITS",
    "UNITS",
    "CsvLog",
    "integer_counts_message",
    "read_csv_log",
    "write_csv_recording",
]
