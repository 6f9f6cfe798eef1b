"""``tactile-torch stream``: classify a live serial sensor, an accelerometer or a taxel array, with a bundle.

Torch-free, as on the robot: pyserial, numpy and onnxruntime (:mod:`tactile_torch.robot.stream.live`, which
assembles the stream's stages, :mod:`tactile_torch.robot.stream.serial_source`,
:class:`tactile_torch.robot.runtime.OnnxPipeline`). The source is built by :func:`open_source` (the
place where other transports plug in) and every result goes to the output hooks of
:func:`output_hooks`.
"""

from __future__ import annotations

import argparse
import math
import sys

from ._codes import (
    STREAM_DISCONNECTED_EXIT,
    STREAM_NO_DATA_EXIT,
    STREAM_OUTPUT_CLOSED_EXIT,
    STREAM_STOPPED_EXIT,
)
from ._options import (
    CPUS,
    Number,
    UsageError,
    add_touch_options,
    at_least,
    in_range,
    parse_range_g,
    touch_options,
)
from ._ros2 import add_dds_options, add_subscriber_options


def register(sub) -> None:
    """Add the ``stream`` command to the subparsers ``sub``."""
    p = sub.add_parser(
        "stream",
        help="classify a live serial sensor (accelerometer samples or taxel frames) with an exported bundle",
        description="Read lines from a serial port (any pyserial URL, e.g. /dev/ttyUSB0, socket://host:port, "
        "loop://): 'x,y,z' or 't,x,y,z' samples (g, or --units, --scale) for a vibration bundle, or one frame "
        "per line (its H*W values, optionally t first) for a taxel-array bundle. Samples are cut into the "
        "bundle's windows; frames into touches (one decision per touch, early when the bundle's calibrated "
        "rule is sure) or sliding windows (--segment windows). The decisions go to stdout; status lines "
        "(silence, disconnection, gaps in t, values out of range, garbage lines, the summary) to stderr; no "
        "window or touch spans a gap. Exit status: 0 done, 3 no data within the timeout, 4 port failed, 5 "
        "stdout closed (see docs/stream.md).",
    )
    p.add_argument("--model", required=True, help="the .onnx bundle (vibration windows or taxel frames)")
    p.add_argument("--port", default=None, help="serial port or pyserial URL (or --ros2-topic)")
    p.add_argument("--baud", type=Number(int, low=1), default=230400, help="baud rate (default: 230400)")
    p.add_argument(
        "--segment",
        default="auto",
        choices=["auto", "windows", "touches"],
        help="frame bundles: cut touches (auto) or sliding windows of the bundle's frames for continuous "
        "exploration; vibration bundles: windows",
    )
    p.add_argument(
        "--step",
        type=at_least(1, int),
        default=None,
        help="windows: new samples or frames between windows, >= 1 (default: half a window)",
    )
    p.add_argument(
        "--max-windows",
        "--max-results",
        dest="max_windows",
        type=at_least(0, int),
        default=0,
        help="stop after this many windows or touches (default: no limit)",
    )
    p.add_argument(
        "--threads",
        type=Number(int, low=0, high=CPUS),
        default=1,
        help=f"onnxruntime intra-op threads, at most this machine's {CPUS} CPUs (0: onnxruntime's choice; default: 1)",
    )
    p.add_argument(
        "--json", action="store_true", help="one JSON object per result on stdout (docs/stream.md)"
    )
    p.add_argument(
        "--vote",
        type=at_least(1, int),
        default=1,
        help="windows: also give the vote over the last N windows (default: 1, no vote)",
    )
    p.add_argument(
        "--vote-method",
        default="majority",
        choices=["majority", "mean"],
        help="majority of the labels, or argmax of the mean scores (default: majority)",
    )
    add_touch_options(p)
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
        help="seconds without a sample reported as a silence, which ends the window or touch (default: 0.5)",
    )
    p.add_argument(
        "--range",
        help="vibration: reject samples beyond +-RANGE g (default: the bundle's sensor_range_g, else 5); frames: "
        "reject frames with a value outside LOW,HIGH (default: the bundle's value_range); inf: off",
    )
    p.add_argument(
        "--units",
        default="g",
        choices=["g", "m/s2"],
        help="vibration: units of the x,y,z values, as train's --units (default: g)",
    )
    p.add_argument(
        "--scale",
        type=in_range(0, 1e6),
        default=None,
        help="vibration: units per count for a sensor that sends integer counts, e.g. 0.0039 (ADXL345 at full "
        "resolution), as train's --scale",
    )
    p.add_argument(
        "--time-unit",
        default="s",
        choices=["s", "ms", "us", "samples"],
        help="unit of the t field; 'samples' for a sample or frame counter (default: s)",
    )
    p.add_argument(
        "--discover",
        type=Number(int, low=0),
        default=0,
        metavar="N",
        help="clustering bundles: propose a new surface after N consecutive novel windows (default: off)",
    )
    add_subscriber_options(add_dds_options(p, reader=True))
    p.set_defaults(handler=run_stream)


def run_stream(args: argparse.Namespace) -> int:
    """Classify the stream until it ends; return the exit status (see :func:`register`)."""
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


def _value_range(text: str | None) -> tuple[float, float] | None:
    """``--range`` of a frame bundle: ``LOW,HIGH`` or ``inf``."""
    if text is None:
        return None
    if text.strip() == "inf":
        return (-math.inf, math.inf)
    try:
        low, high = (float(v) for v in text.split(","))
    except ValueError:
        low = high = math.nan
    if not low < high:
        raise UsageError(
            f"--range must be LOW,HIGH (two numbers, LOW < HIGH) or inf for frames, got {text!r}"
        )
    return low, high


def open_source(args: argparse.Namespace, spec, *, on_event, on_open):
    """Return the stream's :class:`~tactile_torch.robot.stream.source.Source` for the command's options.

    The serial port of ``--port`` (a pyserial URL), reopened by the source to reconnect; or the ROS 2
    topic of ``--ros2-topic`` over DDS (:func:`tactile_torch.cli._ros2.open_ros2_source`). Another
    transport plugs in here (it must yield the items of ``spec``: docs/stream.md, "Sources").
    """
    if args.ros2_topic:
        from ._ros2 import open_ros2_source

        return open_ros2_source(args, spec, on_event=on_event, on_open=on_open)
    from ..robot.stream.port_lines import open_serial_port
    from ..robot.stream.serial_source import SerialSource

    opened = []

    def open_port():
        # The first open discards what the port held from before the stream; a reopen keeps what the
        # sensor sent during the wait (pyserial's open would flush it).
        port = open_serial_port(
            args.port, baudrate=args.baud, timeout=min(0.1, args.silence / 2), keep_input=bool(opened)
        )
        opened.append(args.port)
        return port

    if args.sensor not in (None, "all"):
        raise UsageError(
            "--sensor with --port: 'all' reads the frames of several arrays on one line (or give none)"
        )
    return SerialSource(
        open_port,
        spec,
        all_sensors=args.sensor == "all",
        time_unit=args.time_unit,
        units=args.units,
        scale=args.scale,
        silence_s=args.silence,
        idle_timeout_s=args.idle_timeout or math.inf,
        start_timeout_s=args.start_timeout or math.inf,
        reconnect=args.reconnect,
        on_event=on_event,
        on_open=on_open,
        name=args.port,
    )


def output_hooks(args: argparse.Namespace, pipe, live, info) -> list:
    """Return the callables every result goes to: the printed line (text or JSON), surface discovery."""
    from ..robot.stream.output import result_json, result_text
    from ._output import stdout_closed

    write = result_json if args.json else result_text

    def show(result) -> None:
        try:
            print(write(result), flush=True)
        except BrokenPipeError:  # an unguarded stdout (the guard of cli.main catches it and says so)
            raise _OutputClosed() from None
        if stdout_closed():
            raise _OutputClosed()

    hooks = [show]
    if args.discover:  # new surfaces: N novel windows in a row (tactile_torch.robot.stream.discovery)
        if live.segment != "windows":
            raise UsageError("--discover proposes surfaces from vibration windows, not from touches")
        from ..robot.stream.discovery import stream_consumer

        hooks.append(stream_consumer(pipe, args.discover, sys.stderr if args.json else sys.stdout))
    if args.ros2_topic:  # each decision published back on a ROS 2 topic, as well as printed
        from ._ros2 import decision_hook

        hooks += decision_hook(args, live.source)
    return hooks


class _OutputClosed(Exception):
    """stdout was closed: the reader of the decisions went away."""


def _describe(args, pipe, live, spec) -> str:
    """The ``reading`` line: what is read, how it is cut, the range."""
    where = args.port
    if args.ros2_topic:
        from ._ros2 import describe_ros2_source

        where = describe_ros2_source(args, live.source)
    if spec.kind == "sample":
        return (
            f"{pipe!r}: reading {where}, windows of {live.size} samples every {live.segmenter.step}, "
            f"range {spec.describe_range()}"
        )
    if args.sensor == "all":
        where += ", every sensor (each cut on its own)"
    h, w = spec.shape[:2]
    if live.segment == "windows":
        cut = f"windows of {live.size} frames of {h} x {w} every {live.segmenter.step}"
    else:
        lv = live.levels
        early = live.rule.describe() if live.rule is not None else "decisions at the end of each touch"
        partial = (
            "decisions of cut touches withheld unless the rule is sure"
            if live.options.on_partial == "withhold"
            else "cut touches decided"
        )
        cut = (
            f"touches of {h} x {w} frames ({lv.signal} pressure onset {lv.onset:.4g}, release {lv.release:.4g}, "
            f"at least {lv.min_frames} frames: {lv.source}; {live.size} frames per decision; {early}; {partial})"
        )
    return f"{pipe!r}: reading {where}, {cut}, range {spec.describe_range()}"


def _stream_until_stopped(args: argparse.Namespace) -> int:  # noqa: C901, PLR0915
    from ..robot.contract import SAMPLE_RATE_KEY, WINDOW_SIZE_KEY
    from ..robot.runtime import OnnxPipeline
    from ..robot.stream.live import LiveStream, frame_bundle, item_spec
    from ..robot.stream.port_lines import StreamDisconnected, StreamTimeout
    from ._codes import ARGUMENT_FLAGS, with_flags

    if bool(args.port) == bool(args.ros2_topic):
        raise UsageError("give either --port PORT (a serial sensor) or --ros2-topic TOPIC (a ROS 2 topic)")
    pipe = OnnxPipeline(args.model, intra_op_threads=args.threads)
    frames = frame_bundle(pipe)
    if not frames and WINDOW_SIZE_KEY not in pipe.metadata:
        print(
            f"tactile-torch stream: {args.model} does not take vibration windows or taxel frames",
            file=sys.stderr,
        )
        return 2
    if frames:
        spec = item_spec(pipe, value_range=_value_range(args.range))
    else:
        spec = item_spec(pipe, range_g=parse_range_g(args.range, "--range", off=True))
    if frames and (args.units != "g" or args.scale is not None):
        raise UsageError(
            "--units and --scale apply to accelerometer samples; frames go as the sensor sends them"
        )
        given = [
            o
            for o, v in (
                ("--onset", args.onset),
                ("--release", args.release),
                ("--min-frames", args.min_frames),
            )
            if v is not None
        ]
        if given or args.segment == "touches":
            raise UsageError(
                f"{given[0] if given else '--segment touches'}: touches are cut from frames; {args.model} takes vibration windows"
            )
    if args.time_unit == "samples" and spec.rate_hz is None:
        key = SAMPLE_RATE_KEY if not frames else "frame rate"
        print(
            f"tactile-torch stream: --time-unit samples needs the {key}, which {args.model} lacks",
            file=sys.stderr,
        )
        return 2
    info = sys.stderr  # stdout holds the decisions (text or JSON), stderr everything else
    # the sources name their arguments (pass units='m/s2', sensor=NAME): show the options that set them
    named = ("units", "scale", "time_unit", "sensor", "field", "msgtype", "qos", "msg_defs", "domain_id")
    flags = {**{k: ARGUMENT_FLAGS[k] for k in named}, "range_g": "--range"}

    def say(message: str) -> None:
        print(f"tactile-torch stream: {with_flags(message, flags)}", file=sys.stderr, flush=True)

    reading = []  # printed once the port is open (and the model warm): a sensor may start then

    def opened(name: str) -> None:
        if not reading:
            reading.append(name)
            print(_describe(args, pipe, live, spec), file=info, flush=True)

    options = touch_options(
        args,
        segment=args.segment,
        step=args.step,
        max_results=args.max_windows or None,
        vote=args.vote,
        vote_method=args.vote_method,
    )
    source = open_source(args, spec, on_event=lambda event: say(event.message), on_open=opened)
    live = LiveStream(pipe, source, options, on_event=lambda event: say(event.message))
    hooks = output_hooks(args, pipe, live, info)
    status, why = 0, None
    try:
        # The first call allocates: run it before the port is opened (opening flushes the port's
        # buffer), so that neither the warm-up nor the open costs the sensor's first samples.
        live.warm_up()
        for result in live:
            for hook in hooks:
                hook(result)
    except StreamTimeout as err:
        say(str(err))
        status, why = STREAM_NO_DATA_EXIT, "timeout"
    except StreamDisconnected as err:
        say(str(err))
        status, why = STREAM_DISCONNECTED_EXIT, "disconnected"
    except _OutputClosed:  # nobody reads the decisions any more: classifying on would be for nothing
        what = "windows" if live.segment == "windows" else "touches"
        say(f"stdout closed (its reader went away) after {live.results} {what}; stopping")
        status = STREAM_OUTPUT_CLOSED_EXIT
    except (KeyboardInterrupt, _Stopped) as err:
        say(f"stopped by {'SIGTERM' if isinstance(err, _Stopped) else 'SIGINT (Ctrl-C)'}")
        status, why = STREAM_STOPPED_EXIT, "stopped"
    if why is not None:  # a touch in progress is reported, cut, never dropped silently
        try:
            for result in live.finish(why):
                for hook in hooks:
                    hook(result)
        except _OutputClosed:
            status = STREAM_OUTPUT_CLOSED_EXIT
    notes = [note() for hook in hooks if (note := getattr(hook, "summary_note", None)) is not None]
    print(", ".join([live.summary(), *notes]), file=info, flush=True)
    close = getattr(source, "close", None)  # a transport that holds more than a port (a DDS participant)
    if close is not None:
        close()
    return status


class _Stopped(Exception):
    """SIGTERM arrived while streaming."""


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
