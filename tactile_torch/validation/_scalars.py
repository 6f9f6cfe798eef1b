"""Validation of scalar arguments and random states without torch (the robot side's one set of checks).

The robot modules (runtime, stream, formats, ...) validate their arguments with these helpers;
:mod:`tactile_torch.validation` (tensors, shapes, feature matrices: it needs torch) builds on them for
the rest of the library, so each check has one definition. Every error names the argument, what was
expected and what was given.

Examples
--------
>>> check_count(3, "step", 1)
3
>>> check_number(0.5, "silence_s")
0.5
"""

from __future__ import annotations

import math
import numbers
import sys

import numpy as np

from ..exceptions import InputTypeError

FLOAT32_MAX = float(np.finfo(np.float32).max)
"""The largest float32 (3.4e38): a sample beyond it is kept as it, beyond every sensor's range."""


def saturate_float32(values: np.ndarray) -> np.ndarray:
    """Return finite ``values`` as float32, those beyond float32's range as ``±FLOAT32_MAX`` (not inf).

    A corrupted ``1e308`` then reads as a sample beyond the sensor's range, as ``1e30`` does (refused
    by ``train``, its window left out by ``predict``), instead of overflowing to inf with a warning.

    >>> saturate_float32(np.array([1.0, -1e308]))
    array([ 1.0000000e+00, -3.4028235e+38], dtype=float32)
    """
    return np.clip(values, -FLOAT32_MAX, FLOAT32_MAX).astype(np.float32)


def check_count(value: object, name: str, minimum: int) -> int:
    """Return ``value`` as an ``int`` if it is an integer ``>= minimum`` (bool refused), else raise ``ValueError``.

    >>> check_count(0, "max_windows", 1)
    Traceback (most recent call last):
    ...
    ValueError: max_windows must be an int >= 1, got 0
    """
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"{name} must be an int >= {minimum}, got {value!r}")
    return int(value)


def check_number(value: object, name: str, *, minimum: float = 0.0, strict: bool = True) -> float:
    """Return ``value`` as a ``float`` if it is a number ``> minimum`` (``>=`` unless ``strict``).

    ``math.inf`` passes (a timeout of "never"); NaN does not. Raises ``TypeError`` for a non-number
    (bool included), ``ValueError`` for a value out of range.
    """
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InputTypeError(f"{name} must be a number, got {type(value).__name__}")
    value = float(value)
    if math.isnan(value) or value < minimum or (strict and value == minimum):
        raise ValueError(f"{name} must be {'>' if strict else '>='} {minimum:g}, got {value:g}")
    return value


def check_positive(value: object, name: str, *, strict: bool = True, integer: bool = False) -> None:
    """Raise unless ``value`` is a finite (strictly) positive real (or integer) number.

    ``TypeError`` for a non-number (bool included), ``ValueError`` for NaN, inf or a value out of range.
    """
    kind = numbers.Integral if integer else numbers.Real
    if isinstance(value, bool) or not isinstance(value, kind):
        raise InputTypeError(f"{name} must be {'an integer' if integer else 'a real number'}, got {value!r}")
    if not np.isfinite(value) or (value <= 0 if strict else value < 0):
        raise ValueError(f"{name} must be {'> 0' if strict else '>= 0'}, got {value!r}")


def numpy_rng(random_state: object) -> np.random.Generator:
    """Return a ``numpy.random.Generator`` for an int seed, a numpy or torch generator, or ``None``.

    A torch generator or a legacy ``numpy.random.RandomState`` is consumed (one draw) to seed the numpy
    one, so the result stays a function of the generator's state. ``None`` gives fresh OS entropy. torch is never imported here: a
    ``torch.Generator`` can only come from a caller that already imported it.
    """
    if random_state is None or isinstance(random_state, numbers.Integral):
        return np.random.default_rng(None if random_state is None else int(random_state))
    if isinstance(random_state, np.random.Generator):
        return random_state
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(random_state, torch.Generator):
        seed = int(torch.randint(0, 2**62, (1,), generator=random_state))
        return np.random.default_rng(seed)
    if isinstance(random_state, np.random.RandomState):  # scikit-learn's "random_state" allows it
        return np.random.default_rng(int(random_state.randint(0, 2**31 - 1)))
    raise InputTypeError(
        "random_state must be None, an int, a numpy.random.Generator, a numpy.random.RandomState or a "
        f"torch.Generator, got {type(random_state).__name__}"
    )
