"""Neural candidates as scikit-learn classifiers: raw windows, pressure maps or explorations → surface.

:class:`WindowCNNClassifier` (vibration windows ``(N, 3, W)``, sizes ``"small"`` and ``"large"``),
:class:`TaxelCNNClassifier` (raw pressure maps ``(N, T, H, W)``) and :class:`ExplorationCNNClassifier`
(RGB explorations ``(N, T, 3, H, W)`` uint8) train the networks of :mod:`.networks` with torch on the
CPU. They follow scikit-learn's conventions (``clone``, ``get_params``, ``fit``/``predict``/
``predict_proba``, hyper-parameters validated at ``fit`` from ``_parameter_constraints``) and:

* **seeded**: one ``random_state`` gives the initial weights, the inner validation split and the order
  of the mini-batches (a ``torch.Generator`` and a NumPy generator drawn from it, nothing global), so
  the same seed gives the same weights on the same machine and thread count;
* **early stopping**: ``validation_fraction`` of the training samples (grouped by ``groups`` when
  given to :meth:`fit`) is held out; training stops after ``patience`` epochs without a lower held-out
  cross-entropy and keeps the best epoch's weights;
* **exportable**: :meth:`to_module` returns the inference graph (raw input → labels, softmax scores),
  which :func:`tactile_torch.export.export_classifier` writes to ONNX.

``n_parameters_`` is the number of trained scalars.

Examples
--------
>>> import numpy as np
>>> X = np.random.default_rng(0).normal(size=(40, 3, 64)).astype(np.float32)
>>> y = np.arange(40) % 2
>>> clf = WindowCNNClassifier(max_epochs=2, progress=False, random_state=0).fit(X, y)
>>> clf.predict_proba(X[:3]).shape
(3, 2)
"""

from __future__ import annotations

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
from ..validation import RANDOM_STATE, numpy_rng, torch_generator
from .networks import (
    WINDOW_WIDTHS,
    ClassifierGraph,
    ExplorationCNN,
    SeenClassifier,
    TaxelCNN,
    WindowCNN,
    build,
    count_parameters,
)
from .training import inner_split, train_network


class _NeuralClassifier(ClassifierMixin, BaseEstimator):
    """Shared fit/predict of the neural classifiers; subclasses define the input and the network."""

    _parameter_constraints: ClassVar[dict] = {
        "max_epochs": [Interval(Integral, 1, None, closed="left")],
        "batch_size": [Interval(Integral, 1, None, closed="left")],
        "learning_rate": [Interval(Real, 0, None, closed="neither")],
        "weight_decay": [Interval(Real, 0, None, closed="left")],
        "patience": [Interval(Integral, 1, None, closed="left")],
        "validation_fraction": [Interval(Real, 0, 1, closed="neither")],
        "random_state": RANDOM_STATE,
        "progress": ["boolean"],
    }
    _input_name = "X"
    _layout: tuple[str, ...] = ()

    def __init__(
        self,
        *,
        max_epochs: int = 60,
        batch_size: int = 32,
        learning_rate: float = 3e-3,
        weight_decay: float = 1e-4,
        patience: int = 8,
        validation_fraction: float = 0.2,
        random_state: int | None = None,
        progress: bool = True,
    ) -> None:
        self.max_epochs = max_epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.weight_decay = weight_decay
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.random_state = random_state
        self.progress = progress

    # -- input -------------------------------------------------------------------------------------
    def _as_input(self, X: object) -> torch.Tensor:
        """Return ``X`` as the network's input tensor, or raise naming ``X`` and the expected layout."""
        X = X.numpy() if isinstance(X, torch.Tensor) else X
        X = np.asarray(X)
        layout = "(" + ", ".join(("N", *self._layout)) + ")"
        if X.ndim != len(self._layout) + 1 or X.shape[0] == 0:
            raise ValueError(f"{self._input_name} must have shape {layout} with N >= 1, got {X.shape}")
        if X.dtype.kind not in "fiu":
            raise InputTypeError(f"{self._input_name} must be numeric, got dtype {X.dtype}")
        if X.dtype.kind == "f" and not np.isfinite(X).all():
            raise ValueError(f"{self._input_name} must be finite, got NaN or inf values")
        return torch.from_numpy(np.ascontiguousarray(X, dtype=np.float32))

    def _make_network(self, X: torch.Tensor, n_classes: int, generator: torch.Generator) -> nn.Module:
        raise NotImplementedError

    def _trained_part(self, network: nn.Module, inputs: torch.Tensor) -> tuple[nn.Module, torch.Tensor]:
        """Return the module gradient descent trains and its inputs (the network and ``inputs`` here)."""
        return network, inputs

    # -- fit / predict -----------------------------------------------------------------------------
    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object, groups: object = None) -> _NeuralClassifier:
        """Train the network on ``X``, ``y``; ``groups`` (optional) keeps the inner validation split grouped.

        Returns
        -------
        self
        """
        inputs = self._as_input(X)
        y = np.asarray(y)
        if y.ndim != 1 or len(y) != len(inputs):
            raise ValueError(f"y must have shape ({len(inputs)},), got {y.shape}")
        check_classification_targets(y)
        if groups is not None:
            groups = np.asarray(groups)
            if groups.shape != y.shape:
                raise ValueError(f"groups must have shape {y.shape}, got {groups.shape}")
        self.classes_, encoded = np.unique(y, return_inverse=True)
        self.n_features_in_ = int(np.prod(inputs.shape[1:]))
        self.input_shape_ = tuple(int(s) for s in inputs.shape[1:])
        generator = torch_generator(self.random_state)
        rng = numpy_rng(generator)
        train, held = inner_split(encoded, groups, self.validation_fraction, rng)
        network = self._make_network(inputs[train], len(self.classes_), generator)
        targets = torch.from_numpy(encoded.astype(np.int64))
        trained, inputs = self._trained_part(network, inputs)
        validation = (inputs[held], targets[held]) if len(held) else None
        self.training_log_ = train_network(
            trained,
            inputs[train],
            targets[train],
            validation=validation,
            loss_fn=nn.functional.cross_entropy,
            generator=generator,
            max_epochs=self.max_epochs,
            batch_size=self.batch_size,
            learning_rate=self.learning_rate,
            weight_decay=self.weight_decay,
            patience=self.patience,
            progress=self.progress,
            description=type(self).__name__,
        )
        self.network_ = network
        self.n_parameters_ = count_parameters(network)
        self.n_epochs_ = self.training_log_.epochs
        return self

    def _check_input(self, X: object) -> torch.Tensor:
        check_is_fitted(self)
        inputs = self._as_input(X)
        if tuple(inputs.shape[1:]) != self.input_shape_:
            raise ValueError(
                f"{self._input_name} must have shape (N, {', '.join(map(str, self.input_shape_))}) as in fit, "
                f"got {tuple(inputs.shape)}"
            )
        return inputs

    def predict_proba(self, X: object) -> np.ndarray:
        """Return the softmax class probabilities ``(N, C)`` (float64 copy of the graph's float32 scores)."""
        inputs = self._check_input(X)
        from .._parallel import serial_torch_ops_in_this_thread

        graph = self.to_module()
        with torch.no_grad(), serial_torch_ops_in_this_thread():
            scores = torch.cat([graph(chunk)[1] for chunk in inputs.split(256)])
        return scores.double().numpy()

    def predict(self, X: object) -> np.ndarray:
        """Return the class of each sample, ``(N,)``: the largest probability's."""
        proba = self.predict_proba(X)
        return self.classes_[proba.argmax(1)]

    def to_module(self) -> nn.Module:
        """Return the inference graph: raw input → ``(labels, scores)`` (label = index into ``classes_``)."""
        check_is_fitted(self)
        return ClassifierGraph(self.network_).eval()

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False
        tags.input_tags.three_d_array = True
        tags.non_deterministic = False
        return tags


class WindowCNNClassifier(_NeuralClassifier):
    """A 1-D CNN on raw vibration windows ``(N, 3, W)`` in g (:class:`~.networks.WindowCNN`).

    Parameters
    ----------
    size : {"small", "large"}
        ``"small"``: three convolutions of 12, 16, 16 channels (about 4-5 k parameters);
        ``"large"``: 32, 64, 64, 96 channels (about 90-100 k).
    max_epochs, batch_size, learning_rate, weight_decay, patience, validation_fraction
        Training (Adam, cross-entropy; see the module notes for the early stopping).
    random_state : int, numpy or torch generator, or None
    progress : bool
        A progress bar over the epochs.

    Attributes
    ----------
    classes_ : ndarray
    network_ : nn.Module
    n_parameters_ : int
    n_epochs_ : int
        Epochs run (the best one's weights are kept: ``training_log_.best_epoch``).
    training_log_ : TrainingLog
    """

    _parameter_constraints: ClassVar[dict] = {
        **_NeuralClassifier._parameter_constraints,
        "size": [StrOptions(set(WINDOW_WIDTHS))],
    }
    _input_name = "windows"
    _layout = ("3", "W")

    def __init__(
        self,
        size: str = "small",
        *,
        max_epochs: int = 60,
        batch_size: int = 32,
        learning_rate: float = 3e-3,
        weight_decay: float = 1e-4,
        patience: int = 8,
        validation_fraction: float = 0.2,
        random_state: int | None = None,
        progress: bool = True,
    ) -> None:
        super().__init__(
            max_epochs=max_epochs,
            batch_size=batch_size,
            learning_rate=learning_rate,
            weight_decay=weight_decay,
            patience=patience,
            validation_fraction=validation_fraction,
            random_state=random_state,
            progress=progress,
        )
        self.size = size

    def _as_input(self, X: object) -> torch.Tensor:
        inputs = super()._as_input(X)
        if inputs.shape[1] != 3:
            raise ValueError(f"windows must have shape (N, 3, W) (three axes), got {tuple(inputs.shape)}")
        return inputs

    def _make_network(self, X: torch.Tensor, n_classes: int, generator: torch.Generator) -> nn.Module:
        network = build(WindowCNN, n_classes, WINDOW_WIDTHS[self.size], generator=generator)
        network.set_input_scale(X)
        return network


class TaxelCNNClassifier(_NeuralClassifier):
    """A temporal CNN over every taxel's time series of raw pressure maps ``(N, T, H, W)``
    (:class:`~.networks.TaxelCNN`; parameters as :class:`WindowCNNClassifier` without ``size``)."""

    _input_name = "maps"
    _layout = ("T", "H", "W")

    def _make_network(self, X: torch.Tensor, n_classes: int, generator: torch.Generator) -> nn.Module:
        network = build(TaxelCNN, n_classes, X.shape[2] * X.shape[3], generator=generator)
        network.set_input_scale(X)
        return network


class ExplorationCNNClassifier(_NeuralClassifier):
    """A small 2-D CNN on the mean and maximum darkness of RGB explorations ``(N, T, 3, H, W)``
    (uint8 0-255; :class:`~.networks.ExplorationCNN`).

    Parameters
    ----------
    pool : int or "auto"
        Average pooling of the two darkness images; ``"auto"``: ``max(1, min(H, W) // 24)`` (a 96 x 96
        display is seen at 24 x 24).
    Others as :class:`WindowCNNClassifier` without ``size``.
    """

    _parameter_constraints: ClassVar[dict] = {
        **_NeuralClassifier._parameter_constraints,
        "pool": [Interval(Integral, 1, None, closed="left"), StrOptions({"auto"})],
    }
    _input_name = "frames"
    _layout = ("T", "3", "H", "W")

    def __init__(
        self,
        pool: int | str = "auto",
        *,
        max_epochs: int = 60,
        batch_size: int = 32,
        learning_rate: float = 3e-3,
        weight_decay: float = 1e-4,
        patience: int = 8,
        validation_fraction: float = 0.2,
        random_state: int | None = None,
        progress: bool = True,
    ) -> None:
        super().__init__(
            max_epochs=max_epochs,
            batch_size=batch_size,
            learning_rate=learning_rate,
            weight_decay=weight_decay,
            patience=patience,
            validation_fraction=validation_fraction,
            random_state=random_state,
            progress=progress,
        )
        self.pool = pool

    def _as_input(self, X: object) -> torch.Tensor:
        raw = np.asarray(X.numpy() if isinstance(X, torch.Tensor) else X)
        if raw.ndim == 5 and raw.shape[2] != 3:
            raise ValueError(f"frames must have shape (N, T, 3, H, W) (RGB), got {raw.shape}")
        if raw.dtype.kind == "f" and raw.size and (np.nanmin(raw) < 0 or np.nanmax(raw) > 1):
            raise ValueError("frames must be uint8 (0-255) or float in [0, 1]")
        if raw.dtype.kind == "f":  # float frames in [0, 1]: the 256 levels the exported graph takes
            raw = np.rint(raw * 255.0)
        return super()._as_input(raw)

    def _make_network(self, X: torch.Tensor, n_classes: int, generator: torch.Generator) -> nn.Module:
        pool = max(1, min(X.shape[-2:]) // 24) if self.pool == "auto" else int(self.pool)
        return build(ExplorationCNN, n_classes, pool, generator=generator)

    def _trained_part(self, network: nn.Module, inputs: torch.Tensor) -> tuple[nn.Module, torch.Tensor]:
        # What the network sees has no parameters: computed once, not in every epoch.
        with torch.no_grad():
            seen = torch.cat([network.seen(chunk) for chunk in inputs.split(64)])
        return SeenClassifier(network), seen


__all__ = ["ExplorationCNNClassifier", "TaxelCNNClassifier", "WindowCNNClassifier"]
