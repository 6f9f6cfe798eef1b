"""The binary C-SVC dual and its solver: libsvm's SMO, compiled (:mod:`tactile_torch.svm._smo`).

The training problem is libsvm's C-SVC dual (the L1 hinge loss)::

    min_a  1/2 a^T Q a - sum(a)    subject to  0 <= a_i <= C w_i,  sum_i y_i a_i = 0,
    Q_ij = y_i y_j K(x_i, x_j),    y_i in {-1, +1},

with decision function ``f(x) = sum_i y_i a_i K(x_i, x) - rho``; ``w_i`` (1 unless weighted) is the
sample's weight times its class's weight (libsvm's per-class ``C``, scikit-learn's ``sample_weight``
and ``class_weight``). The binary problems of an estimator
(one per pair of classes, per class, or per tree node) form a :class:`ProblemSet`, solved by
:func:`solve_set` along increasing values of C: each problem's solution at one C warm-starts the
next. Samples are ordered and labelled as libsvm orders and labels them (the first class first,
labelled +1), so that with libsvm's shrinking interval the solver takes libsvm's steps.

Threads: the problems are cut into tasks (the largest problems alone, small ones grouped), which
Python threads take in turn, largest first; the compiled solver releases the GIL. A task solves its
problems along every C, so no thread waits for another between two values of C.

References
----------
C.-C. Chang, C.-J. Lin, "LIBSVM: a library for support vector machines", ACM TIST 2(3), 2011.
R.-E. Fan, P.-H. Chen, C.-J. Lin, "Working set selection using second order information for training
SVM", JMLR 6, 2005.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from . import _smo
from .kernels import KernelData
from .threads import run_blocks

SHRINK_EVERY = 100
"""Iterations between two shrinking passes (libsvm: ``min(n, 1000)``); measured 17 % faster on the
34,020-window benchmark tree, where libsvm's first 1000 iterations run over every sample."""

# A task holds problems of at least this many samples in total (one problem if it is larger): a
# thread's round trip costs about as much as solving a few hundred samples.
_TASK_SAMPLES = 2048


@dataclass(frozen=True)
class ProblemSet:
    """Binary problems stored end to end, each set up as libsvm sets it up.

    Problem ``p`` holds the samples ``rows[offsets[p]:offsets[p + 1]]`` (indices into a
    :class:`~tactile_torch.svm.kernels.KernelData`): those of its first class, labelled +1 in ``y``,
    then those of its second class, labelled -1. ``weight`` holds each stored sample's bound factor
    ``w_i > 0`` (its variable's upper bound is ``C w_i``).
    """

    rows: np.ndarray
    y: np.ndarray
    offsets: np.ndarray
    weight: np.ndarray

    @classmethod
    def of(
        cls, sides: Sequence[tuple[np.ndarray, np.ndarray]], sample_weight: np.ndarray | None = None
    ) -> ProblemSet:
        """The problems ``first`` (+1) against ``second`` (-1) for each ``(first, second)``.

        ``sample_weight`` (indexed like the rows, optional: all 1) gives each sample's bound factor;
        samples of weight 0 are left out (libsvm's ``remove_zero_weight``: they cannot move the
        solution). The callers make sure that every side keeps a sample.
        """
        if sample_weight is not None:
            sides = [
                (first[sample_weight[first] > 0], second[sample_weight[second] > 0])
                for first, second in sides
            ]
        sizes = [(first.shape[0], second.shape[0]) for first, second in sides]
        rows = np.concatenate([part for pair in sides for part in pair]).astype(np.int64)
        y = np.repeat(np.tile([1.0, -1.0], len(sides)), np.ravel(sizes))
        offsets = np.concatenate([[0], np.cumsum([a + b for a, b in sizes])]).astype(np.int64)
        weight = (
            np.ones(rows.shape[0]) if sample_weight is None else np.asarray(sample_weight, np.float64)[rows]
        )
        return cls(rows, y, offsets, np.ascontiguousarray(weight))

    def sample_weight(self, n_samples: int) -> np.ndarray:
        """Each sample's bound factor, shape (n_samples,) (1 for a sample in no problem)."""
        out = np.ones(n_samples)
        out[self.rows] = self.weight
        return out

    def __len__(self) -> int:
        return self.offsets.shape[0] - 1

    @property
    def problem_of(self) -> np.ndarray:
        """The problem of each stored sample, shape (total,)."""
        return np.repeat(np.arange(len(self)), np.diff(self.offsets))

    def remapped(self, index: np.ndarray) -> ProblemSet:
        """The same problems with ``rows`` mapped through ``index`` (into another kernel's samples)."""
        return ProblemSet(np.asarray(index, dtype=np.int64)[self.rows], self.y, self.offsets, self.weight)


@dataclass
class Solutions:
    """The solutions of a :class:`ProblemSet` at one C (arrays stored as the problems are).

    Attributes
    ----------
    C : float
    alpha : ndarray of shape (total,)
        Dual variables, in [0, C].
    grad, grad_bar : ndarray of shape (total,)
        The gradient ``Q a - 1`` and libsvm's ``G_bar`` (gradient of the variables at C), from which
        a solution warm-starts the next C.
    rho, objective : ndarray of shape (n_problems,)
        libsvm's ``rho`` (``f(x) = sum_i y_i a_i K(x_i, x) - rho``) and dual objective
        ``1/2 a^T Q a - sum(a)``.
    n_iter : ndarray of shape (n_problems,)
        SMO iterations.
    converged : ndarray of shape (n_problems,)
        False where ``max_iter`` stopped the solver before libsvm's stopping rule held.
    """

    C: float
    alpha: np.ndarray
    grad: np.ndarray
    grad_bar: np.ndarray
    rho: np.ndarray
    objective: np.ndarray
    n_iter: np.ndarray
    converged: np.ndarray

    @classmethod
    def empty(cls, C: float, problems: ProblemSet) -> Solutions:
        total, count = problems.rows.shape[0], len(problems)
        return cls(
            float(C),
            np.zeros(total),
            np.zeros(total),
            np.zeros(total),
            np.zeros(count),
            np.zeros(count),
            np.zeros(count, dtype=np.int64),
            np.zeros(count, dtype=bool),
        )


def _tasks(problems: ProblemSet) -> list[np.ndarray]:
    """Groups of problems, largest first, each of at least ``_TASK_SAMPLES`` samples (or one problem)."""
    sizes = np.diff(problems.offsets)
    tasks, current, total = [], [], 0
    for p in np.argsort(-sizes, kind="stable"):
        current.append(p)
        total += sizes[p]
        if total >= _TASK_SAMPLES:
            tasks.append(np.array(current, dtype=np.int64))
            current, total = [], 0
    if current:
        tasks.append(np.array(current, dtype=np.int64))
    return tasks


def solve_set(
    data: KernelData,
    problems: ProblemSet,
    Cs: Sequence[float],
    *,
    threads: int = 1,
    tol: float = 1e-3,
    max_iter: int = -1,
    cache_bytes: int = 200 << 20,
    shrink_every: int = SHRINK_EVERY,
) -> list[Solutions]:
    """Solve every problem at every C of ``Cs`` (increasing); return one :class:`Solutions` per C.

    Each problem is solved cold at the first C and warm-started at the next ones. Tasks run on up
    to ``threads`` Python threads; the kernel cache is shared out between them (each problem gets
    ``cache_bytes / threads``).
    """
    out = [Solutions.empty(C, problems) for C in Cs]
    tasks = _tasks(problems)
    threads = max(1, min(threads, len(tasks)))
    per_problem = max(1, int(cache_bytes) // threads)

    def run(which: np.ndarray) -> None:
        for c, sol in enumerate(out):
            prev = out[c - 1] if c else sol
            _smo.smo_many(
                data.XT,
                data.sq,
                data.K,
                problems.rows,
                problems.y,
                problems.weight,
                problems.offsets,
                which,
                sol.C,
                data.gamma,
                data.kind,
                float(tol),
                int(max_iter),
                int(shrink_every),
                per_problem,
                prev.alpha,
                prev.grad,
                prev.grad_bar,
                sol.C / prev.C if c else 0.0,
                sol.alpha,
                sol.grad,
                sol.grad_bar,
                sol.n_iter,
                sol.rho,
                sol.objective,
                sol.converged,
            )

    run_blocks(run, tasks, threads)
    return out


@dataclass
class DualSolution:
    """Solution of one binary C-SVC dual (:func:`solve_dual`).

    Attributes
    ----------
    alpha : ndarray of shape (n,), float64
        Dual variables, in [0, C], in the samples' order.
    rho : float
        libsvm's ``rho``: ``f(x) = sum_i y_i a_i K(x_i, x) - rho``.
    objective : float
        Dual objective ``1/2 a^T Q a - sum(a)`` (libsvm's ``obj``).
    n_iter : int
        SMO iterations.
    converged : bool
        False if ``max_iter`` stopped the solver before libsvm's stopping rule held.
    grad : ndarray of shape (n,)
        The gradient ``Q a - 1``.
    """

    alpha: np.ndarray
    rho: float
    objective: float
    n_iter: int
    converged: bool
    grad: np.ndarray

    @property
    def intercept(self) -> float:
        """``b = -rho`` of ``f(x) = sum_i y_i a_i K(x_i, x) + b``."""
        return -self.rho


def solve_dual(
    x: object,
    y: object,
    C: float,
    *,
    kernel: str = "rbf",
    gamma: float = 1.0,
    tol: float = 1e-3,
    max_iter: int = -1,
    cache_size: float = 200.0,
    shrink_every: int = SHRINK_EVERY,
    sample_weight: object = None,
) -> DualSolution:
    """Solve the binary C-SVC dual of the samples ``x`` with labels ``y`` (+1/-1) and return it.

    The samples are taken in their own order (the estimators order them as libsvm does).

    Parameters
    ----------
    x : array or tensor of shape (n, F)
    y : array or tensor of shape (n,) with values -1 and +1
    C : float
        Upper bound of the dual variables (> 0).
    kernel : {"rbf", "linear"}
    gamma : float
        RBF width.
    tol : float
        Stop when libsvm's maximal violating pair gap is below ``tol``.
    max_iter : int
        Cap on SMO iterations (-1: none).
    cache_size : float
        MiB of float32 kernel rows kept.
    shrink_every : int
        Iterations between shrinking passes (libsvm's is 1000; 0: no shrinking).
    sample_weight : array of shape (n,), optional
        Bound factors ``w_i > 0``: ``0 <= a_i <= C w_i`` (default all 1).

    Returns
    -------
    DualSolution

    Examples
    --------
    >>> x = np.array([[0.0], [1.0], [3.0], [4.0]])
    >>> sol = solve_dual(x, np.array([-1.0, -1.0, 1.0, 1.0]), 10.0, kernel="linear")
    >>> round(sol.intercept, 6), [round(a, 6) for a in sol.alpha.tolist()]
    (-2.0, [0.0, 0.5, 0.5, 0.0])
    """
    x = np.asarray(x.detach().cpu() if hasattr(x, "detach") else x, dtype=np.float64)
    y = np.asarray(y.detach().cpu() if hasattr(y, "detach") else y, dtype=np.float64)
    n = x.shape[0]
    weight = np.ones(n) if sample_weight is None else np.asarray(sample_weight, dtype=np.float64)
    problem = ProblemSet(np.arange(n, dtype=np.int64), np.where(y > 0, 1.0, -1.0), np.array([0, n]), weight)
    (sol,) = solve_set(
        KernelData.of(x, kernel, gamma),
        problem,
        [C],
        tol=tol,
        max_iter=max_iter,
        cache_bytes=int(cache_size * 2**20),
        shrink_every=shrink_every,
    )
    return DualSolution(
        sol.alpha,
        float(sol.rho[0]),
        float(sol.objective[0]),
        int(sol.n_iter[0]),
        bool(sol.converged[0]),
        sol.grad,
    )


__all__ = ["SHRINK_EVERY", "DualSolution", "ProblemSet", "Solutions", "solve_dual", "solve_set"]
