"""Input validation and random-state handling shared by the public entry points.

Public functions validate once, at the entry, with these helpers (in the spirit of kornia's
``KORNIA_CHECK_SHAPE``); internal functions trust their callers. Every error names the argument, what
was expected and what was given.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence

import numpy as np
import torch

ShapeSpec = Sequence[str | int]


def _shape_str(spec: ShapeSpec) -> str:
    return "(" + ", ".join(str(s) for s in spec) + ")"


def check_tensor(x: object, name: str) -> torch.Tensor:
    """Return ``x`` if it is a tensor, else raise ``TypeError`` naming ``name``."""
    if not isinstance(x, torch.Tensor):
        raise TypeError(f"{name} must be a torch.Tensor, got {type(x).__name__}")
    return x


def check_shape(x: torch.Tensor, name: str, spec: ShapeSpec) -> dict[str, int]:
    """Check ``x`` against a shape spec and return the sizes bound to the named dimensions.

    ``spec`` lists one entry per dimension: an ``int`` fixes the size, a string names a free size
    (the same name must have the same size everywhere it appears). ``"*"`` as the first entry
    allows any number of leading dimensions.

    Examples
    --------
    >>> check_shape(torch.zeros(2, 100, 3, 8, 8), "frames", ["B", "T", 3, "H", "W"])
    {'B': 2, 'T': 100, 'H': 8, 'W': 8}
    """
    check_tensor(x, name)
    spec = list(spec)
    shape = tuple(x.shape)
    leading = bool(spec) and spec[0] == "*"
    fixed = spec[1:] if leading else spec
    if (len(shape) < len(fixed)) if leading else (len(shape) != len(fixed)):
        raise ValueError(f"{name} must have shape {_shape_str(spec)}, got {shape}")
    sizes: dict[str, int] = {}
    for want, got in zip(fixed, shape[len(shape) - len(fixed) :], strict=True):
        if isinstance(want, int):
            if got != want:
                raise ValueError(f"{name} must have shape {_shape_str(spec)}, got {shape}")
        elif sizes.setdefault(want, got) != got:
            raise ValueError(f"{name} must have shape {_shape_str(spec)} (equal {want}), got {shape}")
    return sizes


def check_floating(x: torch.Tensor, name: str) -> torch.Tensor:
    """Raise ``TypeError`` unless ``x`` has a floating dtype."""
    if not x.is_floating_point():
        raise TypeError(f"{name} must have a floating dtype (float32 or float64), got {x.dtype}")
    return x


def check_finite(x: torch.Tensor, name: str) -> torch.Tensor:
    """Raise ``ValueError`` if ``x`` holds NaN or inf, saying how many and where the first one is."""
    if x.is_floating_point():
        bad = ~torch.isfinite(x)
        if bool(bad.any()):
            first = tuple(int(i) for i in bad.nonzero()[0])
            raise ValueError(
                f"{name} must be finite, got {int(bad.sum())} NaN/inf value(s) (first at index {first})"
            )
    return x


def check_positive(value: object, name: str, *, strict: bool = True, integer: bool = False) -> None:
    """Raise unless ``value`` is a (strictly) positive real (or integer) number."""
    kind = numbers.Integral if integer else numbers.Real
    if isinstance(value, bool) or not isinstance(value, kind):
        raise TypeError(f"{name} must be {'an integer' if integer else 'a real number'}, got {value!r}")
    if not np.isfinite(value) or (value <= 0 if strict else value < 0):
        raise ValueError(f"{name} must be {'> 0' if strict else '>= 0'}, got {value!r}")


RandomState = int | np.random.Generator | np.random.RandomState | torch.Generator | None


def numpy_rng(random_state: RandomState) -> np.random.Generator:
    """Return a ``numpy.random.Generator`` for an int seed, a numpy or torch generator, or ``None``.

    A torch generator or a legacy ``numpy.random.RandomState`` is consumed (one draw) to seed the numpy
    one, so the result stays a function of the generator's state. ``None`` gives fresh OS entropy.
    """
    if random_state is None or isinstance(random_state, numbers.Integral):
        return np.random.default_rng(None if random_state is None else int(random_state))
    if isinstance(random_state, np.random.Generator):
        return random_state
    if isinstance(random_state, torch.Generator):
        seed = int(torch.randint(0, 2**62, (1,), generator=random_state))
        return np.random.default_rng(seed)
    if isinstance(random_state, np.random.RandomState):  # scikit-learn's "random_state" allows it
        return np.random.default_rng(int(random_state.randint(0, 2**31 - 1)))
    raise TypeError(
        "random_state must be None, an int, a numpy.random.Generator, a numpy.random.RandomState or a "
        f"torch.Generator, got {type(random_state).__name__}"
    )


def torch_generator(random_state: RandomState) -> torch.Generator:
    """Return a CPU ``torch.Generator`` for an int seed, a numpy or torch generator, or ``None``."""
    if isinstance(random_state, torch.Generator):
        return random_state
    seed = int(numpy_rng(random_state).integers(0, 2**62))
    return torch.Generator().manual_seed(seed)


def as_feature_matrix(X: object, name: str = "X", n_features: int | None = None) -> np.ndarray:
    """Return a feature matrix (array-like or tensor) as a C-contiguous float64 ``(n, F)`` array.

    Raises ``TypeError`` if ``X`` is not numeric, ``ValueError`` if it is not 2-D, is empty, has not
    ``n_features`` columns (when given) or holds NaN/inf (saying how many and where the first is).
    """
    if isinstance(X, torch.Tensor):
        X = X.detach().cpu().numpy()
    try:
        arr = np.asarray(X, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise TypeError(
            f"{name} must be a numeric array of shape (n_samples, n_features), got {type(X).__name__}"
        ) from err
    if arr.ndim != 2:
        raise ValueError(f"{name} must have shape (n_samples, n_features), got {arr.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"{name} must hold at least 1 sample and 1 feature, got shape {arr.shape}")
    if n_features is not None and arr.shape[1] != n_features:
        raise ValueError(f"{name} must have {n_features} features (as in fit), got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(
            f"{name} must be finite, got {int(bad.sum())} NaN/inf value(s) (first at index {first})"
        )
    return np.ascontiguousarray(arr)
