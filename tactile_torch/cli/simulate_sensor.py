"""``tactile-torch simulate-sensor``: emulate a serial sensor, an accelerometer or a taxel array, on a port or a pty.

Plays vibration recordings (``x,y,z`` lines, or a synthetic surface) and frame recordings (one frame per
line: a frame recording ``.npz``, image explorations, or a ROS 2 bag of pressure maps,
:mod:`tactile_torch.robot.files.frame_recordings`) in real time or as fast as the reader takes them.
Torch-free with ``--data`` (the synthetic surface needs the training extra).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass

import numpy as np

from ._options import (
    SEED,
    Number,
    UsageError,
    add_allow_pickle,
    add_csv_options,
    in_range,
    message_definitions,
)
from ._ros2 import add_dds_options, add_publisher_options

MAX_SIMULATED_S = 600
"""Longest synthetic recording ``simulate-sensor`` generates (28 surfaces are generated: 160 MB)."""


def register(sub) -> None:
    """Add the ``simulate-sensor`` command to the subparsers ``sub``."""
    p = sub.add_parser(
        "simulate-sensor",
        help="emulate a serial sensor: write a recording as 'x,y,z' lines, or frames one per line",
    )
    p.add_argument(
        "--port", default="", help="serial port or pyserial URL (e.g. the other end of a pty pair)"
    )
    p.add_argument(
        "--pty",
        action="store_true",
        help="instead of --port, open a pseudo-terminal and print the port to read",
    )
    p.add_argument(
        "--data",
        nargs="+",
        default=[],
        help="what to play, in order (a day's session: several files of one kind): vibration .npz or CSV logs, or "
        "frames: frame recordings .npz (frames and t), image explorations (.npz) or ROS 2 bags of pressure maps "
        "(default: a synthetic surface)",
    )
    add_csv_options(p.add_argument_group("reading a CSV log (docs/formats.md)"))
    p.add_argument(
        "--recording",
        type=Number(int, low=0),
        default=None,
        help="index of the recording (vibration, default 0) or exploration (default: all, with --rest between) to play",
    )
    p.add_argument(
        "--rest",
        type=in_range(0, 3600),
        default=0.5,
        help="explorations: seconds of resting frames after each (default: 0.5)",
    )
    p.add_argument(
        "--seconds",
        type=in_range(0, MAX_SIMULATED_S),
        default=10.0,
        help=f"synthetic: length in seconds, at most {MAX_SIMULATED_S} (default: 10)",
    )
    p.add_argument(
        "--rate",
        type=in_range(0, 1e6),
        default=None,
        help="samples (frames) per second when the file has none, > 0 (default: 800 for a vibration .npz that "
        "states none; explorations: their frame_rate_hz, else it is needed); stated for a CSV log (its time stamps "
        "must agree within 5%%; default: their rate)",
    )
    p.add_argument("--topic", default=None, help="bags: the topic to play (default: the only readable one)")
    p.add_argument(
        "--shape", default=None, help="bags: H,W of the pressure maps (default: the message layout)"
    )
    p.add_argument("--baud", type=Number(int, low=1), default=230400, help="baud rate (default: 230400)")
    p.add_argument("--fast", action="store_true", help="write as fast as possible instead of in real time")
    p.add_argument(
        "--timestamps",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="write 't,...' lines, t in seconds: the recordings' own stamps (a CSV log's, a frame recording's), "
        "else from 0 at the rate (default: when the data have their own stamps; --no-timestamps: never)",
    )
    p.add_argument(
        "--wait-reader",
        type=Number(float, low=0),
        default=60.0,
        metavar="S",
        help="--pty: wait up to S s for a reader to open the port before writing, so that nothing is lost at the "
        "start (0: write at once; default: 60)",
    )
    p.add_argument("--seed", type=SEED, default=0, help="synthetic: random seed (default: 0)")
    add_allow_pickle(p)
    add_publisher_options(add_dds_options(p, reader=False))
    p.set_defaults(handler=run_simulate_sensor)


def _frames_file(path: str) -> bool:
    """Whether ``--data`` holds frames (a frame recording, explorations, a bag of pressure maps)."""
    from pathlib import Path

    from ..robot.ros2.bags import is_bag

    if is_bag(path):
        return True
    if Path(path).suffix.lower() != ".npz":
        return False
    from ..robot.files.npz import read_npz

    return "frames" in read_npz(path, what="data file (.npz of docs/formats.md)")


@dataclass
class Playlist:
    """What ``simulate-sensor`` plays: the items of every ``--data`` file in order, with their stamps.

    ``kind``: ``"samples"`` (``values`` ``(n, 3)`` in g) or ``"frames"`` (``(n, H, W)``, ``(n, H, W, 3)``);
    ``t``: each item's own stamp in seconds when every file has them (a CSV log's time column, a frame
    recording's ``t``), else ``None``; ``pace``: when each item is written, in seconds since the first:
    each file at its own stamps (pauses inside a file kept), the next file one period after the last item
    of the previous one (the stamps' jump between two files is not waited for, the reader sees it in ``t``).
    """

    kind: str
    values: np.ndarray
    t: np.ndarray | None
    pace: np.ndarray
    rate_hz: float
    names: list[str]


def _joined(kind: str, parts: list, names: list[str]) -> Playlist:
    """``parts``: ``(values, own t or None, rate)`` per file, in order."""
    values = np.concatenate([v for v, _, _ in parts])
    rate = float(parts[0][2])
    own = all(t is not None for _, t, _ in parts)
    pace, start = [], 0.0
    for v, t, r in parts:
        step = (np.arange(len(v)) / r) if t is None else (t - t[0])
        pace.append(start + step)
        start += float(step[-1]) + 1.0 / r if len(v) else 0.0
    t = np.concatenate([t for _, t, _ in parts]) if own else None
    return Playlist(kind, values, t, np.concatenate(pace), rate, names)


def _states_no_rate(path: str) -> bool:
    """Whether a ``.npz`` of explorations states no frame rate (neither ``t`` nor ``frame_rate_hz``), from its members."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as archive:
            members = set(archive.namelist())
    except (OSError, zipfile.BadZipFile):
        return False  # a bag, or a file the reader refuses with its own line
    return "frames.npy" in members and not members & {"t.npy", "frame_rate_hz.npy"}


def _playlist(args: argparse.Namespace) -> Playlist:
    """Read every ``--data`` file (or make a synthetic surface); return what to play."""
    data = list(args.data)
    if not data:
        from ..data import make_vibration_recordings  # numpy only, as on the robot

        rec = make_vibration_recordings(28, duration_s=args.seconds, random_state=args.seed)
        recording = 0 if args.recording is None else args.recording
        return _joined("samples", [(rec.signals[recording % 28], None, rec.rate_hz)], ["a synthetic surface"])
    frames = [_frames_file(path) for path in data]
    if any(frames) and not all(frames):
        raise UsageError(f"--data: play frames or samples, not both in one session, got {data}")
    if all(frames):
        from ..robot.files.data_sources import DataOptions
        from ..robot.files.frame_recordings import read_frame_recording

        shape = None
        if args.shape:
            from ._options import _shape

            shape = _shape(args.shape)
        options = DataOptions(
            topic=args.topic,
            shape=shape,
            field=args.field,
            sensor=args.sensor,
            msg_defs=message_definitions(args),
        )
        for path in data:
            if args.rate is None and _states_no_rate(path):
                raise UsageError(
                    f"--rate: {path} holds explorations without 't' or 'frame_rate_hz', so their frame rate is "
                    "unknown; give it"
                )
        recs = [
            read_frame_recording(
                path, recording=args.recording, frame_rate_hz=args.rate, rest_s=args.rest, options=options
            )
            for path in data
        ]
        shapes = {r.frames.shape[1:] for r in recs}
        if len(shapes) > 1:
            raise UsageError(
                f"--data: the recordings hold frames of different shapes {sorted(shapes)}; play one sensor"
            )
        return _joined("frames", [(r.frames, r.t, r.rate_hz) for r in recs], [r.name for r in recs])
    parts = [_samples(args, path) for path in data]
    rates = {round(r, 6) for _, _, r in parts}
    if len(rates) > 1:
        raise UsageError(
            f"--data: the files have different sample rates ({sorted(rates)} Hz); play one rate at a time"
        )
    return _joined("samples", parts, data)


def _samples(args: argparse.Namespace, path: str) -> tuple:
    """``(samples (n, 3) in g, own stamps in seconds or None, rate)`` of one vibration file."""
    recording = 0 if args.recording is None else args.recording
    if path.lower().endswith(".csv"):  # a logger's CSV, read as train reads it, with its own stamps
        from ..robot.files.csv_logs import read_csv_log

        log = read_csv_log(
            path,
            columns=args.columns,
            units=args.units or "g",
            scale=args.scale,
            time_unit=args.time_unit,
            sample_rate_hz=args.rate,
        )
        return log.signal, log.t, log.rate_hz
    from ..robot.files.formats import read_recordings  # any layout of docs/formats.md

    csv_only = [
        o for o, v in (("--columns", args.columns), ("--units", args.units), ("--scale", args.scale)) if v
    ]
    if csv_only or args.time_unit != "auto":
        raise UsageError(f"{', '.join(csv_only) or '--time-unit'} applies to a CSV log, got {path}")
    data = read_recordings(path, allow_pickle=args.allow_pickle, default_rate_hz=args.rate or 800.0)
    if not 0 <= recording < len(data):
        raise UsageError(f"--recording must be in 0..{len(data) - 1} ({path}), got {recording}")
    return data.signals[recording], None, data.rate_hz


def run_simulate_sensor(args: argparse.Namespace) -> int:
    """Write the recordings to the port as sensor lines; return the exit status."""
    import contextlib

    import serial

    from ..robot.stream.wire import pseudo_terminal, simulate_frames, simulate_sensor, wait_for_reader

    if bool(args.port) + args.pty + bool(args.ros2_topic) != 1:
        print(
            "tactile-torch simulate-sensor: give one of --port PORT, --pty or --ros2-topic TOPIC",
            file=sys.stderr,
        )
        return 2
    if args.ros2_topic:  # a ROS 2 publisher over DDS: samples as sensor_msgs/Imu, frames as frame messages
        from ._ros2 import check_ros2_options, run_simulate_ros2

        check_ros2_options(args, "--ros2-topic")
        play = _playlist(args)
        kind = "frame" if play.kind == "frames" else "sample"
        return run_simulate_ros2(args, play.values, play.rate_hz, kind, t=play.t)
    play = _playlist(args)
    timestamps = play.t is not None if args.timestamps is None else args.timestamps
    what = f"{play.names[0]}" + (f" and {len(play.names) - 1} more" if len(play.names) > 1 else "")
    with contextlib.ExitStack() as stack:
        if args.pty:
            port, name = stack.enter_context(pseudo_terminal())
            print(f"sensor on {name}: read it with tactile-torch stream --port {name}", flush=True)
            if args.wait_reader and not wait_for_reader(port, args.wait_reader):
                print(
                    f"tactile-torch simulate-sensor: no reader opened {name} within {args.wait_reader:g} s; writing anyway",
                    file=sys.stderr,
                    flush=True,
                )
        else:
            port, name = stack.enter_context(serial.serial_for_url(args.port, baudrate=args.baud)), args.port
        stamps = "their own t" if timestamps and play.t is not None else "t from 0" if timestamps else "no t"
        frames = play.kind == "frames"
        unit = "frames" if frames else "samples"
        shape = f" of {play.values.shape[1]} x {play.values.shape[2]}" if frames else ""
        rate = f"{play.rate_hz:.4g} frames/s" if frames else f"{play.rate_hz:g} Hz"
        print(f"writing {len(play.values)} {unit}{shape} at {rate} ({what}; {stamps}) to {name}", flush=True)
        n = (simulate_frames if frames else simulate_sensor)(
            port,
            play.values,
            rate_hz=play.rate_hz,
            t=play.t,
            pace=play.pace,
            realtime=not args.fast,
            timestamps=timestamps,
        )
    print(f"{n} {unit} written")
    return 0
