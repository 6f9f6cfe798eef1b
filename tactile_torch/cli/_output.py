"""What the commands print besides their results: class reports, a progress line for a silent step,
warnings as one line, and a ``sys.stdout`` that survives a closed pipe.

Torch-free: ``predict`` and ``stream`` import it on the robot (``stage`` imports tqdm when used).
"""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Iterator


def recordings_line(data, args) -> str:
    """What the command reads from vibration recordings: how many, the sample rate and where it comes
    from, the sessions and where they come from (``"24 recordings at 800 Hz (from the time stamps;
    --rate states it), 4 sessions (folder per session)"``)."""
    from pathlib import Path

    import numpy as np

    paths = [Path(p) for p in args.data]
    from_file = len(paths) == 1 and paths[0].suffix.lower() == ".npz"
    if getattr(args, "sample_rate_hz", None) is not None:
        origin = "stated with --rate"
    else:
        origin = "the file's rate_hz" if from_file else "from the time stamps; --rate states it"
    line = f"{len(data.signals)} recordings at {data.rate_hz:g} Hz ({origin})"
    if data.session is None:
        return line + ", no sessions (each recording its own)"
    n = len(np.unique(np.asarray(data.session).astype(str)))
    return line + f", {n} session{'s' if n != 1 else ''} ({session_origin(args)})"


def session_origin(args) -> str:
    """Where the sessions of ``args.data`` come from, as :func:`recordings_line` says it."""
    from pathlib import Path

    from ._options import data_layout

    paths = [Path(p) for p in args.data]
    if len(paths) == 1 and paths[0].suffix.lower() == ".npz":
        return "the file's session array"
    names = data_layout(args)
    return "the file's name" if names is None else names.layout


def print_class_report(rep) -> None:
    """Print a :class:`tactile_torch.metrics.ClassReport` as a table, then the overall accuracy ("n/a"
    where a rate is undefined, e.g. a class of the model with no sample in the data: never "nan")."""
    print(rep)


@contextlib.contextmanager
def stage(label: str, *, delay: float = 1.0) -> Iterator[None]:
    """Show ``label`` and the time elapsed on stderr while the block runs (a step of seconds that
    reports nothing itself, such as the ONNX export), from ``delay`` seconds on (a quick step, or one
    that fails at once, prints nothing); the line is cleared when it ends."""
    from tqdm.auto import tqdm

    bar = tqdm(desc=label, bar_format="{desc}: {elapsed}", file=sys.stderr, leave=False, delay=delay)
    done = threading.Event()

    def tick() -> None:
        while not done.wait(0.5):
            bar.refresh()

    ticker = threading.Thread(target=tick, daemon=True)
    ticker.start()
    try:
        yield
    finally:
        done.set()
        ticker.join()
        bar.close()


def warning_line(prefix: str, flags: dict[str, str] | None = None):
    """A ``warnings.showwarning`` that prints one line, ``<prefix>: warning: <message>``, on stderr:
    no file name, line number or source line (``--debug`` keeps Python's own format). ``flags``:
    argument names shown as the command's options (:func:`tactile_torch.cli.with_flags`)."""

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        text = " ".join(str(message).split())
        if flags:
            from ._codes import with_flags

            text = with_flags(text, flags)
        print(f"{prefix}: warning: {text}", file=sys.stderr if file is None else file)

    return show


class StdoutGuard:
    """``sys.stdout`` that survives a closed pipe (``tactile-torch train ... | head -1``).

    After the reader of the pipe has gone, further output is discarded (the descriptor is pointed
    at ``os.devnull``, so the interpreter's final flush does not fail either) and the command goes on
    to write its files; :attr:`closed_pipe` says so to a command whose output is its only product
    (``stream`` stops).
    """

    def __init__(self, stream) -> None:
        self._stream = stream
        self.closed_pipe = False

    def _drop(self) -> None:
        import os

        self.closed_pipe = True
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, self._stream.fileno())
        finally:
            os.close(devnull)

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._drop()
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._drop()
            try:
                self._stream.flush()
            except BrokenPipeError:
                pass

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def stdout_closed() -> bool:
    """Return whether the reader of ``sys.stdout`` has gone (a write met a closed pipe)."""
    return bool(getattr(sys.stdout, "closed_pipe", False))


def guard_stdout():
    """Return the ``sys.stdout`` to restore; wrap it in :class:`StdoutGuard` when it is a real file."""
    original = sys.stdout
    try:
        original.fileno()
    except (AttributeError, OSError, ValueError):  # captured output (tests): nothing to guard
        return original
    sys.stdout = StdoutGuard(original)
    return original
