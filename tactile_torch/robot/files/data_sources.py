"""One entry for every data argument: a ``.npz``, CSV logs or ROS 2 bags, read with declared units and checked.

:func:`read_source` is what ``tactile-torch train``, ``cluster`` and ``tradeoff`` (and
:func:`tactile_torch.features.files.load_features`, :func:`tactile_torch.tradeoff.load_tradeoff_data`)
call on their ``--data``: it returns the arrays of :mod:`tactile_torch.robot.files.formats`
(``ExplorationArrays``, ``RecordingArrays`` or ``FeatureArrays``), and refuses, in one line naming
the file and the sample, vibration recordings that the declared units make implausible
(:func:`check_recordings`).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ...validation import FLOAT32_MAX
from ..contract import DEFAULT_RANGE_G
from ..ros2.bags import MAX_BAG_MESSAGES, is_bag, read_bag_topic
from .csv_logs import STANDARD_GRAVITY, UNITS
from .naming import recording_names
from .sample_times import RATE_TOLERANCE, describe_timing, time_base

PathLike = str | os.PathLike

GRAVITY_BAND_G = (7.0, 12.0)
"""A recording whose mean acceleration has a norm in this band, read as g, is gravity in m/s^2."""


@dataclass(frozen=True)
class DataOptions:
    """How to read a data argument (the data options of the command line, in the same names).

    Attributes
    ----------
    columns : str or sequence, optional
        CSV logs: the t, x, y, z columns by name or 0-based index (:mod:`tactile_torch.robot.files.csv_logs`).
    units : {"g", "m/s2"}, optional
        Accelerations of CSV logs and ``.npz`` recordings (default: g, as docs/formats.md says).
        IMU topics are m/s^2 by definition and converted whatever this says.
    scale : float, optional
        Units per count, for integer counts (refused without it).
    time_unit : {"auto", "s", "ms", "us"}
        CSV logs: unit of the time column.
    sample_rate_hz : float, optional
        Vibration recordings: the sample rate, stated. CSV logs and bags: their time stamps must
        agree with it within 5 % (:data:`~tactile_torch.robot.files.sample_times.RATE_TOLERANCE`); a
        ``.npz``: its ``rate_hz`` must. Default: the time stamps' rate (or the file's ``rate_hz``).
    topic : str, optional
        Bags: the topic to read (default: the only IMU or pressure-array topic).
    shape : (H, W), optional
        Bags: the taxel grid of pressure-array messages.
    field : str, optional
        Bags: the dotted path of the field holding the numbers, for any message type.
    sensor : str, optional
        Bags of ``tactile_msgs/msg/TactileState``: the sensor (channel) to read.
    msg_defs : sequence of MessageDefinition
        Bags: definitions (``.msg`` text) of message types neither standard nor stored in the bag.
    frames : int, optional
        Bags of pressure maps: frames per exploration (default: the shortest recording's length).
    index : path, optional
        A CSV ``file,class[,session]`` giving each file's class and session (else the files' layout).
    class_from : {"folder", "file"}, optional
        Each file's class from its folder or its file name (default: the tree decides,
        :func:`tactile_torch.robot.files.naming.recording_names`).
    session_from : {"folder", "file", "recording"}, optional
        Each file's session from its folder, its file name, or the file itself (default: the other
        level than the class's).
    sensor_range_g : float
        Samples beyond ±this are refused (``inf``: no check).
    max_messages : int
        Bags: messages read per topic at most.
    allow_pickle : bool
        Legacy vibration ``.npz`` of tactile-torch 0.1 (trusted files only).
    check : bool
        Refuse implausible recordings (:func:`check_recordings`); ``predict`` leaves the windows it
        cannot classify out instead.
    """

    columns: str | Sequence[str | int] | None = None
    units: str | None = None
    scale: float | None = None
    time_unit: str = "auto"
    sample_rate_hz: float | None = None
    topic: str | None = None
    shape: tuple[int, int] | None = None
    field: str | None = None
    sensor: str | None = None
    msg_defs: tuple = ()
    frames: int | None = None
    index: PathLike | None = None
    class_from: str | None = None
    session_from: str | None = None
    sensor_range_g: float = DEFAULT_RANGE_G
    max_messages: int = MAX_BAG_MESSAGES
    allow_pickle: bool = False
    check: bool = True


def _kind_of(path: Path) -> str:
    if is_bag(path):
        return "bag"
    return "csv" if path.suffix.lower() == ".csv" else "npz"


def _frame_recording(path: Path) -> bool:
    """Whether one ``.npz`` is a frame recording (``frames`` and ``t``), from its member names only."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as archive:
            members = set(archive.namelist())
    except (OSError, zipfile.BadZipFile):
        return False  # the reader says what is wrong with it
    return {"frames.npy", "t.npy"} <= members


def read_source(paths: PathLike | Sequence[PathLike], options: DataOptions | None = None):
    """Read ``paths`` (one ``.npz``, CSV logs, or ROS 2 bags) with ``options``; return its arrays.

    Returns
    -------
    ExplorationArrays, RecordingArrays, FeatureArrays or FrameRecordings
        As :func:`tactile_torch.robot.files.formats.read_data` (``.kind`` says which); frame recordings
        (``.npz`` of ``frames`` and ``t``, one or several) as
        :func:`~tactile_torch.robot.files.frame_recordings.read_frame_recordings`. Vibration recordings are
        in g and have passed :func:`check_recordings`; ``RecordingArrays.session`` is set from the
        files' layout or the index.

    Raises
    ------
    ValueError
        One line naming the file: anything :mod:`tactile_torch.robot.files.formats`, :mod:`tactile_torch.robot.files.csv_logs` or
        :mod:`~tactile_torch.robot.bags` refuse, files of different kinds together, or implausible samples.
    """
    from .formats import data_kind, read_csv_recordings, recordings_from_arrays
    from .npz import read_npz

    options = options or DataOptions()
    paths = [Path(paths)] if isinstance(paths, str | os.PathLike) else [Path(p) for p in paths]
    if not paths:
        raise ValueError("data must name a .npz file, CSV logs or ROS 2 bags, got none")
    kinds = {_kind_of(p) for p in paths}
    if len(kinds) > 1:
        raise ValueError(
            f"data must be one .npz file, frame recordings, CSV logs or ROS 2 bags (one kind), got {[str(p) for p in paths]}"
        )
    kind = kinds.pop()
    if kind == "npz" and (len(paths) > 1 or _frame_recording(paths[0])):
        from .frame_recordings import read_frame_recordings

        arrays = [read_npz(p, what="data file (.npz of docs/formats.md)") for p in paths]
        if len(paths) > 1 and not all("frames" in a and "t" in a for a in arrays):
            raise ValueError(
                f"data must be one .npz file, or frame recordings (frames and t), got {[str(p) for p in paths]}"
            )
        return read_frame_recordings(paths, options, arrays=arrays)
    units = options.units or "g"
    if units not in UNITS:
        raise ValueError(f"units must be one of {list(UNITS)}, got {units!r}")
    stated = options.sample_rate_hz
    if stated is not None and not (isinstance(stated, int | float) and np.isfinite(stated) and stated > 0):
        raise ValueError(f"sample_rate_hz must be a finite number of Hz > 0, got {stated!r}")
    if kind == "bag":
        return _read_bags(paths, options)
    if kind == "csv":
        data = read_csv_recordings(
            paths,
            index=options.index,
            class_from=options.class_from,
            session_from=options.session_from,
            columns=options.columns,
            scale=options.scale,
            units=units,
            time_unit=options.time_unit,
            sample_rate_hz=stated,
        )
        sources = [str(p) for p in paths]
    else:
        path = paths[0]
        arrays = read_npz(path, allow_pickle=options.allow_pickle, what="data file (.npz of docs/formats.md)")
        if data_kind(arrays, path) != "vibration":
            from .formats import read_data

            if stated is not None:
                raise ValueError(
                    f"sample_rate_hz applies to vibration recordings, got {data_kind(arrays, path)} data ({path})"
                )
            return read_data(path, allow_pickle=options.allow_pickle)
        signals = arrays["signals"]
        factor = UNITS[units] * (1.0 if options.scale is None else float(options.scale))
        if signals.dtype == object and factor != 1.0:
            raise ValueError(
                f"{path}: units or a scale apply to plain signals arrays, not to the pickled recordings of "
                "tactile-torch 0.1: re-save the file first (docs/formats.md)"
            )
        if signals.dtype != object and (factor != 1.0 or options.scale is not None):
            if np.issubdtype(signals.dtype, np.integer) and options.scale is None:
                from .csv_logs import integer_counts_message

                raise ValueError(integer_counts_message(f"{path}: signals", f"{signals.dtype}"))
            if np.issubdtype(signals.dtype, np.number):
                arrays["signals"] = signals.astype(np.float64) * factor
        data = recordings_from_arrays(arrays, path)
        if stated is not None:
            _check_stated(stated, data.rate_hz, f"{path}: rate_hz is")
            data.rate_hz = float(stated)
        session = data.session if data.session is not None else np.arange(len(data))
        sources = [f"{path}: recording {i} (session {s})" for i, s in enumerate(session)]
    if options.check:
        check_recordings(
            data.signals,
            sources,
            data.rate_hz,
            sensor_range_g=options.sensor_range_g,
            units=units,
            gaps=data.gaps,
        )
    data.sources = sources
    return data


def _check_stated(stated: float, found: float, what: str) -> None:
    """Refuse a stated rate off the one the data give by more than ``RATE_TOLERANCE``."""
    if abs(found / stated - 1.0) > RATE_TOLERANCE:
        raise ValueError(
            f"{what} {found:.6g} Hz, but sample_rate_hz={stated:g} was stated (they must agree within "
            f"{RATE_TOLERANCE:.0%}); check the rate"
        )


def _read_bags(paths: list[Path], options: DataOptions):
    from .formats import RecordingArrays

    names = recording_names(
        paths, index=options.index, class_from=options.class_from, session_from=options.session_from
    )
    classes, sessions = names.classes, names.sessions
    topics = [read_bag_topic(p, options) for p in paths]
    kinds = {t.kind for t in topics}
    if len(kinds) > 1:
        raise ValueError(
            f"the bags' topics hold IMU samples and frames ({sorted({t.msgtype for t in topics})}); read one kind at a time"
        )
    stated = options.sample_rate_hz
    if stated is not None:
        if kinds == {"frame"}:
            raise ValueError(
                f"sample_rate_hz applies to vibration recordings, got pressure maps ({paths[0]})"
            )
        for i, t in enumerate(topics):
            _check_stated(stated, t.rate_hz, f"{t.name}: the time stamps give")
            stamps = (t.stamps_s - t.stamps_s[0]) * 1e9
            timing = time_base(stamps, resolution=1.0, period=1e9 / stated)
            topics[i] = replace(t, rate_hz=float(stated), timing=timing)
    rates = np.array([t.rate_hz for t in topics])
    if np.abs(rates / rates[0] - 1).max() > 1e-2:
        odd = int(np.argmax(np.abs(rates / rates[0] - 1)))
        raise ValueError(
            f"the bags have different rates ({topics[0].name}: {rates[0]:g} Hz, {topics[odd].name}: "
            f"{rates[odd]:g} Hz); resample them to a common rate"
        )
    names = tuple(sorted(set(classes)))
    labels = np.array([names.index(c) for c in classes], dtype=np.int64)
    if kinds == {"frame"}:
        return _explorations(topics, labels, names, options.frames)
    signals = [t.values for t in topics]
    sources = [t.name for t in topics]
    for line in describe_timing([(t.name, t.timing, 1e-9) for t in topics], what="bag"):
        warnings.warn(line, stacklevel=3)
    gaps = [t.timing.gaps for t in topics]
    if options.check:
        check_recordings(
            signals, sources, float(rates[0]), sensor_range_g=options.sensor_range_g, units="m/s2", gaps=gaps
        )
    return RecordingArrays(
        signals,
        labels,
        names,
        float(rates[0]),
        np.array(sessions),
        gaps if any(g.size for g in gaps) else None,
    )


def _explorations(topics, labels: np.ndarray, names: tuple[str, ...], frames: int | None):
    """Cut each bag's pressure maps into explorations of ``frames`` maps; groups = the bag."""
    from .formats import ExplorationArrays

    shapes = {t.values.shape[1:] for t in topics}
    if len(shapes) > 1:
        raise ValueError(
            f"the bags' pressure maps differ in shape ({sorted(shapes)}); give bags of one sensor"
        )
    shortest = min(len(t.values) for t in topics)
    frames = shortest if frames is None else int(frames)
    if frames < 1 or frames > shortest:
        short = min(topics, key=lambda t: len(t.values))
        raise ValueError(
            f"frames must be in 1..{shortest} (the shortest recording, {short.name}, has {shortest} maps), got {frames}"
        )
    parts, y, groups = [], [], []
    for g, (t, label) in enumerate(zip(topics, labels, strict=True)):
        n = len(t.values) // frames
        parts.append(t.values[: n * frames].reshape(n, frames, *t.values.shape[1:]))
        y += [label] * n
        groups += [g] * n
    rate = float(np.median([t.rate_hz for t in topics]))  # the stamps' rate: a bag states its frame rate
    return ExplorationArrays(
        None, np.concatenate(parts), np.array(y, np.int64), names, np.array(groups, np.int64), rate
    )


def check_recordings(
    signals: Sequence[np.ndarray],
    sources: Sequence[str],
    rate_hz: float,
    *,
    sensor_range_g: float = DEFAULT_RANGE_G,
    units: str = "g",
    gaps: Sequence[np.ndarray] | None = None,
) -> None:
    """Refuse recordings whose samples the declared units make implausible; return ``None`` if all pass.

    ``gaps`` (per recording, the samples after a gap in its time stamps): a sample after a gap is
    named without a time, which ``index / rate_hz`` no longer gives.

    Checked per recording ``(n, 3)`` in g, in this order: the mean acceleration's norm lies in
    :data:`GRAVITY_BAND_G` (gravity of m/s^2 data read as g; only when ``units`` is ``"g"``); a
    sample beyond ``±sensor_range_g`` (1e30, a corrupted value, a wrong scale); every axis constant
    (a disconnected sensor: no vibration to classify). Non-finite samples are refused by the readers.

    Raises
    ------
    ValueError
        One line naming the recording (``sources[i]``), the sample (index and time) and the value.
    """
    for i, (signal, where) in enumerate(zip(signals, sources, strict=True)):
        s = np.asarray(signal, dtype=np.float64)
        if not len(s):
            continue
        mean = s.mean(axis=0)
        norm = float(np.linalg.norm(mean))
        if units == "g" and GRAVITY_BAND_G[0] <= norm <= GRAVITY_BAND_G[1]:
            raise ValueError(
                f"{where}: the mean acceleration is {norm:.3g} g (x, y, z = {', '.join(f'{m:.3g}' for m in mean)}): "
                f"gravity reads 1 g, so these look like m/s^2 ({STANDARD_GRAVITY} m/s^2 = 1 g); pass units='m/s2'"
            )
        beyond = np.abs(s) > sensor_range_g
        if beyond.any():
            row, axis = (int(i) for i in np.argwhere(beyond)[0])
            value = s[row, axis]
            reads = (
                f"{value:.4g} g"
                if abs(value) < FLOAT32_MAX
                else f"{'-' if value < 0 else ''}{FLOAT32_MAX:.3g} g or more (beyond float32)"
            )
            after_gap = gaps is not None and len(gaps[i]) and row >= int(gaps[i][0])
            when = "after a gap in t" if after_gap else f"t = {row / rate_hz:.4g} s"
            raise ValueError(
                f"{where}: sample {row} ({when}) reads {reads} on {'xyz'[axis]}, "
                f"beyond the sensor's ±{sensor_range_g:g} g ({int(beyond.any(axis=1).sum())} samples beyond); "
                "declare the range with sensor_range_g=G, or the units with units= / scale="
            )
        if len(s) > 1 and (np.ptp(s, axis=0) == 0).all():
            raise ValueError(
                f"{where}: all {len(s)} samples are equal ({', '.join(f'{v:.4g}' for v in s[0])} g): no vibration "
                "(a disconnected or saturated sensor?)"
            )


__all__ = ["GRAVITY_BAND_G", "DataOptions", "check_recordings", "read_source"]
