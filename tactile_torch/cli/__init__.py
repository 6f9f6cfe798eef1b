"""The ``tactile-torch`` command line: :func:`main`, the exit statuses and how errors are reported.

One module per command (or group of commands), each holding its parser section (``register``) and a
handler that parses, calls the library and prints: :mod:`.report`, :mod:`.bench`, :mod:`.train`,
:mod:`.cluster`, :mod:`.export`, :mod:`.predict`, :mod:`.stream`, :mod:`.simulate_sensor`,
:mod:`.tradeoff`. The options several commands share (``--data`` and how to
read it, sensor ranges, the ``--out`` check) are in :mod:`._options`, what they print besides their
results in :mod:`._output`, the exit statuses and the argument names' options in :mod:`._codes`. The handlers import the library lazily so that ``tactile-torch predict``
and ``stream`` run on a robot with onnxruntime and no torch.

Exit statuses (:data:`EXIT_STATUSES`, also in ``tactile-torch --help``): 0 done; 2 bad input, one
line ``tactile-torch CMD: ...`` on stderr naming the file or option; 1 an internal error (a bug),
one line asking to report it, the traceback with ``--debug``; 130 interrupted; ``tradeoff`` 3 (no
adequate candidate) and 4 (none exported); ``stream`` 3 (no data), 4 (port failed) and 5 (stdout
closed: the reader of its decisions went away).
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings

from .._exports import lazy_exports
from ._codes import (
    ARGUMENT_FLAGS,
    BAD_INPUT_EXIT,
    EXIT_STATUSES,
    INTERNAL_ERROR_EXIT,
    INTERRUPTED_EXIT,
    MAX_READ_ENV,
    with_flags,
)

TRAIN_EXTRA = "train"
TRAIN_MODULES = (
    "torch",
    "scipy",
    "sklearn",
    "numba",
    "matplotlib",
    "onnx",
    "onnxscript",
    "tqdm",
    "threadpoolctl",
)
"""Modules of the ``[train]`` extra (pyproject.toml); the robot install has numpy, onnxruntime, pyserial."""
NEEDS_TRAIN_EXTRA = ("report", "bench", "train", "cluster", "export", "tradeoff")
"""Commands that need the ``[train]`` extra; ``predict``, ``stream`` and ``simulate-sensor --data`` do not."""

COMMAND_MODULES = (
    "report",
    "bench",
    "train",
    "cluster",
    "export",
    "predict",
    "stream",
    "simulate_sensor",
    "tradeoff",
)
"""The modules of :mod:`tactile_torch.cli` that register commands, in the order of ``--help``."""


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser with every subcommand."""
    import importlib

    from .. import __version__
    from ._options import CommandParser, at_least

    parser = CommandParser(
        prog="tactile-torch",
        description="Recognise surfaces from tactile images and vibration; train, cluster, export, run.",
        epilog=EXIT_STATUSES,
    )
    parser.add_argument("--version", action="version", version=f"tactile-torch {__version__}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=CommandParser)
    for name in COMMAND_MODULES:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    for p in sub.choices.values():  # --debug is accepted after the command too
        p.add_argument(
            "--debug", action="store_true", default=argparse.SUPPRESS, help="show the traceback of an error"
        )
        p.add_argument(
            "--max-read-mb",
            type=at_least(0.001),
            default=None,
            metavar="MB",
            help="refuse input files whose arrays would take more than MB MiB in memory (default: 1024; "
            "docs/formats.md)",
        )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status.

    Bad input prints one line ``tactile-torch <command>: <file>: <what is wrong>`` on stderr and
    returns :data:`BAD_INPUT_EXIT`: the errors the library raises on purpose about its input
    (:mod:`tactile_torch.exceptions`), any ``ValueError`` (numpy and scikit-learn raise it for bad data),
    ``OSError`` (files, ports, disks) and a missing optional dependency; the argument names in the
    message become the options that set them (:func:`with_flags`). Any other exception is a bug: one
    line saying so, asking to report it, and :data:`INTERNAL_ERROR_EXIT`. ``--debug`` shows the
    traceback instead. Warnings print as one line each, with Python's own format under ``--debug``.
    """
    from ._output import warning_line

    parser = build_parser()
    args = parser.parse_args(argv)
    debug = bool(getattr(args, "debug", False))
    prefix = f"tactile-torch {args.command}"
    options = set(_subparser(parser, args.command)._option_string_actions)
    flags = {name: flag for name, flag in ARGUMENT_FLAGS.items() if flag in options}
    with warnings.catch_warnings():  # restores the caller's warning display when the command ends
        if not debug:
            warnings.showwarning = warning_line(prefix, flags)
        return _run(args, prefix, debug, flags)


def _subparser(parser: argparse.ArgumentParser, command: str) -> argparse.ArgumentParser:
    for action in parser._subparsers._group_actions:
        if command in action.choices:
            return action.choices[command]
    raise LookupError(command)  # pragma: no cover - argparse accepted the command


def is_user_error(err: BaseException) -> bool:
    """Return whether ``err`` is about the user's input (reported in one line, status 2), not a bug.

    An :class:`~tactile_torch.exceptions.InternalError` (an exception, of any class, that left a stage
    running on input already accepted: :func:`~tactile_torch.exceptions.internal_stage`) is a bug.
    """
    from ..exceptions import InputError, InternalError

    return not isinstance(err, InternalError) and isinstance(err, InputError | ValueError | OSError)


def internal_error_line(err: BaseException) -> str:
    """The line (without the command's prefix) that reports a bug: what failed, where, and what to do."""
    from ..exceptions import InternalError

    where, cause = "", err
    if isinstance(err, InternalError):
        where, cause = f" in {err.stage}", err.error
    return (
        f"internal error{where}: {type(cause).__name__}: {_one_line(cause)} (rerun with --debug for the "
        "traceback, and please report it)"
    )


def _missing_train_modules() -> list[str]:
    import importlib.util

    def missing(name: str) -> bool:
        try:
            return importlib.util.find_spec(name) is None
        except (ImportError, ValueError):  # a broken or blocked installation counts as missing
            return True

    return [name for name in TRAIN_MODULES if missing(name)]


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    if isinstance(err, FileNotFoundError) and err.filename and not text.startswith(str(err.filename)):
        text = f"{err.filename}: {err.strerror or 'no such file'}"  # OSError's own "[Errno 2] ..." form
    return text or type(err).__name__


def _run(args: argparse.Namespace, prefix: str, debug: bool, flags: dict[str, str]) -> int:
    """Run the parsed command and map its errors to one line and an exit status (see :func:`main`)."""
    from ._options import check_out
    from ._output import guard_stdout

    if args.command in NEEDS_TRAIN_EXTRA:
        missing = _missing_train_modules()
        if missing:
            print(
                f"{prefix}: needs the training extra, which is not installed here (missing: "
                f"{', '.join(missing)}): pip install 'tactile-torch[{TRAIN_EXTRA}]'",
                file=sys.stderr,
            )
            return BAD_INPUT_EXIT
    stdout = guard_stdout()
    limit_before = os.environ.get(MAX_READ_ENV)
    if (
        getattr(args, "max_read_mb", None) is not None
    ):  # read by every reader (robot.files.npz.max_read_bytes)
        os.environ[MAX_READ_ENV] = repr(float(args.max_read_mb))
    try:
        check_out(args)
        return int(args.handler(args))
    except KeyboardInterrupt:
        if debug:
            raise
        print(f"{prefix}: interrupted", file=sys.stderr)
        return INTERRUPTED_EXIT
    except ModuleNotFoundError as err:
        if debug:
            raise
        if (err.name or "").split(".")[0] in TRAIN_MODULES:
            print(
                f"{prefix}: needs the training extra ({err.name} is not installed): "
                f"pip install 'tactile-torch[{TRAIN_EXTRA}]'",
                file=sys.stderr,
            )
            return BAD_INPUT_EXIT
        print(f"{prefix}: {_one_line(err)} (rerun with --debug for the traceback)", file=sys.stderr)
        return INTERNAL_ERROR_EXIT
    except MemoryError:
        if debug:
            raise
        print(
            f"{prefix}: not enough memory for this input (reads are bounded by --max-read-mb, "
            "docs/formats.md); use smaller files or a larger machine",
            file=sys.stderr,
        )
        return BAD_INPUT_EXIT
    except Exception as err:
        if debug:
            raise
        if is_user_error(err):
            print(f"{prefix}: {with_flags(_one_line(err), flags)}", file=sys.stderr)
            return BAD_INPUT_EXIT
        print(f"{prefix}: {internal_error_line(err)}", file=sys.stderr)
        return INTERNAL_ERROR_EXIT
    finally:
        sys.stdout = stdout
        if limit_before is None:
            os.environ.pop(MAX_READ_ENV, None)
        else:
            os.environ[MAX_READ_ENV] = limit_before


__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {  # the commands' modules are not API: main and the exit statuses are
        "_codes": (
            "ARGUMENT_FLAGS",
            "BAD_INPUT_EXIT",
            "EXIT_STATUSES",
            "INTERNAL_ERROR_EXIT",
            "INTERRUPTED_EXIT",
            "NOT_BUILT_EXIT",
            "NOT_EXPORTED_EXIT",
            "NO_RECOMMENDATION_EXIT",
            "STREAM_DISCONNECTED_EXIT",
            "STREAM_NO_DATA_EXIT",
            "STREAM_OUTPUT_CLOSED_EXIT",
            "STREAM_STOPPED_EXIT",
            "with_flags",
        ),
    },
    defined=("TRAIN_MODULES", "build_parser", "internal_error_line", "is_user_error", "main"),
)
