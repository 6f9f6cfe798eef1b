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

**Naming rule** (:func:`class_and_session`): a file ``<class>_<n>.<ext>`` whose name ends in
``_`` and a number is recording ``n`` (the session) of class ``<class>``: ``felt_3.csv`` → class
``felt``, session ``3`` (``felt_03.csv`` too). Any other name is a class of its own and its own session: ``glass.csv``
→ class ``glass``, session ``glass``. An index CSV (:func:`read_index`) overrides the rule.

Examples
--------
>>> class_and_session("logs/felt_3.csv"), class_and_session("glass.csv")
(('felt', '3'), ('glass', 'glass'))
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .npz import _too_large, max_read_bytes
from .safe_write import write_atomic

PathLike = str | os.PathLike

STANDARD_GRAVITY = 9.80665
UNITS = {"g": 1.0, "m/s2": 1.0 / STANDARD_GRAVITY}
"""Accepted ``units`` and their factor to g."""
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
"""Accepted ``time_unit`` and their factor to seconds (``"auto"`` picks seconds, see the module notes)."""
PLAUSIBLE_RATE_HZ = (10.0, 100_000.0)
"""Sample rates an accelerometer log is taken to have under ``time_unit="auto"``."""
INDEX_COLUMNS = ("file", "class")
"""Columns an index CSV must have (``session`` is optional)."""
_CSV_EXPANSION = 4  # bytes of parsed table per byte of CSV text, at most ("0,0,0,0\n": 8 bytes, 4 float64)


# ------------------------------------------------------------------------------------ naming rule
def class_and_session(path: PathLike) -> tuple[str, str]:
    """Return ``(class, session)`` of a recording from its file name (the naming rule above).

    >>> class_and_session("cork_12.csv"), class_and_session("run.bag"), class_and_session("a_b.mcap")
    (('cork', '12'), ('run', 'run'), ('a_b', 'a_b'))
    """
    stem = (
        Path(path).stem if Path(path).suffix.lower() in (".csv", ".db3", ".mcap", ".bag") else Path(path).name
    )
    base, _, tail = stem.rpartition("_")
    if base and tail.isdigit():
        return base, str(int(tail))  # felt_03 and cork_3 are both session 3
    return stem, stem


def read_index(path: PathLike) -> dict[str, tuple[str, str]]:
    """Return ``{file: (class, session)}`` from an index CSV with columns ``file,class[,session]``.

    ``file`` is a path relative to the index's directory (or absolute); a missing ``session``
    makes each file its own session. Keys are the resolved paths as strings.

    Raises
    ------
    ValueError
        One line naming the index file: a missing column, an empty class, a file listed twice.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such index file")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        header = [h.strip().lower() for h in (reader.fieldnames or [])]
        missing = [c for c in INDEX_COLUMNS if c not in header]
        if missing:
            raise ValueError(
                f"{path}: an index CSV needs the columns file,class[,session], missing {missing} "
                f"(header: {header})"
            )
        reader.fieldnames = header
        index: dict[str, tuple[str, str]] = {}
        for row_number, row in enumerate(reader, start=2):
            name, label = (row.get("file") or "").strip(), (row.get("class") or "").strip()
            if not name or not label:
                raise ValueError(f"{path}: row {row_number} must give a file and a class, got {dict(row)}")
            key = str((path.parent / name).resolve())
            if key in index:
                raise ValueError(f"{path}: row {row_number} lists {name!r} a second time")
            index[key] = (label, (row.get("session") or "").strip() or Path(name).stem)
    if not index:
        raise ValueError(f"{path}: the index lists no file")
    return index


def names_for(
    paths: Sequence[PathLike],
    *,
    class_names: Sequence[str] | None = None,
    sessions: Sequence[str] | None = None,
    index: PathLike | dict | None = None,
) -> tuple[list[str], list[str]]:
    """Return each path's class and session: given explicitly, from an index CSV, or the naming rule.

    Raises
    ------
    ValueError
        When ``class_names``/``sessions`` do not give one entry per file, or a file is not in the index.
    """
    if index is not None:
        table = index if isinstance(index, dict) else read_index(index)
        absent = [str(p) for p in paths if str(Path(p).resolve()) not in table]
        if absent:
            where = index if not isinstance(index, dict) else "the index"
            raise ValueError(
                f"{where}: lists no class for {absent[0]} ({len(absent)} file(s) not in the index)"
            )
        rule = [table[str(Path(p).resolve())] for p in paths]
    else:
        rule = [class_and_session(p) for p in paths]
    classes = [c for c, _ in rule] if class_names is None else [str(c) for c in class_names]
    session = [s for _, s in rule] if sessions is None else [str(s) for s in sessions]
    for name, given in (("class_names", classes), ("sessions", session)):
        if len(given) != len(paths):
            raise ValueError(f"{name} must give one entry per file ({len(paths)}), got {len(given)}")
    return classes, session


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
                "acceleration columns with columns= / --columns, e.g. --columns "
                f"{_suggest(header)}"
            )
        else:
            index.append(header.index(item))
    return index


def _suggest(header: list[str]) -> str:
    time = next((h for h in header if h in ("t", "time", "timestamp", "stamp")), header[0])
    axes = [h for h in header if h != time and h.lower().startswith(("acc", "a"))][:3]
    return ",".join([time, *axes]) if len(axes) == 3 else "t,x,y,z"


def _seconds_per_tick(path: Path, step: float, time_unit: str) -> float:
    if time_unit != "auto":
        if time_unit not in TIME_UNITS:
            raise ValueError(f"time_unit must be one of {[*TIME_UNITS, 'auto']}, got {time_unit!r}")
        return TIME_UNITS[time_unit]
    low, high = PLAUSIBLE_RATE_HZ
    if low <= 1.0 / step <= high:
        return 1.0
    plausible = [u for u, f in TIME_UNITS.items() if low <= 1.0 / (step * f) <= high]
    name = {"ms": "milliseconds", "us": "microseconds", "s": "seconds"}
    if plausible:
        unit = plausible[0]
        raise ValueError(
            f"{path}: t looks like {name[unit]}: median step {step:g} s would be {1.0 / step:.3g} Hz; "
            f"pass --time-unit {unit} (time_unit={unit!r}), or --time-unit s if the rate is right"
        )
    raise ValueError(
        f"{path}: the median time step {step:g} gives {1.0 / step:.3g} Hz in seconds, "
        f"{1e3 / step:.3g} Hz in ms and {1e6 / step:.3g} Hz in us, none a plausible accelerometer rate "
        f"({low:g} Hz to {high:g} Hz); check the time column (--columns) or pass --time-unit"
    )


def integer_counts_message(where: str, found: str) -> str:
    """The one message for accelerations given as integer counts without a declared scale (CSV and .npz)."""
    return (
        f"{where}: accelerations must be in g or m/s^2, got {found} (raw sensor counts?); declare the "
        "scale in units per count, --scale 0.0039 (scale=0.0039) for the ADXL345 at full resolution, "
        "or convert them to g first"
    )


def read_csv_log(
    path: PathLike,
    *,
    columns: str | Sequence[str | int] | None = None,
    units: str = "g",
    scale: float | None = None,
    time_unit: str = "auto",
) -> tuple[np.ndarray, float]:
    """Read one CSV log; return ``(signal (n, 3) float32 in g, rate_hz)``.

    Parameters
    ----------
    path : path
    columns, units, scale, time_unit
        See the module notes.

    Returns
    -------
    signal : ndarray (n, 3) float32
        ``value * scale * units factor`` (scale 1 when not given), in g.
    rate_hz : float
        ``1 / median(dt)`` in the declared (or detected) time unit; samples are taken as uniformly
        spaced (a warning says when a step deviates from the median by more than 5 %).

    Raises
    ------
    ValueError
        One line naming the file: a missing column, a value that is not a finite number, fewer than
        2 rows, time stamps that do not strictly increase, an implausible rate under
        ``time_unit="auto"``, integer counts without ``scale``, an unknown unit, or a file whose parsing
        would exceed the read bound (:func:`tactile_torch.robot.npz.max_read_bytes`, ``--max-read-mb``).
    """
    import warnings

    path = Path(path)
    if units not in UNITS:
        raise ValueError(f"units must be one of {list(UNITS)}, got {units!r}")
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a finite number > 0 (units per count), got {scale!r}")
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, expected a CSV log")
    limit = max_read_bytes()  # the readers' one bound (--max-read-mb, TACTILE_TORCH_MAX_READ_MB)
    if path.stat().st_size * _CSV_EXPANSION > limit:  # parsing takes up to ~4 bytes per byte of text
        raise _too_large(path, "parsing the CSV log", path.stat().st_size * _CSV_EXPANSION, limit)
    spec = _column_spec(columns)
    with path.open(newline="") as f:
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
                path, delimiter=",", skiprows=0 if header is None else 1, usecols=index, ndmin=2, dtype=str
            )
    except ValueError as err:
        raise ValueError(f"{path}: every row must have the columns {index} ({err})") from None
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
            f"(first at data row {bad[0] + 1}, column {index[bad[1]]})"
        )
    dt = np.diff(values[:, 0])
    if (dt <= 0).any():
        raise ValueError(
            f"{path}: time stamps must strictly increase, data row {int(np.argmax(dt <= 0)) + 2} does not"
        )
    step = float(np.median(dt))
    seconds = _seconds_per_tick(path, step, time_unit)
    rate = float(f"{1.0 / (step * seconds):.9g}")  # 0.01 s steps written as text give 100.00000000000213 Hz
    if np.abs(dt - step).max() > 0.05 * step:
        warnings.warn(
            f"{path}: time steps vary by up to {np.abs(dt - step).max() / step:.0%} of the median; "
            "the samples are taken as uniformly spaced",
            stacklevel=2,
        )
    if (
        scale is None
        and not np.char.count(table[:, 1:], ".").any()
        and not np.char.count(np.char.lower(table[:, 1:]), "e").any()
    ):
        raise ValueError(integer_counts_message(str(path), "integers only"))
    factor = (1.0 if scale is None else float(scale)) * UNITS[units]
    return (values[:, 1:] * factor).astype(np.float32), rate


def read_csv_recording(
    path: PathLike,
    *,
    columns: str | Sequence[str | int] | None = None,
    scale: float | None = None,
    units: str = "g",
    time_unit: str = "auto",
) -> tuple[np.ndarray, float]:
    """Read one CSV log of time and three accelerations; return ``(signal (n, 3) float32 in g, rate_hz)``.

    ``columns`` (names or indices of t, x, y, z), ``units`` (``"g"``, ``"m/s2"``), ``scale`` (units
    per count, required for integer counts) and ``time_unit`` (``"s"``, ``"ms"``, ``"us"``,
    ``"auto"``) are those of :func:`read_csv_log`, which reads the file
    (NumPy only). The rate is ``1 / median(dt)``.

    Raises
    ------
    ValueError
        If a column is missing, a value is not a finite number, there are fewer than 2 rows, the
        time stamps do not strictly increase, the rate is implausible for the time unit, or the
        accelerations are integer counts without a ``scale``.
    """
    return read_csv_log(path, columns=columns, units=units, scale=scale, time_unit=time_unit)


def write_csv_recording(path: PathLike, signal: np.ndarray, rate_hz: float) -> Path:
    """Write one recording ``(n, 3)`` in g as a CSV log with the header ``t,x,y,z``; return the path.

    Times are ``i / rate_hz`` seconds; values keep float32 precision (9 significant digits), so
    :func:`read_csv_recording` gives the same samples and rate back.
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


def csv_class_name(path: PathLike) -> str:
    """Return the class a CSV log is named after (:func:`class_and_session`).

    >>> csv_class_name("logs/cork_12.csv"), csv_class_name("glass.csv")
    ('cork', 'glass')
    """
    return class_and_session(path)[0]


__all__ = [
    "INDEX_COLUMNS",
    "PLAUSIBLE_RATE_HZ",
    "TIME_UNITS",
    "UNITS",
    "class_and_session",
    "csv_class_name",
    "integer_counts_message",
    "names_for",
    "read_csv_log",
    "read_csv_recording",
    "read_index",
    "write_csv_recording",
]
