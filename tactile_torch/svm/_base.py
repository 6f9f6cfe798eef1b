"""What :class:`~tactile_torch.svm.SVC` and :class:`~tactile_torch.svm.HierarchicalSVC` share
(:class:`_KernelMachine`): validation, the solve along C (``fit_path``), decision values on threads,
Platt scaling (``probability=True``, ``predict_proba``) and the tensors of the inference graph."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from numbers import Integral, Real
from typing import ClassVar

import numpy as np
import torch
from sklearn.base import BaseEstimator, ClassifierMixin, _fit_context
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils._available_if import available_if
from sklearn.utils._param_validation import Interval, Options, StrOptions
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from ..validation import RANDOM_STATE, numpy_rng
from . import _smo
from .kernels import KERNELS, KernelData, scale_gamma
from .probability import cross_val_decisions, platt_parameters
from .solver import ProblemSet, Solutions, solve_set
from .threads import resolve_threads, run_blocks

# Prediction runs on several threads only above this many kernel values per thread (a few
# milliseconds of work: a thread's round trip, or a wait for a busy core, costs more than a few rows),
# in blocks of at least _KERNEL_VALUES_PER_BLOCK, up to 16 per thread, so that a worker slowed by a
# busy core holds little of the work when the caller has done the rest.
_KERNEL_VALUES_PER_THREAD = 400_000
_KERNEL_VALUES_PER_BLOCK = 20_000
_BLOCKS_PER_THREAD = 16


def _as_numpy(value: object) -> object:
    if isinstance(value, torch.Tensor):
        return value.detach().cpu().numpy()
    return value


def _check_finite(X: np.ndarray) -> None:
    bad = ~np.isfinite(X)
    if bad.any():
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"X must be finite, got {int(bad.sum())} NaN/inf value(s) (first at index {first})")


def _check_2d(X: object) -> None:
    if isinstance(X, np.ndarray) and X.ndim != 2:
        raise ValueError(
            f"X must have shape (n_samples, n_features), got {X.shape} (Reshape your data: "
            "X.reshape(1, -1) for one sample, X.reshape(-1, 1) for one feature)"
        )


class _KernelMachine(ClassifierMixin, BaseEstimator):
    """What the two estimators share: validation, the solve along C, decision values, export."""

    _parameter_constraints: ClassVar[dict] = {
        "C": [Interval(Real, 0, None, closed="neither")],
        "kernel": [StrOptions(set(KERNELS))],
        "gamma": [StrOptions({"scale"}), Interval(Real, 0, None, closed="neither")],
        "tol": [Interval(Real, 0, None, closed="neither")],
        "cache_size": [Interval(Real, 0, None, closed="neither")],
        "max_iter": [Options(Integral, {-1}), Interval(Integral, 1, None, closed="left")],
        "probability": ["boolean"],
        "n_jobs": [None, Options(Integral, {-1}), Interval(Integral, 1, None, closed="left")],
        "random_state": RANDOM_STATE,
    }

    # --- training -----------------------------------------------------------------------------

    def _training_data(self, X: object, y: object) -> tuple[np.ndarray, np.ndarray]:
        """Validate ``X`` and ``y``; set ``classes_``, ``n_features_in_``; return ``(X, y_index)``."""
        X, y = _as_numpy(X), _as_numpy(y)
        _check_2d(X)
        X, y = validate_data(self, X, y, dtype=np.float64, order="C", ensure_all_finite=False)
        _check_finite(X)
        if y.dtype.kind == "f" and not np.isfinite(y).all():
            raise ValueError("y must not contain NaN or inf labels")
        check_classification_targets(y)
        self.classes_, y_index, counts = np.unique(y, return_inverse=True, return_counts=True)
        if self.classes_.shape[0] < 2:
            raise ValueError(f"y must hold at least 2 classes, got one class: {self.classes_.tolist()}")
        if counts.min() < 2:
            lonely = self.classes_[counts < 2].tolist()
            raise ValueError(
                f"every class needs at least 2 samples (a class seen once cannot be both learnt and "
                f"validated), got 1 sample of class(es) {lonely}"
            )
        return X, y_index.astype(np.int64)

    @_fit_context(prefer_skip_nested_validation=True)
    def fit_path(
        self,
        X: object,
        y: object,
        Cs: Sequence[float],
        *,
        kernel_data: KernelData | None = None,
        rows: np.ndarray | None = None,
    ) -> list:
        """Fit one model per value of ``Cs`` (taken in increasing order) and return them, in that order.

        Each binary problem is solved at the smallest C first and every solution warm-starts the
        next C (``alpha`` scales with C), so a path costs little more than its largest C. The
        models equal independent fits up to the solver's tolerance. Every other hyper-parameter is
        this estimator's.

        Parameters
        ----------
        X : array or tensor of shape (n_samples, n_features)
        y : array-like of shape (n_samples,)
        Cs : sequence of float > 0
        kernel_data : KernelData, optional
            Kernel values to use (e.g. one precomputed kernel shared by every fold of a grid
            search); ``rows`` maps the samples of ``X`` to its samples. Its gamma must be this
            estimator's.
        rows : int array of shape (n_samples,), optional

        Returns
        -------
        list of fitted estimators (copies of this one with ``C`` set), by increasing C.
        """
        return self._fit_path(X, y, Cs, kernel_data=kernel_data, rows=rows)

    def _fit_path(
        self,
        X: object,
        y: object,
        Cs: Sequence[float],
        *,
        kernel_data: KernelData | None = None,
        rows: np.ndarray | None = None,
    ) -> list:
        """:meth:`fit_path` once the hyper-parameters are validated."""
        Cs = sorted(float(c) for c in Cs)
        if not Cs or Cs[0] <= 0:
            raise ValueError(f"Cs must list values of C > 0, got {Cs}")
        # New instances rather than clones: a torch Generator as random_state cannot be deep-copied.
        params = self.get_params(deep=False)
        models = [type(self)(**{**params, "C": C}) for C in Cs]
        first = models[0]
        X, y_index = first._training_data(X, y)
        first.gamma_ = scale_gamma(X) if isinstance(self.gamma, str) else float(self.gamma)
        if kernel_data is None:
            kernel_data, rows = KernelData.of(X, self.kernel, first.gamma_), None
        problems = first._problems(X, y_index)
        solutions = solve_set(
            kernel_data,
            problems if rows is None else problems.remapped(rows),
            Cs,
            threads=resolve_threads(self.n_jobs),
            cache_bytes=int(self.cache_size * 2**20),
            tol=self.tol,
            max_iter=self.max_iter,
        )
        for model, sol in zip(models, solutions, strict=True):
            model._copy_fitted(first)  # classes_, n_features_in_, gamma_, the tree
            model._store(X, y_index, problems, sol)
        if self.probability:
            held_out = cross_val_decisions(
                X,
                problems,
                Cs,
                kernel=self.kernel,
                gamma=first.gamma_,
                rng=numpy_rng(self.random_state),
                kernel_data=kernel_data,
                rows=rows,
                threads=resolve_threads(self.n_jobs),
                cache_bytes=int(self.cache_size * 2**20),
                tol=self.tol,
                max_iter=self.max_iter,
            )
            for model, decision in zip(models, held_out, strict=True):
                model.probA_, model.probB_ = platt_parameters(decision, problems, model._platt_sign())
        if not all(sol.converged.all() for sol in solutions):
            warnings.warn(
                f"the SVM solver stopped at max_iter={self.max_iter} before libsvm's stopping rule "
                f"held (gap <= tol={self.tol}); the solution is not optimal (raise max_iter)",
                ConvergenceWarning,
                stacklevel=2,
            )
        return models

    def _copy_fitted(self, other: _KernelMachine) -> None:
        """Take ``other``'s fitted attributes (trailing underscore, or private ``_fitted_*``)."""
        for name, value in vars(other).items():
            if name.endswith("_") or name.startswith("_fitted"):
                setattr(self, name, value)

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object) -> _KernelMachine:
        """Fit on ``X`` (n_samples, n_features) and labels ``y`` (n_samples,); return ``self``.

        Raises ``ValueError`` for fewer than 2 classes, a class with 1 sample, NaN/inf features,
        mismatched lengths and bad hyper-parameters (``C <= 0``, unknown kernel ...). Repeated
        samples and constant features are fine. Warns (``ConvergenceWarning``) if ``max_iter``
        stopped a binary problem early.
        """
        (model,) = self._fit_path(X, y, [self.C])
        for name in ("probA_", "probB_"):  # from an earlier fit with probability=True
            self.__dict__.pop(name, None)
        self._copy_fitted(model)
        return self

    # --- probabilities ------------------------------------------------------------------------

    def _platt_sign(self) -> float:
        """-1: the decision values are > 0 for a problem's second side (binary, one-vs-rest, tree)."""
        return -1.0

    def _check_probability(self) -> bool:
        if not self.probability:
            raise AttributeError(
                "predict_proba is available only when probability=True (Platt scaling is fitted by an "
                "internal cross-validation at fit)"
            )
        return True

    @available_if(_check_probability)
    def predict_proba(self, X: object) -> np.ndarray:
        """Return the probability of each class, shape (n, n_classes), columns in ``classes_`` order.

        Platt's sigmoids, fitted on the decision values of an internal 5-fold cross-validation at
        ``fit`` (``probA_``, ``probB_``), combined as :mod:`tactile_torch.svm.probability` describes:
        pairwise coupling for one-vs-one, normalised one-vs-rest sigmoids, the product of the branch
        probabilities down the tree of a :class:`HierarchicalSVC`. Available only with
        ``probability=True``. As in scikit-learn, the class of largest probability can differ from
        ``predict`` on a few samples near a boundary.
        """
        X = self._check_predict_input(X)
        check_is_fitted(self, "probA_")
        with torch.no_grad():
            return self._probabilities(X).numpy()

    @available_if(_check_probability)
    def predict_log_proba(self, X: object) -> np.ndarray:
        """Return the log of :meth:`predict_proba`, shape (n, n_classes)."""
        with np.errstate(divide="ignore"):
            return np.log(self.predict_proba(X))

    def _support(self, y_index: np.ndarray, problems: ProblemSet, sol: Solutions) -> np.ndarray:
        """Set ``support_`` and ``n_support_`` (the support vectors of any problem, grouped by class as
        libsvm groups them); return each training sample's column among them (-1: none)."""
        used = np.zeros(y_index.shape[0], dtype=bool)
        used[problems.rows[sol.alpha > 0]] = True
        grouped = np.argsort(y_index, kind="stable")
        self.support_ = grouped[used[grouped]]
        self.n_support_ = np.bincount(y_index[self.support_], minlength=self.classes_.shape[0]).astype(
            np.int32
        )
        column = np.full(y_index.shape[0], -1, dtype=np.int64)
        column[self.support_] = np.arange(self.support_.shape[0])
        return column

    def _store_results(self, sol: Solutions) -> None:
        self.n_iter_ = sol.n_iter.astype(np.int32)
        self.objective_ = sol.objective.copy()

    def _store_kernel_tables(self) -> None:
        """Arrays the compiled prediction reads, derived once from the fitted attributes."""
        sv = self.support_vectors_
        self._fitted_svt = np.ascontiguousarray(sv.T)
        self._fitted_sv_sq = np.einsum("ij,ij->i", sv, sv)

    # --- prediction ---------------------------------------------------------------------------

    def _check_predict_input(self, X: object) -> np.ndarray:
        check_is_fitted(self)
        X = _as_numpy(X)
        _check_2d(X)
        X = validate_data(self, X, reset=False, dtype=np.float64, order="C", ensure_all_finite=False)
        _check_finite(X)
        return X

    def _decisions(self, X: np.ndarray, kernel_fn, n_out: int) -> np.ndarray:
        """Run a compiled decision kernel over the rows of ``X`` on up to ``n_jobs`` threads."""
        out = np.empty((X.shape[0], n_out))
        n = X.shape[0]
        n_sv = max(1, self.support_.shape[0])
        threads = max(1, min(resolve_threads(self.n_jobs), n * n_sv // _KERNEL_VALUES_PER_THREAD))
        rows_per_block = max(1, _KERNEL_VALUES_PER_BLOCK // n_sv)
        step = max(rows_per_block, -(-n // (threads * _BLOCKS_PER_THREAD))) if threads > 1 else max(n, 1)
        blocks = [slice(start, start + step) for start in range(0, n, step)]

        def run(block: slice) -> None:
            kernel_fn(X[block], out[block])

        run_blocks(run, blocks, threads)
        return out

    def _dense_margins(self, X: np.ndarray) -> np.ndarray:
        """``K(X, sv) @ dual_coef_.T + intercept_`` (binary, one-vs-rest, tree nodes)."""
        kind = _smo.RBF if self.kernel == "rbf" else _smo.LINEAR
        coef = self._fitted_coef_t

        def run(rows: np.ndarray, out: np.ndarray) -> None:
            _smo.decision_dense(
                rows, self._fitted_svt, self._fitted_sv_sq, coef, self.intercept_, self.gamma_, kind, out
            )

        return self._decisions(X, run, coef.shape[1])

    def _platt_tensors(self, dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor]:
        return torch.tensor(self.probA_, dtype=dtype), torch.tensor(self.probB_, dtype=dtype)

    def _probability_tables(self, probability: bool, dtype: torch.dtype) -> dict[str, torch.Tensor]:
        if not probability:
            return {}
        if not hasattr(self, "probA_"):
            raise ValueError(
                "to_module(probability=True) needs a model fitted with probability=True, "
                f"got one fitted with probability={self.probability!r}"
            )
        prob_a, prob_b = self._platt_tensors(dtype)
        return {"prob_a": prob_a, "prob_b": prob_b}

    def _module_tensors(self, dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        check_is_fitted(self)
        return (
            torch.tensor(self.support_vectors_, dtype=dtype),
            torch.tensor(self.dual_coef_, dtype=dtype),
            torch.tensor(self.intercept_, dtype=dtype),
        )
