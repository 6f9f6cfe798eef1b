"""Support vector machines with a torch solver: a binary soft-margin :class:`SVC` and the
hierarchical multi-class :class:`HierarchicalSVC` of method 1.

The training problem is libsvm's C-SVC dual (the L1 hinge loss)::

    min_a  1/2 a^T Q a - sum(a)    subject to  0 <= a_i <= C,  sum_i y_i a_i = 0,
    Q_ij = y_i y_j K(x_i, x_j),    y_i in {-1, +1},

with decision function ``f(x) = sum_i y_i a_i K(x_i, x) + b``. It is solved by a multilevel
primal-dual active-set (semismooth Newton) method: a guess of which variables are free, at 0 or at C
gives one linear system (the free variables and the bias); its solution updates the guess; the loop
ends when the guess no longer changes, which is an exact optimum. Each step is a few large tensor
operations (a Cholesky factorisation of the free block, kernel blocks by matrix products) instead of
thousands of two-variable SMO steps, which would spend their time in Python and torch dispatch.
The problem is solved on a stratified ..., 1/16, 1/4 of the samples first, each solution warm-starting
the next, so the first guesses on the full set are already close. A step that would cycle is
restricted to the most violating variables; if that also fails the solver finishes with libsvm's
own SMO (second-order working-set selection), which always converges. The result is accepted with
libsvm's stopping rule (maximal violating pair gap ``<= tol``), and the bias is computed as libsvm
computes it, so the dual objective, the support set and the decision function agree with
``sklearn.svm.SVC`` (tested).

Prediction evaluates the kernel against the support vectors with one matrix product; for the tree,
against the union of every node's support vectors, so all node margins cost one product. The
inference path is an ``nn.Module`` (:class:`SVMInference`) that exports to ONNX.

References
----------
C.-C. Chang, C.-J. Lin, "LIBSVM: a library for support vector machines", ACM TIST 2(3), 2011.
R.-E. Fan, P.-H. Chen, C.-J. Lin, "Working set selection using second order information for training
SVM", JMLR 6, 2005.
M. Hintermüller, K. Ito, K. Kunisch, "The primal-dual active set strategy as a semismooth Newton
method", SIAM J. Optim. 13(3), 2003.
"""

from __future__ import annotations

import contextlib
import math
import numbers
import warnings
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import torch
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.validation import check_is_fitted

from ._checks import RandomState, as_feature_matrix, check_positive, numpy_rng

KERNELS = ("rbf", "linear")

# Rows of a kernel block computed at once when a product over all samples is needed: bounds the
# memory of one block to _ROW_CHUNK * n_columns float64 values.
_ROW_CHUNK = 4096

# Problems up to this many samples are solved on one thread (see solve_dual).
_SINGLE_THREAD_MAX = 5000
# Predictions of at most this many rows run on one thread (see _KernelMachine._margins).
_FEW_ROWS = 16

# Shrinking threshold of the active-set method, in units of margin (see _active_set).
_SHRINK = 0.5
# Samples this close beyond their margin join the interior-point working set.
_NEAR = 0.1


# --------------------------------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------------------------------


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


def _kernel_times(
    x: torch.Tensor,
    rows: torch.Tensor | None,
    cols: torch.Tensor,
    coef: torch.Tensor,
    kernel: str,
    gamma: float,
) -> torch.Tensor:
    """Return ``K(x[rows], x[cols]) @ coef`` computed in row chunks (``rows=None``: every row)."""
    xc = x[cols]
    xr = x if rows is None else x[rows]
    out = torch.empty(xr.shape[0], *coef.shape[1:], dtype=x.dtype)
    for start in range(0, xr.shape[0], _ROW_CHUNK):
        block = kernel_matrix(xr[start : start + _ROW_CHUNK], xc, kernel=kernel, gamma=gamma)
        out[start : start + _ROW_CHUNK] = block @ coef
    return out


# --------------------------------------------------------------------------------------------------
# The dual solver
# --------------------------------------------------------------------------------------------------


@dataclass
class DualSolution:
    """Solution of one binary C-SVC dual, as returned by :func:`solve_dual`.

    Attributes
    ----------
    alpha : tensor of shape (n,), float64
        Dual variables, in [0, C].
    intercept : float
        Bias ``b`` of ``f(x) = sum_i y_i a_i K(x_i, x) + b`` (libsvm's ``-rho``).
    n_iter : int
        Newton (active-set) steps plus SMO steps taken.
    gap : float
        libsvm's maximal violating pair gap at the solution (``<= tol`` unless ``max_iter`` stopped it).
    objective : float
        Dual objective ``1/2 a^T Q a - sum(a)`` (libsvm's ``obj``).
    method : str
        ``"active-set"`` if the active-set iteration converged, ``"smo"`` if SMO finished the job.
    """

    alpha: torch.Tensor
    intercept: float
    n_iter: int
    gap: float
    objective: float
    method: str


class _Dual:
    """One binary dual problem: data, labels, kernel, and the kernel products the solvers need.

    Kernel columns ``K(:, j)`` of the samples that become support vectors (or candidates) are
    computed once, over every sample, and kept (as columns of a row-major ``(n, slots)`` buffer, so
    that the rows of a subset of samples are contiguous) up to ``cache_bytes``; beyond that they
    are recomputed when needed. A margin evaluation is then one matrix-vector product over the
    cached columns. The linear kernel needs no cache: ``f(x) = w . x``.
    """

    def __init__(
        self, x: torch.Tensor, y: torch.Tensor, C: float, kernel: str, gamma: float, cache_bytes: int
    ) -> None:
        self.x, self.y, self.C, self.kernel, self.gamma = x, y, C, kernel, gamma
        self.n = x.shape[0]
        slots = 0 if kernel == "linear" else int(cache_bytes // (x.element_size() * self.n))
        self.max_slots = min(slots, self.n)
        self.slot = torch.full((self.n,), -1, dtype=torch.long)
        # Untouched pages of an empty tensor cost no memory: the cache is reserved at once.
        self.cache = torch.empty((self.n, self.max_slots), dtype=x.dtype)
        self.n_cached = 0

    def _cache(self, idx: torch.Tensor) -> None:
        """Compute and cache the columns of ``idx`` not cached yet, as far as the cache allows."""
        missing = idx[self.slot[idx] < 0].unique()
        add = missing[: self.max_slots - self.n_cached]
        if add.numel() == 0:
            return
        end = self.n_cached + add.numel()
        for start in range(0, self.n, _ROW_CHUNK):
            self.cache[start : start + _ROW_CHUNK, self.n_cached : end] = kernel_matrix(
                self.x[start : start + _ROW_CHUNK], self.x[add], kernel=self.kernel, gamma=self.gamma
            )
        self.slot[add] = torch.arange(self.n_cached, end)
        self.n_cached = end

    def kernel_block(self, rows: torch.Tensor, cols: torch.Tensor) -> torch.Tensor:
        """Return ``K(x[rows], x[cols])`` (computed: gathering it from the cache is slower)."""
        return kernel_matrix(self.x[rows], self.x[cols], kernel=self.kernel, gamma=self.gamma)

    def column(self, j: int) -> torch.Tensor:
        """Return ``K(:, j)`` over every sample."""
        self._cache(torch.tensor([j]))
        slot = int(self.slot[j])
        if slot >= 0:
            return self.cache[:, slot]
        return kernel_matrix(self.x, self.x[j : j + 1], kernel=self.kernel, gamma=self.gamma)[:, 0]

    def margins(self, rows: torch.Tensor | None, alpha: torch.Tensor, b: float) -> torch.Tensor:
        """Return ``y_i f(x_i) - 1`` for ``rows`` (``None``: all) given the full ``alpha`` and ``b``."""
        sv = torch.nonzero(alpha).squeeze(1)
        y = self.y if rows is None else self.y[rows]
        if sv.numel() == 0:
            return y * b - 1.0
        coef = alpha[sv] * self.y[sv]
        if self.kernel == "linear":
            # f(x) = w . x with w = sum_i y_i a_i x_i: O(n F) instead of O(n n_SV F).
            return y * ((self.x if rows is None else self.x[rows]) @ (self.x[sv].T @ coef) + b) - 1.0
        self._cache(sv)
        slots = self.slot[sv]
        hit = slots >= 0
        weights = torch.zeros(self.n_cached, dtype=coef.dtype)
        weights[slots[hit]] = coef[hit]
        cached = self.cache[:, : self.n_cached]
        if rows is None or rows.numel() > self.n // 4:
            # Gathering many rows costs more than the product over all of them.
            f = cached @ weights
            f = f if rows is None else f[rows]
        else:
            f = cached.index_select(0, rows) @ weights
        if not bool(hit.all()):
            f += _kernel_times(self.x, rows, sv[~hit], coef[~hit], self.kernel, self.gamma)
        return y * (f + b) - 1.0

    def gradient(self, alpha: torch.Tensor) -> torch.Tensor:
        """Return the dual gradient ``Q a - 1`` over all samples."""
        # With b = 0, y_i f(x_i) - 1 = (Q a)_i - 1.
        return self.margins(None, alpha, 0.0)

    def objective(self, alpha: torch.Tensor, grad: torch.Tensor) -> float:
        # libsvm: obj = sum_i a_i (G_i - 1) / 2 with G = Q a - 1.
        return float((alpha * (grad - 1.0)).sum() / 2.0)

    def diagonal(self) -> torch.Tensor:
        """Return ``K(x_i, x_i)`` for every sample."""
        if self.kernel == "linear":
            return (self.x * self.x).sum(1)
        return torch.ones(self.n, dtype=self.x.dtype)


def _up_low(alpha: torch.Tensor, y: torch.Tensor, C: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Return libsvm's index sets I_up and I_low as boolean masks."""
    pos = y > 0
    below, above = alpha < C, alpha > 0
    return (pos & below) | (~pos & above), (pos & above) | (~pos & below)


def _gap(alpha: torch.Tensor, y: torch.Tensor, grad: torch.Tensor, C: float) -> float:
    """Return libsvm's maximal violating pair gap ``max_{I_up} -y G - min_{I_low} -y G``."""
    up, low = _up_low(alpha, y, C)
    if not bool(up.any()) or not bool(low.any()):
        return 0.0
    score = -y * grad
    return float(score[up].max() - score[low].min())


def _bias(alpha: torch.Tensor, y: torch.Tensor, grad: torch.Tensor, C: float) -> float:
    """Return the bias ``b = -rho`` as libsvm's ``calculate_rho`` computes it.

    ``rho`` is the mean of ``y_i G_i`` over the free variables; without free variables, the middle
    of the interval that the bounded ones leave for it.
    """
    yg = y * grad
    free = (alpha > 0) & (alpha < C)
    if bool(free.any()):
        return -float(yg[free].mean())
    at_upper = alpha >= C
    pos = y > 0
    ub_mask = (at_upper & ~pos) | (~at_upper & pos)
    ub = float(yg[ub_mask].min()) if bool(ub_mask.any()) else math.inf
    lb = float(yg[~ub_mask].max()) if bool((~ub_mask).any()) else -math.inf
    if math.isinf(ub) or math.isinf(lb):
        return -(ub if math.isfinite(ub) else lb)
    return -(ub + lb) / 2.0


def _stratified_order(y: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Return a permutation of the samples whose every prefix holds both labels in proportion.

    Each sample gets the key ``(rank within its label + U(0, 1)) / label count`` under a random
    ranking; the first sample of each label is put in front so that the smallest level sees both.
    """
    keys = np.empty(y.shape[0])
    for label in (-1.0, 1.0):
        idx = np.flatnonzero(y == label)
        ranks = rng.permutation(idx.shape[0])
        keys[idx] = (ranks + rng.random(idx.shape[0])) / idx.shape[0]
        keys[idx[ranks == 0]] = -1.0
    return np.argsort(keys, kind="stable")


def _cholesky(q: torch.Tensor) -> torch.Tensor | None:
    """Return the Cholesky factor of ``q``, or ``None`` if ``q`` is not numerically positive definite."""
    factor, info = torch.linalg.cholesky_ex(q)
    return factor if int(info) == 0 else None


def _newton_step(
    problem: _Dual, free: torch.Tensor, upper: torch.Tensor
) -> tuple[torch.Tensor, float] | None:
    """Solve the KKT system of one active-set guess; return ``(a_free, b)``, or ``None`` if singular.

    With ``a = 0`` off the guess and ``a = C`` on ``upper``, the free variables and the bias solve
    ``Q_FF a_F + b y_F = 1 - C Q_FU 1`` and ``y_F^T a_F = -C sum(y_U)``: every free sample exactly on
    its margin. Eliminating ``b`` takes two solves with one Cholesky factor. ``None`` means the
    block is singular: samples repeat, or (linear kernel) more variables are free than there are
    features, and the guess cannot be exact.
    """
    C, y = problem.C, problem.y
    y_free = y[free]
    n_free = free.numel()
    if n_free == 0:
        return torch.zeros(1, dtype=y.dtype)[:0], math.nan  # the caller sets the bias
    block = problem.kernel_block(free, torch.cat([free, upper]))
    rhs = 1.0 - C * y_free * (block[:, n_free:] @ y[upper])
    q = block[:, :n_free].mul_(y_free[:, None]).mul_(y_free[None, :])
    factor = _cholesky(q)
    if factor is None:
        return None
    sol = torch.cholesky_solve(torch.stack([rhs, y_free], 1), factor)
    u, w = sol[:, 0], sol[:, 1]
    yw = float(y_free @ w)
    if not yw > 0.0:  # y^T Q^-1 y > 0 for a positive definite Q: rounding says Q is not
        return None
    b = (float(y_free @ u) + C * float(y[upper].sum())) / yw
    return u - b * w, b


def _interior_point(
    problem: _Dual,
    idx: torch.Tensor,
    linear: torch.Tensor,
    total: float,
    *,
    low_rank: bool = False,
    tol: float = 1e-9,
    max_iter: int = 200,
) -> tuple[torch.Tensor, int]:
    """Solve the dual restricted to the samples ``idx`` with a primal-dual interior-point method.

    The subproblem is ``min 1/2 a^T Q a + linear^T a`` subject to ``y^T a = total`` and
    ``0 <= a <= C`` over ``idx`` (the other variables fixed, which gives ``linear`` and ``total``).
    Mehrotra's predictor-corrector with multipliers ``z`` (lower bounds) and ``w`` (upper bounds);
    each iteration solves with ``Q + D``, ``D = diag(z / a + w / (C - a))``, twice. About 10-30
    iterations reach ``tol`` whatever the conditioning of ``Q``. ``low_rank`` (linear kernel):
    ``Q = Z Z^T`` with ``Z = y x`` of F columns, and the Woodbury identity solves with ``Q + D`` in
    ``O(m F^2)``, so the whole linear problem is solved this way; otherwise ``Q + D`` is factorised
    (Cholesky), which is the robust step of the RBF active-set method (the cold first level, a guess
    whose Newton step swings out of the box, a singular block, cycling). Returns
    ``(a, iterations)``; a variable closer to a bound than its multiplier is put on it.
    """
    C = problem.C
    y = problem.y[idx]
    m = idx.numel()
    low, high = -C * float((y < 0).sum()), C * float((y > 0).sum())
    if min(total - low, high - total) <= 1e-12 * C * m:
        # The equality leaves one point of the box (every variable at the bound it pushes to).
        return torch.where((y > 0) == (total > (low + high) / 2), C, 0.0).to(y.dtype), 0
    if low_rank:
        zmat = problem.x[idx] * y[:, None]
        eye = torch.eye(zmat.shape[1], dtype=y.dtype)

        def times_q(v: torch.Tensor) -> torch.Tensor:
            return zmat @ (zmat.T @ v)

        def solver(d: torch.Tensor):
            # (D + Z Z^T)^-1 r = D^-1 r - D^-1 Z (I + Z^T D^-1 Z)^-1 Z^T D^-1 r
            zd = zmat / d[:, None]
            small = _cholesky(eye + zmat.T @ zd)

            def solve(r: torch.Tensor) -> torch.Tensor:
                rd = r / d[:, None]
                return rd - zd @ torch.cholesky_solve(zmat.T @ rd, small)

            return solve
    else:
        q = problem.kernel_block(idx, idx).mul_(y[:, None]).mul_(y[None, :])

        def times_q(v: torch.Tensor) -> torch.Tensor:
            return q @ v

        def solver(d: torch.Tensor):
            matrix = q.clone()
            matrix.diagonal().add_(d)
            factor = _cholesky(matrix)
            jitter = 1e-14 * float(matrix.diagonal().max())
            while factor is None:  # pragma: no cover - only for badly scaled data
                matrix.diagonal().add_(jitter)
                jitter *= 100.0
                factor = _cholesky(matrix)
            return lambda r: torch.cholesky_solve(r, factor)

    # Start inside the box, shifted along y towards the equality.
    a = (torch.full((m,), C / 2.0, dtype=y.dtype) + (total - C / 2.0 * float(y.sum())) / m * y).clamp_(
        0.05 * C, 0.95 * C
    )
    z = torch.ones(m, dtype=y.dtype)
    w = torch.ones(m, dtype=y.dtype)
    b = 0.0
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is returned
        s, t = a, C - a
        r_dual = times_q(a) + linear + b * y - z + w
        r_eq = float(y @ a) - total
        mu = float(s @ z + t @ w) / (2 * m)
        if mu < tol and float(r_dual.abs().max()) < tol and abs(r_eq) < tol * max(C, 1.0):
            break
        solve = solver(z / s + w / t)
        v = solve(y[:, None])[:, 0]
        yv = float(y @ v)
        # The step bounds: a, C - a, z, w over the rate at which a direction shrinks them.
        room = torch.cat([s, t, z, w])

        def direction(target_l: torch.Tensor, target_u: torch.Tensor) -> tuple[torch.Tensor, ...]:
            # Linearised: s z -> target_l, t w -> target_u, stationarity and the equality.
            u = solve((-r_dual + (target_l - s * z) / s - (target_u - t * w) / t)[:, None])[:, 0]  # noqa: B023
            db = (float(y @ u) + r_eq) / yv  # noqa: B023
            da = u - db * v  # noqa: B023
            dz = (target_l - s * z - z * da) / s  # noqa: B023
            dw = (target_u - t * w + w * da) / t  # noqa: B023
            # The longest step in [0, 1] that keeps a, C - a, z and w positive (one fused pass).
            shrink = torch.cat([-da, da, -dz, -dw])
            step = min(1.0, float(torch.where(shrink > 0, room / shrink, math.inf).min()))  # noqa: B023
            return da, db, dz, dw, step

        zero = torch.zeros_like(a)
        da, _, dz, dw, step = direction(zero, zero)
        mu_aff = float((s + step * da) @ (z + step * dz) + (t - step * da) @ (w + step * dw)) / (2 * m)
        sigma = (mu_aff / mu) ** 3
        da, db, dz, dw, step = direction(sigma * mu - da * dz, sigma * mu + da * dw)
        step *= 0.99
        a = a + step * da
        b += step * db
        z = z + step * dz
        w = w + step * dw
    # A variable is at a bound when its distance to it is below its multiplier.
    a = torch.where((C - a) < w, C, torch.where(a < z, 0.0, a)).to(a.dtype)
    return a, it


def _largest(values: torch.Tensor) -> float:
    return float(values.abs().max()) if values.numel() else 0.0


@dataclass
class _Guess:
    """Free and upper-bound masks over one level's samples (the rest is at 0)."""

    free: torch.Tensor
    upper: torch.Tensor

    @classmethod
    def of(cls, a: torch.Tensor, C: float) -> _Guess:
        return cls((a > 0) & (a < C), a >= C)

    def key(self) -> bytes:
        return self.free.numpy().tobytes() + self.upper.numpy().tobytes()


def _active_set(
    problem: _Dual, order: np.ndarray, tol: float, budget: int, *, base: int = 256, ratio: int = 4
) -> tuple[torch.Tensor, torch.Tensor | None, int, bool]:
    """Run the multilevel active-set iteration; return ``(alpha, grad, steps, converged)``.

    Levels: prefixes of ``order`` of ``n / ratio^k`` samples (at least ``base``), smallest first,
    up to all of them; the smallest is solved by the interior-point method, each later level starts
    from the previous one's solution (ratio 4 rather than 2: fewer levels, each with a fixed cost in
    steps, measured faster at 3,400 and 34,000 samples). Within a level, a guess of the free and upper
    sets gives one Newton step (:func:`_newton_step`); its solution and margins give the next guess.
    Where that fails (the cold first level, a step that swings out of the box, a singular block, a
    repeated guess or no fewer violations for a few steps), the free variables and the violators are
    solved together by the interior-point method (:func:`_interior_point`), the others fixed: a
    decomposition step that always lowers the objective. On failure within the step budget
    ``alpha`` is the last feasible iterate, from which SMO continues.
    """
    n, C, y = problem.n, problem.C, problem.y
    sizes = [n]
    while sizes[-1] > base:
        sizes.append(max(base, sizes[-1] // ratio))
    # A sample on the wrong side of its margin by more than tol / 2 must change set; within that,
    # a guess counts as optimal, which bounds libsvm's gap by tol (see solve_dual).
    eps = tol / 2.0
    diagonal = problem.diagonal().clamp_min(1e-12)
    patience = 3
    alpha = torch.zeros(n, dtype=y.dtype)
    b, steps = 0.0, 0
    order_t = torch.from_numpy(order)
    nu = torch.empty(0, dtype=y.dtype)
    carry = False
    for level, size in enumerate(sorted(set(sizes))):
        S = order_t[:size]
        diag_s = diagonal[S]
        feasible, feasible_b = alpha.clone(), b
        guess = _Guess.of(alpha[S], C)
        seen: set[bytes] = set()
        best, stall = math.inf, 0
        # Robust steps for the cold first level (every sample violates), and from the start of a
        # level after one where Newton steps failed (the regime, e.g. few free and many bounded
        # variables, persists); within a level, robust steps once taken continue.
        robust, failed = level == 0 or carry, False
        first = True  # the level's first Newton step
        full, active = True, torch.ones(size, dtype=torch.bool)
        while True:
            if full:
                best, stall = math.inf, 0  # new samples may violate: progress is measured afresh
                nu = problem.margins(S, alpha, b)
                # Shrinking: samples well beyond their margin (y f > 1 + _SHRINK) stay at 0 for a
                # while; until the level looks solved only the others are evaluated, then all are.
                active = (nu < _SHRINK) | guess.free | guess.upper
            else:
                nu[active] = problem.margins(S[active], alpha, b)
            a_s = alpha[S]
            lower = ~guess.free & ~guess.upper
            to_lower = guess.free & (a_s <= 0)
            to_upper = guess.free & (a_s >= C)
            leave_lower = lower & (nu < -eps)
            leave_upper = guess.upper & (nu > eps)
            violating = leave_lower | leave_upper
            n_change = int((to_lower | to_upper | violating).sum())
            if n_change == 0:
                if full:
                    carry = failed
                    break  # the level is solved
                full = True
                continue
            full = False
            if steps >= budget:
                return feasible, None, steps, False
            stall = stall + 1 if n_change >= best else 0
            best = min(best, n_change)
            if not robust:
                # At most half as many variables leave a bound per step as are free (at least 64;
                # the worst violators), so that the blocks grow by half at most.
                max_enter = max(16, int(guess.free.sum()) // 2)
                if int(violating.sum()) > max_enter:
                    worst = torch.topk(torch.where(violating, nu.abs(), -1.0), max_enter).indices
                    keep = torch.zeros_like(violating)
                    keep[worst] = True
                    leave_lower, leave_upper = leave_lower & keep, leave_upper & keep
                # A violator goes where one Newton step on it alone would take it (PDAS with
                # c_i = 1 / Q_ii): free, or straight to the other bound.
                target = a_s - nu / diag_s
                new = _Guess(
                    (guess.free & ~(to_lower | to_upper))
                    | (leave_lower & (target < C))
                    | (leave_upper & (target > 0)),
                    (guess.upper & ~leave_upper) | to_upper | (leave_lower & (target >= C)),
                )
                solved = None
                if new.key() not in seen and stall <= patience:
                    seen.add(new.key())
                    solved = _newton_step(problem, S[new.free], S[new.upper])
                    steps += 1
                # The first step from a new level's guess may overshoot the box by tens of C,
                # harmlessly; later steps that still swing by more than a few C are cycling (few
                # free and many bounded variables), and a far-off guess sends them to thousands of C.
                swing = (100.0 if first else 10.0) * C
                first = False
                if solved is not None and _largest(solved[0]) <= swing:
                    guess, (a_free, b) = new, solved
                    alpha[S] = torch.where(guess.upper, C, 0.0).to(alpha.dtype)
                    alpha[S[guess.free]] = a_free
                    if not bool(guess.free.any()):
                        # No free variable: the bias is the middle of the interval left by the bounds.
                        b = _bias(alpha[S], y[S], problem.margins(S, alpha, 0.0), C)
                    if bool(((a_free > 0) & (a_free < C)).all()):
                        feasible, feasible_b = alpha.clone(), b
                    continue
                failed = True
            # Robust step from the last feasible point: support vectors and (near-)violators by their
            # margins at that point solved together, the others fixed at 0.
            alpha, b = feasible.clone(), feasible_b
            nu = problem.margins(S, alpha, b)
            a_s = alpha[S]
            # The working set: every support vector, every violator and the samples just beyond
            # their margin, so that one solve leaves few new violators.
            work_m = (a_s > 0) | (nu < _NEAR)
            work = S[work_m]
            if work.numel() == 0:  # the feasible point is optimal: only the guess was off
                guess = _Guess.of(a_s, C)
                continue
            y_w = y[work]
            q_ww = problem.kernel_block(work, work).mul_(y_w[:, None]).mul_(y_w[None, :])
            linear = (nu[work_m] - b * y_w) - q_ww @ alpha[work]
            rest = S[~work_m]
            alpha[work], ipm_steps = _interior_point(problem, work, linear, -float(y[rest] @ alpha[rest]))
            steps += ipm_steps
            guess = _Guess.of(alpha[S], C)
            free = S[guess.free]
            # Make the identified guess exact (one Newton step) where it can be.
            solved = _newton_step(problem, free, S[guess.upper]) if free.numel() else None
            if solved is not None and bool(((solved[0] > 0) & (solved[0] < C)).all()):
                alpha[free], b = solved
            else:
                b = _bias(alpha[S], y[S], problem.margins(S, alpha, 0.0), C)
            feasible, feasible_b = alpha.clone(), b
            seen.clear()
            best, stall, full, robust = math.inf, 0, True, True
    # The last margins were computed on every sample (in level order): G = nu - b y.
    grad = torch.empty_like(alpha)
    grad[order_t] = nu - b * y[order_t]
    return alpha, grad, steps, True


def _smo(
    problem: _Dual, alpha: torch.Tensor, tol: float, budget: int
) -> tuple[torch.Tensor, torch.Tensor, int, bool]:
    """Run libsvm's SMO (second-order working-set selection, WSS3) from a feasible ``alpha``.

    Returns ``(alpha, grad, steps, converged)``. Each step moves two variables, so this costs a few
    tensor operations per step; it is the safe finish of the active-set method and the reference
    solver (``solver="smo"``).
    """
    y, C = problem.y, problem.C
    alpha = alpha.clone()
    grad = problem.gradient(alpha)
    diag = problem.diagonal()
    row = problem.column

    tau = 1e-12
    steps = 0
    while True:
        up, low = _up_low(alpha, y, C)
        score = -y * grad
        up_score = torch.where(up, score, -math.inf)
        i = int(up_score.argmax())
        g_max = float(up_score[i])
        low_score = torch.where(low, score, math.inf)
        if g_max - float(low_score.min()) <= tol:
            return alpha, grad, steps, True
        if steps >= budget:
            return alpha, grad, steps, False
        k_i = row(i)
        diff = g_max - low_score
        quad = (diag[i] + diag - 2.0 * k_i).clamp_min(tau)
        gain = torch.where(low & (diff > 0), -(diff * diff) / quad, math.inf)
        j = int(gain.argmin())
        k_j = row(j)
        yi, yj = float(y[i]), float(y[j])
        ai, aj = float(alpha[i]), float(alpha[j])
        gi, gj = float(grad[i]), float(grad[j])
        kij = float(k_i[j])
        # libsvm's two-variable update (Solver::Solve), with Q_ij = y_i y_j K_ij.
        if yi != yj:
            quad_ij = max(float(diag[i] + diag[j]) + 2.0 * yi * yj * kij, tau)
            delta = (-gi - gj) / quad_ij
            d = ai - aj
            ai, aj = ai + delta, aj + delta
            if d > 0:
                if aj < 0:
                    aj, ai = 0.0, d
            elif ai < 0:
                ai, aj = 0.0, -d
            if d > 0:
                if ai > C:
                    ai, aj = C, C - d
            elif aj > C:
                aj, ai = C, C + d
        else:
            quad_ij = max(float(diag[i] + diag[j]) - 2.0 * yi * yj * kij, tau)
            delta = (gi - gj) / quad_ij
            s = ai + aj
            ai, aj = ai - delta, aj + delta
            if s > C:
                if ai > C:
                    ai, aj = C, s - C
            elif aj < 0:
                aj, ai = 0.0, s
            if s > C:
                if aj > C:
                    aj, ai = C, s - C
            elif ai < 0:
                ai, aj = 0.0, s
        dai, daj = ai - float(alpha[i]), aj - float(alpha[j])
        alpha[i], alpha[j] = ai, aj
        grad += y * (yi * dai * k_i + yj * daj * k_j)
        steps += 1


def solve_dual(
    x: torch.Tensor,
    y: torch.Tensor,
    C: float,
    *,
    kernel: str = "rbf",
    gamma: float = 1.0,
    tol: float = 1e-3,
    max_iter: int = -1,
    solver: str = "active-set",
    cache_size: float = 512.0,
    random_state: RandomState = None,
) -> DualSolution:
    """Solve the binary C-SVC dual (libsvm's problem) and return the solution.

    Parameters
    ----------
    x : tensor of shape (n, F), float64
    y : tensor of shape (n,), float64 with values -1 and +1 (both present)
    C : float
        Upper bound of the dual variables (> 0).
    kernel, gamma
        As in :func:`kernel_matrix`.
    tol : float
        Stop when libsvm's maximal violating pair gap is ``<= tol``.
    max_iter : int
        Cap on the solver steps (active-set steps plus SMO steps); ``-1``: no cap.
    solver : {"active-set", "smo"}
        ``"active-set"`` (default) as described in the module notes; ``"smo"``: libsvm's SMO only.
    cache_size : float
        Memory for cached kernel columns, in MiB (float64 columns over all samples).
    random_state
        Seeds the order in which samples join the multilevel iteration (the optimum does not
        depend on it, only the path to it).

    Returns
    -------
    DualSolution

    Examples
    --------
    >>> x = torch.tensor([[0.0], [1.0], [3.0], [4.0]], dtype=torch.float64)
    >>> sol = solve_dual(x, torch.tensor([-1.0, -1.0, 1.0, 1.0], dtype=torch.float64), 10.0, kernel="linear")
    >>> round(sol.intercept, 6), [round(a, 6) for a in sol.alpha.tolist()]
    (-2.0, [0.0, 0.5, 0.5, 0.0])
    """
    # Below a few thousand samples the solver's tensors are small and every step is a few dozen
    # small operations, which intra-op threads only slow down (many times over on a loaded
    # machine): such problems run on one thread, and the caller's setting is restored after.
    with _torch_threads(1 if x.shape[0] <= _SINGLE_THREAD_MAX else torch.get_num_threads()):
        return _solve_dual(x, y, C, kernel, gamma, tol, max_iter, solver, cache_size, random_state)


@contextlib.contextmanager
def _torch_threads(n: int) -> Iterator[None]:
    before = torch.get_num_threads()
    if n != before:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        if n != before:
            torch.set_num_threads(before)


def _solve_dual(x, y, C, kernel, gamma, tol, max_iter, solver, cache_size, random_state) -> DualSolution:
    problem = _Dual(x, y, float(C), kernel, float(gamma), int(cache_size * 2**20))
    budget = max_iter if max_iter > 0 else 1 << 62
    steps, method = 0, "smo"
    alpha = torch.zeros(problem.n, dtype=x.dtype)
    grad = None
    converged = False
    if solver == "active-set" and kernel == "linear":
        # Q = Z Z^T has rank <= F: active-set blocks are singular as soon as more than F variables
        # are free, while the interior-point method solves with Q + D in O(n F^2) per iteration.
        everyone = torch.arange(problem.n)
        alpha, steps = _interior_point(problem, everyone, -torch.ones_like(y), 0.0, low_rank=True)
        method = "interior-point"
        converged = steps <= budget
    elif solver == "active-set":
        order = _stratified_order(y.numpy(), numpy_rng(random_state))
        alpha, grad, steps, converged = _active_set(problem, order, tol, budget)
        method = "active-set"
        if converged:
            grad = problem.gradient(alpha) if grad is None else grad
            if _gap(alpha, y, grad, problem.C) > tol:
                converged = False  # rounding in a near-singular system: let SMO finish
    if not converged and steps < budget:
        alpha, grad, smo_steps, converged = _smo(problem, alpha, tol, budget - steps)
        steps += smo_steps
        method = "smo" if solver == "smo" or smo_steps else method
    if grad is None:
        grad = problem.gradient(alpha)
    return DualSolution(
        alpha=alpha,
        intercept=_bias(alpha, y, grad, problem.C),
        n_iter=steps,
        gap=_gap(alpha, y, grad, problem.C),
        objective=problem.objective(alpha, grad),
        method=method,
    )


# --------------------------------------------------------------------------------------------------
# Inference: functions on tensors, and the nn.Module that exports to ONNX
# --------------------------------------------------------------------------------------------------


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


class SVMInference(torch.nn.Module):
    """Labels and per-class scores of a fitted :class:`SVC` or :class:`HierarchicalSVC`, as a module.

    ``forward(x)`` with ``x`` of shape (B, F) returns ``(labels, scores)``: int64 labels of shape (B,)
    (indices into the estimator's ``classes_``) and scores of shape (B, n_classes), in the module's
    dtype (float64 by default; the input is cast to it). Binary SVC: scores ``[-f, f]``; one-vs-rest:
    the per-class decision values; hierarchical: :func:`path_scores`, labels by :func:`tree_descent`.
    The support vectors of every decision function are stored once. Exports to ONNX with
    ``tactile_torch._onnx.export_onnx`` (gather/where steps for the tree, no loops in the graph).

    Build it with the estimators' ``to_module()``.
    """

    def __init__(
        self,
        support_vectors: torch.Tensor,
        dual_coef: torch.Tensor,
        intercept: torch.Tensor,
        *,
        kernel: str,
        gamma: float,
        mode: str,
        tree: dict[str, torch.Tensor] | None = None,
        depth: int = 0,
    ) -> None:
        super().__init__()
        self.kernel, self.gamma, self.mode, self.depth = kernel, float(gamma), mode, int(depth)
        self.register_buffer("support_vectors", support_vectors)
        self.register_buffer("dual_coef", dual_coef)
        self.register_buffer("intercept", intercept)
        for name, value in (tree or {}).items():
            self.register_buffer(name, value)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        margins = svm_margins(
            x, self.support_vectors, self.dual_coef, self.intercept, kernel=self.kernel, gamma=self.gamma
        )
        if self.mode == "binary":
            scores = torch.cat([-margins, margins], dim=1)
            return (margins[:, 0] > 0).long(), scores
        if self.mode == "ovr":
            return margins.argmax(dim=1), margins
        labels = tree_descent(margins, self.left, self.right, self.column, self.leaf_label, self.depth)
        return labels, path_scores(margins, self.path_sign)


# --------------------------------------------------------------------------------------------------
# Estimators
# --------------------------------------------------------------------------------------------------

SOLVERS = ("active-set", "smo")


_as_features = as_feature_matrix


def _check_training_data(X: object, y: object) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validate training data; return ``(X, y, classes, y_index)`` (``y_index`` indexes ``classes``)."""
    X = _as_features(X)
    if isinstance(y, torch.Tensor):
        y = y.detach().cpu().numpy()
    y = np.asarray(y)
    if y.ndim != 1:
        raise ValueError(f"y must be a 1-D array of labels, got shape {y.shape}")
    if y.shape[0] != X.shape[0]:
        raise ValueError(f"X and y must have the same number of samples, got {X.shape[0]} and {y.shape[0]}")
    if y.dtype.kind == "f" and not np.isfinite(y).all():
        raise ValueError("y must not contain NaN or inf labels")
    classes, y_index, counts = np.unique(y, return_inverse=True, return_counts=True)
    if classes.shape[0] < 2:
        raise ValueError(f"y must hold at least 2 classes, got only {classes.tolist()}")
    if counts.min() < 2:
        lonely = classes[counts < 2].tolist()
        raise ValueError(
            f"every class needs at least 2 samples (a class seen once cannot be both learnt and "
            f"validated), got 1 sample of class(es) {lonely}"
        )
    return X, y, classes, y_index


def _check_hyper_parameters(est: SVC | HierarchicalSVC) -> None:
    check_positive(est.C, "C")
    if est.kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {est.kernel!r}")
    if not (isinstance(est.gamma, str) and est.gamma == "scale"):
        if isinstance(est.gamma, str):
            raise ValueError(f"gamma must be 'scale' or a float > 0, got {est.gamma!r}")
        check_positive(est.gamma, "gamma")
    check_positive(est.tol, "tol")
    if (
        isinstance(est.max_iter, bool)
        or not isinstance(est.max_iter, numbers.Integral)
        or not (est.max_iter == -1 or est.max_iter > 0)
    ):
        raise ValueError(f"max_iter must be -1 (no limit) or an integer > 0, got {est.max_iter!r}")
    if est.solver not in SOLVERS:
        raise ValueError(f"solver must be one of {SOLVERS}, got {est.solver!r}")
    check_positive(est.cache_size, "cache_size")


def scale_gamma(X: np.ndarray) -> float:
    """Return scikit-learn's ``gamma="scale"``: ``1 / (n_features * X.var())`` (1.0 if ``X.var() == 0``).

    Examples
    --------
    >>> scale_gamma(np.array([[0.0, 2.0], [2.0, 0.0]]))
    0.5
    """
    var = float(np.asarray(X, dtype=np.float64).var())
    return 1.0 / (X.shape[1] * var) if var != 0.0 else 1.0


def _resolve_gamma(gamma: str | float, X: np.ndarray) -> float:
    return scale_gamma(X) if isinstance(gamma, str) else float(gamma)


def _fit_binary(
    X: torch.Tensor, positive: torch.Tensor, params: dict, gamma: float, random_state: RandomState
) -> DualSolution:
    """Fit one binary dual (``positive`` marks the +1 samples); warn if ``max_iter`` stopped it."""
    y = torch.where(positive, 1.0, -1.0).to(torch.float64)
    sol = solve_dual(
        X,
        y,
        params["C"],
        kernel=params["kernel"],
        gamma=gamma,
        tol=params["tol"],
        max_iter=params["max_iter"],
        solver=params["solver"],
        cache_size=params["cache_size"],
        random_state=random_state,
    )
    if sol.gap > params["tol"]:
        from sklearn.exceptions import ConvergenceWarning

        warnings.warn(
            f"the SVM solver stopped at max_iter={params['max_iter']} with gap {sol.gap:.3g} > tol="
            f"{params['tol']}; the solution is not optimal (raise max_iter)",
            ConvergenceWarning,
            stacklevel=3,
        )
    return sol


def _stack_solutions(
    X: np.ndarray, solutions: list[DualSolution], labels: list[torch.Tensor]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Merge binary solutions over one training set into ``(support_, support_vectors_, dual_coef_,
    intercept_)``: support vectors are the union (sorted indices), each stored once."""
    alpha = torch.stack([sol.alpha for sol in solutions])  # (K, n)
    signed = alpha * torch.stack(labels)
    support = torch.nonzero((alpha > 0).any(dim=0)).squeeze(1).numpy()
    return (
        support,
        X[support],
        signed[:, support].numpy(),
        np.array([sol.intercept for sol in solutions], dtype=np.float64),
    )


class _KernelMachine(ClassifierMixin, BaseEstimator):
    """What the two estimators share: hyper-parameter checks, margins, the inference module."""

    def _check_predict_input(self, X: object) -> torch.Tensor:
        check_is_fitted(self, "support_vectors_")
        X = _as_features(X)
        if X.shape[1] != self.n_features_in_:
            raise ValueError(f"X must have {self.n_features_in_} features (as in fit), got shape {X.shape}")
        return torch.from_numpy(X)

    def _margins(self, X: object) -> np.ndarray:
        x = self._check_predict_input(X)
        sv = torch.from_numpy(self.support_vectors_)
        coef = torch.from_numpy(self.dual_coef_)
        intercept = torch.from_numpy(self.intercept_)
        out = torch.empty(x.shape[0], coef.shape[0], dtype=torch.float64)
        # A few rows are a few hundred microseconds of work on one thread; an intra-op parallel
        # region (the support vectors' norms) would wait for a second thread, which on a loaded
        # machine means a scheduler time slice (tens of milliseconds, measured): one thread then.
        n_threads = 1 if x.shape[0] <= _FEW_ROWS else torch.get_num_threads()
        with _torch_threads(n_threads):
            for start in range(0, x.shape[0], _ROW_CHUNK):
                out[start : start + _ROW_CHUNK] = svm_margins(
                    x[start : start + _ROW_CHUNK], sv, coef, intercept, kernel=self.kernel, gamma=self.gamma_
                )
        return out.numpy()

    def _module_tensors(self, dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        check_is_fitted(self, "support_vectors_")
        return (
            torch.tensor(self.support_vectors_, dtype=dtype),
            torch.tensor(self.dual_coef_, dtype=dtype),
            torch.tensor(self.intercept_, dtype=dtype),
        )


class SVC(_KernelMachine):
    """Soft-margin support vector classifier (libsvm's C-SVC) with a torch solver.

    Two classes: one binary SVM, ``f(x) = sum_i dual_coef_[0, i] K(sv_i, x) + intercept_[0]``,
    ``f > 0`` predicts ``classes_[1]`` (as scikit-learn). More classes: one-vs-rest, one binary SVM
    per class against all others, the class with the largest decision value wins (scikit-learn's
    ``SVC`` trains one-vs-one instead). The dual is solved as described in :mod:`tactile_torch.svm`
    and matches libsvm (same problem, same stopping rule, same bias).

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
        Stop when libsvm's maximal violating pair gap is ``<= tol`` (libsvm's ``-e``).
    max_iter : int, default -1
        Cap on solver steps per binary problem (-1: none). Hitting it warns (``ConvergenceWarning``).
    solver : {"active-set", "smo"}, default "active-set"
        The multilevel active-set method, or libsvm's SMO (slow in torch; a reference).
    cache_size : float, default 512
        MiB of kernel columns kept during training.
    random_state : int, numpy or torch Generator, or None
        Order in which samples join the multilevel solver (the optimum does not depend on it).

    Attributes
    ----------
    classes_ : ndarray of shape (n_classes,)
    support_ : ndarray of shape (n_SV,)
        Indices of the support vectors in the training data (of any binary problem), sorted.
    support_vectors_ : ndarray of shape (n_SV, n_features), float64
    dual_coef_ : ndarray of shape (n_problems, n_SV)
        ``y_i a_i`` per binary problem (1 problem for two classes, one per class otherwise).
    intercept_ : ndarray of shape (n_problems,)
    n_iter_ : int or ndarray of shape (n_problems,)
        Solver steps (active-set Newton steps, interior-point iterations and SMO steps).
    objective_ : ndarray of shape (n_problems,)
        Dual objective ``1/2 a^T Q a - sum(a)`` at the solution (libsvm's ``obj``).
    gamma_ : float
        The RBF width used.
    n_features_in_ : int

    Examples
    --------
    >>> from sklearn.datasets import make_moons
    >>> X, y = make_moons(200, noise=0.2, random_state=0)
    >>> model = SVC(C=10.0, random_state=0).fit(X, y)
    >>> float((model.predict(X) == y).mean()) > 0.95
    True

    References
    ----------
    C.-C. Chang, C.-J. Lin, "LIBSVM: a library for support vector machines", ACM TIST 2(3), 2011.
    """

    def __init__(
        self,
        C: float = 1.0,
        kernel: str = "rbf",
        gamma: str | float = "scale",
        tol: float = 1e-3,
        max_iter: int = -1,
        solver: str = "active-set",
        cache_size: float = 512.0,
        random_state: RandomState = None,
    ) -> None:
        self.C = C
        self.kernel = kernel
        self.gamma = gamma
        self.tol = tol
        self.max_iter = max_iter
        self.solver = solver
        self.cache_size = cache_size
        self.random_state = random_state

    def fit(self, X: object, y: object) -> SVC:
        """Fit the SVM on ``X`` (n_samples, n_features) and labels ``y`` (n_samples,); return ``self``.

        Raises ``ValueError`` for fewer than 2 classes, a class with 1 sample, NaN/inf features,
        mismatched lengths and bad hyper-parameters (``C <= 0``, unknown kernel ...). Repeated
        samples and constant features are fine.
        """
        _check_hyper_parameters(self)
        X, _, self.classes_, y_index = _check_training_data(X, y)
        self.n_features_in_ = X.shape[1]
        self.gamma_ = _resolve_gamma(self.gamma, X)
        rng = numpy_rng(self.random_state)
        x = torch.from_numpy(X)
        target = torch.from_numpy(y_index)
        columns = [1] if self.classes_.shape[0] == 2 else range(self.classes_.shape[0])
        params = self.get_params()
        solutions, labels = [], []
        for k in columns:  # one binary problem, or one per class (one-vs-rest)
            positive = target == k
            solutions.append(_fit_binary(x, positive, params, self.gamma_, rng))
            labels.append(torch.where(positive, 1.0, -1.0).to(torch.float64))
        self.support_, self.support_vectors_, self.dual_coef_, self.intercept_ = _stack_solutions(
            X, solutions, labels
        )
        iters = np.array([sol.n_iter for sol in solutions])
        self.n_iter_ = int(iters[0]) if len(solutions) == 1 else iters
        self.objective_ = np.array([sol.objective for sol in solutions])
        return self

    def decision_function(self, X: object) -> np.ndarray:
        """Return the decision values: shape (n,) for two classes (> 0: ``classes_[1]``), else
        (n, n_classes), one per class (one-vs-rest)."""
        margins = self._margins(X)
        return margins[:, 0] if self.classes_.shape[0] == 2 else margins

    def predict(self, X: object) -> np.ndarray:
        """Return the predicted class of each sample, shape (n,)."""
        margins = self._margins(X)
        if self.classes_.shape[0] == 2:
            return self.classes_[(margins[:, 0] > 0).astype(np.int64)]
        return self.classes_[margins.argmax(axis=1)]

    def to_module(self, dtype: torch.dtype = torch.float64) -> SVMInference:
        """Return the inference path as an :class:`SVMInference` module (labels index ``classes_``)."""
        sv, coef, intercept = self._module_tensors(dtype)
        mode = "binary" if self.classes_.shape[0] == 2 else "ovr"
        return SVMInference(sv, coef, intercept, kernel=self.kernel, gamma=self.gamma_, mode=mode)


DECREASE = 100


def split_classes(means: np.ndarray, *, n_init: int = 10, random_state: RandomState = None) -> np.ndarray:
    """Return a boolean mask splitting class mean vectors into two groups by 2-means.

    k-means++ seeding and Lloyd iterations, restarted ``n_init`` times; the split with the smallest
    within-group sum of squares wins. Neither group is ever empty: seeds are two distinct means,
    and should a Lloyd step empty a group, the mean farthest from the other group's centre moves
    into it. If every mean is the same point, the classes are split in two halves in their order.

    Parameters
    ----------
    means : array of shape (K, F), K >= 2
    n_init : int
        Restarts.
    random_state : int, numpy or torch Generator, or None

    Returns
    -------
    bool array of shape (K,): True for the second group. With two classes, ``[False, True]``.

    Examples
    --------
    >>> split_classes(np.array([[0.0], [0.1], [5.0], [5.2]]), random_state=0).tolist()
    [False, False, True, True]
    """
    means = np.asarray(means, dtype=np.float64)
    k = means.shape[0]
    if k == 2:
        return np.array([False, True])
    rng = numpy_rng(random_state)
    best, best_inertia = None, math.inf
    for _ in range(n_init):
        first = int(rng.integers(k))
        d2 = ((means - means[first]) ** 2).sum(1)
        if d2.sum() == 0.0:
            break  # every mean is the same point
        second = int(rng.choice(k, p=d2 / d2.sum()))
        centres = means[[first, second]]
        for _ in range(100):
            dist = ((means[:, None, :] - centres[None, :, :]) ** 2).sum(2)
            group = dist.argmin(1).astype(bool)
            if group.all() or not group.any():
                empty = int(group.all() is np.True_) ^ 1  # the group that lost every member
                other_dist = dist[:, 1 - empty]
                group[int(other_dist.argmax())] = bool(empty)
            new = np.stack([means[~group].mean(0), means[group].mean(0)])
            if np.array_equal(new, centres):
                break
            centres = new
        inertia = float(((means - centres[group.astype(int)]) ** 2).sum())
        if inertia < best_inertia - 1e-12:
            # Orient so that the group holding the first class is the negative one.
            best, best_inertia = (group if not group[0] else ~group), inertia
    if best is None:
        best = np.arange(k) >= k // 2
    return best


@dataclass
class TreeNode:
    """One node of a :class:`HierarchicalSVC` tree.

    Attributes
    ----------
    index : int
        Node number (preorder; the root is 0).
    classes : tuple
        Class labels under this node.
    depth : int
    n_samples : int
        Training samples of those classes.
    svc : SVC or None
        The binary SVM of an internal node (``f > 0``: go to ``right``); None for a leaf.
    left, right : TreeNode or None
        Children on the negative and positive side.
    column : int
        Column of this node in ``HierarchicalSVC.node_decision_function`` (-1 for a leaf).
    """

    index: int
    classes: tuple
    depth: int
    n_samples: int
    svc: SVC | None = None
    left: TreeNode | None = None
    right: TreeNode | None = None
    column: int = -1

    @property
    def is_leaf(self) -> bool:
        return self.svc is None

    def nodes(self) -> list[TreeNode]:
        """Return this node and every node below it, in preorder."""
        out = [self]
        for child in (self.left, self.right):
            if child is not None:
                out += child.nodes()
        return out

    def describe(self, indent: str = "", sign: str = "") -> str:
        """Return the subtree as indented text: ``-`` marks the negative side, ``+`` the positive."""
        names = ", ".join(str(c) for c in self.classes)
        if self.is_leaf:
            return f"{indent}{sign}leaf {self.index}: {names} ({self.n_samples} samples)"
        svc = self.svc
        line = (
            f"{indent}{sign}node {self.index}: {{{names}}} ({self.n_samples} samples, "
            f"{svc.support_.shape[0]} support vectors, {svc.n_iter_} solver steps)"
        )
        inner = indent + ("   " if sign else "")
        return "\n".join([line, self.left.describe(inner, "- "), self.right.describe(inner, "+ ")])

    def __str__(self) -> str:
        return self.describe()


class HierarchicalSVC(_KernelMachine):
    """Hierarchical multi-class SVM (HM-SVM, method 1): a binary tree of binary :class:`SVC`.

    The class mean vectors are split in two groups by 2-means (:func:`split_classes`); a binary SVM
    separates the samples of the two groups (second group positive); each group is split again
    until every leaf holds one class. A sample is classified by descending the tree (margin > 0:
    positive side). Every node uses the same C, kernel and gamma (``"scale"`` is computed once on
    all training data), so prediction computes the kernel against the union of all nodes' support
    vectors once and every node margin with one matrix product.

    Parameters
    ----------
    C, kernel, gamma, tol, max_iter, solver, cache_size
        As in :class:`SVC`, for every node.
    n_init : int, default 10
        Restarts of each 2-means split.
    random_state : int, numpy or torch Generator, or None
        Seeds the 2-means splits and the node solvers.

    Attributes
    ----------
    classes_ : ndarray of shape (n_classes,)
    tree_ : TreeNode
        The root; ``print(model.tree_)`` (or ``model.describe()``) shows the tree.
    support_ : ndarray of shape (n_SV,)
        Indices (in the training data) of the support vectors of any node, sorted.
    support_vectors_ : ndarray of shape (n_SV, n_features)
    dual_coef_ : ndarray of shape (n_nodes, n_SV)
        ``y_i a_i`` of each support vector in each internal node (0 where it is not one of its
        support vectors); rows in preorder of the internal nodes.
    intercept_ : ndarray of shape (n_nodes,)
    n_iter_, objective_ : ndarray of shape (n_nodes,)
        Solver steps and dual objective of each internal node.
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
    The hierarchical SVM of method 1 (DESIGN.md); libsvm for the node problems.
    """

    def __init__(
        self,
        C: float = 1.0,
        kernel: str = "rbf",
        gamma: str | float = "scale",
        tol: float = 1e-3,
        max_iter: int = -1,
        solver: str = "active-set",
        cache_size: float = 512.0,
        n_init: int = 10,
        random_state: RandomState = None,
    ) -> None:
        self.C = C
        self.kernel = kernel
        self.gamma = gamma
        self.tol = tol
        self.max_iter = max_iter
        self.solver = solver
        self.cache_size = cache_size
        self.n_init = n_init
        self.random_state = random_state

    def fit(self, X: object, y: object) -> HierarchicalSVC:
        """Build the tree and fit one binary SVM per internal node; return ``self``.

        Raises ``ValueError`` as :meth:`SVC.fit` does.
        """
        _check_hyper_parameters(self)
        check_positive(self.n_init, "n_init", integer=True)
        X, _, self.classes_, y_index = _check_training_data(X, y)
        self.n_features_in_ = X.shape[1]
        self.gamma_ = _resolve_gamma(self.gamma, X)
        rng = numpy_rng(self.random_state)
        n_classes = self.classes_.shape[0]
        onehot = np.eye(n_classes)[y_index]
        counts = onehot.sum(0)
        means = (onehot.T @ X) / counts[:, None]
        node_params = {
            k: v for k, v in self.get_params().items() if k not in ("n_init", "random_state", "gamma")
        }
        counter = iter(range(2 * n_classes))

        def build(members: np.ndarray, depth: int) -> TreeNode:
            node = TreeNode(
                next(counter), tuple(self.classes_[members].tolist()), depth, int(counts[members].sum())
            )
            if members.shape[0] == 1:
                return node
            positive = members[split_classes(means[members], n_init=self.n_init, random_state=rng)]
            rows = np.flatnonzero(np.isin(y_index, members))
            seed = int(rng.integers(2**31))
            node.svc = SVC(**node_params, gamma=self.gamma_, random_state=seed)
            node.svc.fit(X[rows], np.isin(y_index[rows], positive))
            node.svc.support_ = rows[node.svc.support_]  # indices into the whole training set
            node.left = build(np.setdiff1d(members, positive), depth + 1)
            node.right = build(positive, depth + 1)
            return node

        self.tree_ = build(np.arange(n_classes), 0)
        self._index_tree(X)
        return self

    def _index_tree(self, X: np.ndarray) -> None:
        """Number the internal nodes, merge their support vectors and build the descent tables."""
        nodes = self.tree_.nodes()
        internal = [node for node in nodes if not node.is_leaf]
        for column, node in enumerate(internal):
            node.column = column
        self.support_ = np.unique(np.concatenate([node.svc.support_ for node in internal]))
        self.support_vectors_ = X[self.support_]
        self.dual_coef_ = np.zeros((len(internal), self.support_.shape[0]))
        for node in internal:
            self.dual_coef_[node.column, np.searchsorted(self.support_, node.svc.support_)] = (
                node.svc.dual_coef_[0]
            )
        self.intercept_ = np.array([node.svc.intercept_[0] for node in internal])
        self.n_iter_ = np.array([node.svc.n_iter_ for node in internal])
        self.objective_ = np.array([node.svc.objective_[0] for node in internal])
        self.depth_ = max(node.depth for node in nodes)
        label_of = {c: i for i, c in enumerate(self.classes_.tolist())}
        count = len(nodes)
        self._left = np.arange(count)
        self._right = np.arange(count)
        self._column = np.zeros(count, dtype=np.int64)
        self._leaf_label = np.zeros(count, dtype=np.int64)
        self._path_sign = np.zeros((self.classes_.shape[0], len(internal)), dtype=np.int64)
        for node in nodes:
            if node.is_leaf:
                self._leaf_label[node.index] = label_of[node.classes[0]]
                continue
            self._left[node.index], self._right[node.index] = node.left.index, node.right.index
            self._column[node.index] = node.column
            for child, sign in ((node.left, -1), (node.right, 1)):
                self._path_sign[[label_of[c] for c in child.classes], node.column] = sign

    def _tree_tensors(self) -> dict[str, torch.Tensor]:
        return {
            "left": torch.from_numpy(self._left),
            "right": torch.from_numpy(self._right),
            "column": torch.from_numpy(self._column),
            "leaf_label": torch.from_numpy(self._leaf_label),
            "path_sign": torch.from_numpy(self._path_sign),
        }

    def node_decision_function(self, X: object) -> np.ndarray:
        """Return every internal node's margin, shape (n, n_nodes) (columns: ``TreeNode.column``)."""
        return self._margins(X)

    def decision_function(self, X: object) -> np.ndarray:
        """Return per-class scores, shape (n, n_classes): the smallest signed node margin on the path
        to each class (:func:`path_scores`); ``>= 0`` only for the class descent reaches."""
        margins = torch.from_numpy(self._margins(X))
        return path_scores(margins, torch.from_numpy(self._path_sign)).numpy()

    def predict(self, X: object) -> np.ndarray:
        """Return the class reached by descending the tree, shape (n,)."""
        margins = torch.from_numpy(self._margins(X))
        # The class descent reaches is the argmax of the path scores (a few tensor operations
        # whatever the depth); only a margin of exactly 0 can make them differ, so such rows descend.
        labels = path_scores(margins, torch.from_numpy(self._path_sign)).argmax(dim=1)
        tie = (margins == 0).any(dim=1)
        if bool(tie.any()):
            t = self._tree_tensors()
            labels[tie] = tree_descent(
                margins[tie], t["left"], t["right"], t["column"], t["leaf_label"], self.depth_
            )
        return self.classes_[labels.numpy()]

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
            tree=self._tree_tensors(),
            depth=self.depth_,
        )


__all__ = [
    "KERNELS",
    "SVC",
    "DualSolution",
    "HierarchicalSVC",
    "SVMInference",
    "TreeNode",
    "kernel_matrix",
    "path_scores",
    "scale_gamma",
    "solve_dual",
    "split_classes",
    "svm_margins",
    "tree_descent",
]
