"""The estimators: :class:`SVC` (binary, one-vs-one, one-vs-rest) and :class:`HierarchicalSVC`.

Both follow scikit-learn's contract (hyper-parameters stored unchanged in ``__init__`` and validated
at ``fit`` from ``_parameter_constraints``; results in trailing-underscore attributes;
``NotFittedError`` before ``fit``), accept NumPy arrays, pandas DataFrames and torch tensors, and export their inference
path with ``to_module()`` (:class:`~tactile_torch.svm.inference.SVMInference`). Every binary problem
is solved by the compiled SMO (:mod:`tactile_torch.svm.solver`); independent problems (pairs of
classes, classes, tree nodes) run on ``n_jobs`` Python threads. ``fit_path`` fits one model per C
of an increasing sequence, each warm-started from the previous, which the batched grid search
(:class:`tactile_torch.model_selection.SVMGridSearchCV`) builds on.
"""

from __future__ import annotations

from numbers import Integral
from typing import ClassVar

import numpy as np
import torch
from sklearn.utils._param_validation import Interval
from sklearn.utils.validation import check_is_fitted

from ._base import _KernelMachine
from ._svc import SVC
from .inference import SVMInference, probabilities
from .solver import ProblemSet, Solutions
from .tree import build_tree


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
    C, kernel, gamma, tol, cache_size, max_iter, class_weight, n_jobs
        As in :class:`SVC`, for every node (a sample's bound is ``C`` times its sample weight times
        its class's weight, in every node it belongs to).
    probability : bool, default False
        Fit Platt's sigmoid of every node by an internal 5-fold cross-validation, for
        :meth:`predict_proba` (the product of the branch probabilities from the root to each class)
        and ``to_module(probability=True)``.
    n_init : int, default 10
        Restarts of each 2-means split.
    random_state : int, numpy or torch Generator, or None
        Seeds the 2-means splits and the folds of ``probability=True``.

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
    probA_, probB_ : ndarray of shape (n_nodes,)
        Each node's sigmoid ``P(right | margin f) = 1 / (1 + exp(A f + B))`` (``probability=True``).
    gamma_ : float
    class_weight_ : ndarray of shape (n_classes,)
        The weight of each class (1 without ``class_weight``).
    n_features_in_ : int
    feature_names_in_ : ndarray of str
        Column names, when ``X`` was a pandas DataFrame with string column names.

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
        probability: bool = False,
        class_weight: dict | str | None = None,
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
        self.probability = probability
        self.class_weight = class_weight
        self.n_init = n_init
        self.n_jobs = n_jobs
        self.random_state = random_state

    def _problems(self, X: np.ndarray, y_index: np.ndarray, weight: np.ndarray | None) -> ProblemSet:
        n_class = self.classes_.shape[0]
        used = np.ones(y_index.shape[0], dtype=bool) if weight is None else weight > 0
        counts = np.bincount(y_index[used], minlength=n_class)
        # the class means weighted by the samples' weights (a class's own weight cancels)
        w = np.ones(y_index.shape[0]) if weight is None else weight
        totals = np.bincount(y_index, weights=w, minlength=n_class)
        sums = [np.bincount(y_index, weights=w * X[:, f], minlength=n_class) for f in range(X.shape[1])]
        means = np.stack(sums, axis=1) / totals[:, None]
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
        return ProblemSet.of(sides, weight)

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
        """Return every internal node's margin, shape (n, n_nodes) (columns: ``TreeNode.column``).

        Parameters
        ----------
        X : array, tensor or DataFrame of shape (n, n_features_in_)

        Returns
        -------
        ndarray of shape (n, n_nodes), float64
            Column ``j``: the margin of the node whose ``TreeNode.column`` is ``j``.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError
            If ``X`` is not 2-D, has another number of features than in ``fit`` or a NaN/inf value.
        """
        return self._dense_margins(self._check_predict_input(X))

    def decision_function(self, X: object) -> np.ndarray:
        """Return per-class scores, shape (n, n_classes): the smallest signed node margin on the path
        to each class (:func:`~tactile_torch.svm.inference.path_scores`), ``>= 0`` only for the class
        descent reaches. Two classes: the root's margin, shape (n,) (> 0: ``classes_[1]``).

        Parameters
        ----------
        X : array, tensor or DataFrame of shape (n, n_features_in_)

        Returns
        -------
        ndarray of shape (n, n_classes), or (n,) for two classes, float64
            As above.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError
            If ``X`` is not 2-D, has another number of features than in ``fit`` or a NaN/inf value.
        """
        margins = self.node_decision_function(X)
        if self.classes_.shape[0] == 2:
            return margins[:, 0]
        return self._path_scores(margins)

    def predict(self, X: object) -> np.ndarray:
        """Return the class reached by descending the tree, shape (n,).

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
        """Return the tree as text (one line per node; ``-``/``+``: negative/positive side).

        Returns
        -------
        str
            A head line (classes, depth, support vectors, kernel, C, gamma), then one line per node.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        """
        check_is_fitted(self, "tree_")
        head = (
            f"HierarchicalSVC: {self.classes_.shape[0]} classes, depth {self.depth_}, "
            f"{self.support_.shape[0]} distinct support vectors, kernel={self.kernel}, "
            f"C={self.C}, gamma={self.gamma_:.4g}"
        )
        return head + "\n" + self.tree_.describe()

    def _probabilities(self, X: np.ndarray) -> torch.Tensor:
        margins = torch.from_numpy(self._dense_margins(X))
        tables = {"path_sign": torch.from_numpy(self._fitted_path_sign)}
        return probabilities("tree", margins, *self._platt_tensors(torch.float64), tables)

    def to_module(self, dtype: torch.dtype = torch.float64, *, probability: bool = False) -> SVMInference:
        """Return the inference path (kernel, node margins, descent, path scores) as a module.

        With ``probability=True`` (a model fitted with ``probability=True``), its scores are
        :meth:`predict_proba`'s probabilities (the product of the branch probabilities down the tree).

        Parameters
        ----------
        dtype : torch.dtype, default torch.float64
            Dtype of the module's support vectors, coefficients and intercepts (float32 for a
            smaller export; float64 reproduces :meth:`decision_function` to rounding).
        probability : bool, default False
            Scores are the class probabilities instead of the path scores.

        Returns
        -------
        SVMInference
            ``module(x)`` with ``x`` of shape (B, n_features_in_) returns ``(labels, scores)``:
            int64 labels of shape (B,) (indices into ``classes_``) and scores of shape
            (B, n_classes); exports to ONNX (``tactile_torch.export.export_onnx``).

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError
            With ``probability=True`` for a model fitted with ``probability=False``.

        Examples
        --------
        >>> import numpy as np
        >>> X = np.random.default_rng(0).normal(size=(30, 2)) + np.repeat(np.eye(3, 2) * 4, 10, 0)
        >>> y = np.repeat([0, 1, 2], 10)
        >>> labels, scores = HierarchicalSVC(random_state=0).fit(X, y).to_module()(torch.tensor(X[:4]))
        >>> labels.shape, scores.shape
        (torch.Size([4]), torch.Size([4, 3]))
        """
        sv, coef, intercept = self._module_tensors(dtype)
        return SVMInference(
            sv,
            coef,
            intercept,
            kernel=self.kernel,
            gamma=self.gamma_,
            mode="tree",
            tables={**self._tree_tensors(), **self._probability_tables(probability, dtype)},
            depth=self.depth_,
        )


__all__ = ["SVC", "HierarchicalSVC"]
