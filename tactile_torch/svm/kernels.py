"""Kernels: the torch kernel matrix of the inference graph, ``gamma="scale"``, and the arrays the
compiled solver and prediction read (:class:`KernelData`).

The compiled kernels (:mod:`~tactile_torch.svm._smo`, numba) are imported by the methods of
:class:`KernelData` that call them, so that the inference graph (:mod:`~tactile_torch.svm.inference`,
which needs :func:`kernel_matrix` only) does not load numba.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from .threads import run_blocks

KERNELS = ("rbf", "linear")
"""The kernels the solver and the inference graph implement."""

# Rows of a precomputed kernel computed per task (a few MiB of float32 per task).
_BLOCK_ROWS = 256


def kernel_matrix(
    a: torch.Tensor, b: torch.Tensor, *, kernel: str = "rbf", gamma: float = 1.0
) -> torch.Tensor:
    """Return the kernel matrix between the rows of ``a`` and the rows of ``b``.

    ``rbf``: ``exp(-gamma * ||a_i - b_j||^2)`` with the squared distance computed as
    ``||a_i||^2 + ||b_j||^2 - 2 a_i . b_j`` (one matrix product; clamped at 0 against rounding), the
    formula libsvm uses while training. ``linear``: ``a_i . b_j`` (``gamma`` ignored).

    Parameters
    ----------
    a : tensor of shape (N, F)
    b : tensor of shape (M, F), same dtype as ``a``
    kernel : {"rbf", "linear"}
    gamma : float
        RBF width (> 0).

    Returns
    -------
    tensor of shape (N, M), dtype of the inputs.

    Raises
    ------
    RuntimeError
        torch's, where shapes disagree: no check of its own (a step of the exported inference
        graph, which cannot raise; the estimators validate their input before calling it).

    Examples
    --------
    >>> kernel_matrix(torch.zeros(2, 3), torch.ones(1, 3), gamma=0.5)
    tensor([[0.2231],
            [0.2231]])
    """
    if kernel == "linear":
        return a @ b.T
    # ||b_j||^2 - 2 a_i . b_j in one BLAS call, then in-place passes: the blocks are large.
    sq = torch.addmm((b * b).sum(1)[None, :], a, b.T, alpha=-2.0)
    sq += (a * a).sum(1)[:, None]
    return sq.clamp_min_(0.0).mul_(-gamma).exp_()


def scale_gamma(X: np.ndarray) -> float:
    """Return scikit-learn's ``gamma="scale"``: ``1 / (n_features * X.var())`` (1.0 if ``X.var() == 0``).

    Parameters
    ----------
    X : array of shape (n, F)
        Training features (all of them, unweighted, as scikit-learn's ``SVC``).

    Returns
    -------
    float > 0

    Raises
    ------
    ValueError
        If ``X`` cannot be converted to float64 (numpy's message); no other check of its own: the
        estimators validate ``X`` before calling it.

    Examples
    --------
    >>> scale_gamma(np.array([[0.0, 2.0], [2.0, 0.0]]))
    0.5
    """
    var = float(np.asarray(X, dtype=np.float64).var())
    return 1.0 / (X.shape[1] * var) if var != 0.0 else 1.0


@dataclass(frozen=True)
class KernelData:
    """What the compiled solver reads to evaluate ``K(x_i, x_j)`` for the samples of one data set.

    Either the features (transposed, ``XT`` of shape (F, n), with squared norms ``sq``), from which
    kernel rows are computed as needed, or a precomputed float32 kernel matrix ``K`` of shape
    (n, n) (:meth:`precomputed`: one matrix per gamma serves every fold, C value and binary problem
    of a grid search). Build it with :meth:`of` or :meth:`precomputed`.
    """

    XT: np.ndarray
    sq: np.ndarray
    K: np.ndarray
    kind: int
    gamma: float

    @property
    def n_samples(self) -> int:
        return self.sq.shape[0]

    @classmethod
    def of(cls, X: np.ndarray, kernel: str, gamma: float) -> KernelData:
        """Kernel rows computed from ``X`` (float64, shape (n, F)) when the solver needs them."""
        from . import _smo

        kind = {"rbf": _smo.RBF, "linear": _smo.LINEAR}[kernel]
        X = np.ascontiguousarray(X, dtype=np.float64)
        return cls(np.ascontiguousarray(X.T), np.einsum("ij,ij->i", X, X), _EMPTY_K, kind, float(gamma))

    @classmethod
    def precomputed(cls, X: np.ndarray, kernel: str, gamma: float, threads: int) -> KernelData:
        """The whole float32 kernel matrix of ``X``, computed on ``threads`` Python threads.

        Its values equal, bit for bit, the rows the solver computes from the features, so a
        problem solved on either takes the same steps.
        """
        from . import _smo

        rows = cls.of(X, kernel, gamma)
        n = rows.n_samples
        K = np.empty((n, n), dtype=np.float32)
        X = np.ascontiguousarray(X, dtype=np.float64)
        blocks = [(start, min(n, start + _BLOCK_ROWS)) for start in range(0, n, _BLOCK_ROWS)]

        def fill(block: tuple[int, int]) -> None:
            _smo.kernel_block(X, rows.sq, rows.XT, rows.sq, rows.gamma, rows.kind, K, *block)

        run_blocks(fill, blocks, threads)
        return cls(_EMPTY_X, rows.sq, K, _smo.PRECOMPUTED, float(gamma))


_EMPTY_K = np.zeros((0, 0), dtype=np.float32)
_EMPTY_X = np.zeros((0, 0), dtype=np.float64)


__all__ = ["KERNELS", "KernelData", "kernel_matrix", "scale_gamma"]
