"""``tactile-torch simulate-sensor``: emulate a serial sensor, an accelerometer or a taxel array, on a port or a pty.

Plays vibration recordings (``x,y,z`` lines, or a synthetic surface) and frame recordings (one frame per
line: a frame recording ``.npz``, image explorations, or a ROS 2 bag of pressure maps,
:mod:`tactile_torch.robot.files.frame_recordings`) in real time or as fast as the reader takes them.
Torch-free with ``--data`` (the synthetic surface needs the training extra).
"""

from __future__ import annotations

import argparse
import sys

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
        default="",
        help="vibration .npz or CSV to play, or frames: a frame recording .npz (frames and t), image "
        "explorations (.npz) or a ROS 2 bag of pressure maps (default: a synthetic surface)",
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
        help="samples (frames) per second when the file has none, > 0 (default: 800; explorations: 10); "
        "stated for a CSV log (its time stamps must agree within 5%%; default: their rate)",
    )
    p.add_argument("--topic", default=None, help="bags: the topic to play (default: the only readable one)")
    p.add_argument(
        "--shape", default=None, help="bags: H,W of the pressure maps (default: the message layout)"
    )
    p.add_argument("--baud", type=Number(int, low=1), default=230400, help="baud rate (default: 230400)")
    p.add_argument("--fast", action="store_true", help="write as fast as possible instead of in real time")
    p.add_argument("--timestamps", action="store_true", help="write 't,...' lines (t in seconds)")
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


def _recording(args: argparse.Namespace):
    """Return ``("frames", FrameRecording)`` or ``("samples", (n, 3) samples, rate)`` for the options."""
    if args.data and _frames_file(args.data):
        from ..robot.files.data_sources import DataOptions
        from ..robot.files.frame_recordings import read_frame_recording

        shape = None
        if args.shape:
            from ._options import _shape

            shape = _shape(args.shape)
        rec = read_frame_recording(
            args.data,
            recording=args.recording,
            rate_hz=args.rate or 10.0,
            rest_s=args.rest,
            options=DataOptions(
                topic=args.topic,
                shape=shape,
                field=args.field,
                sensor=args.sensor,
                msg_defs=message_definitions(args),
            ),
        )
        return "frames", rec
    recording = 0 if args.recording is None else args.recording
    if args.data.lower().endswith(".csv"):  # a logger's CSV, read as train reads it
        from ..robot.files.data_sources import DataOptions, read_source

        declared = {
            "columns": args.columns,
            "units": args.units,
            "scale": args.scale,
            "time_unit": args.time_unit,
        }
        data = read_source([args.data], DataOptions(**declared, sample_rate_hz=args.rate, check=False))
    elif args.data:  # any layout of docs/formats.md, incl. recordings of different lengths
        from ..robot.files.formats import read_recordings

        csv_only = [
            o for o, v in (("--columns", args.columns), ("--units", args.units), ("--scale", args.scale)) if v
        ]
        if csv_only or args.time_unit != "auto":
            raise UsageError(f"{', '.join(csv_only) or '--time-unit'} applies to a CSV log, got {args.data}")
        data = read_recordings(args.data, allow_pickle=args.allow_pickle, default_rate_hz=args.rate or 800.0)
    if args.data:
        if not 0 <= recording < len(data):
            raise UsageError(f"--recording must be in 0..{len(data) - 1} ({args.data}), got {recording}")
        return "samples", (data.signals[recording], data.rate_hz)
    from ..data import make_vibration_recordings

    rec = make_vibration_recordings(28, duration_s=args.seconds, random_state=args.seed)
    return "samples", (rec.signals[recording % 28], rec.rate_hz)


def run_simulate_sensor(args: argparse.Namespace) -> int:
    """Write the recording to the port as sensor lines; return the exit status."""
    import contextlib

    import serial

    from ..robot.stream.wire import pseudo_terminal, simulate_frames, simulate_sensor

    if bool(args.port) + args.pty + bool(args.ros2_topic) != 1:
        print(
            "tactile-torch simulate-sensor: give one of --port PORT, --pty or --ros2-topic TOPIC",
            file=sys.stderr,
        )
        return 2
    if args.ros2_topic:  # a ROS 2 publisher over DDS: samples as sensor_msgs/Imu, frames as frame messages
        from ._ros2 import check_ros2_options, run_simulate_ros2

        check_ros2_options(args, "--ros2-topic")
        kind, what = _recording(args)
        if kind == "frames":
            return run_simulate_ros2(args, what.frames, what.rate_hz, "frame", t=what.t)
        return run_simulate_ros2(args, what[0], what[1], "sample")
    kind, what = _recording(args)
    with contextlib.ExitStack() as stack:
        if args.pty:
            port, name = stack.enter_context(pseudo_terminal())
            print(f"sensor on {name}: read it with tactile-torch stream --port {name}", flush=True)
        else:
            port, name = stack.enter_context(serial.serial_for_url(args.port, baudrate=args.baud)), args.port
        if kind == "frames":
            h, w = what.frames.shape[1:3]
            print(
                f"writing {len(what)} frames of {h} x {w} at {what.rate_hz:.4g} frames/s ({what.name}) to {name}",
                flush=True,
            )
            n = simulate_frames(
                port, what.frames, t=what.t, realtime=not args.fast, timestamps=args.timestamps
            )
            print(f"{n} frames written")
            return 0
        recording, rate = what
        print(f"writing {len(recording)} samples at {rate:g} Hz to {name}", flush=True)
        n = simulate_sensor(port, recording, rate_hz=rate, realtime=not args.fast, timestamps=args.timestamps)
    print(f"{n} samples written")
    return 0
