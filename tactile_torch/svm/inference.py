"""The inference graph of the fitted SVMs: plain functions on tensors, and the ``nn.Module``
(:class:`SVMInference`) that the estimators' ``to_module()`` returns and that exports to ONNX.

Every step is a fixed sequence of tensor operations (no data-dependent loop), so the graph exports
with the dynamo exporter (``tactile_torch.export.export_onnx``) and runs under onnxruntime. The
estimators' own ``predict`` and ``decision_function`` compute the same values with compiled
kernels (:mod:`tactile_torch.svm._smo`); tests hold the two paths equal.
"""

from __future__ import annotations

from typing import ClassVar

import torch

from .kernels import kernel_matrix
from .probability import couple_pairwise, sigmoid_probability, tree_probabilities

MODES = ("binary", "ovr", "ovo", "tree")
"""What :class:`SVMInference` computes from the decision values: see its docstring."""


def svm_margins(
    x: torch.Tensor,
    support_vectors: torch.Tensor,
    dual_coef: torch.Tensor,
    intercept: torch.Tensor,
    *,
    kernel: str = "rbf",
    gamma: float = 1.0,
) -> torch.Tensor:
    """Return the decision values ``f_k(x) = sum_j dual_coef[k, j] K(sv_j, x) + intercept[k]``.

    One kernel block against the support vectors and one matrix product give every output at once
    (every binary problem of a one-vs-rest SVC, every node of a :class:`HierarchicalSVC`).

    Parameters
    ----------
    x : tensor of shape (B, F)
    support_vectors : tensor of shape (S, F)
    dual_coef : tensor of shape (K, S)
        ``y_j a_j`` of each support vector in each of the K decision functions (0 where it is not
        a support vector of that function).
    intercept : tensor of shape (K,)
    kernel, gamma
        As in :func:`kernel_matrix`.

    Returns
    -------
    tensor of shape (B, K), dtype of ``support_vectors``.

    Examples
    --------
    >>> sv = torch.tensor([[0.0], [2.0]])
    >>> svm_margins(torch.tensor([[0.0], [2.0]]), sv, torch.tensor([[-1.0, 1.0]]), torch.tensor([0.0]), kernel="linear")
    tensor([[0.],
            [4.]])
    """
    x = x.to(support_vectors.dtype)
    return kernel_matrix(x, support_vectors, kernel=kernel, gamma=gamma) @ dual_coef.T + intercept


def tree_descent(
    margins: torch.Tensor,
    left: torch.Tensor,
    right: torch.Tensor,
    column: torch.Tensor,
    leaf_label: torch.Tensor,
    depth: int,
) -> torch.Tensor:
    """Return the label of the leaf each sample reaches by descending a binary decision tree.

    From the root (node 0), a sample goes to ``right[node]`` where the node's margin is > 0 and to
    ``left[node]`` otherwise; leaves point to themselves, so ``depth`` gather/where steps (the
    tree's depth) bring every sample to its leaf with no data-dependent loop (what ONNX needs).

    Parameters
    ----------
    margins : tensor of shape (B, M)
        Margin of every internal node (column ``column[node]``).
    left, right, column, leaf_label : int64 tensors of shape (N,)
        Per node: children (leaves: itself), margin column (leaves: any valid column), and the label
        of a leaf (internal nodes: any).
    depth : int
        Number of edges on the longest root-to-leaf path.

    Returns
    -------
    int64 tensor of shape (B,)
    """
    node = torch.zeros(margins.shape[0], dtype=torch.long, device=margins.device)
    for _ in range(depth):
        value = margins.gather(1, column[node][:, None])[:, 0]
        node = torch.where(value > 0, right[node], left[node])
    return leaf_label[node]


def path_scores(margins: torch.Tensor, path_sign: torch.Tensor) -> torch.Tensor:
    """Return each class's score: the smallest signed node margin on the path from the root to it.

    ``path_sign[c, m]`` is +1 if class ``c`` lies on the positive side of internal node ``m``, -1 on
    its negative side, 0 if the node is not on its path. The score of the class that descent
    reaches is the smallest margin it crossed (> 0 unless a margin is exactly 0); every other class
    has a negative score (the margin of the node where its path leaves the descent, or lower). So
    ``argmax`` of the scores is the descended class, and the scores rank the others.

    Parameters
    ----------
    margins : tensor of shape (B, M)
    path_sign : tensor of shape (C, M)

    Returns
    -------
    tensor of shape (B, C)
    """
    signed = margins[:, None, :] * path_sign[None, :, :].to(margins.dtype)
    inf = torch.tensor(float("inf"), dtype=margins.dtype, device=margins.device)
    return torch.where(path_sign[None, :, :] != 0, signed, inf).amin(dim=2)


def ovo_decisions(
    kernel_values: torch.Tensor,
    class_index: torch.Tensor,
    class_coef: torch.Tensor,
    pair_index: torch.Tensor,
    intercept: torch.Tensor,
) -> torch.Tensor:
    """Return libsvm's one-vs-one decision values, one per pair of classes ``(i, j)``, ``i < j``.

    The support vectors are grouped by class. Class ``c``'s kernel values (``class_index[c]``,
    padded with any column) times its coefficients in each of its ``K - 1`` pairs
    (``class_coef[c]``, zero on the padding) give ``T[:, c, q]`` by one batched product; the decision
    of pair ``p = (i, j)`` is ``T[:, i, j - 1] + T[:, j, i] + intercept[p]`` (libsvm's layout of
    ``dual_coef_``). No reshape depends on K, so a graph exported with free sizes serves any K.

    Parameters
    ----------
    kernel_values : tensor of shape (B, S)
        Kernel between the samples and the support vectors.
    class_index : int64 tensor of shape (K, M)
        Columns of each class's support vectors, padded to the largest count ``M``.
    class_coef : tensor of shape (K, M, K - 1)
    pair_index : int64 tensor of shape (4, P)
        Per pair ``(i, j)``: ``i``, ``j - 1``, ``j``, ``i`` (where its two terms are in ``T``).
    intercept : tensor of shape (P,)

    Returns
    -------
    tensor of shape (B, P): > 0 votes for the pair's first class.
    """
    blocks = kernel_values[:, class_index].transpose(0, 1)  # (K, B, M)
    terms = torch.matmul(blocks, class_coef).transpose(0, 1)  # (B, K, K - 1)
    return terms[:, pair_index[0], pair_index[1]] + terms[:, pair_index[2], pair_index[3]] + intercept


def ovo_votes(decisions: torch.Tensor, pair_classes: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Return libsvm's labels and scikit-learn's one-vs-rest-shaped scores from pairwise decisions.

    Labels: each pair ``(i, j)`` votes for ``i`` if its decision is > 0, else for ``j``; the class
    with most votes wins, the first one on ties (libsvm's ``predict``). Scores: scikit-learn's
    ``decision_function_shape="ovr"``: votes (decision >= 0 for ``i``) plus the summed decisions
    ``s`` of each class squashed to ``s / (3 (|s| + 1))``, within (-1/3, 1/3).

    Parameters
    ----------
    decisions : tensor of shape (B, P)
    pair_classes : tensor of shape (2, P, K), the decisions' dtype
        One-hot rows of each pair's first and second class.

    Returns
    -------
    labels : int64 tensor of shape (B,)
    scores : tensor of shape (B, K)
    """
    first, second = pair_classes[0], pair_classes[1]
    wins = (decisions > 0).to(decisions.dtype)
    labels = (wins @ first + (1 - wins) @ second).argmax(dim=1)
    ties_first = (decisions >= 0).to(decisions.dtype)
    confidence = decisions @ (first - second)
    scores = ties_first @ first + (1 - ties_first) @ second + confidence / (3 * (confidence.abs() + 1))
    return labels, scores


def ovo_tables(n_support: torch.Tensor, dtype: torch.dtype) -> dict[str, torch.Tensor]:
    """Return the tables of :func:`ovo_decisions` and :func:`ovo_votes` for support vectors grouped
    by class (``n_support`` of shape (K,)): ``class_index`` (K, M) with ``class_mask`` (K, M) (1 on
    a class's own columns, 0 on the padding), ``pair_index`` and ``pair_classes``."""
    counts = n_support.long()
    n_class = counts.shape[0]
    starts = torch.cumsum(counts, 0) - counts
    width = max(1, int(counts.max()))
    offsets = torch.arange(width)[None, :]
    class_mask = offsets < counts[:, None]
    class_index = torch.where(class_mask, starts[:, None] + offsets, 0)
    first, second = torch.triu_indices(n_class, n_class, 1)
    pair_index = torch.stack([first, second - 1, second, first])
    eye = torch.eye(n_class, dtype=dtype)
    return {
        "class_index": class_index,
        "class_mask": class_mask.to(dtype),
        "pair_index": pair_index,
        "pair_classes": torch.stack([eye[first], eye[second]]),
    }


def probabilities(
    mode: str,
    decision: torch.Tensor,
    prob_a: torch.Tensor,
    prob_b: torch.Tensor,
    tables: dict[str, torch.Tensor],
) -> torch.Tensor:
    """Return class probabilities from decision values and Platt's sigmoids (see
    :mod:`tactile_torch.svm.probability`).

    Parameters
    ----------
    mode : {"binary", "ovr", "ovo", "tree"}
    decision : tensor of shape (B, M)
        The margins (binary: (B, 1); one-vs-rest: one per class; tree: one per node) or the
        pairwise decision values (one-vs-one).
    prob_a, prob_b : tensors of shape (M,)
    tables : dict
        ``pair_classes`` or ``n_support`` (one-vs-one), ``path_sign`` (tree).

    Returns
    -------
    tensor of shape (B, n_classes)
    """
    if mode == "tree":
        return tree_probabilities(decision, prob_a, prob_b, tables["path_sign"])
    p = sigmoid_probability(decision, prob_a, prob_b)
    if mode == "binary":
        return torch.cat([1 - p, p], dim=1)
    if mode == "ovr":
        return p / p.sum(dim=1, keepdim=True)
    pair_classes = tables.get("pair_classes")
    if pair_classes is None:
        pair_classes = ovo_tables(tables["n_support"], decision.dtype)["pair_classes"]
    return couple_pairwise(p, pair_classes)


class SVMInference(torch.nn.Module):
    """Labels and per-class scores of a fitted :class:`~tactile_torch.svm.SVC` or
    :class:`~tactile_torch.svm.HierarchicalSVC`, as a module.

    ``forward(x)`` with ``x`` of shape (B, F) returns ``(labels, scores)``: int64 labels of shape (B,)
    (indices into the estimator's ``classes_``) and scores of shape (B, n_classes), in the module's
    dtype (float64 by default; the input is cast to it). By ``mode``:

    - ``"binary"``: scores ``[-f, f]``;
    - ``"ovr"`` (one-vs-rest): the per-class decision values, labels by arg-max;
    - ``"ovo"`` (one-vs-one, libsvm's and scikit-learn's default): :func:`ovo_decisions`, then
      libsvm's votes and scikit-learn's scores (:func:`ovo_votes`); ``dual_coef`` in libsvm's layout
      (K - 1, S), ``intercept`` one per pair, and the support vectors per class ``n_support``;
    - ``"tree"`` (HM-SVM): :func:`path_scores`, labels by :func:`tree_descent`.

    With the tables ``prob_a`` and ``prob_b`` (Platt's sigmoids of a model fitted with
    ``probability=True``: ``to_module(probability=True)``), the scores are the class probabilities
    (:func:`probabilities`) and the labels stay the ones above.

    The support vectors of every decision function are stored once. Exports to ONNX with
    ``tactile_torch.export.export_onnx`` (gather/where steps, no loops in the graph). Build it with the
    estimators' ``to_module()``, or from saved buffers with :meth:`from_state`.

    Parameters
    ----------
    support_vectors : tensor of shape (S, F)
    dual_coef : tensor of shape (n_outputs, S)
        For ``ovo``, libsvm's layout (K - 1, S).
    intercept : tensor of shape (n_outputs,) (``ovo``: one per pair)
    kernel : {"rbf", "linear"}
    gamma : float
    mode : {"binary", "ovr", "ovo", "tree"}
    tables : dict of str to tensor, optional
        The mode's further buffers: ``left``, ``right``, ``column``, ``leaf_label``, ``path_sign``
        (tree); ``n_support`` (ovo: the other tables are derived from it, not saved); optionally
        ``prob_a`` and ``prob_b`` (one per decision function), for probabilities as scores.
    depth : int
        Depth of the tree (``tree`` mode).
    tree : dict, optional
        Former name of ``tables``, still accepted.
    """

    TABLES: ClassVar[dict[str, tuple[str, ...]]] = {
        "binary": (),
        "ovr": (),
        "ovo": ("n_support",),
        "tree": ("left", "right", "column", "leaf_label", "path_sign"),
    }
    PROBABILITY_TABLES: ClassVar[tuple[str, ...]] = ("prob_a", "prob_b")

    def __init__(
        self,
        support_vectors: torch.Tensor,
        dual_coef: torch.Tensor,
        intercept: torch.Tensor,
        *,
        kernel: str,
        gamma: float,
        mode: str,
        tables: dict[str, torch.Tensor] | None = None,
        depth: int = 0,
        tree: dict[str, torch.Tensor] | None = None,
    ) -> None:
        super().__init__()
        if mode not in self.TABLES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        tables = {**(tree or {}), **(tables or {})}
        missing = sorted(set(self.TABLES[mode]) - set(tables))
        if missing:
            raise ValueError(f"mode {mode!r} needs the tables {list(self.TABLES[mode])}, missing {missing}")
        self.kernel, self.gamma, self.mode, self.depth = kernel, float(gamma), mode, int(depth)
        self.register_buffer("support_vectors", support_vectors)
        self.register_buffer("dual_coef", dual_coef)
        self.register_buffer("intercept", intercept)
        self.probability = all(name in tables for name in self.PROBABILITY_TABLES)
        for name in self.TABLES[mode] + (self.PROBABILITY_TABLES if self.probability else ()):
            self.register_buffer(name, tables[name])
        if mode == "ovo":
            for name, value in ovo_tables(tables["n_support"], dual_coef.dtype).items():
                self.register_buffer(name, value, persistent=False)

    @classmethod
    def from_state(
        cls, state: dict[str, torch.Tensor], *, mode: str, kernel: str, gamma: float, depth: int = 0
    ) -> SVMInference:
        """Rebuild a module from its ``state_dict()`` and its ``mode``, ``kernel``, ``gamma``, ``depth``."""
        names = cls.TABLES.get(mode, ()) + cls.PROBABILITY_TABLES
        tables = {name: state[name] for name in names if name in state}
        return cls(
            state["support_vectors"],
            state["dual_coef"],
            state["intercept"],
            kernel=kernel,
            gamma=gamma,
            mode=mode,
            tables=tables,
            depth=depth,
        )

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = x.to(self.support_vectors.dtype)
        if self.mode == "ovo":
            values = kernel_matrix(x, self.support_vectors, kernel=self.kernel, gamma=self.gamma)
            # Each class's coefficients in its K - 1 pairs, padded like class_index: (K, M, K - 1).
            class_coef = self.dual_coef[:, self.class_index].permute(1, 2, 0) * self.class_mask[:, :, None]
            decisions = ovo_decisions(values, self.class_index, class_coef, self.pair_index, self.intercept)
            labels, scores = ovo_votes(decisions, self.pair_classes)
            if self.probability:
                scores = probabilities(
                    "ovo", decisions, self.prob_a, self.prob_b, {"pair_classes": self.pair_classes}
                )
            return labels, scores
        margins = svm_margins(
            x, self.support_vectors, self.dual_coef, self.intercept, kernel=self.kernel, gamma=self.gamma
        )
        if self.mode == "binary":
            labels, scores = (margins[:, 0] > 0).long(), torch.cat([-margins, margins], dim=1)
        elif self.mode == "ovr":
            labels, scores = margins.argmax(dim=1), margins
        else:
            labels = tree_descent(margins, self.left, self.right, self.column, self.leaf_label, self.depth)
            scores = path_scores(margins, self.path_sign)
        if self.probability:
            tables = {"path_sign": self.path_sign} if self.mode == "tree" else {}
            scores = probabilities(self.mode, margins, self.prob_a, self.prob_b, tables)
        return labels, scores


__all__ = [
    "MODES",
    "SVMInference",
    "ovo_decisions",
    "ovo_tables",
    "ovo_votes",
    "path_scores",
    "probabilities",
    "svm_margins",
    "tree_descent",
]
