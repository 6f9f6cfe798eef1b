"""Argument checks of the public image functions (each public entry validates once, here).

Checks that depend on the values (finite, range) are skipped while tracing for export: an exported
graph cannot raise, and the trace must not depend on the example input's values.
"""

from __future__ import annotations

import torch

from ..exceptions import InputTypeError
from ..validation import check_finite, check_floating, check_positive, check_shape, check_tensor

Threshold = float | torch.Tensor | str


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
    if frames.is_floating_point() and not torch.compiler.is_exporting():
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
    if not torch.compiler.is_exporting():
        check_finite(x, name)
    return x


def check_temperature(temperature: float | None) -> None:
    """``None`` (hard mode) or a positive number."""
    if temperature is not None:
        check_positive(temperature, "temperature")


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
        if not torch.compiler.is_exporting():
            check_finite(threshold, name)
        return
    check_positive(threshold, name)
    if threshold > 1.0:
        raise ValueError(f"{name} must be in (0, 1] (the 0-255 scale divided by 255), got {threshold!r}")
