"""Class probabilities of the SVMs: Platt scaling fitted by internal cross-validation, as libsvm's
``-b 1`` and scikit-learn's ``SVC(probability=True)``, and how the binary probabilities combine.

Fitting (:func:`platt_parameters`): every binary problem of a fitted estimator (the pair of classes,
the class against the rest, the tree node) is cross-validated once more on its own samples
(:func:`cross_val_decisions`: stratified folds, 5 by default, drawn from the estimator's
``random_state``); the held-out decision values ``f`` and the sides of their samples give a sigmoid
``P(positive side | f) = 1 / (1 + exp(A f + B))`` (:func:`fit_sigmoid`, Platt 2000 with the Newton
method and the smoothed targets of Lin, Lin and Weng 2007). The positive side is where the
estimator's decision value is > 0: ``classes_[1]`` (binary), the class (one-vs-rest), the pair's
first class (one-vs-one), the right child (tree node).

Combining (:func:`svm_probabilities`, torch, exported to ONNX):

- binary: ``[1 - P, P]``;
- one-vs-rest: each class's ``P``, normalised to sum 1;
- one-vs-one: the pairwise probabilities ``r_ij`` coupled into one distribution by the second method
  of Wu, Lin and Weng (2004), the one libsvm uses: ``p`` minimises ``sum_{i<j} (r_ji p_i - r_ij p_j)^2``
  subject to ``sum p = 1``. Here it is solved exactly (``(Q + 1 1^T) x = 1``, ``p = x / sum(x)``,
  :func:`couple_pairwise`) where libsvm iterates to a tolerance of ``0.005 / K``, so the two agree to
  about that;
- hierarchical: the product of the branch probabilities along the path from the root to the class's
  leaf, ``p_c = prod_m P_m^[c right of m] (1 - P_m)^[c left of m]``. The leaves partition the
  classes, so the probabilities sum to 1 without normalising.

As in scikit-learn, the probabilities come from the cross-validated sigmoids while ``predict`` keeps
the decision values: on a few samples near a boundary the class of largest probability can differ
from the predicted class.

References
----------
J. Platt, "Probabilistic outputs for support vector machines and comparisons to regularized
likelihood methods", Advances in Large Margin Classifiers, 2000.
H.-T. Lin, C.-J. Lin, R. C. Weng, "A note on Platt's probabilistic outputs for support vector
machines", Machine Learning 68, 2007.
T.-F. Wu, C.-J. Lin, R. C. Weng, "Probability estimates for multi-class classification by pairwise
coupling", JMLR 5, 2004.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import torch

from ..validation import tensor_from_array
from .kernels import KernelData, kernel_matrix

if TYPE_CHECKING:  # the solver (numba) is imported where it runs: the inference graph does without
    from .solver import ProblemSet

N_FOLDS = 5
"""Folds of the internal cross-validation (libsvm's and scikit-learn's)."""

MIN_PROBABILITY = 1e-7
"""Pairwise probabilities are clipped to ``[MIN_PROBABILITY, 1 - MIN_PROBABILITY]`` before coupling
(libsvm's ``min_prob``), so that the coupling system stays positive definite."""


def fit_sigmoid(decision: np.ndarray, positive: np.ndarray) -> tuple[float, float]:
    """Return Platt's ``(A, B)`` of ``P(positive | f) = 1 / (1 + exp(A f + B))``.

    Minimises the cross-entropy between the sigmoid and the smoothed targets
    ``(N+ + 1) / (N+ + 2)`` (positive samples) and ``1 / (N- + 2)`` (negative samples) by Newton's
    method with a backtracking line search, as Lin, Lin and Weng (2007) give it (at most 100
    iterations; stops when both gradient components are below 1e-5). ``A`` is negative when larger
    decision values mean the positive side.

    Parameters
    ----------
    decision : array of shape (n,)
        Held-out decision values.
    positive : bool array of shape (n,)
        Whether each sample is on the positive side.

    Returns
    -------
    (A, B) : tuple of float

    Examples
    --------
    >>> A, B = fit_sigmoid(np.array([-2.0, -1.0, 1.0, 2.0]), np.array([False, False, True, True]))
    >>> A < 0 and abs(B) < 1e-9
    True
    """
    f = np.asarray(decision, dtype=np.float64)
    positive = np.asarray(positive, dtype=bool)
    n_pos, n_neg = int(positive.sum()), int((~positive).sum())
    target = np.where(positive, (n_pos + 1.0) / (n_pos + 2.0), 1.0 / (n_neg + 2.0))
    a, b = 0.0, float(np.log((n_neg + 1.0) / (n_pos + 1.0)))

    def objective(a: float, b: float) -> float:
        z = f * a + b
        # -log-likelihood t z + log(1 + exp(-z)), written so that no exp overflows
        return float(np.sum(np.where(z >= 0, target * z, (target - 1) * z) + np.log1p(np.exp(-np.abs(z)))))

    value = objective(a, b)
    for _ in range(100):
        z = f * a + b
        p = np.where(z >= 0, np.exp(-np.abs(z)) / (1 + np.exp(-np.abs(z))), 1 / (1 + np.exp(-np.abs(z))))
        d2 = p * (1 - p)
        h11, h22, h21 = 1e-12 + np.sum(f * f * d2), 1e-12 + np.sum(d2), np.sum(f * d2)
        d1 = target - p
        g1, g2 = float(np.sum(f * d1)), float(np.sum(d1))
        if abs(g1) < 1e-5 and abs(g2) < 1e-5:
            break
        det = h11 * h22 - h21 * h21
        da, db = -(h22 * g1 - h21 * g2) / det, -(-h21 * g1 + h11 * g2) / det
        slope = g1 * da + g2 * db
        step = 1.0
        while step >= 1e-10:
            new = objective(a + step * da, b + step * db)
            if new < value + 1e-4 * step * slope:
                a, b, value = a + step * da, b + step * db, new
                break
            step /= 2
        else:  # the line search failed: the objective is flat to rounding here
            break
    return float(a), float(b)


def cross_val_decisions(
    X: np.ndarray,
    problems: ProblemSet,
    Cs: Sequence[float],
    *,
    kernel: str,
    gamma: float,
    rng: np.random.Generator,
    kernel_data: KernelData | None = None,
    rows: np.ndarray | None = None,
    n_folds: int = N_FOLDS,
    **solver: object,
) -> list[np.ndarray]:
    """Return the held-out decision values of every sample of every problem, one array per C.

    Each problem's samples are split into ``n_folds`` stratified folds (each side shuffled by ``rng``
    and dealt out in turn); the problem is solved on all folds but one and its decision function
    ``f(x) = sum_i y_i a_i K(x_i, x) - rho`` (> 0: the problem's first side) evaluated on the fold
    left out. All the fold problems are solved together by :func:`~tactile_torch.svm.solver.solve_set`.
    A side of 2 samples (the fewest ``fit`` accepts) keeps one in every training fold.

    Parameters
    ----------
    X : array of shape (n_samples, n_features)
    problems : ProblemSet
        The estimator's binary problems (rows index ``X``).
    Cs : sequence of float
        Increasing values of C (the estimator's, or a path's).
    kernel, gamma
        The estimator's kernel.
    rng : numpy Generator
    kernel_data, rows : optional
        Kernel values to solve with and the map of ``X``'s samples into them (as ``fit_path``'s).
    n_folds : int
    **solver
        ``threads``, ``tol``, ``max_iter``, ``cache_bytes`` of :func:`solve_set`.

    Returns
    -------
    list of arrays of shape (n_stored,), aligned with ``problems.rows``.
    """
    from .solver import ProblemSet, solve_set

    sides, held = [], []
    for p in range(len(problems)):
        start, stop = problems.offsets[p], problems.offsets[p + 1]
        y = problems.y[start:stop]
        fold = np.empty(stop - start, dtype=np.int64)
        for label in (1.0, -1.0):
            members = np.flatnonzero(y == label)
            fold[rng.permutation(members)] = (np.arange(members.shape[0]) + rng.integers(n_folds)) % n_folds
        local = problems.rows[start:stop]
        for k in range(n_folds):
            test = fold == k
            if test.any():
                sides.append((local[~test & (y > 0)], local[~test & (y < 0)]))
                held.append(start + np.flatnonzero(test))
    folds = ProblemSet.of(sides, problems.sample_weight(X.shape[0]))
    if kernel_data is None:
        kernel_data = KernelData.of(X, kernel, gamma)
    solutions = solve_set(kernel_data, folds if rows is None else folds.remapped(rows), list(Cs), **solver)
    X_t = tensor_from_array(np.ascontiguousarray(X, dtype=np.float64))
    out = []
    for sol in solutions:
        decision = np.empty(problems.rows.shape[0])
        for k, positions in enumerate(held):
            part = slice(folds.offsets[k], folds.offsets[k + 1])
            used = sol.alpha[part] > 0
            coef = torch.from_numpy((sol.alpha[part] * folds.y[part])[used])
            K = kernel_matrix(
                X_t[problems.rows[positions]], X_t[folds.rows[part][used]], kernel=kernel, gamma=gamma
            )
            decision[positions] = (K @ coef).numpy() - sol.rho[k]
        out.append(decision)
    return out


def platt_parameters(
    decision: np.ndarray, problems: ProblemSet, sign: float
) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(A, B)`` of every problem, each of shape (n_problems,).

    ``decision`` holds the held-out values of :func:`cross_val_decisions` (> 0: the problem's first
    side); ``sign`` turns them into the estimator's convention (+1 where its decision value is > 0
    for the first side, as one-vs-one; -1 where it is > 0 for the second side).
    """
    A, B = np.empty(len(problems)), np.empty(len(problems))
    for p in range(len(problems)):
        part = slice(problems.offsets[p], problems.offsets[p + 1])
        A[p], B[p] = fit_sigmoid(sign * decision[part], sign * problems.y[part] > 0)
    return A, B


def couple_pairwise(pairwise: torch.Tensor, pair_classes: torch.Tensor) -> torch.Tensor:
    """Return class probabilities from pairwise ones (Wu, Lin and Weng's second method, solved exactly).

    With ``R[i, j] = r_ij`` (probability of class ``i`` against ``j``, ``r_ji = 1 - r_ij``),
    ``Q[t, t] = sum_j r_jt^2`` and ``Q[t, j] = -r_jt r_tj``, the probabilities minimise ``p^T Q p``
    subject to ``sum p = 1``; equivalently ``p = x / sum(x)`` with ``(Q + 1 1^T) x = 1``, a positive
    definite system (for ``r`` strictly inside (0, 1)) solved by Gauss-Jordan elimination unrolled
    over the K classes (no data-dependent loop: exports to ONNX). Consistent pairwise probabilities
    (``r_ij = p_i / (p_i + p_j)``) give back ``p``.

    Parameters
    ----------
    pairwise : tensor of shape (B, P)
        ``r_ij`` of each pair ``(i, j)``, ``i < j``, in the order of ``pair_classes``.
    pair_classes : tensor of shape (2, P, K)
        One-hot rows of each pair's first and second class (:func:`~tactile_torch.svm.inference.ovo_tables`).

    Returns
    -------
    tensor of shape (B, K), rows summing to 1.
    """
    first, second = pair_classes[0].to(pairwise.dtype), pair_classes[1].to(pairwise.dtype)
    r = pairwise.clamp(MIN_PROBABILITY, 1 - MIN_PROBABILITY)
    # R[b, i, j] = r_ij for every ordered pair (0 on the diagonal)
    R = torch.matmul(first.T * r[:, None, :], second) + torch.matmul(second.T * (1 - r)[:, None, :], first)
    n_class = first.shape[1]
    eye = torch.eye(n_class, dtype=r.dtype)
    Q = eye * (R * R).sum(dim=1)[:, None, :] - R.transpose(1, 2) * R
    system = torch.cat([Q + 1.0, torch.ones_like(Q[:, :, :1])], dim=2)  # (B, K, K + 1): [Q + 1 1^T | 1]
    for k in range(n_class):
        pivot_row = system[:, k : k + 1, :]
        factor = system[:, :, k : k + 1] / system[:, k : k + 1, k : k + 1] * (1 - eye[k])[None, :, None]
        system = system - factor * pivot_row
    x = system[:, :, n_class] / torch.diagonal(system[:, :, :n_class], dim1=1, dim2=2)
    x = x.clamp_min(0.0)
    return x / x.sum(dim=1, keepdim=True)


def sigmoid_probability(decision: torch.Tensor, prob_a: torch.Tensor, prob_b: torch.Tensor) -> torch.Tensor:
    """Return ``1 / (1 + exp(A f + B))`` of each decision value (``(B, M)`` with ``A``, ``B`` of shape (M,))."""
    return torch.sigmoid(-(decision * prob_a + prob_b))


def tree_probabilities(
    margins: torch.Tensor, prob_a: torch.Tensor, prob_b: torch.Tensor, path_sign: torch.Tensor
) -> torch.Tensor:
    """Return each class's probability: the product of the branch probabilities on its path.

    Parameters
    ----------
    margins : tensor of shape (B, M)
        Node margins (> 0: right).
    prob_a, prob_b : tensors of shape (M,)
        Each node's sigmoid of ``P(right | margin)``.
    path_sign : tensor of shape (C, M)
        +1 / -1 where class ``c`` is right / left of node ``m``, 0 off its path.

    Returns
    -------
    tensor of shape (B, C)
    """
    z = margins * prob_a + prob_b  # P(right) = sigmoid(-z)
    right = torch.nn.functional.logsigmoid(-z)
    left = torch.nn.functional.logsigmoid(z)
    sign = path_sign.to(margins.dtype)
    log_p = right @ (sign > 0).to(margins.dtype).T + left @ (sign < 0).to(margins.dtype).T
    return log_p.exp()


__all__ = [
    "MIN_PROBABILITY",
    "N_FOLDS",
    "couple_pairwise",
    "cross_val_decisions",
    "fit_sigmoid",
    "platt_parameters",
    "sigmoid_probability",
    "tree_probabilities",
]
