"""Method 2 with the spectral feature's cut-off learned, under the same hinge-loss head as :mod:`.front_end`.

Of the 21 window features only one has a continuous setting a gradient can move: ``hf``, the sum of the
amplitude spectrum ``|rfft(a - a[0])|`` over the upper half of the bins (``W/4 < k <= W/2``, i.e.
above a quarter of the sample rate). The moments (variance, skewness, kurtosis, fifth moment) and
the total variation have no setting; the 20 crossing thresholds are evenly spaced between the
window's extremes, a count (piecewise constant: zero gradient almost everywhere), left as they are.

:class:`LearnedCutoffClassifier` replaces the upper-half sum by a soft mask over the bins,
``hf_c = sum_k |X_k| sigmoid((k / (W/2) - c) / tau)``, with the cut-off ``c`` (a fraction of the
Nyquist frequency, hand-set 0.5: the study's upper half) and ``tau`` as torch parameters, trained with
a linear Crammer-Singer hinge head on the standardised 21 features (stage 1). Stage 2 trains the head
again on the *hard* features at the learned cut-off (``hf_c`` over the bins ``k > c W/2``, the study's
form with another edge). ``learn=False`` keeps ``c = 0.5``: the hand-set baseline with the same head.
The exported graph computes the 21 features with :class:`tactile_torch.signal.WindowFeatures` and
replaces the three ``hf`` columns by the sum over the learned bins (a cos/sin basis MatMul, as the
package's own export of the spectrum).
"""

from __future__ import annotations

import math
from numbers import Integral, Real
from typing import ClassVar

import numpy as np
import torch
from sklearn.base import _fit_context
from sklearn.utils._param_validation import Interval
from sklearn.utils.validation import check_is_fitted
from torch import nn

from ..validation import RANDOM_STATE, numpy_rng, torch_generator
from .front_end import HardFrontEndGraph, _HingeHeadClassifier, crammer_singer_loss

HF_COLUMNS = (6, 13, 20)
"""Columns of ``hf`` among the 21 features (axis-major order)."""


def _spectra(windows: torch.Tensor) -> torch.Tensor:
    """``|rfft(a - a[0])|`` of windows ``(N, 3, W)`` → ``(N, 3, W // 2 + 1)`` float64."""
    d = windows.to(torch.float64)
    return torch.fft.rfft(d - d[..., :1], dim=-1).abs()


def _positions(width: int) -> torch.Tensor:
    """Bin positions ``k / (W / 2)`` of the ``W // 2 + 1`` rfft bins (0 = DC, 1 = Nyquist)."""
    return torch.arange(width // 2 + 1, dtype=torch.float64) / (width / 2)


class CutoffWindowFeatures(nn.Module):
    """Windows ``(B, 3, W)`` → the 21 features with ``hf`` summed over the bins ``k > cutoff * W / 2``."""

    def __init__(self, width: int, cutoff: float) -> None:
        super().__init__()
        from ..signal import WindowFeatures

        self.features = WindowFeatures(width)
        bins = np.flatnonzero(_positions(width).numpy() > cutoff)
        t = np.arange(width)[:, None]
        angle = 2 * np.pi * t * bins[None, :] / width
        self.n_bins = len(bins)
        self.register_buffer(
            "basis", torch.from_numpy(np.concatenate([np.cos(angle), -np.sin(angle)], 1)).float()
        )

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        x = windows.to(torch.float32)
        base = self.features(x).to(torch.float32)
        proj = (x - x[..., :1]) @ self.basis  # (B, 3, 2K)
        re, im = proj[..., : self.n_bins], proj[..., self.n_bins :]
        hf = torch.sqrt(re * re + im * im).sum(-1)  # (B, 3)
        columns = list(base.unbind(-1))
        for axis, column in enumerate(HF_COLUMNS):
            columns[column] = hf[:, axis]
        return torch.stack(columns, dim=-1)


class LearnedCutoffClassifier(_HingeHeadClassifier):
    """The 21 window features with a learned spectral cut-off and a hinge-loss linear head.

    Parameters
    ----------
    learn : bool
        ``False``: keep the hand-set ``cutoff``.
    cutoff : float in (0, 1)
        Hand-set cut-off as a fraction of the Nyquist frequency (0.5: the study's upper half).
    temperature : float > 0
        Initial ``tau`` of the soft mask (fraction of Nyquist).
    epochs, batch_size, learning_rate, alpha, head_steps, random_state
        As :class:`~.front_end.LearnedFrontEndClassifier`.

    Attributes
    ----------
    cutoff_ : float
        The cut-off the model uses.
    temperature_ : float
    history_ : list of dict
        Stage 1: cut-off and mean hinge loss after each epoch.
    """

    _n_learned = 2
    _parameter_constraints: ClassVar[dict] = {
        "learn": ["boolean"],
        "cutoff": [Interval(Real, 0, 1, closed="neither")],
        "temperature": [Interval(Real, 0, None, closed="neither")],
        "epochs": [Interval(Integral, 1, None, closed="left")],
        "batch_size": [Interval(Integral, 1, None, closed="left")],
        "learning_rate": [Interval(Real, 0, None, closed="neither")],
        "alpha": [Interval(Real, 0, None, closed="left")],
        "head_steps": [Interval(Integral, 1, None, closed="left")],
        "random_state": RANDOM_STATE,
    }

    def __init__(
        self,
        learn: bool = True,
        *,
        cutoff: float = 0.5,
        temperature: float = 0.02,
        epochs: int = 30,
        batch_size: int = 32,
        learning_rate: float = 0.02,
        alpha: float = 1e-3,
        head_steps: int = 300,
        random_state: int | None = None,
    ) -> None:
        self.learn = learn
        self.cutoff = cutoff
        self.temperature = temperature
        self.epochs = epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.alpha = alpha
        self.head_steps = head_steps
        self.random_state = random_state

    @staticmethod
    def _windows(X: object) -> torch.Tensor:
        raw = np.asarray(X.numpy() if isinstance(X, torch.Tensor) else X)
        if raw.ndim != 3 or raw.shape[1] != 3 or raw.shape[0] == 0 or raw.shape[2] < 4:
            raise ValueError(f"windows must have shape (N, 3, W) with N >= 1 and W >= 4, got {raw.shape}")
        if raw.dtype.kind != "f" or not np.isfinite(raw).all():
            raise ValueError("windows must be finite floats (g)")
        return torch.from_numpy(np.ascontiguousarray(raw, dtype=np.float32))

    def _learn(self, windows: torch.Tensor, y: torch.Tensor, generator: torch.Generator) -> None:
        from ..signal import window_features
        from .networks import build

        base = window_features(windows).to(torch.float64)
        spectra = _spectra(windows)
        positions = _positions(windows.shape[-1])
        c = nn.Parameter(torch.tensor(math.log(self.cutoff / (1 - self.cutoff)), dtype=torch.float64))
        log_tau = nn.Parameter(torch.tensor(math.log(self.temperature), dtype=torch.float64))

        def features(index: torch.Tensor) -> torch.Tensor:
            mask = torch.sigmoid((positions - torch.sigmoid(c)) / log_tau.exp())
            hf = spectra[index] @ mask  # (b, 3)
            F = base[index].clone()
            F[:, list(HF_COLUMNS)] = hf
            return F

        everything = torch.arange(len(windows))
        with torch.no_grad():
            start = features(everything)
        mean, scale = start.mean(0), start.std(0).clamp_min(1e-12)
        linear = build(nn.Linear, 21, len(self.classes_), generator=generator).double()
        optimiser = torch.optim.Adam([c, log_tau, *linear.parameters()], lr=self.learning_rate)
        self.history_ = [{"epoch": 0, "loss": None, "cutoff": self.cutoff}]
        for epoch in range(1, self.epochs + 1):
            total = 0.0
            for index in torch.randperm(len(windows), generator=generator).split(self.batch_size):
                optimiser.zero_grad()
                scores = linear((features(index) - mean) / scale)
                loss = crammer_singer_loss(scores, y[index]) + self.alpha * (linear.weight**2).sum()
                loss.backward()
                optimiser.step()
                total += float(loss.detach()) * len(index)
            self.history_.append(
                {"epoch": epoch, "loss": total / len(windows), "cutoff": float(torch.sigmoid(c.detach()))}
            )
        self.cutoff_ = float(torch.sigmoid(c.detach()))
        self.temperature_ = float(log_tau.detach().exp())

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object) -> LearnedCutoffClassifier:
        """Learn the cut-off (``learn=True``), then the hinge head on the hard features; return self."""
        from .._parallel import serial_torch_ops_in_this_thread

        windows = self._windows(X)
        targets = self._targets(len(windows), y)
        self.input_shape_ = tuple(int(s) for s in windows.shape[1:])
        generator = torch_generator(self.random_state)
        numpy_rng(generator)
        self.cutoff_, self.temperature_, self.history_ = float(self.cutoff), float(self.temperature), []
        with serial_torch_ops_in_this_thread():
            if self.learn:
                self._learn(windows, targets, generator)
            self._fit_head(self._features(windows), targets, generator)
        return self

    def _features(self, windows: torch.Tensor) -> torch.Tensor:
        with torch.no_grad():
            return CutoffWindowFeatures(windows.shape[-1], self.cutoff_)(windows)

    def to_module(self) -> nn.Module:
        """Return the inference graph: windows → 21 features at the cut-off → ``(labels, scores)``."""
        check_is_fitted(self)
        features = CutoffWindowFeatures(self.input_shape_[-1], self.cutoff_)
        return HardFrontEndGraph(features, self.feature_mean_, self.feature_scale_, self.linear_).eval()

    def decision_function(self, X: object) -> np.ndarray:
        """Return the linear scores ``(N, C)``."""
        check_is_fitted(self)
        windows = self._windows(X)
        self._check_shape(windows, "windows")
        with torch.no_grad():
            return self.to_module()(windows)[1].double().numpy()

    def learned_settings(self) -> dict[str, object]:
        """Return ``{"cutoff": (hand-set, used), "temperature": (initial, learned)}``."""
        check_is_fitted(self)
        return {
            "cutoff": (float(self.cutoff), self.cutoff_),
            "temperature": (float(self.temperature), self.temperature_),
        }


__all__ = ["HF_COLUMNS", "CutoffWindowFeatures", "LearnedCutoffClassifier"]
