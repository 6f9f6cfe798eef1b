"""Method 1's front end learned through the differentiable image ops, under a multi-class hinge-loss head.

:class:`LearnedFrontEndClassifier` fits in two stages:

1. **Front end, end to end** (``learn=True``): the soft pipeline of :mod:`tactile_torch.image`
   (``sigmoid((threshold - I) / t1)`` pressed region, soft-minimum erosion ``-t2 logsumexp(-x / t2)``,
   soft Sobel edges ``sigmoid((gx^2 + gy^2 - e^2) / t3)``, noisy-OR fusion, gradient statistics) with the
   pressure ``threshold``, the ``edge_threshold`` ``e`` and the temperatures ``t1`` and ``t3`` as torch
   parameters (logit / log parametrised, so they stay in range; ``t2`` stays fixed, because the soft
   minimum pads the border with +inf, where its derivative in ``t2`` is undefined), started from the study's hand-set values
   (240/255, 0.5) and trained jointly with a linear head by the **Crammer-Singer multi-class hinge
   loss** ``max(0, 1 + max_{j != y} s_j - s_y)`` plus ``alpha ||W||^2`` (Adam). Each step sees a
   mini-batch of explorations and ``frames_per_step`` frames of each, drawn from the generator (the
   soft erosion keeps ``erosion`` tensors of the input's size for the backward pass: 100 frames of
   96 x 96 per exploration would not fit a small machine).
2. **Head on the whole explorations**: the *hard* features (:func:`tactile_torch.image.exploration_features`,
   all frames) at the learned threshold and edge threshold (or the hand-set ones with ``learn=False``)
   are standardised and the same hinge-loss head is trained on them by gradient (full batch).

The fitted model, and the exported graph, is hard ops at the learned values → standardisation →
linear scores (labels = argmax): exactly the form of the hand-set pipeline, so the parity test of the
hard image ops applies, and ``learn=False`` gives the hand-set baseline with the same head, the
comparison of :mod:`tactile_torch.studies.learned_models`. The temperatures only shape the training
signal; they are reported (``temperatures_``) but not used at inference. The erosion side is an integer
(the number of pixels of the structuring element) and is not learned.
"""

from __future__ import annotations

import math
from numbers import Integral, Real
from typing import ClassVar

import numpy as np
import torch
from sklearn.base import BaseEstimator, ClassifierMixin, _fit_context
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted
from torch import nn

from ..exceptions import InputTypeError
from ..validation import RANDOM_STATE, numpy_rng, tensor_from_array, torch_generator

INITIAL_TEMPERATURES = (0.02, 0.05, 0.5)
"""Starting temperatures of the soft threshold (gray levels on the 0-1 scale), the soft erosion and the
soft edges (squared Sobel magnitude)."""


def crammer_singer_loss(scores: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """Return the mean Crammer-Singer hinge loss ``max(0, 1 + max_{j != y} s_j - s_y)`` of ``(B, C)`` scores."""
    true = scores.gather(1, y[:, None])
    others = scores.masked_fill(nn.functional.one_hot(y, scores.shape[1]).bool(), -math.inf)
    return torch.clamp(1.0 + others.amax(1, keepdim=True) - true, min=0.0).mean()


class SoftFrontEnd(nn.Module):
    """Frames ``(B, T, 3, H, W)`` float in [0, 1] → ``(B, 12)`` soft method-1 features with learnable settings.

    Parameters
    ----------
    threshold : float in (0, 1)
    edge_threshold : float > 0
    erosion : int >= 1
    temperatures : three floats > 0
        Soft threshold, soft erosion, soft edges.
    """

    def __init__(
        self,
        threshold: float,
        edge_threshold: float,
        erosion: int,
        temperatures: tuple[float, float, float] = INITIAL_TEMPERATURES,
    ) -> None:
        super().__init__()
        self.erosion = int(erosion)
        self.threshold_logit = nn.Parameter(torch.tensor(math.log(threshold / (1 - threshold))))
        self.log_edge_threshold = nn.Parameter(torch.tensor(math.log(edge_threshold)))
        self.log_temperatures = nn.Parameter(torch.log(torch.tensor(temperatures[::2], dtype=torch.float32)))
        # The erosion's temperature stays fixed: the soft minimum pads the border with +inf, where
        # the derivative in the temperature is inf * 0 (NaN).
        self.erosion_temperature = float(temperatures[1])

    def settings(self) -> dict[str, object]:
        """Return the current ``threshold``, ``edge_threshold`` and ``temperatures`` as plain floats."""
        with torch.no_grad():
            return {
                "threshold": float(torch.sigmoid(self.threshold_logit)),
                "edge_threshold": float(self.log_edge_threshold.exp()),
                "temperatures": [
                    float(self.log_temperatures[0].exp()),
                    self.erosion_temperature,
                    float(self.log_temperatures[1].exp()),
                ],
            }

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        from ..image import learnable_exploration_features

        t_mask, t_edge = self.log_temperatures.exp().unbind()
        return learnable_exploration_features(
            frames,
            torch.sigmoid(self.threshold_logit),
            self.log_edge_threshold.exp(),
            (t_mask, self.erosion_temperature, t_edge),
            self.erosion,
        )


class HardFrontEndGraph(nn.Module):
    """Frames → ``(labels, scores)``: hard method-1 features at fixed settings, standardisation, linear scores."""

    def __init__(
        self, features: nn.Module, mean: torch.Tensor, scale: torch.Tensor, linear: nn.Linear
    ) -> None:
        super().__init__()
        self.features = features
        self.register_buffer("mean", mean.to(torch.float32))
        self.register_buffer("scale", scale.to(torch.float32))
        self.linear = linear

    def embed(self, frames: torch.Tensor) -> torch.Tensor:
        """Return the standardised features ``(B, F)``: what the linear scores are computed from."""
        return (self.features(frames).to(torch.float32) - self.mean) / self.scale

    def classify(self, embedding: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Return ``(labels, scores)`` of standardised features (``forward(x) == classify(embed(x))``)."""
        scores = self.linear(embedding)
        return scores.argmax(-1), scores

    def forward(self, frames: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.classify(self.embed(frames))


def _train_head(
    F: torch.Tensor, y: torch.Tensor, n_classes: int, alpha: float, steps: int, generator: torch.Generator
) -> nn.Linear:
    """Return a linear head trained on standardised features ``F`` by full-batch Adam on the hinge loss."""
    from .networks import build

    linear = build(nn.Linear, F.shape[1], n_classes, generator=generator)
    optimiser = torch.optim.Adam(linear.parameters(), lr=0.05)
    for _ in range(steps):
        optimiser.zero_grad()
        loss = crammer_singer_loss(linear(F), y) + alpha * (linear.weight**2).sum()
        loss.backward()
        optimiser.step()
    linear.eval()
    return linear


def _fit_standardised_head(
    F: torch.Tensor, y: torch.Tensor, n_classes: int, alpha: float, steps: int, generator: torch.Generator
) -> tuple[torch.Tensor, torch.Tensor, nn.Linear]:
    """Return ``(mean, scale, head)``: ``F``'s standardisation and :func:`_train_head` fitted on it."""
    from .._parallel import serial_torch_ops_in_this_thread

    mean, scale = F.mean(0), F.std(0).clamp_min(1e-6)
    with serial_torch_ops_in_this_thread():
        return mean, scale, _train_head((F - mean) / scale, y, n_classes, alpha, steps, generator)


class _HingeHeadClassifier(ClassifierMixin, BaseEstimator):
    """What the learned front ends share: the targets, the hinge head on their hard features, predict."""

    _n_learned = 0
    """Settings the front end learns (counted in ``n_parameters_`` when ``learn``)."""

    def _targets(self, n: int, y: object) -> torch.Tensor:
        y = np.asarray(y)
        if y.shape != (n,):
            raise ValueError(f"y must have shape ({n},), got {y.shape}")
        check_classification_targets(y)
        self.classes_, encoded = np.unique(y, return_inverse=True)
        return torch.from_numpy(encoded.astype(np.int64))

    def _fit_head(self, features: torch.Tensor, targets: torch.Tensor, generator: torch.Generator) -> None:
        self.feature_mean_, self.feature_scale_, self.linear_ = _fit_standardised_head(
            features, targets, len(self.classes_), self.alpha, self.head_steps, generator
        )
        head = self.linear_.weight.numel() + self.linear_.bias.numel()
        self.n_parameters_ = int(head) + (self._n_learned if self.learn else 0)

    def _check_shape(self, inputs: torch.Tensor, name: str) -> None:
        if tuple(inputs.shape[1:]) != self.input_shape_:
            raise ValueError(
                f"{name} must have shape (N, {self.input_shape_}) as in fit, got {tuple(inputs.shape)}"
            )

    def predict(self, X: object) -> np.ndarray:
        """Return the class of each input (largest score)."""
        return self.classes_[self.decision_function(X).argmax(1)]


class LearnedFrontEndClassifier(_HingeHeadClassifier):
    """Method 1 with its front-end settings learned through the soft ops and a hinge-loss linear head.

    See the module notes for the two stages.

    Parameters
    ----------
    learn : bool
        ``False``: keep the hand-set ``threshold`` and ``edge_threshold`` (the baseline with the same head).
    threshold : float in (0, 1)
        Hand-set pressure threshold (gray level, 0-1 scale; the study's 240/255).
    edge_threshold : float > 0
        Hand-set Sobel edge threshold (0.5).
    erosion : int or "relative"
        Side of the erosion square; ``"relative"`` scales the study's 10 px of 96 px to the frame
        (:func:`tactile_torch.image.relative_erosion`).
    epochs, frames_per_step, batch_size, learning_rate
        Stage 1 (Adam on the soft pipeline).
    alpha : float
        Weight of ``||W||^2`` in the hinge loss.
    head_steps : int
        Full-batch Adam steps of stage 2.
    random_state : int, generator or None
    progress : bool
        A progress bar over stage 1's epochs.

    Attributes
    ----------
    classes_ : ndarray
    threshold_, edge_threshold_ : float
        The settings the model uses (learned, or the hand-set ones).
    temperatures_ : list of float
        The learned temperatures (the initial ones with ``learn=False``).
    erosion_ : int
    history_ : list of dict
        Stage 1: the settings and the mean hinge loss after each epoch.
    """

    _n_learned = 4
    _parameter_constraints: ClassVar[dict] = {
        "learn": ["boolean"],
        "threshold": [Interval(Real, 0, 1, closed="neither")],
        "edge_threshold": [Interval(Real, 0, None, closed="neither")],
        "erosion": [Interval(Integral, 1, None, closed="left"), StrOptions({"relative"})],
        "epochs": [Interval(Integral, 1, None, closed="left")],
        "frames_per_step": [Interval(Integral, 1, None, closed="left")],
        "batch_size": [Interval(Integral, 1, None, closed="left")],
        "learning_rate": [Interval(Real, 0, None, closed="neither")],
        "alpha": [Interval(Real, 0, None, closed="left")],
        "head_steps": [Interval(Integral, 1, None, closed="left")],
        "random_state": RANDOM_STATE,
        "progress": ["boolean"],
    }

    def __init__(
        self,
        learn: bool = True,
        *,
        threshold: float = 240 / 255,
        edge_threshold: float = 0.5,
        erosion: int | str = "relative",
        epochs: int = 6,
        frames_per_step: int = 8,
        batch_size: int = 8,
        learning_rate: float = 0.05,
        alpha: float = 1e-3,
        head_steps: int = 300,
        random_state: int | None = None,
        progress: bool = True,
    ) -> None:
        self.learn = learn
        self.threshold = threshold
        self.edge_threshold = edge_threshold
        self.erosion = erosion
        self.epochs = epochs
        self.frames_per_step = frames_per_step
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.alpha = alpha
        self.head_steps = head_steps
        self.random_state = random_state
        self.progress = progress

    @staticmethod
    def _frames(X: object) -> torch.Tensor:
        raw = np.asarray(X.numpy() if isinstance(X, torch.Tensor) else X)
        if raw.ndim != 5 or raw.shape[2] != 3 or raw.shape[0] == 0:
            raise ValueError(f"frames must have shape (N, T, 3, H, W) with N >= 1, got {raw.shape}")
        if raw.dtype != np.uint8:
            raise InputTypeError(f"frames must be uint8 RGB (0-255), got dtype {raw.dtype}")
        return tensor_from_array(np.ascontiguousarray(raw))

    def _hard_features(self, frames: torch.Tensor) -> torch.Tensor:
        from ..image import exploration_features

        return exploration_features(
            frames, threshold=self.threshold_, erosion=self.erosion_, edge_threshold=self.edge_threshold_
        ).to(torch.float32)

    def _learn_front_end(self, frames: torch.Tensor, y: torch.Tensor, generator: torch.Generator) -> None:
        from .._parallel import serial_torch_ops_in_this_thread

        n_classes = len(self.classes_)
        front = SoftFrontEnd(self.threshold, self.edge_threshold, self.erosion_)
        n, n_frames = frames.shape[:2]
        take = min(self.frames_per_step, n_frames)

        def sample(index: torch.Tensor) -> torch.Tensor:
            chosen = torch.stack([torch.randperm(n_frames, generator=generator)[:take] for _ in index])
            picked = frames[index[:, None], chosen.sort(1).values]  # (b, take, 3, H, W)
            return picked.to(torch.float32) / 255.0

        with torch.no_grad(), serial_torch_ops_in_this_thread():  # standardisation at the hand-set values
            start = torch.cat([front(sample(i)) for i in torch.arange(n).split(self.batch_size)])
        mean, scale = start.mean(0), start.std(0).clamp_min(1e-6)
        from .networks import build

        linear = build(nn.Linear, start.shape[1], n_classes, generator=generator)
        optimiser = torch.optim.Adam([*front.parameters(), *linear.parameters()], lr=self.learning_rate)
        self.history_ = [{"epoch": 0, "loss": None, **front.settings()}]
        epochs = range(1, self.epochs + 1)
        if self.progress:
            from tqdm.auto import tqdm

            epochs = tqdm(epochs, desc="learned front end", leave=False, dynamic_ncols=True)
        with serial_torch_ops_in_this_thread():
            for epoch in epochs:
                total = 0.0
                for index in torch.randperm(n, generator=generator).split(self.batch_size):
                    optimiser.zero_grad()
                    F = (front(sample(index)).to(torch.float32) - mean) / scale
                    loss = crammer_singer_loss(linear(F), y[index]) + self.alpha * (linear.weight**2).sum()
                    loss.backward()
                    optimiser.step()
                    total += float(loss.detach()) * len(index)
                self.history_.append({"epoch": epoch, "loss": total / n, **front.settings()})
        learned = front.settings()
        self.threshold_ = learned["threshold"]
        self.edge_threshold_ = learned["edge_threshold"]
        self.temperatures_ = learned["temperatures"]

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object) -> LearnedFrontEndClassifier:
        """Learn the front end (``learn=True``), then the hinge-loss head on the whole explorations.

        Parameters
        ----------
        X : array of shape (N, T, 3, H, W), uint8
        y : array of shape (N,)

        Returns
        -------
        self
        """
        from ..image import relative_erosion

        frames = self._frames(X)
        targets = self._targets(len(frames), y)
        self.input_shape_ = tuple(int(s) for s in frames.shape[1:])
        height, width = frames.shape[-2:]
        self.erosion_ = relative_erosion(height, width) if self.erosion == "relative" else int(self.erosion)
        generator = torch_generator(self.random_state)
        numpy_rng(generator)  # one draw: the head's seed does not depend on whether stage 1 ran
        self.threshold_, self.edge_threshold_ = float(self.threshold), float(self.edge_threshold)
        self.temperatures_ = list(INITIAL_TEMPERATURES)
        self.history_ = []
        if self.learn:
            self._learn_front_end(frames, targets, generator)
        self._fit_head(self._hard_features(frames), targets, generator)
        return self

    def to_module(self) -> nn.Module:
        """Return the inference graph: hard features at the model's settings → ``(labels, scores)``."""
        from ..image import ExplorationFeatures

        check_is_fitted(self)
        features = ExplorationFeatures(
            threshold=self.threshold_, erosion=self.erosion_, edge_threshold=self.edge_threshold_
        )
        return HardFrontEndGraph(features, self.feature_mean_, self.feature_scale_, self.linear_).eval()

    def decision_function(self, X: object) -> np.ndarray:
        """Return the linear scores ``(N, C)`` of the head on the standardised hard features."""
        check_is_fitted(self)
        frames = self._frames(X)
        self._check_shape(frames, "frames")
        with torch.no_grad():
            scores = self.linear_((self._hard_features(frames) - self.feature_mean_) / self.feature_scale_)
        return scores.double().numpy()

    def learned_settings(self) -> dict[str, object]:
        """Return the settings used next to the hand-set ones: ``{"threshold": (hand-set, used), ...}``."""
        check_is_fitted(self)
        return {
            "threshold": (float(self.threshold), self.threshold_),
            "edge_threshold": (float(self.edge_threshold), self.edge_threshold_),
            "temperatures": (list(INITIAL_TEMPERATURES), self.temperatures_),
        }


__all__ = [
    "INITIAL_TEMPERATURES",
    "HardFrontEndGraph",
    "LearnedFrontEndClassifier",
    "SoftFrontEnd",
    "crammer_singer_loss",
]
