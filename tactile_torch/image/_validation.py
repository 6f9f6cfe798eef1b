"""Argument checks of the public image functions (each public entry validates once, here).

Checks that depend on the values (finite, range) are skipped while the values cannot be read
(:func:`tactile_torch.validation.values_unavailable`: ONNX export, ``torch.compile``, ``jit.trace``,
``vmap``): an exported graph cannot raise, and a trace must not depend on the example input's values.
"""

from __future__ import annotations

import warnings

import torch

from ..exceptions import InputTypeError
from ..validation import (
    check_finite,
    check_floating,
    check_positive,
    check_shape,
    check_tensor,
    values_unavailable,
)

Threshold = float | torch.Tensor | str
"""A pressure threshold: a number in (0, 1], a floating tensor of shape () or (B,), or ``"otsu"``."""
Scalar = float | torch.Tensor
"""A soft parameter (temperature, edge threshold): a real number or a floating 0-d tensor, which may
require gradients."""


def check_frames(frames: object, name: str = "frames", *, batched: bool = True) -> torch.Tensor:
    """Validate RGB frames ``(B, T, 3, H, W)`` (or ``(..., 3, H, W)``): uint8, or float in [0, 1]."""
    check_tensor(frames, name)
    check_shape(frames, name, ["B", "T", 3, "H", "W"] if batched else ["*", 3, "H", "W"])
    if frames.dtype != torch.uint8 and not frames.is_floating_point():
        raise InputTypeError(f"{name} must be uint8 (0-255) or float in [0, 1], got {frames.dtype}")
    if any(s == 0 for s in frames.shape):
        what = (
            "frame per exploration (T >= 1)" if batched and frames.shape[1] == 0 else "non-empty dimensions"
        )
        raise ValueError(f"{name} must have at least one {what}, got shape {tuple(frames.shape)}")
    if frames.is_floating_point() and not values_unavailable():
        check_unit_range(frames, name)
    return frames


def check_unit_range(x: torch.Tensor, name: str) -> None:
    """Raise ``ValueError`` unless every value of ``x`` is finite and in [0, 1]."""
    lo, hi = torch.aminmax(x.detach())
    if not (bool(torch.isfinite(lo)) and bool(torch.isfinite(hi))):
        check_finite(x, name)
    if float(lo) < 0.0 or float(hi) > 1.0:
        raise ValueError(
            f"{name} must be float in [0, 1] (or uint8 0-255), got values in [{float(lo):g}, {float(hi):g}]"
        )


def check_image(x: object, name: str, spec: list) -> torch.Tensor:
    """Validate a floating, finite, non-empty image stack of shape ``spec``."""
    check_tensor(x, name)
    check_shape(x, name, spec)
    check_floating(x, name)
    if any(s == 0 for s in x.shape):
        raise ValueError(f"{name} must have non-empty dimensions, got shape {tuple(x.shape)}")
    if not values_unavailable():
        check_finite(x, name)
    return x


def check_scalar(value: object, name: str, *, strict: bool = True) -> None:
    """A real number, or a floating 0-d tensor, ``> 0`` (``>= 0`` unless ``strict``) and finite.

    A tensor's value is checked unless the values cannot be read (:func:`values_unavailable`).
    """
    if not isinstance(value, torch.Tensor):
        check_positive(value, name, strict=strict)
        return
    if value.ndim != 0:
        raise ValueError(
            f"{name} must be a number or a 0-d tensor, got a tensor of shape {tuple(value.shape)}"
        )
    check_floating(value, name)
    if values_unavailable():
        return
    number = float(value.detach())
    if not (number > 0 if strict else number >= 0) or number == float("inf"):
        raise ValueError(f"{name} must be {'> 0' if strict else '>= 0'} and finite, got {number!r}")


def check_temperature(temperature: Scalar | None) -> None:
    """``None`` (hard mode), a positive number or a positive floating 0-d tensor."""
    if temperature is not None:
        check_scalar(temperature, "temperature")


def warn_if_gradient_lost(temperature: Scalar | None, **inputs: object) -> None:
    """Warn (one line) when the hard mode is given tensors that require gradients it cannot give.

    The hard steps are comparisons: their output has no gradient. Silent otherwise (soft mode, grad
    mode off, nothing requiring gradients, values unavailable).
    """
    if temperature is not None or not torch.is_grad_enabled() or values_unavailable():
        return
    names = [n for n, x in inputs.items() if isinstance(x, torch.Tensor) and x.requires_grad]
    if names:
        warnings.warn(
            f"{' and '.join(names)} require{'s' if len(names) == 1 else ''} gradients, but the hard mode "
            "(temperature=None) has none: pass temperature= for the differentiable mode, or detach",
            UserWarning,
            stacklevel=4,  # the caller of the public function (under its quiet_jit_trace wrapper)
        )


def check_threshold(threshold: Threshold, batch: int, name: str = "threshold") -> None:
    """A number in (0, 1], a floating tensor of shape () or (batch,), or ``"otsu"``."""
    if isinstance(threshold, str):
        if threshold != "otsu":
            raise ValueError(f"{name} must be a number in (0, 1], a tensor or 'otsu', got {threshold!r}")
        return
    if isinstance(threshold, torch.Tensor):
        if threshold.ndim > 1 or (threshold.ndim == 1 and threshold.shape[0] not in (1, batch)):
            raise ValueError(
                f"{name} must be a scalar tensor or have shape ({batch},), got {tuple(threshold.shape)}"
            )
        check_floating(threshold, name)
        if not values_unavailable():
            check_finite(threshold, name)
        return
    check_positive(threshold, name)
    if threshold > 1.0:
        raise ValueError(f"{name} must be in (0, 1] (the 0-255 scale divided by 255), got {threshold!r}")
