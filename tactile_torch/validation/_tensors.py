"""Input validation and random-state handling shared by the public entry points.

Public functions validate once, at the entry, with these helpers (in the spirit of kornia's
``KORNIA_CHECK_SHAPE``); internal functions trust their callers. Every error names the argument, what
was expected and what was given. The checks that need no torch (numbers, counts, random states) are
defined in :mod:`tactile_torch.validation`, which the robot side uses, and imported here.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from ..exceptions import InputTypeError
from ._scalars import check_count, check_number, check_positive, numpy_rng

ShapeSpec = Sequence[str | int]


def _shape_str(spec: ShapeSpec) -> str:
    return "(" + ", ".join(str(s) for s in spec) + ")"


def check_tensor(x: object, name: str) -> torch.Tensor:
    """Return ``x`` if it is a tensor, else raise ``TypeError`` naming ``name``."""
    if not isinstance(x, torch.Tensor):
        raise InputTypeError(f"{name} must be a torch.Tensor, got {type(x).__name__}")
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
        raise InputTypeError(f"{name} must have a floating dtype (float32 or float64), got {x.dtype}")
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


RandomState = int | np.random.Generator | np.random.RandomState | torch.Generator | None


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
        raise InputTypeError(
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


__all__ = [
    "RandomState",
    "ShapeSpec",
    "as_feature_matrix",
    "check_count",
    "check_finite",
    "check_floating",
    "check_number",
    "check_positive",
    "check_shape",
    "check_tensor",
    "numpy_rng",
    "torch_generator",
]
