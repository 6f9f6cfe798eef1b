"""The exceptions the library raises on purpose about its input.

A caller (the command line, a service) tells a user error from a bug by their class: the
validation helpers (:mod:`tactile_torch.validation`, the readers of :mod:`tactile_torch.robot.files.formats`, the
robot side's checks) raise :class:`InputValueError` or :class:`InputTypeError` when an argument, a
file or the data do not fit, with one line naming it, what was expected and what was given. Both
are also ``ValueError`` / ``TypeError``, so ``except ValueError`` and scikit-learn's conventions keep
working. A bare ``TypeError`` or ``AttributeError`` escaping the library is a bug.

A failure in a stage that runs on input the library has already accepted is a bug, whatever
exception it started as: a ``ValueError`` raised by an internal call (a shape check of a helper fed by
the library itself) says nothing about the user's input. :func:`internal_stage` marks such a stage:
any exception leaving it (but ``OSError``: files, disks, ports; ``MemoryError``; an interrupt) becomes
an :class:`InternalError` naming the stage, which the command line reports as an internal error
(status 1), never as bad input (status 2).

Torch-free and import-free: it lives in the robot package, whose validators use it, and the rest
of the library imports it from there.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager


class InputError(Exception):
    """Base of the errors the library raises on purpose about its input (never a bug)."""


class InputValueError(InputError, ValueError):
    """An argument, a file or data with a value the library refuses (range, shape, content)."""


class InputTypeError(InputError, TypeError):
    """An argument, a file or data of a type the library refuses (an array's dtype, an object's class)."""


class InternalError(RuntimeError):
    """A failure inside a stage that runs on accepted input (a bug), with the stage's name.

    Attributes
    ----------
    stage : str
        What was running (``"breaking points"``, ``"cross-validation"``).
    error : BaseException
        The exception the stage raised (also ``__cause__``).
    """

    def __init__(self, stage: str, error: BaseException) -> None:
        self.stage = stage
        self.error = error
        text = " ".join(str(error).split()) or type(error).__name__
        super().__init__(f"{stage}: {type(error).__name__}: {text}")


@contextmanager
def internal_stage(stage: str) -> Iterator[None]:
    """Run a block whose input is already accepted: an exception leaving it becomes :class:`InternalError`.

    ``OSError`` (a file, a disk, a port), ``MemoryError`` and :class:`InternalError` pass unchanged, as
    do ``KeyboardInterrupt`` and ``SystemExit``.

    >>> with internal_stage("demo"):
    ...     raise ValueError("x must have shape (B, F), got (2, 3, 8)")
    Traceback (most recent call last):
    ...
    tactile_torch.exceptions.InternalError: demo: ValueError: x must have shape (B, F), got (2, 3, 8)
    """
    try:
        yield
    except (InternalError, OSError, MemoryError):
        raise
    except Exception as err:
        raise InternalError(stage, err) from err


__all__ = ["InputError", "InputTypeError", "InputValueError", "InternalError", "internal_stage"]
