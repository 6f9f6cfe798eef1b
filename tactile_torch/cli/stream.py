"""``tactile-torch stream`` and ``simulate-sensor``: classify a live serial accelerometer, and emulate one.

Torch-free, as on the robot: pyserial, numpy and onnxruntime (:mod:`tactile_torch.robot.stream`,
:mod:`tactile_torch.robot.stream_output`, :class:`tactile_torch.robot.runtime.OnnxPipeline`).
"""

from __future__ import annotations

import argparse
import sys

from . import (
    STREAM_DISCONNECTED_EXIT,
    STREAM_NO_DATA_EXIT,
    STREAM_OUTPUT_CLOSED_EXIT,
    STREAM_STOPPED_EXIT,
)
from ._options import (
    SEED,
    Number,
    UsageError,
    add_allow_pickle,
    add_csv_options,
    at_least,
    in_range,
    parse_range_g,
)

MAX_SIMULATED_S = 600
"""Longest synthetic recording ``simulate-sensor`` generates (28 surfaces are generated: 160 MB)."""


def register(sub) -> None:
    """Add the ``stream`` and ``simulate-sensor`` commands to the subparsers ``sub``."""
    p = sub.add_parser(
        "stream",
        help="classify a live serial accelerometer stream with an exported vibration bundle",
        description="Read 'x,y,z' or 't,x,y,z' lines (g, or --units, --scale) from a serial port (any pyserial URL, e.g. "
        "/dev/ttyUSB0, socket://host:port, loop://), cut them into the bundle's windows and print each "
        "window's class on stdout. Status lines (silence, disconnection, gaps in t, samples out of range, "
        "garbage lines, the summary) go to stderr; no window spans a gap. Exit status: 0 done, 3 no data "
        "within the timeout, 4 port failed, 5 stdout closed (see docs/stream.md).",
    )
    p.add_argument("--model", required=True, help="the .onnx vibration bundle")
    p.add_argument("--port", required=True, help="serial port or pyserial URL")
    p.add_argument("--baud", type=Number(int, low=1), default=230400, help="baud rate (default: 230400)")
    p.add_argument(
        "--step",
        type=at_least(1, int),
        default=None,
        help="new samples between windows, >= 1 (default: half a window)",
    )
    p.add_argument(
        "--max-windows",
        type=at_least(0, int),
        default=0,
        help="stop after this many windows (default: no limit)",
    )
    p.add_argument(
        "--threads", type=at_least(0, int), default=1, help="onnxruntime intra-op threads (default: 1)"
    )
    p.add_argument(
        "--json", action="store_true", help="one JSON object per window on stdout (docs/stream.md)"
    )
    p.add_argument(
        "--vote",
        type=at_least(1, int),
        default=1,
        help="also give the vote over the last N windows (default: 1, no vote)",
    )
    p.add_argument(
        "--vote-method",
        default="majority",
        choices=["majority", "mean"],
        help="majority of the labels, or argmax of the mean scores (default: majority)",
    )
    p.add_argument(
        "--reconnect", action="store_true", help="reopen the port with backoff when it fails (default: exit)"
    )
    p.add_argument(
        "--idle-timeout",
        "--timeout",
        type=at_least(0),
        default=10.0,
        help="give up after this many seconds without a sample; 0: never (default: 10)",
    )
    p.add_argument(
        "--start-timeout",
        type=at_least(0),
        default=60.0,
        help="wait this long for the first sample; 0: forever (default: 60)",
    )
    p.add_argument(
        "--silence",
        type=at_least(0.01),
        default=0.5,
        help="seconds without a sample reported as a silence, which ends the window (default: 0.5)",
    )
    p.add_argument(
        "--range",
        type=Number(low=0, open_low=True, allow_inf=True, unit="g"),
        help="reject samples beyond +-RANGE g; inf: off (default: the bundle's sensor_range_g, else 5 for the "
        "ADXL345)",
    )
    p.add_argument(
        "--units",
        default="g",
        choices=["g", "m/s2"],
        help="units of the x,y,z values, as train's --units (default: g)",
    )
    p.add_argument(
        "--scale",
        type=in_range(0, 1e6),
        default=None,
        help="units per count for a sensor that sends integer counts, e.g. 0.0039 (ADXL345 at full "
        "resolution), as train's --scale",
    )
    p.add_argument(
        "--time-unit",
        default="s",
        choices=["s", "ms", "us", "samples"],
        help="unit of the t field of t,x,y,z lines; 'samples' for a sample counter (default: s)",
    )
    p.add_argument(
        "--discover",
        type=Number(int, low=0),
        default=0,
        metavar="N",
        help="clustering bundles: propose a new surface after N consecutive novel windows (default: off)",
    )
    p.set_defaults(handler=run_stream)

    p = sub.add_parser(
        "simulate-sensor",
        help="emulate the serial accelerometer: write a recorded or synthetic recording as 'x,y,z' lines",
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
        "--data", default="", help="vibration .npz or CSV log to play (default: a synthetic surface)"
    )
    add_csv_options(p.add_argument_group("reading a CSV log (docs/formats.md)"))
    p.add_argument(
        "--recording", type=Number(int, low=0), default=0, help="index of the recording to play (default: 0)"
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
        help="sample rate (Hz): of a .npz without rate_hz (default: 800), or stated for a CSV log (its time "
        "stamps must agree within 5%%; default: their rate)",
    )
    p.add_argument("--baud", type=Number(int, low=1), default=230400, help="baud rate (default: 230400)")
    p.add_argument("--fast", action="store_true", help="write as fast as possible instead of in real time")
    p.add_argument("--timestamps", action="store_true", help="write 't,x,y,z' lines (t in seconds)")
    p.add_argument("--seed", type=SEED, default=0, help="synthetic: random seed (default: 0)")
    add_allow_pickle(p)
    p.set_defaults(handler=run_simulate_sensor)


def run_stream(args: argparse.Namespace) -> int:
    """Classify the stream's windows until it ends; return the exit status (see :func:`register`)."""
    # torch-free: pyserial, numpy and onnxruntime only, as on the robot.
    # SIGTERM (how systemd stops a service) ends the stream as Ctrl-C does: summary line, status 0.
    restore = _stop_on_sigterm()
    try:
        return _stream_until_stopped(args)
    except _Stopped:  # before reading: nothing read, a requested end
        print("tactile-torch stream: stopped by SIGTERM before reading", file=sys.stderr)
        return STREAM_STOPPED_EXIT
    finally:
        restore()


def _stream_until_stopped(args: argparse.Namespace) -> int:
    import math

    import numpy as np
    import serial

    from ..robot.contract import SAMPLE_RATE_KEY, WINDOW_SIZE_KEY
    from ..robot.runtime import OnnxPipeline
    from ..robot.stream import (
        StreamDisconnected,
        StreamTimeout,
        WindowReader,
        open_serial_port,
        sensor_range_g,
    )
    from ..robot.stream_output import WindowVote, classify_windows, result_json, result_text
    from . import ARGUMENT_FLAGS, with_flags
    from ._output import stdout_closed

    range_g = parse_range_g(args.range, "--range", off=True)
    pipe = OnnxPipeline(args.model, intra_op_threads=args.threads)
    if WINDOW_SIZE_KEY not in pipe.metadata:
        print(f"tactile-torch stream: {args.model} does not take vibration windows", file=sys.stderr)
        return 2
    size = int(pipe.metadata[WINDOW_SIZE_KEY])
    step = args.step if args.step is not None else max(size // 2, 1)
    rate = float(pipe.metadata[SAMPLE_RATE_KEY]) if SAMPLE_RATE_KEY in pipe.metadata else None
    if args.time_unit == "samples" and rate is None:
        print(
            f"tactile-torch stream: --time-unit samples needs the sample rate, which {args.model} lacks",
            file=sys.stderr,
        )
        return 2
    # stdout holds the decisions (one line per window, text or JSON), stderr everything else
    info = sys.stderr
    # the reader names its arguments (pass units='m/s2'): show the options that set them
    flags = {**{k: ARGUMENT_FLAGS[k] for k in ("units", "scale", "time_unit")}, "range_g": "--range"}

    def say(message: str) -> None:
        print(f"tactile-torch stream: {with_flags(message, flags)}", file=sys.stderr, flush=True)

    ports_opened = []

    def open_port():
        # The first open discards what the port held from before the stream; a reopen keeps what the
        # sensor sent during the wait (pyserial's open would flush it: issue 34).
        options = {"baudrate": args.baud, "timeout": min(0.1, args.silence / 2)}
        port = (
            open_serial_port(args.port, **options, keep_input=True)
            if ports_opened
            else serial.serial_for_url(args.port, **options)
        )
        ports_opened.append(args.port)
        return port

    reading = []  # printed once the port is open (and the model warm): a sensor may start then

    def opened(name: str) -> None:
        if not reading:
            reading.append(name)
            print(
                f"{pipe!r}: reading {args.port}, windows of {size} samples every {step}, range ±{reader.range_g:g} g",
                file=info,
                flush=True,
            )

    reader = WindowReader(
        open_port,
        window_size=size,
        step=step,
        max_windows=args.max_windows or None,
        rate_hz=rate,
        time_unit=args.time_unit,
        units=args.units,
        scale=args.scale,
        range_g=range_g or sensor_range_g(pipe.metadata),
        silence_s=args.silence,
        idle_timeout_s=args.idle_timeout or math.inf,
        start_timeout_s=args.start_timeout or math.inf,
        reconnect=args.reconnect,
        on_event=lambda event: say(event.message),
        on_open=opened,
        name=args.port,
    )
    vote = WindowVote(args.vote, args.vote_method, pipe.class_names) if args.vote > 1 else None
    # Each classified window goes to every consumer in turn.
    write = result_json if args.json else result_text
    unknown = [0]

    def show(result) -> None:
        unknown[0] += result.label == -1
        try:
            print(write(result), flush=True)
        except BrokenPipeError:  # an unguarded stdout (the guard of cli.main catches it and says so)
            raise _OutputClosed() from None
        if stdout_closed():
            raise _OutputClosed()

    consumers = [show]
    if args.discover:  # new surfaces: N novel windows in a row (tactile_torch.robot.discovery)
        from ..robot.discovery import stream_consumer

        consumers.append(stream_consumer(pipe, args.discover, sys.stderr if args.json else sys.stdout))
    status = 0
    try:
        # The first call allocates: run it before the port is opened (opening flushes the port's
        # buffer), so that neither the warm-up nor the open costs the sensor's first samples.
        warm = np.linspace(-0.5, 0.5, 3 * size, dtype=np.float32).reshape(1, 3, size)
        pipe.classify(warm)
        for result in classify_windows(reader, pipe, vote=vote, range_g=reader.range_g):
            for consume in consumers:
                consume(result)
    except StreamTimeout as err:
        say(str(err))
        status = STREAM_NO_DATA_EXIT
    except StreamDisconnected as err:
        say(str(err))
        status = STREAM_DISCONNECTED_EXIT
    except _OutputClosed:  # nobody reads the decisions any more: classifying on would be for nothing
        say(f"stdout closed (its reader went away) after {reader.windows} windows; stopping")
        status = STREAM_OUTPUT_CLOSED_EXIT
    except (KeyboardInterrupt, _Stopped) as err:
        say(f"stopped by {'SIGTERM' if isinstance(err, _Stopped) else 'SIGINT (Ctrl-C)'}")
        status = STREAM_STOPPED_EXIT
    print(
        f"{reader.samples} samples read, {reader.windows} windows, {reader.skipped} lines skipped, "
        f"{reader.rejected} samples out of range, {reader.gaps} gaps ({reader.lost} samples known lost), "
        f"{reader.reconnects} reconnections, {unknown[0]} windows unknown, {reader.format_switches} "
        "line-format switches",
        file=info,
        flush=True,
    )
    return status


class _Stopped(Exception):
    """SIGTERM arrived while streaming."""


class _OutputClosed(Exception):
    """stdout was closed: the reader of the decisions went away."""


def _stop_on_sigterm():
    """Make SIGTERM raise :class:`_Stopped` in the main thread; return the function that restores it."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def stop(signum, frame):
        raise _Stopped()

    previous = signal.signal(signal.SIGTERM, stop)
    return lambda: signal.signal(signal.SIGTERM, previous)


def run_simulate_sensor(args: argparse.Namespace) -> int:
    """Write the recording to the port as sensor lines; return the exit status."""
    import contextlib

    import serial

    from ..robot.stream import pseudo_terminal, simulate_sensor

    if bool(args.port) == args.pty:
        print("tactile-torch simulate-sensor: give either --port PORT or --pty", file=sys.stderr)
        return 2
    if args.data.lower().endswith(".csv"):  # a logger's CSV, read as train reads it
        from ..robot.data_sources import DataOptions, read_source

        declared = {
            "columns": args.columns,
            "units": args.units,
            "scale": args.scale,
            "time_unit": args.time_unit,
        }
        data = read_source([args.data], DataOptions(**declared, sample_rate_hz=args.rate, check=False))
    elif args.data:  # any layout of docs/formats.md, incl. recordings of different lengths
        from ..robot.formats import read_recordings

        csv_only = [
            o for o, v in (("--columns", args.columns), ("--units", args.units), ("--scale", args.scale)) if v
        ]
        if csv_only or args.time_unit != "auto":
            raise UsageError(f"{', '.join(csv_only) or '--time-unit'} applies to a CSV log, got {args.data}")
        data = read_recordings(args.data, allow_pickle=args.allow_pickle, default_rate_hz=args.rate or 800.0)
    if args.data:
        if not 0 <= args.recording < len(data):
            raise UsageError(f"--recording must be in 0..{len(data) - 1} ({args.data}), got {args.recording}")
        recording, rate = data.signals[args.recording], data.rate_hz
    else:
        from ..data import make_vibration_recordings

        rec = make_vibration_recordings(28, duration_s=args.seconds, random_state=args.seed)
        recording, rate = rec.signals[args.recording % 28], rec.rate_hz
    with contextlib.ExitStack() as stack:
        if args.pty:
            port, name = stack.enter_context(pseudo_terminal())
            print(f"sensor on {name}: read it with tactile-torch stream --port {name}", flush=True)
        else:
            port, name = stack.enter_context(serial.serial_for_url(args.port, baudrate=args.baud)), args.port
        print(f"writing {len(recording)} samples at {rate:g} Hz to {name}", flush=True)
        n = simulate_sensor(port, recording, rate_hz=rate, realtime=not args.fast, timestamps=args.timestamps)
    print(f"{n} samples written")
    return 0
