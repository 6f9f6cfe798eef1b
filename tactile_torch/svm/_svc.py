"""The SVC estimator, :class:`SVC` (public from :mod:`tactile_torch.svm.estimators`, beside
:class:`HierarchicalSVC`, whose nodes are SVCs; split from it to keep modules short)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import torch
from sklearn.utils._param_validation import StrOptions
from sklearn.utils.validation import check_is_fitted

from . import _smo
from ._base import _KernelMachine
from .inference import SVMInference, probabilities
from .solver import ProblemSet, Solutions


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
    probability : bool, default False
        Fit Platt's sigmoids by an internal 5-fold cross-validation (about 5 more fits), for
        :meth:`predict_proba` and ``to_module(probability=True)``; as scikit-learn's.
    class_weight : dict, "balanced" or None, default None
        As scikit-learn's: the C of class ``c`` is ``class_weight[c] * C`` (classes not in the dict
        keep weight 1); ``"balanced"`` gives ``n_samples / (n_classes * np.bincount(y))``. Combined
        with ``fit``'s ``sample_weight`` by product.
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
        Seeds the folds of the internal cross-validation of ``probability=True``; the solver itself
        is deterministic.

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
    class_weight_ : ndarray of shape (n_classes,)
        The weight of each class (1 without ``class_weight``).
    probA_, probB_ : ndarray of shape (n_problems,)
        Platt's ``A`` and ``B`` of each binary problem (``probability=True`` only):
        ``P = 1 / (1 + exp(A f + B))`` of the side where its decision value ``f`` is > 0.
    n_features_in_ : int
    feature_names_in_ : ndarray of str
        Column names, when ``X`` was a pandas DataFrame with string column names.

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
        probability: bool = False,
        class_weight: dict | str | None = None,
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
        self.probability = probability
        self.class_weight = class_weight
        self.multi_class = multi_class
        self.decision_function_shape = decision_function_shape
        self.n_jobs = n_jobs
        self.random_state = random_state

    def _platt_sign(self) -> float:
        """+1 for one-vs-one, whose decision values are > 0 for a pair's first class; else -1."""
        return 1.0 if self._mode() == "ovo" else -1.0

    def _mode(self) -> str:
        if self.classes_.shape[0] == 2:
            return "binary"
        return self.multi_class

    def _problems(self, X: np.ndarray, y_index: np.ndarray, weight: np.ndarray | None) -> ProblemSet:
        members = [np.flatnonzero(y_index == k) for k in range(self.classes_.shape[0])]
        mode = self._mode()
        if mode == "binary":
            sides = [(members[0], members[1])]
        elif mode == "ovr":
            sides = [(np.flatnonzero(y_index != k), members[k]) for k in range(len(members))]
        else:
            first, second = np.triu_indices(len(members), 1)
            sides = [(members[i], members[j]) for i, j in zip(first, second, strict=True)]
        return ProblemSet.of(sides, weight)

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
        or (n, n_pairs) (one-vs-one with ``"ovo"``: > 0 votes for the pair's first class).

        Parameters
        ----------
        X : array, tensor or DataFrame of shape (n, n_features_in_)

        Returns
        -------
        ndarray of shape (n,), (n, n_classes) or (n, n_pairs), float64
            As above.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError
            If ``X`` is not 2-D, has another number of features than in ``fit`` or a NaN/inf value.
        """
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
        the first class).

        Parameters
        ----------
        X : array, tensor or DataFrame of shape (n, n_features_in_)

        Returns
        -------
        ndarray of shape (n,)
            Labels from ``classes_``.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError
            If ``X`` is not 2-D, has another number of features than in ``fit`` or a NaN/inf value.
        """
        X = self._check_predict_input(X)
        mode = self._mode()
        if mode == "ovo":
            return self.classes_[_ovo_scores(self._ovo_decisions(X), self.classes_.shape[0])[0]]
        margins = self._dense_margins(X)
        if mode == "binary":
            return self.classes_[(margins[:, 0] > 0).astype(np.int64)]
        return self.classes_[margins.argmax(axis=1)]

    def _probabilities(self, X: np.ndarray) -> torch.Tensor:
        mode = self._mode()
        decision = self._ovo_decisions(X) if mode == "ovo" else self._dense_margins(X)
        tables = {"n_support": torch.from_numpy(self.n_support_.astype(np.int64))} if mode == "ovo" else {}
        return probabilities(mode, torch.from_numpy(decision), *self._platt_tensors(torch.float64), tables)

    def to_module(self, dtype: torch.dtype = torch.float64, *, probability: bool = False) -> SVMInference:
        """Return the inference path as an :class:`SVMInference` module (labels index ``classes_``).

        With ``probability=True`` (a model fitted with ``probability=True``), its scores are
        :meth:`predict_proba`'s probabilities instead of the decision values.

        Parameters
        ----------
        dtype : torch.dtype, default torch.float64
            Dtype of the module's support vectors, coefficients and intercepts.
        probability : bool, default False
            Scores are the class probabilities instead of the decision values.

        Returns
        -------
        SVMInference
            ``module(x)`` with ``x`` of shape (B, n_features_in_) returns ``(labels, scores)``:
            int64 labels of shape (B,) and scores of shape (B, n_classes) (``[-f, f]`` for two
            classes); exports to ONNX (``tactile_torch.export.export_onnx``).

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError
            With ``probability=True`` for a model fitted with ``probability=False``.
        """
        check_is_fitted(self)
        mode = self._mode()
        sv, coef, intercept = self._module_tensors(dtype)
        tables = {"n_support": torch.from_numpy(self.n_support_.astype(np.int64))} if mode == "ovo" else {}
        return SVMInference(
            sv,
            coef,
            intercept,
            kernel=self.kernel,
            gamma=self.gamma_,
            mode=mode,
            tables={**tables, **self._probability_tables(probability, dtype)},
        )
