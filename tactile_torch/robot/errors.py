"""The exceptions the library raises on purpose about its input.

A caller (the command line, a service) tells a user error from a bug by their class: the
validation helpers (:mod:`tactile_torch._checks`, the readers of :mod:`tactile_torch.robot.formats`, the
robot side's checks) raise :class:`InputValueError` or :class:`InputTypeError` when an argument, a
file or the data do not fit, with one line naming it, what was expected and what was given. Both
are also ``ValueError`` / ``TypeError``, so ``except ValueError`` and scikit-learn's conventions keep
working. A bare ``TypeError`` or ``AttributeError`` escaping the library is a bug.

Torch-free and import-free: it lives in the robot package, whose validators use it, and the rest
of the library imports it from there.
"""

from __future__ import annotations


class InputError(Exception):
    """Base of the errors the library raises on purpose about its input (never a bug)."""


class InputValueError(InputError, ValueError):
    """An argument, a file or data with a value the library refuses (range, shape, content)."""


class InputTypeError(InputError, TypeError):
    """An argument, a file or data of a type the library refuses (an array's dtype, an object's class)."""


__all__ = ["InputError", "InputTypeError", "InputValueError"]
