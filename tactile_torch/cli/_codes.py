"""The command line's exit statuses and the translation of the library's argument names into options.

Imported by :mod:`tactile_torch.cli` (which exports these names) and by the command modules, so that
no module of the command line imports the package ``__init__`` that imports it: the standard library
only (``predict`` and ``stream`` run on the robot).
"""

from __future__ import annotations

import re

BAD_INPUT_EXIT = 2
"""Exit status for bad input (a missing or malformed file, a wrong option), after one line on stderr."""
INTERNAL_ERROR_EXIT = 1
"""Exit status for an unexpected error (a bug): one line on stderr, the traceback with ``--debug``."""
INTERRUPTED_EXIT = 130
"""Exit status after Ctrl-C (SIGINT) outside ``stream``."""
NOT_BUILT_EXIT = 2
"""Exit status when a command cannot do its work (e.g. ``bench`` outside a source checkout)."""
NO_RECOMMENDATION_EXIT = 3
"""Exit status of ``tradeoff`` when no candidate is adequate (none reaches ``--target``, or none is
significantly above the trivial baseline): the outputs are written, nothing is deployed."""
NOT_EXPORTED_EXIT = 4
"""Exit status of ``tradeoff`` when no candidate could be fitted and exported (the notes say why)."""
STREAM_NO_DATA_EXIT = 3
"""Exit status of ``stream`` when no sample came within the start or idle timeout."""
STREAM_DISCONNECTED_EXIT = 4
"""Exit status of ``stream`` when the port failed and was not (or could not be) reconnected."""
STREAM_STOPPED_EXIT = 0
"""Exit status of ``stream`` stopped by SIGTERM or SIGINT (Ctrl-C): a requested end, after the summary."""
STREAM_OUTPUT_CLOSED_EXIT = 5
"""Exit status of ``stream`` when its stdout was closed (the reader of the decisions went away): it stops
at the next decision it cannot write, after one line and the summary on stderr."""
EXIT_STATUSES = (
    "exit status: 0 done; 2 bad input (one line naming the file or option); 1 internal error (a bug: one "
    "line, please report it; --debug shows the traceback); 130 interrupted; tradeoff: 3 no adequate "
    "candidate, 4 none exported, 1 also when a late stage failed (the rest is written); stream: 3 no data, "
    "4 port failed, 5 stdout closed"
)
"""What ``tactile-torch --help`` says about exit statuses."""

MAX_READ_ENV = "TACTILE_TORCH_MAX_READ_MB"
"""Where ``--max-read-mb`` puts the read bound (:func:`tactile_torch.robot.files.npz.max_read_bytes` reads it)."""

ARGUMENT_FLAGS = {
    "n_folds": "--folds",
    "window": "--window",
    "windows": "--windows",
    "step": "--step",
    "frame_rate_hz": "--frame-rate",
    "threshold": "--threshold",
    "erosion": "--erosion",
    "contact": "--contact",
    "max_per_class": "--max-per-class",
    "classifiers": "--classifiers",
    "features": "--features",
    "target": "--target",
    "deploy": "--deploy",
    "random_state": "--seed",
    "out": "--out",
    "select": "--select",
    "columns": "--columns",
    "units": "--units",
    "scale": "--scale",
    "time_unit": "--time-unit",
    "sample_rate_hz": "--rate",
    "sensor_range_g": "--sensor-range",
    "topic": "--topic",
    "shape": "--shape",
    "field": "--field",
    "sensor": "--sensor",
    "msg_defs": "--msg-def",
    "domain_id": "--domain-id",
    "frames": "--frames",
    "max_messages": "--max-messages",
    "index": "--index",
    "class_from": "--class-from",
    "session_from": "--session-from",
    "allow_pickle": "--allow-pickle",
    "n_consecutive": "--discover",
    "max_iter": "--max-iter",
    "max_seconds": "--max-seconds",
    "calibrate": "--calibrate",
    "novelty_components": "--novelty-components",
    "false_alarm": "--false-alarm",
    "sessions": "--sessions",
    "onset": "--onset",
    "release": "--release",
    "min_frames": "--min-frames",
    "touch_signal": "--touch-signal",
    "segment": "--segment",
    "msgtype": "--ros2-type",
    "qos": "--qos",
    "on_partial": "--on-partial",
    "all_sensors": "--sensor all",
    MAX_READ_ENV: "--max-read-mb",
}
"""The library's argument names and the options that set them: the one place where an error message
of the library, which names the argument, is translated to the option a user typed (:func:`with_flags`)."""


def with_flags(message: str, flags: dict[str, str]) -> str:
    """Return ``message`` with the library's argument names shown as the options that set them.

    The library names an argument either at the start of a message about it (``n_folds must be >= 2``,
    ``window: none of the window sizes ...``), which becomes the option (``--folds must be >= 2``), or
    as a keyword to set, in Python's syntax (``pass time_unit='ms'``, ``name one with topic=``,
    ``shape=(H, W)``, ``allow_pickle=True``), which becomes the option and its value on the command
    line (``pass --time-unit ms``, ``name one with --topic``, ``--shape H,W``, ``--allow-pickle``).
    ``flags``: argument name -> option, those of the command at hand (:data:`ARGUMENT_FLAGS`). A
    message that starts with a file name is about the file's content and keeps its words (``x.npz:
    features must be finite``).
    """
    if not flags:
        return message
    names = "|".join(sorted(map(re.escape, flags), key=len, reverse=True))

    def keyword(m: re.Match) -> str:
        quoted, pair, word = m[3], m[4], m[5]
        value = quoted if quoted is not None else pair.replace(" ", "") if pair is not None else word or ""
        return f"{m[1]}{flags[m[2]]}" + (f" {value}" if value and value != "True" else "")

    message = re.sub(rf"^({names})( must| needs| applies|:)", lambda m: flags[m[1]] + m[2], message)
    return re.sub(rf"(^|[\s(,/])({names})=(?:'([^']*)'|\(([^()]*)\)|([\w.+-]+))?", keyword, message)
