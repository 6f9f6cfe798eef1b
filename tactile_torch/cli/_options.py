"""The options several commands share, and how their values are checked.

- the data options (``--data`` and how to read it), shared by train, cluster, predict and tradeoff:
  :func:`add_data_options` declares them on a subcommand; :func:`data_options` turns the parsed
  arguments into a :class:`tactile_torch.robot.files.data_sources.DataOptions`; :func:`read_data_arg` reads
  ``--data`` with them (:func:`tactile_torch.robot.files.data_sources.read_source`);
- the value types of numeric options (:func:`at_least`, :func:`in_range`) and the sensor ranges in g
  (:func:`parse_range_g`, :func:`declare_range`);
- the check of an ``--out`` file against the command's inputs (:func:`check_out`);
- :class:`CommandParser`, whose usage errors are one line, and :class:`UsageError`, a bad combination
  of options found by a handler.

Torch-free: ``predict`` and ``stream`` import it on the robot.
"""

from __future__ import annotations

import argparse
import math
import os
from dataclasses import dataclass
from pathlib import Path

from ._codes import BAD_INPUT_EXIT


class UsageError(ValueError):
    """Bad command-line input detected by a handler (reported in one line, like any ``ValueError``)."""


class CommandParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (``tactile-torch CMD: argument --x: ...``), status 2."""

    def error(self, message: str):
        self.exit(BAD_INPUT_EXIT, f"{self.prog}: {' '.join(message.split())}\n")


DATA_HELP = (
    "a .npz of docs/formats.md (frames, signals or features), CSV logs (t,x,y,z; --columns to name others), "
    "frame recordings (.npz of frames and t), or ROS 2 bags (directories or .db3/.mcap files; --topic). Class "
    "and session from the files' layout: felt_3.csv -> class felt, session 3; cork/2026-11-02.csv (a folder per "
    "class) or day2/cork.csv (a folder per session), decided by which names read as dates or sessions and "
    "printed first; --class-from, --session-from or --index say it"
)


def _shape(text: str) -> tuple[int, int]:
    parts = text.replace("x", ",").split(",")
    if len(parts) != 2 or not all(p.strip().isdigit() and int(p) > 0 for p in parts):
        raise argparse.ArgumentTypeError(f"expected H,W (two whole numbers > 0), got {text!r}")
    return int(parts[0]), int(parts[1])


CPUS = os.cpu_count() or 1
"""This machine's CPUs: the most threads an option asks for (more only make the threads wait for each other)."""
INT_CAP = 2**31 - 1
"""The largest whole number an option takes when it declares no ``high`` (what C libraries take as an int)."""
FLOAT_CAP = 1e12
"""The largest number an option takes when it declares no ``high`` (``allow_inf`` options: ``inf`` too)."""


@dataclass(frozen=True)
class Number:
    """An argparse type for a numeric option: a finite number of ``kind`` within bounds, or one of ``words``.

    Every numeric option of every command is declared with one (``tests/cli/test_options.py`` checks it),
    so a value that is not a number, NaN, or out of range is refused by the parser in one line that
    names the option, before any work: ``tactile-torch train: argument --gamma: expected 'scale' or a
    number > 0, got 'abc'``. Without a ``high``, a number is at most :data:`INT_CAP` (whole numbers) or
    :data:`FLOAT_CAP`: no option passes 1e300 on to a library that would overflow on it.

    >>> Number(int, low=1)("3"), Number(float, low=0, open_low=True, words=("scale",))("scale")
    (3, 'scale')
    """

    kind: type = float
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    open_high: bool = False
    words: tuple[str, ...] = ()
    allow_inf: bool = False
    unit: str = ""

    def expected(self) -> str:
        """The accepted values in words (``"a whole number >= 1"``, ``"'auto' or a number in (0, 1]"``)."""
        what = "a whole number" if self.kind is int else "a number" if self.allow_inf else "a finite number"
        what += f" of {self.unit}" if self.unit else ""
        if self.low is not None and self.high is not None:
            what += f" in {'(' if self.open_low else '['}{self.low:g}, {self.high:g}{')' if self.open_high else ']'}"
        elif self.low is not None:
            what += f" {'>' if self.open_low else '>='} {self.low:g}"
        elif self.high is not None:
            what += f" {'<' if self.open_high else '<='} {self.high:g}"
        if self.allow_inf:
            what += " (inf: no check)"
        words = " or ".join(repr(w) for w in self.words)
        return f"{words} or {what}" if words else what

    def __call__(self, text: str):
        text = str(text).strip()
        if text in self.words:
            return text
        try:
            value = float(text)
            if self.kind is int:
                if not value.is_integer():
                    raise ValueError(text)
                value = int(text) if text.lstrip("+-").isdigit() else int(value)
        except (ValueError, OverflowError):
            value = None
        if value is not None and not (math.isfinite(value) or (self.allow_inf and value == math.inf)):
            value = None
        if value is not None and self.low is not None:
            value = value if (value > self.low if self.open_low else value >= self.low) else None
        if value is not None and self.high is not None and value != math.inf:
            value = value if (value < self.high if self.open_high else value <= self.high) else None
        if value is None:
            raise argparse.ArgumentTypeError(f"expected {self.expected()}, got {text!r}")
        cap = INT_CAP if self.kind is int else FLOAT_CAP
        if self.high is None and value != math.inf and abs(value) > cap:
            raise argparse.ArgumentTypeError(
                f"expected {self.expected()}, at most {cap:g} in size, got {text!r}"
            )
        return value


SEED = Number(int, low=0)
"""``--seed``: a whole number >= 0 (numpy's seeds)."""


def window_type() -> Number:
    """``--window``: a number of samples in ``MIN_WINDOW .. MAX_WINDOW`` (:mod:`tactile_torch.robot.stream.windows`)."""
    from ..robot.stream.windows import MAX_WINDOW, MIN_WINDOW

    return Number(int, low=MIN_WINDOW, high=MAX_WINDOW)


def window_list(text: str) -> tuple[int, ...]:
    """``--windows``: comma-separated window sizes, each as :func:`window_type` accepts."""
    one = window_type()
    try:
        return tuple(one(part) for part in str(text).split(","))
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated window sizes, each {one.expected()}, got {text!r}"
        ) from None


def add_csv_options(g) -> None:
    """Add the options saying how to read CSV logs (``--columns``, ``--units``, ``--scale``, ``--time-unit``)
    to the parser or argument group ``g`` (:func:`add_data_options` adds them with the others)."""
    g.add_argument(
        "--columns",
        default=None,
        help="CSV logs: the t,x,y,z columns by name or 0-based index, or x,y,z (time: t or time), "
        "e.g. time,accel_x,accel_y,accel_z (default: t/time,x,y,z by name, else the first four)",
    )
    g.add_argument(
        "--units",
        default=None,
        choices=["g", "m/s2"],
        help="CSV and .npz accelerations (default: g); ROS Imu topics are m/s2 by definition",
    )
    g.add_argument(
        "--scale",
        type=Number(low=0, open_low=True),
        default=None,
        help="units per count for integer sensor counts, e.g. 0.0039 (ADXL345 at full resolution)",
    )
    g.add_argument(
        "--time-unit",
        default="auto",
        choices=["auto", "s", "ms", "us"],
        help="CSV logs: unit of the time column (default: auto, seconds unless the rate is implausible; a "
        "declared unit that makes it implausible is refused too)",
    )


def add_data_options(
    p: argparse.ArgumentParser, *, data_help: str = DATA_HELP, sensor_range: bool = True
) -> None:
    """Add ``--data`` and the options saying how to read it to the subcommand parser ``p``.

    ``sensor_range``: add ``--sensor-range`` (recordings beyond it are refused); without it, no range
    check (``predict`` leaves such windows out with its own ``--range``).
    """
    p.add_argument("--data", required=True, nargs="+", help=data_help)
    g = p.add_argument_group("reading the data (docs/formats.md)")
    add_csv_options(g)
    g.add_argument(
        "--rate",
        dest="sample_rate_hz",
        type=Number(float, low=0, open_low=True),
        default=None,
        metavar="HZ",
        help="vibration: the sample rate, stated; the time stamps (or a .npz's rate_hz) must agree within 5%% "
        "(default: the slope of the time stamps against the sample index, robust to rounding and gaps)",
    )
    if sensor_range:
        g.add_argument(
            "--sensor-range",
            dest="data_sensor_range",
            type=Number(low=0, open_low=True, allow_inf=True, unit="g"),
            default=None,
            metavar="G",
            help="recordings with samples beyond +-G g are refused; inf: no check (default: 5, the ADXL345)",
        )
    g.add_argument(
        "--topic", default=None, help="ROS 2 bags: the topic (default: the only IMU or array topic)"
    )
    g.add_argument(
        "--shape",
        type=_shape,
        default=None,
        metavar="H,W",
        help="ROS 2 bags: taxels of Float32MultiArray pressure maps (default: the message layout)",
    )
    g.add_argument(
        "--field",
        default=None,
        help="ROS 2 bags: the dotted path of the field that holds the numbers, for any message type "
        "(e.g. taxels.values; default: the standard types' own field)",
    )
    g.add_argument(
        "--sensor",
        default=None,
        metavar="NAME",
        help="ROS 2 bags of tactile_msgs/TactileState: the sensor (channel) to read (default: the only one)",
    )
    add_msg_def(g)
    g.add_argument(
        "--frames",
        type=Number(int, low=1),
        default=None,
        help="ROS 2 bags of pressure maps: frames per exploration (default: the shortest bag's); frame recordings: "
        "frames each touch is brought to (default: the median touch's)",
    )
    g.add_argument(
        "--max-messages",
        type=Number(int, low=1),
        default=None,
        help="ROS 2 bags: read at most this many messages per topic (default: 10,000,000)",
    )
    g.add_argument("--index", default=None, help="CSV file,class[,session] giving each data file's class")
    g.add_argument(
        "--class-from",
        default=None,
        choices=["folder", "file"],
        help="each file's class from its folder (cork/2026-11-02.csv -> cork) or its file name (day2/cork.csv -> "
        "cork); default: decided from the tree (docs/formats.md)",
    )
    g.add_argument(
        "--session-from",
        default=None,
        choices=["folder", "file", "recording"],
        help="each file's session from its folder, its file name, or the file itself (recording: every file its "
        "own session); default: the level the classes are not taken from",
    )


def add_msg_def(g) -> None:
    """Add ``--msg-def FILE`` (repeatable: a robot's own ROS 2 message definitions) to the parser or group ``g``."""
    g.add_argument(
        "--msg-def",
        dest="msg_defs",
        action="append",
        default=[],
        metavar="FILE",
        help="ROS 2: the .msg text of a message type of your robot, as pkg/msg/Name.msg or pkg/msg/Name=FILE "
        "(a lone FILE defines the topic's type); repeat for the types it uses",
    )


def message_definitions(args: argparse.Namespace) -> tuple:
    """Return the :class:`~tactile_torch.robot.ros2.messages.MessageDefinition` of every ``--msg-def``."""
    from ..robot.ros2.message_types import read_message_definition

    return tuple(read_message_definition(path) for path in getattr(args, "msg_defs", []))


def add_touch_options(p: argparse.ArgumentParser) -> None:
    """Add the options that cut touches from frames (``stream`` and ``predict``; docs/stream.md)."""
    g = p.add_argument_group("touches (frame bundles, docs/stream.md)")
    g.add_argument(
        "--onset",
        type=Number(float),
        default=None,
        help="a touch starts where the frame's total (or peak) pressure above rest reaches this (default: the "
        "bundle's level, from its training data)",
    )
    g.add_argument(
        "--release",
        type=Number(float),
        default=None,
        help="a touch ends where it falls below this (default: the bundle's; half of a given --onset)",
    )
    g.add_argument(
        "--min-frames",
        type=at_least(1, int),
        default=None,
        help="shortest touch in frames (default: the bundle's)",
    )
    g.add_argument(
        "--touch-signal",
        default=None,
        choices=["total", "peak"],
        help="total or peak pressure above rest (default: the bundle's)",
    )
    g.add_argument(
        "--no-early",
        action="store_true",
        help="decide at the end of each touch only, not early with the bundle's calibrated rule",
    )
    g.add_argument(
        "--on-partial",
        default="withhold",
        choices=["withhold", "decide"],
        help="a touch cut by a pause, a gap, a disconnection or the end (or the rest after such a cut): "
        "withhold its decision unless the bundle's early rule is sure of it (default), or decide anyway; "
        "either way it says partial: true",
    )


def touch_options(args: argparse.Namespace, **more):
    """Return the :class:`~tactile_torch.robot.stream.live.LiveOptions` of the parsed touch options (and ``more``)."""
    from ..robot.stream.live import LiveOptions

    return LiveOptions(
        early=not args.no_early,
        onset=args.onset,
        release=args.release,
        min_frames=args.min_frames,
        touch_signal=args.touch_signal,
        on_partial=args.on_partial,
        **more,
    )


def data_options(args: argparse.Namespace):
    """Return the :class:`~tactile_torch.robot.files.data_sources.DataOptions` the parsed arguments declare."""
    from ..robot.contract import DEFAULT_RANGE_G
    from ..robot.files.data_sources import DataOptions
    from ..robot.ros2.bags import MAX_BAG_MESSAGES

    return DataOptions(
        columns=args.columns,
        units=args.units,
        scale=args.scale,
        time_unit=args.time_unit,
        sample_rate_hz=args.sample_rate_hz,
        topic=args.topic,
        shape=args.shape,
        field=args.field,
        sensor=args.sensor,
        msg_defs=message_definitions(args),
        frames=args.frames,
        index=args.index,
        class_from=args.class_from,
        session_from=args.session_from,
        sensor_range_g=(args.data_sensor_range or DEFAULT_RANGE_G)
        if "data_sensor_range" in args
        else float("inf"),
        max_messages=args.max_messages or MAX_BAG_MESSAGES,
        allow_pickle=getattr(args, "allow_pickle", False),
        check="data_sensor_range" in args,  # predict: no --sensor-range; it leaves such windows out
    )


_OPTION_NAMES = {
    "columns": "--columns",
    "units": "--units",
    "scale": "--scale",
    "time_unit": "--time-unit",
    "sample_rate_hz": "--rate",
    "data_sensor_range": "--sensor-range",
    "topic": "--topic",
    "shape": "--shape",
    "field": "--field",
    "sensor": "--sensor",
    "frames": "--frames",
    "max_messages": "--max-messages",
    "index": "--index",
    "class_from": "--class-from",
    "session_from": "--session-from",
}


def data_option_words(args: argparse.Namespace) -> list[str]:
    """Return the data options given (not at their defaults) as command-line words, to rerun a command."""
    words = []
    for name, option in _OPTION_NAMES.items():
        value = getattr(args, name, None)
        if value is None or (name == "time_unit" and value == "auto"):
            continue
        text = (
            ",".join(str(v) for v in value)
            if isinstance(value, tuple)
            else f"{value:g}"
            if isinstance(value, float)
            else str(value)
        )
        words.append(f"{option} {text}")
    words += [f"--msg-def {path}" for path in getattr(args, "msg_defs", None) or []]
    return words


def data_layout(args: argparse.Namespace):
    """Return how ``--data`` of several files gives classes and sessions (:class:`~tactile_torch.robot.files.naming.RecordingNames`),
    ``None`` for one file (its classes are its own). Decided from the paths alone, before any file is read:
    an ambiguous tree is refused here, in one line naming ``--class-from`` and ``--index``."""
    from ..robot.files.frame_recordings import labelled_recordings, recordings_layout

    if len(args.data) < 2:
        return None
    return recordings_layout(args.data, data_options(args), labelled=labelled_recordings(args.data))


def announce_layout(args: argparse.Namespace, log) -> None:
    """Say with ``log`` how ``--data`` gives classes and sessions (:func:`data_layout`), before any long work."""
    from ._codes import ARGUMENT_FLAGS, with_flags

    names = data_layout(args)
    if names is not None:
        log(f"{data_name(args.data)}: {with_flags(names.describe(), ARGUMENT_FLAGS)}")


def read_data_arg(args: argparse.Namespace):
    """Read ``--data`` with the declared options; return the arrays (``.kind`` says which)."""
    from ..robot.files.data_sources import read_source

    return read_source(args.data, data_options(args))


def data_name(paths: str | Path | list) -> str:
    """Return how messages name ``--data`` (one file, or the first of several)."""
    from ..robot.files.formats import data_name as name

    return name(paths)


def add_allow_pickle(p: argparse.ArgumentParser) -> None:
    """Add ``--allow-pickle`` to the subcommand parser ``p``."""
    p.add_argument(
        "--allow-pickle",
        action="store_true",
        help="read the pickled recordings of a trusted vibration .npz written by tactile-torch 0.1",
    )


def at_least(minimum: float, kind: type = float) -> Number:
    """Return an argparse type: a finite number of ``kind`` >= ``minimum``, else a one-line usage error."""
    return Number(kind, low=minimum)


def in_range(low: float, high: float) -> Number:
    """Return an argparse type: a finite number ``low < x <= high``, else a one-line usage error."""
    return Number(float, low=low, high=high, open_low=True)


def parse_range_g(text: str | None, option: str, *, off: bool) -> float | None:
    """Return the sensor range in g an option gives (``None`` when not given), or raise a one-line error.

    ``off``: ``inf`` is accepted (no range check).
    """
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and (off or value != float("inf"))):
        expected = "a number of g > 0 ('inf': no check)" if off else "a finite number of g > 0"
        raise UsageError(f"{option} must be {expected}, got {text!r}")
    return value


def declare_range(source: dict, args: argparse.Namespace) -> None:
    """Keep a declared finite ``--sensor-range`` in a vibration model's source (export's default range)."""
    declared = getattr(args, "data_sensor_range", None)
    if source.get("kind") == "vibration" and declared is not None and declared != float("inf"):
        source["sensor_range_g"] = float(declared)


WRITES_OUT_FILE = ("train", "predict", "export")
"""Commands whose ``--out`` is one file: it is checked against their inputs before any work."""
WRITES_OUT_DIR = {"tradeoff": True, "cluster": False, "report": False}
"""Commands whose ``--out`` is a directory, and whether it is replaced as a whole (written next to it,
then moved into place) rather than written into: checked before any work."""


def check_out(args: argparse.Namespace) -> None:
    """Refuse an ``--out`` where nothing can be written (a read-only place), or one that is an input, a
    directory (a device, a symbolic link) where a file is expected: one line naming ``--out``, status 2,
    before any work."""
    from ..robot.files.safe_write import check_output_dir, check_output_path

    out = getattr(args, "out", "")
    if args.command in WRITES_OUT_DIR and out:
        check_output_dir(out, what="--out", replace=WRITES_OUT_DIR[args.command])
        return
    if args.command not in WRITES_OUT_FILE or not out:
        return
    inputs = list(getattr(args, "data", None) or [])
    inputs += [args.model] if getattr(args, "model", None) else []
    check_output_path(out, inputs=inputs, what="--out")


__all__ = [
    "DATA_HELP",
    "SEED",
    "CommandParser",
    "Number",
    "UsageError",
    "add_allow_pickle",
    "add_csv_options",
    "add_data_options",
    "announce_layout",
    "at_least",
    "check_out",
    "data_layout",
    "data_name",
    "data_option_words",
    "data_options",
    "declare_range",
    "in_range",
    "parse_range_g",
    "read_data_arg",
    "window_list",
    "window_type",
]
