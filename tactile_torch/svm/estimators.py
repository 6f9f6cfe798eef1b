"""The estimators: :class:`SVC` (binary, one-vs-one, one-vs-rest) and :class:`HierarchicalSVC`.

Both follow scikit-learn's contract (hyper-parameters stored unchanged in ``__init__`` and validated
at ``fit`` from ``_parameter_constraints``; results in trailing-underscore attributes;
``NotFittedError`` before ``fit``), accept NumPy arrays and torch tensors, and export their inference
path with ``to_module()`` (:class:`~tactile_torch.svm.inference.SVMInference`). Every binary problem
is solved by the compiled SMO (:mod:`tactile_torch.svm.solver`); independent problems (pairs of
classes, classes, tree nodes) run on ``n_jobs`` Python threads. ``fit_path`` fits one model per C
of an increasing sequence, each warm-started from the previous, which the batched grid search
(:class:`tactile_torch.model_selection.SVMGridSearchCV`) builds on.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from numbers import Integral, Real
from typing import ClassVar

import numpy as np
import torch
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils._param_validation import Interval, Options, StrOptions
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from . import _smo
from .inference import SVMInference
from .kernels import KERNELS, KernelData, scale_gamma
from .solver import ProblemSet, Solutions, solve_set
from .threads import resolve_threads, run_blocks
from .tree import build_tree

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
        "n_jobs": [None, Options(Integral, {-1}), Interval(Integral, 1, None, closed="left")],
        "random_state": [
            None,
            Interval(Integral, 0, None, closed="left"),
            np.random.Generator,
            torch.Generator,
        ],
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
        self._validate_params()
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

    def fit(self, X: object, y: object) -> _KernelMachine:
        """Fit on ``X`` (n_samples, n_features) and labels ``y`` (n_samples,); return ``self``.

        Raises ``ValueError`` for fewer than 2 classes, a class with 1 sample, NaN/inf features,
        mismatched lengths and bad hyper-parameters (``C <= 0``, unknown kernel ...). Repeated
        samples and constant features are fine. Warns (``ConvergenceWarning``) if ``max_iter``
        stopped a binary problem early.
        """
        (model,) = self.fit_path(X, y, [self.C])
        self._copy_fitted(model)
        return self

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

    def _module_tensors(self, dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        check_is_fitted(self)
        return (
            torch.tensor(self.support_vectors_, dtype=dtype),
            torch.tensor(self.dual_coef_, dtype=dtype),
            torch.tensor(self.intercept_, dtype=dtype),
        )


def _ovo_scores(dec: np.ndarray, n_class: int) -> tuple[np.ndarray, np.ndarray]:
    """libsvm's one-vs-one labels and scikit-learn's one-vs-rest-shaped scores (compiled twin of
    :func:`tactile_torch.svm.inference.ovo_votes`)."""
    labels = np.empty(dec.shape[0], dtype=np.int64)
    scores = np.empty((dec.shape[0], n_class))
    _smo.ovo_votes(np.ascontiguousarray(dec), n_class, labels, scores)
    return labels, scores


class SVC(_KernelMachine):
    """Soft-margin support vector classifier (libsvm's C-SVC), compiled solver.

    Two classes: one binary SVM, ``f(x) = sum_i dual_coef_[0, i] K(sv_i, x) + intercept_[0]``,
    ``f > 0`` predicts ``classes_[1]`` (as scikit-learn). More classes: one-vs-one by default, as
    libsvm and scikit-learn's ``SVC`` (one binary SVM per pair of classes, majority vote, same
    attributes and layout as scikit-learn's), or one-vs-rest (``multi_class="ovr"``: one binary SVM
    per class against the others, the largest decision value wins). The binary problems are libsvm's
    and solved as libsvm solves them (same problem, same steps, same stopping rule, same bias);
    see :mod:`tactile_torch.svm.solver`.

    Parameters
    ----------
    C : float, default 1.0
        Penalty of the hinge loss (> 0): the upper bound of the dual variables.
    kernel : {"rbf", "linear"}, default "rbf"
        ``exp(-gamma ||x - x'||^2)`` or ``x . x'``.
    gamma : "scale" or float, default "scale"
        RBF width; ``"scale"`` is ``1 / (n_features * X.var())`` of the training data (as
        scikit-learn). Ignored by the linear kernel.
    tol : float, default 1e-3
        Stop when libsvm's maximal violating pair gap is below ``tol`` (libsvm's ``-e``).
    cache_size : float, default 512
        MiB of float32 kernel rows kept while training (shared out between the threads).
    max_iter : int, default -1
        Cap on SMO iterations per binary problem (-1: none). Hitting it warns
        (``ConvergenceWarning``).
    multi_class : {"ovo", "ovr"}, default "ovo"
        One-vs-one (libsvm's, scikit-learn's) or one-vs-rest, for more than two classes.
    decision_function_shape : {"ovr", "ovo"}, default "ovr"
        As scikit-learn's: with one-vs-one training, ``"ovr"`` turns the pairwise decision values
        into one score per class (votes plus squashed confidences), ``"ovo"`` returns them as they
        are. One-vs-rest training always gives one score per class.
    n_jobs : int or None, default None
        Python threads for training (one binary problem per thread) and prediction (blocks of
        rows). ``None``: ``torch.get_num_threads()``; -1: every core.
    random_state : int, numpy or torch Generator, or None
        Accepted for compatibility (scikit-learn's signature, earlier versions): the solver is
        deterministic and does not use it.

    Attributes
    ----------
    classes_ : ndarray of shape (n_classes,)
    support_ : ndarray of shape (n_SV,)
        Indices of the support vectors in the training data, grouped by class (libsvm's order).
    support_vectors_ : ndarray of shape (n_SV, n_features), float64
    n_support_ : ndarray of shape (n_classes,)
        Support vectors per class.
    dual_coef_ : ndarray
        Two classes: (1, n_SV), ``y_i a_i`` with ``y = +1`` for ``classes_[1]``. One-vs-one:
        (n_classes - 1, n_SV) in libsvm's layout (the coefficients of a class-``i`` support vector
        in the pair ``(i, j)`` are in row ``j - 1``, those of a class-``j`` one in row ``i``).
        One-vs-rest: (n_classes, n_SV), one row per class.
    intercept_ : ndarray of shape (n_problems,)
        One per binary problem (pairs in the order ``(0, 1), (0, 2), ..., (1, 2), ...``).
    n_iter_ : ndarray of shape (n_problems,)
        SMO iterations of each binary problem.
    objective_ : ndarray of shape (n_problems,)
        Dual objective ``1/2 a^T Q a - sum(a)`` at each solution (libsvm's ``obj``).
    gamma_ : float
        The RBF width used.
    n_features_in_ : int

    Examples
    --------
    >>> from sklearn.datasets import make_moons
    >>> X, y = make_moons(200, noise=0.2, random_state=0)
    >>> model = SVC(C=10.0).fit(X, y)
    >>> float((model.predict(X) == y).mean()) > 0.95
    True

    References
    ----------
    C.-C. Chang, C.-J. Lin, "LIBSVM: a library for support vector machines", ACM TIST 2(3), 2011.
    """

    _parameter_constraints: ClassVar[dict] = {
        **_KernelMachine._parameter_constraints,
        "multi_class": [StrOptions({"ovo", "ovr"})],
        "decision_function_shape": [StrOptions({"ovo", "ovr"})],
    }

    def __init__(
        self,
        C: float = 1.0,
        kernel: str = "rbf",
        gamma: str | float = "scale",
        tol: float = 1e-3,
        cache_size: float = 512.0,
        max_iter: int = -1,
        multi_class: str = "ovo",
        decision_function_shape: str = "ovr",
        n_jobs: int | None = None,
        random_state=None,
    ) -> None:
        self.C = C
        self.kernel = kernel
        self.gamma = gamma
        self.tol = tol
        self.cache_size = cache_size
        self.max_iter = max_iter
        self.multi_class = multi_class
        self.decision_function_shape = decision_function_shape
        self.n_jobs = n_jobs
        self.random_state = random_state

    def _mode(self) -> str:
        if self.classes_.shape[0] == 2:
            return "binary"
        return self.multi_class

    def _problems(self, X: np.ndarray, y_index: np.ndarray) -> ProblemSet:
        members = [np.flatnonzero(y_index == k) for k in range(self.classes_.shape[0])]
        mode = self._mode()
        if mode == "binary":
            return ProblemSet.of([(members[0], members[1])])
        if mode == "ovr":
            return ProblemSet.of([(np.flatnonzero(y_index != k), members[k]) for k in range(len(members))])
        first, second = np.triu_indices(len(members), 1)
        return ProblemSet.of([(members[i], members[j]) for i, j in zip(first, second, strict=True)])

    def _store(self, X: np.ndarray, y_index: np.ndarray, problems: ProblemSet, sol: Solutions) -> None:
        column = self._support(y_index, problems, sol)
        self.support_vectors_ = X[self.support_]
        nz = sol.alpha > 0
        sample, problem = problems.rows[nz], problems.problem_of[nz]
        coef = (sol.alpha * problems.y)[nz]  # libsvm's y_i a_i, positive for the first class
        n_class = self.classes_.shape[0]
        if self._mode() == "ovo":
            first, second = np.triu_indices(n_class, 1)
            # libsvm's layout: a class-i coefficient of the pair (i, j) in row j - 1, a class-j one in row i
            row = np.where(y_index[sample] == first[problem], second[problem] - 1, first[problem])
            self.dual_coef_ = np.zeros((n_class - 1, self.support_.shape[0]))
            self.dual_coef_[row, column[sample]] = coef
            self.intercept_ = -sol.rho
        else:
            # Toward each problem's second class: classes_[1], or the class against the rest.
            self.dual_coef_ = np.zeros((len(problems), self.support_.shape[0]))
            self.dual_coef_[problem, column[sample]] = -coef
            self.intercept_ = sol.rho.copy()
        self._store_results(sol)
        self._store_kernel_tables()
        self._fitted_coef_t = np.ascontiguousarray(self.dual_coef_.T)

    def _ovo_decisions(self, X: np.ndarray) -> np.ndarray:
        kind = _smo.RBF if self.kernel == "rbf" else _smo.LINEAR
        starts = np.concatenate([[0], np.cumsum(self.n_support_)]).astype(np.int64)

        def run(rows: np.ndarray, out: np.ndarray) -> None:
            _smo.decision_ovo(
                rows,
                self._fitted_svt,
                self._fitted_sv_sq,
                self._fitted_coef_t,
                starts,
                self.intercept_,
                self.gamma_,
                kind,
                out,
            )

        return self._decisions(X, run, self.intercept_.shape[0])

    def decision_function(self, X: object) -> np.ndarray:
        """Return the decision values: shape (n,) for two classes (> 0: ``classes_[1]``); with more
        classes (n, n_classes) (one-vs-rest, or one-vs-one with ``decision_function_shape="ovr"``)
        or (n, n_pairs) (one-vs-one with ``"ovo"``: > 0 votes for the pair's first class)."""
        X = self._check_predict_input(X)
        mode = self._mode()
        if mode != "ovo":
            margins = self._dense_margins(X)
            return margins[:, 0] if mode == "binary" else margins
        dec = self._ovo_decisions(X)
        if self.decision_function_shape == "ovo":
            return dec
        return _ovo_scores(dec, self.classes_.shape[0])[1]

    def predict(self, X: object) -> np.ndarray:
        """Return the predicted class of each sample, shape (n,) (one-vs-one: libsvm's vote, ties to
        the first class)."""
        X = self._check_predict_input(X)
        mode = self._mode()
        if mode == "ovo":
            return self.classes_[_ovo_scores(self._ovo_decisions(X), self.classes_.shape[0])[0]]
        margins = self._dense_margins(X)
        if mode == "binary":
            return self.classes_[(margins[:, 0] > 0).astype(np.int64)]
        return self.classes_[margins.argmax(axis=1)]

    def to_module(self, dtype: torch.dtype = torch.float64) -> SVMInference:
        """Return the inference path as an :class:`SVMInference` module (labels index ``classes_``)."""
        check_is_fitted(self)
        mode = self._mode()
        sv, coef, intercept = self._module_tensors(dtype)
        tables = {"n_support": torch.from_numpy(self.n_support_.astype(np.int64))} if mode == "ovo" else None
        return SVMInference(
            sv, coef, intercept, kernel=self.kernel, gamma=self.gamma_, mode=mode, tables=tables
        )


class HierarchicalSVC(_KernelMachine):
    """Hierarchical multi-class SVM (HM-SVM, method 1): a binary tree of binary SVMs.

    The class mean vectors are split in two groups by 2-means (:func:`~tactile_torch.svm.tree.split_classes`);
    a binary SVM separates the samples of the two groups (second group positive); each group is
    split again until every leaf holds one class. A sample is classified by descending the tree
    (margin > 0: positive side). Every node uses the same C, kernel and gamma (``"scale"`` is
    computed once on all training data), so prediction computes the kernel against the union of all
    nodes' support vectors once and every node margin from it. The node problems are independent
    once the tree is built: they run on ``n_jobs`` threads, the largest first.

    Parameters
    ----------
    C, kernel, gamma, tol, cache_size, max_iter, n_jobs
        As in :class:`SVC`, for every node.
    n_init : int, default 10
        Restarts of each 2-means split.
    random_state : int, numpy or torch Generator, or None
        Seeds the 2-means splits.

    Attributes
    ----------
    classes_ : ndarray of shape (n_classes,)
    tree_ : TreeNode
        The root; ``print(model.tree_)`` (or ``model.describe()``) shows the tree. Each internal
        node's ``svc`` is a fitted binary :class:`SVC` (``support_`` indexes the whole training set).
    support_ : ndarray of shape (n_SV,)
        Indices of the support vectors of any node, grouped by class.
    support_vectors_ : ndarray of shape (n_SV, n_features)
    n_support_ : ndarray of shape (n_classes,)
    dual_coef_ : ndarray of shape (n_nodes, n_SV)
        ``y_i a_i`` of each support vector in each internal node (0 where it is not one of its
        support vectors); rows in preorder of the internal nodes.
    intercept_ : ndarray of shape (n_nodes,)
    n_iter_, objective_ : ndarray of shape (n_nodes,)
        SMO iterations and dual objective of each internal node.
    depth_ : int
        Edges on the longest root-to-leaf path.
    gamma_ : float
    n_features_in_ : int

    Examples
    --------
    >>> from sklearn.datasets import make_blobs
    >>> X, y = make_blobs(300, centers=5, random_state=0)
    >>> model = HierarchicalSVC(C=10.0, random_state=0).fit(X, y)
    >>> float((model.predict(X) == y).mean()) > 0.9
    True

    References
    ----------
    The hierarchical SVM of method 1; libsvm for the node problems.
    """

    _parameter_constraints: ClassVar[dict] = {
        **_KernelMachine._parameter_constraints,
        "n_init": [Interval(Integral, 1, None, closed="left")],
    }

    def __init__(
        self,
        C: float = 1.0,
        kernel: str = "rbf",
        gamma: str | float = "scale",
        tol: float = 1e-3,
        cache_size: float = 512.0,
        max_iter: int = -1,
        n_init: int = 10,
        n_jobs: int | None = None,
        random_state=None,
    ) -> None:
        self.C = C
        self.kernel = kernel
        self.gamma = gamma
        self.tol = tol
        self.cache_size = cache_size
        self.max_iter = max_iter
        self.n_init = n_init
        self.n_jobs = n_jobs
        self.random_state = random_state

    def _problems(self, X: np.ndarray, y_index: np.ndarray) -> ProblemSet:
        n_class = self.classes_.shape[0]
        counts = np.bincount(y_index, minlength=n_class)
        sums = [np.bincount(y_index, weights=X[:, f], minlength=n_class) for f in range(X.shape[1])]
        means = np.stack(sums, axis=1) / counts[:, None]
        self._fitted_tree = build_tree(
            self.classes_, means, counts, n_init=self.n_init, random_state=self.random_state
        )
        sides = []
        for node in self._fitted_tree.nodes():
            if not node.is_leaf:
                side = np.zeros(n_class, dtype=np.int8)  # 1: left group, 2: right group
                side[node.left.members], side[node.right.members] = 1, 2
                of_sample = side[y_index]
                sides.append((np.flatnonzero(of_sample == 1), np.flatnonzero(of_sample == 2)))
        return ProblemSet.of(sides)

    def _store(self, X: np.ndarray, y_index: np.ndarray, problems: ProblemSet, sol: Solutions) -> None:
        self.tree_ = self._fitted_tree.copy()
        column = self._support(y_index, problems, sol)
        self.support_vectors_ = X[self.support_]
        nz = sol.alpha > 0
        sample, problem = problems.rows[nz], problems.problem_of[nz]
        # Toward the right (second) group of each node.
        self.dual_coef_ = np.zeros((len(problems), self.support_.shape[0]))
        self.dual_coef_[problem, column[sample]] = -(sol.alpha * problems.y)[nz]
        self.intercept_ = sol.rho.copy()
        self._store_results(sol)
        internal = [node for node in self.tree_.nodes() if not node.is_leaf]
        for k, node in enumerate(internal):
            node.column = k
            part = slice(problems.offsets[k], problems.offsets[k + 1])
            node.svc = self._node_svc(X, problems.rows[part], problems.y[part], sol.alpha[part], sol, k)
        self._index_tree()
        self._store_kernel_tables()
        self._fitted_coef_t = np.ascontiguousarray(self.dual_coef_.T)

    def _node_svc(
        self, X: np.ndarray, rows: np.ndarray, y: np.ndarray, a: np.ndarray, sol: Solutions, k: int
    ) -> SVC:
        """Node ``k``'s binary SVM as a fitted :class:`SVC` (labels False: left, True: right;
        ``support_`` indexes the whole training set)."""
        svc = SVC(
            C=self.C,
            kernel=self.kernel,
            gamma=self.gamma_,
            tol=self.tol,
            cache_size=self.cache_size,
            max_iter=self.max_iter,
            n_jobs=1,
        )
        svc.classes_ = np.array([False, True])
        svc.n_features_in_, svc.gamma_ = self.n_features_in_, self.gamma_
        used = a > 0  # left samples come first, as libsvm groups them
        svc.support_ = rows[used]
        svc.n_support_ = np.array([int((used & (y > 0)).sum()), int((used & (y < 0)).sum())], dtype=np.int32)
        svc.support_vectors_ = X[svc.support_]
        svc.dual_coef_ = -(a * y)[used][None, :]
        svc.intercept_ = sol.rho[k : k + 1].copy()
        svc.n_iter_ = sol.n_iter[k : k + 1].astype(np.int32)
        svc.objective_ = sol.objective[k : k + 1].copy()
        svc._store_kernel_tables()
        svc._fitted_coef_t = np.ascontiguousarray(svc.dual_coef_.T)
        return svc

    def _index_tree(self) -> None:
        """Build the descent tables (children, margin column, leaf label, path signs)."""
        nodes = self.tree_.nodes()
        internal = [node for node in nodes if not node.is_leaf]
        self.depth_ = max(node.depth for node in nodes)
        label_of = {c: i for i, c in enumerate(self.classes_.tolist())}
        count = len(nodes)
        self._fitted_left = np.arange(count)
        self._fitted_right = np.arange(count)
        self._fitted_column = np.zeros(count, dtype=np.int64)
        self._fitted_leaf_label = np.zeros(count, dtype=np.int64)
        self._fitted_path_sign = np.zeros((self.classes_.shape[0], len(internal)), dtype=np.int64)
        for node in nodes:
            if node.is_leaf:
                self._fitted_leaf_label[node.index] = label_of[node.classes[0]]
                continue
            self._fitted_left[node.index], self._fitted_right[node.index] = node.left.index, node.right.index
            self._fitted_column[node.index] = node.column
            for child, sign in ((node.left, -1), (node.right, 1)):
                self._fitted_path_sign[[label_of[c] for c in child.classes], node.column] = sign

    def _tree_tensors(self) -> dict[str, torch.Tensor]:
        return {
            "left": torch.from_numpy(self._fitted_left),
            "right": torch.from_numpy(self._fitted_right),
            "column": torch.from_numpy(self._fitted_column),
            "leaf_label": torch.from_numpy(self._fitted_leaf_label),
            "path_sign": torch.from_numpy(self._fitted_path_sign),
        }

    def _path_scores(self, margins: np.ndarray) -> np.ndarray:
        """NumPy twin of :func:`tactile_torch.svm.inference.path_scores`."""
        sign = self._fitted_path_sign
        signed = margins[:, None, :] * sign[None, :, :]
        return np.where(sign[None, :, :] != 0, signed, np.inf).min(axis=2)

    def node_decision_function(self, X: object) -> np.ndarray:
        """Return every internal node's margin, shape (n, n_nodes) (columns: ``TreeNode.column``)."""
        return self._dense_margins(self._check_predict_input(X))

    def decision_function(self, X: object) -> np.ndarray:
        """Return per-class scores, shape (n, n_classes): the smallest signed node margin on the path
        to each class (:func:`~tactile_torch.svm.inference.path_scores`), ``>= 0`` only for the class
        descent reaches. Two classes: the root's margin, shape (n,) (> 0: ``classes_[1]``)."""
        margins = self.node_decision_function(X)
        if self.classes_.shape[0] == 2:
            return margins[:, 0]
        return self._path_scores(margins)

    def predict(self, X: object) -> np.ndarray:
        """Return the class reached by descending the tree, shape (n,)."""
        margins = self.node_decision_function(X)
        # The class descent reaches is the argmax of the path scores; only a margin of exactly 0
        # can make them differ, so such rows descend.
        labels = self._path_scores(margins).argmax(axis=1)
        tie = (margins == 0).any(axis=1)
        if tie.any():
            from .inference import tree_descent

            t = self._tree_tensors()
            labels[tie] = tree_descent(
                torch.from_numpy(margins[tie]),
                t["left"],
                t["right"],
                t["column"],
                t["leaf_label"],
                self.depth_,
            ).numpy()
        return self.classes_[labels]

    def describe(self) -> str:
        """Return the tree as text (one line per node; ``-``/``+``: negative/positive side)."""
        check_is_fitted(self, "tree_")
        head = (
            f"HierarchicalSVC: {self.classes_.shape[0]} classes, depth {self.depth_}, "
            f"{self.support_.shape[0]} distinct support vectors, kernel={self.kernel}, "
            f"C={self.C}, gamma={self.gamma_:.4g}"
        )
        return head + "\n" + self.tree_.describe()

    def to_module(self, dtype: torch.dtype = torch.float64) -> SVMInference:
        """Return the inference path (kernel, node margins, descent, path scores) as a module."""
        sv, coef, intercept = self._module_tensors(dtype)
        return SVMInference(
            sv,
            coef,
            intercept,
            kernel=self.kernel,
            gamma=self.gamma_,
            mode="tree",
            tables=self._tree_tensors(),
            depth=self.depth_,
        )


__all__ = ["SVC", "HierarchicalSVC"]
