"""The binary C-SVC dual and its solver: libsvm's SMO, compiled (:mod:`tactile_torch.svm._smo`).

The training problem is libsvm's C-SVC dual (the L1 hinge loss)::

    min_a  1/2 a^T Q a - sum(a)    subject to  0 <= a_i <= C,  sum_i y_i a_i = 0,
    Q_ij = y_i y_j K(x_i, x_j),    y_i in {-1, +1},

with decision function ``f(x) = sum_i y_i a_i K(x_i, x) - rho``. Every binary problem of the
estimators (one per pair of classes, per class, or per tree node) goes through :func:`solve`;
independent problems run on Python threads (:func:`solve_all`), the compiled solver releasing the
GIL. Samples are ordered and labelled as libsvm orders and labels them (the first class first,
labelled +1), so that with libsvm's settings the solver takes libsvm's steps.

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

from .._parallel import map_blocks
from . import _smo
from .kernels import KernelData

SHRINK_EVERY = 100
"""Iterations between two shrinking passes (libsvm: ``min(n, 1000)``); measured 17 % faster on the
34,020-window benchmark tree, where libsvm's first 1000 iterations run over every sample."""


@dataclass(frozen=True)
class BinaryProblem:
    """One binary problem: ``first`` (labelled +1) against ``second`` (-1), as libsvm sets it up.

    ``rows`` indexes the samples of a :class:`~tactile_torch.svm.kernels.KernelData`: those of the
    first class, then those of the second.
    """

    rows: np.ndarray
    y: np.ndarray

    @classmethod
    def of(cls, first: np.ndarray, second: np.ndarray) -> BinaryProblem:
        rows = np.concatenate([first, second]).astype(np.int64)
        y = np.concatenate([np.ones(first.shape[0]), -np.ones(second.shape[0])])
        return cls(rows, y)


@dataclass
class DualSolution:
    """Solution of one binary C-SVC dual.

    Attributes
    ----------
    alpha : ndarray of shape (n,), float64
        Dual variables, in [0, C], in the problem's sample order.
    rho : float
        libsvm's ``rho``: ``f(x) = sum_i y_i a_i K(x_i, x) - rho``.
    objective : float
        Dual objective ``1/2 a^T Q a - sum(a)`` (libsvm's ``obj``).
    n_iter : int
        SMO iterations.
    converged : bool
        False if ``max_iter`` stopped the solver before libsvm's stopping rule held.
    C : float
    grad, grad_bar : ndarray of shape (n,)
        The gradient ``Q a - 1`` and libsvm's ``G_bar`` (gradient of the variables at C), from which
        a solution warm-starts the next C (:func:`solve_path`).
    """

    alpha: np.ndarray
    rho: float
    objective: float
    n_iter: int
    converged: bool
    C: float
    grad: np.ndarray
    grad_bar: np.ndarray

    @property
    def intercept(self) -> float:
        """``b = -rho`` of ``f(x) = sum_i y_i a_i K(x_i, x) + b``."""
        return -self.rho


def solve(
    data: KernelData,
    problem: BinaryProblem,
    C: float,
    *,
    tol: float = 1e-3,
    max_iter: int = -1,
    cache_bytes: int = 200 << 20,
    shrink_every: int = SHRINK_EVERY,
    warm: DualSolution | None = None,
) -> DualSolution:
    """Solve one binary dual with the compiled SMO; ``warm``: a solution at a smaller C on the
    same problem, scaled to ``C`` (its ``alpha``, ``G + 1`` and ``G_bar`` scale with C)."""
    n = problem.rows.shape[0]
    if warm is None:
        alpha, grad, grad_bar, mode = np.zeros(n), np.zeros(n), np.zeros(n), 0
    else:
        r = C / warm.C
        alpha, grad_bar, mode = warm.alpha * r, warm.grad_bar * r, 1
        grad = (warm.grad + 1.0) * r - 1.0
    n_iter, rho, objective, converged = _smo.smo(
        data.XT,
        data.sq,
        data.K,
        problem.rows,
        problem.y,
        float(C),
        data.gamma,
        data.kind,
        float(tol),
        int(max_iter),
        int(shrink_every),
        int(cache_bytes),
        alpha,
        grad,
        grad_bar,
        mode,
    )
    return DualSolution(alpha, rho, objective, n_iter, converged, float(C), grad, grad_bar)


def solve_path(
    data: KernelData, problem: BinaryProblem, Cs: Sequence[float], **options
) -> list[DualSolution]:
    """Solve one problem for increasing values of C, each warm-started from the previous one."""
    out: list[DualSolution] = []
    for C in Cs:
        out.append(solve(data, problem, C, warm=out[-1] if out else None, **options))
    return out


def solve_all(
    data: KernelData,
    problems: Sequence[BinaryProblem],
    Cs: Sequence[float],
    *,
    threads: int = 1,
    cache_bytes: int = 200 << 20,
    **options,
) -> list[list[DualSolution]]:
    """Solve every problem along ``Cs`` (increasing), on up to ``threads`` Python threads.

    Returns one list per problem (one solution per C). The largest problems start first; the kernel
    cache is shared out between the threads (each problem gets ``cache_bytes / threads``).
    """
    order = sorted(range(len(problems)), key=lambda k: -problems[k].rows.shape[0])
    threads = max(1, min(threads, len(problems)))
    per_problem = max(1, cache_bytes // threads)

    def run(k: int) -> list[DualSolution]:
        return solve_path(data, problems[k], Cs, cache_bytes=per_problem, **options)

    solved = map_blocks(run, order, threads)
    out: list[list[DualSolution]] = [[] for _ in problems]
    for k, sols in zip(order, solved, strict=True):
        out[k] = sols
    return out


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
) -> DualSolution:
    """Solve the binary C-SVC dual of the samples ``x`` with labels ``y`` (+1/-1) and return it.

    A thin entry to :func:`solve` for a whole data set, in the samples' own order (the estimators
    order them as libsvm does).

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
    data = KernelData.of(x, kernel, gamma)
    problem = BinaryProblem(np.arange(x.shape[0], dtype=np.int64), np.where(y > 0, 1.0, -1.0))
    return solve(data, problem, C, tol=tol, max_iter=max_iter, cache_bytes=int(cache_size * 2**20))


__all__ = ["SHRINK_EVERY", "BinaryProblem", "DualSolution", "solve", "solve_all", "solve_dual", "solve_path"]
