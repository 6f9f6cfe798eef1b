"""Compiled (numba) kernels of the SVM solver and of prediction; see :mod:`tactile_torch.svm.solver`.

:func:`smo` is libsvm's C-SVC solver (``Solver::Solve`` of libsvm 3.x as scikit-learn ships it): SMO
with second-order working-set selection (WSS3), shrinking with gradient reconstruction, and an LRU
cache of kernel rows stored as float32 (libsvm's ``Qfloat``). Positions are swapped as libsvm swaps
them (shrunk variables move to the end, the cache swaps with them), so that the loops run over a
contiguous prefix. With libsvm's shrinking interval (1000) it takes libsvm's steps exactly (tested:
same iterations, same ``rho``); the estimators shrink every 100 iterations, which on large problems
keeps the kernel rows short sooner. One addition: a warm start (``alpha``, with or without its
gradient); the C-path of the batched model selection scales a solution to the next C (``alpha``,
``G + 1`` and ``G_bar`` scale with C). Each variable has its own upper bound ``C_i = C w_i`` (libsvm's
``get_C(i)``: class weights, and the sample weights of scikit-learn's patched libsvm); ``w = 1``
gives the plain problem bit for bit.

Kernel rows are computed from a transposed copy of the features (the dot products vectorise over
the samples) and the squared norms, ``exp(-gamma (|x_i|^2 + |x_j|^2 - 2 x_i . x_j))`` as libsvm, or
read from a precomputed float32 kernel matrix (one per gamma, shared by every fold, C value and
tree node of a grid search). Every kernel here is compiled eagerly with an explicit signature,
cached on disk and runs without the GIL, so that Python threads run several problems at once.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

f8, f4, i8, b1, void = types.float64, types.float32, types.int64, types.boolean, types.void
A1, A2 = types.Array(f8, 1, "C"), types.Array(f8, 2, "C")
F1, F2 = types.Array(f4, 1, "C"), types.Array(f4, 2, "C")
I1 = types.Array(i8, 1, "C")
# Inputs that are only read are typed read-only: a writable array passes too, and read-only ones
# (a memory-mapped or unpickled model, a read-only user array) need no copy.
R1, R2 = types.Array(f8, 1, "C", readonly=True), types.Array(f8, 2, "C", readonly=True)
RF2 = types.Array(f4, 2, "C", readonly=True)
RI1 = types.Array(i8, 1, "C", readonly=True)

RBF, LINEAR, PRECOMPUTED = 0, 1, 2
"""Kernel codes: computed RBF, computed linear, or read from a precomputed float32 kernel matrix."""

LOWER, UPPER, FREE = 0, 1, 2
TAU = 1e-12
_INF = np.inf


# --------------------------------------------------------------------------------------------------
# kernel rows and the LRU cache
# --------------------------------------------------------------------------------------------------


# exp by Cody-Waite range reduction and a degree-12 Taylor polynomial, in three branch-free loops
# that vectorise (numba's math.exp calls the scalar libm one, twice as slow here): within 2.3e-16
# relative of libm for the kernel's arguments (<= 0; below -700 the result is taken at -700, ~1e-304).
_LOG2E = 1.4426950408889634
_LN2_HI, _LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10
_ROUND = 6755399441055744.0  # 1.5 * 2**52: adding it rounds to an integer held in the low bits
_ROUND_BITS = np.array([_ROUND]).view(np.int64)[0]


@njit(void(A1, A1), cache=True, nogil=True)
def _exp_inplace(v, scratch):
    """``v[t] = exp(v[t])`` for every ``t`` (``v[t] <= 0``); ``scratch`` at least as long as ``v``.

    Loops here run over ``range(n)`` of views: numba cannot prove an index of ``range(start, stop)``
    non-negative, and its wrap-around check stops the loop from vectorising.
    """
    n = v.shape[0]
    for t in range(n):
        x = max(v[t], -700.0)
        k = x * _LOG2E + _ROUND
        m = k - _ROUND
        r = x - m * _LN2_HI - m * _LN2_LO
        p = 1.0 / 479001600.0
        p = p * r + 1.0 / 39916800.0
        p = p * r + 1.0 / 3628800.0
        p = p * r + 1.0 / 362880.0
        p = p * r + 1.0 / 40320.0
        p = p * r + 1.0 / 5040.0
        p = p * r + 1.0 / 720.0
        p = p * r + 1.0 / 120.0
        p = p * r + 1.0 / 24.0
        p = p * r + 1.0 / 6.0
        p = p * r + 0.5
        p = p * r + 1.0
        v[t] = p * r + 1.0
        scratch[t] = k
    bits = scratch.view(np.int64)
    for t in range(n):  # 2**m from the integer's bits
        bits[t] = (bits[t] - _ROUND_BITS + 1023) << 52
    for t in range(n):
        v[t] *= scratch[t]


# Rows of the per-position arrays (positions move when the solver swaps them, as in libsvm).
Y, GRAD, HBAR, ALPHA, QD, SQ, BOUND = 0, 1, 2, 3, 4, 5, 6  # float64 rows of ``fs``
GIDX, ASET, SLOT, FILLED = 0, 1, 2, 3  # int64 rows of ``ist``
STATUS, UP, LOW = 0, 1, 2  # int8 rows of ``cs``
I2 = types.Array(i8, 2, "C")
C2 = types.Array(types.int8, 2, "C")
# Kernel context (kind, gamma, transposed features, precomputed kernel, scratch) and cache context
# (float32 kernel rows, LRU links with a sentinel at the end, free slots, number of free slots).
KC = types.Tuple((i8, f8, A2, RF2, A1, A1))
CC = types.Tuple((F2, I2, I1, I1))

# The solver works with ``g = -y G`` (G: libsvm's gradient) and kernel rows ``K`` rather than
# ``Q = y y^T K``: both of libsvm's selection loops then read the same expressions for either label
# (the scans vectorise), and every quantity equals libsvm's bit for bit (a product by y = +-1 is exact).
# ``hbar = -y G_bar``.


@njit(void(i8, F1, i8, i8, KC, A2, I2), cache=True, nogil=True)
def _fill_row(i, row, start, end, kc, fs, ist):
    """Write ``K(x_i, x_t)`` into ``row[t]`` for ``start <= t < end`` (loops over views: see
    :func:`_exp_inplace`)."""
    kind, gamma, XT, K, tmp, scratch = kc
    m = end - start
    out = row[start:end]
    if kind == PRECOMPUTED:
        kr = K[ist[GIDX, i]]
        cols = ist[GIDX, start:end]
        for t in range(m):
            out[t] = kr[cols[t]]
        return
    acc = tmp[start:end]
    for t in range(m):
        acc[t] = 0.0
    for f in range(XT.shape[0]):
        xf = XT[f, i]
        xrow = XT[f, start:end]
        for t in range(m):
            acc[t] += xf * xrow[t]
    if kind == RBF:
        sq = fs[SQ, start:end]
        si = fs[SQ, i]
        for t in range(m):
            acc[t] = -gamma * (si + sq[t] - 2.0 * acc[t])
        _exp_inplace(acc, scratch)
    for t in range(m):
        out[t] = acc[t]


@njit(void(i8, I2), cache=True, nogil=True)
def _unlink(h, links):
    prev, nxt = links[0], links[1]
    prev[nxt[h]] = prev[h]
    nxt[prev[h]] = nxt[h]


@njit(void(i8, I2), cache=True, nogil=True)
def _link_last(h, links):
    prev, nxt = links[0], links[1]
    end = prev.shape[0] - 1  # the sentinel
    nxt[h] = end
    prev[h] = prev[end]
    nxt[prev[end]] = h
    prev[end] = h


@njit(i8(i8, i8, CC, KC, A2, I2), cache=True, nogil=True)
def _row(i, length, cc, kc, fs, ist):
    """Return the cache slot holding ``K(x_i, x_t)`` for ``t < length``, computing what is missing
    (libsvm's get_Q). The least recently used row goes when no slot is free; the cache holds at
    least two rows, so the row of the previous request survives this one."""
    cache, links, free, nfree = cc
    slot_of, filled_of = ist[SLOT], ist[FILLED]
    s = slot_of[i]
    if s >= 0:
        _unlink(i, links)
        filled = filled_of[i]
    else:
        if nfree[0] > 0:
            nfree[0] -= 1
            s = free[nfree[0]]
        else:
            old = links[1, links.shape[1] - 1]
            _unlink(old, links)
            s = slot_of[old]
            slot_of[old] = -1
            filled_of[old] = 0
        slot_of[i] = s
        filled = 0
    if filled < length:
        _fill_row(i, cache[s], filled, length, kc, fs, ist)
        filled_of[i] = length
    _link_last(i, links)
    return s


@njit(void(i8, i8, A2, I2, C2, A2, CC), cache=True, nogil=True)
def _swap(i, j, fs, ist, cs, XT, cc):
    """Swap positions ``i`` and ``j`` everywhere, the cache included (libsvm's swap_index)."""
    if i == j:
        return
    cache, links, free, nfree = cc
    for r in range(fs.shape[0]):
        fs[r, i], fs[r, j] = fs[r, j], fs[r, i]
    for r in range(cs.shape[0]):
        cs[r, i], cs[r, j] = cs[r, j], cs[r, i]
    for f in range(XT.shape[0]):
        XT[f, i], XT[f, j] = XT[f, j], XT[f, i]
    slot_of, filled_of = ist[SLOT], ist[FILLED]
    if slot_of[i] >= 0:
        _unlink(i, links)
    if slot_of[j] >= 0:
        _unlink(j, links)
    for r in range(ist.shape[0]):
        ist[r, i], ist[r, j] = ist[r, j], ist[r, i]
    if slot_of[i] >= 0:
        _link_last(i, links)
    if slot_of[j] >= 0:
        _link_last(j, links)
    lo, hi = min(i, j), max(i, j)
    end = links.shape[1] - 1
    h = links[1, end]
    while h != end:
        after = links[1, h]
        if filled_of[h] > lo:
            if filled_of[h] > hi:
                row = cache[slot_of[h]]
                row[lo], row[hi] = row[hi], row[lo]
            else:  # the row covers one of the two: give it up
                _unlink(h, links)
                free[nfree[0]] = slot_of[h]
                nfree[0] += 1
                slot_of[h] = -1
                filled_of[h] = 0
        h = after


@njit(void(i8, A2, C2), cache=True, nogil=True)
def _set_status(t, fs, cs):
    """Status of ``alpha_t`` (against its bound ``C_t``) and its membership of libsvm's sets I_up and
    I_low."""
    a, positive = fs[ALPHA, t], fs[Y, t] > 0.0
    if a >= fs[BOUND, t]:
        status = UPPER
    elif a <= 0.0:
        status = LOWER
    else:
        status = FREE
    cs[STATUS, t] = status
    cs[UP, t] = (positive and status != UPPER) or (not positive and status != LOWER)
    cs[LOW, t] = (positive and status != LOWER) or (not positive and status != UPPER)


@njit(f8(i8, A2, C2), cache=True, nogil=True)
def _rho(active, fs, cs):
    """libsvm's calculate_rho over the first ``active`` positions (``y G = -g``)."""
    ub, lb, total, n_free = _INF, -_INF, 0.0, 0
    y, g, status = fs[Y], fs[GRAD], cs[STATUS]
    for t in range(active):
        yG = -g[t]
        if status[t] == UPPER:
            if y[t] < 0:
                ub = min(ub, yG)
            else:
                lb = max(lb, yG)
        elif status[t] == LOWER:
            if y[t] > 0:
                ub = min(ub, yG)
            else:
                lb = max(lb, yG)
        else:
            n_free += 1
            total += yG
    if n_free > 0:
        return total / n_free
    return (ub + lb) / 2.0


@njit(types.UniTuple(i8, 2)(i8, f8, A2, I2, C2, CC, KC), cache=True, nogil=True, fastmath={"nnan"})
def _select(active, tol, fs, ist, cs, cc, kc):
    """libsvm's WSS3 over the active positions; ``(-1, -1)`` when the pair gap is below ``tol``.

    Each arg-max is two passes: the extreme value (a reduction that vectorises), then the last
    position holding it (libsvm keeps the last of equal candidates), scanning backwards.
    """
    g, qd = fs[GRAD], fs[QD]
    up, low = cs[UP], cs[LOW]
    g_max = -_INF
    for t in range(active):
        g_max = max(g_max, g[t] if up[t] else -_INF)
    i = -1
    for t in range(active - 1, -1, -1):
        if up[t] and g[t] == g_max:
            i = t
            break
    if i < 0:
        return -1, -1
    row = cc[0][_row(i, active, cc, kc, fs, ist)]
    qi = qd[i]
    g_max2, best = -_INF, _INF
    for t in range(active):
        lo = low[t] != 0
        g_max2 = max(g_max2, -g[t] if lo else -_INF)
        diff = g_max - g[t]
        quad = qi + qd[t] - 2.0 * row[t]
        obj = -(diff * diff) / (quad if quad > 0.0 else TAU)
        best = min(best, obj if lo and diff > 0.0 else _INF)
    if g_max + g_max2 < tol or best == _INF:
        return -1, -1
    for t in range(active - 1, -1, -1):
        if low[t]:
            diff = g_max - g[t]
            if diff > 0.0:
                quad = qi + qd[t] - 2.0 * row[t]
                if -(diff * diff) / (quad if quad > 0.0 else TAU) == best:
                    return i, t
    return -1, -1  # pragma: no cover - the scan finds the minimum it just computed


@njit(void(i8, i8, i8, A2, I2, C2, CC, KC), cache=True, nogil=True)
def _update(i, j, active, fs, ist, cs, cc, kc):
    """libsvm's two-variable step on ``(i, j)`` and the updates of ``g``, the statuses and ``hbar``."""
    cache = cc[0]
    l = fs.shape[1]
    ki = cache[_row(i, active, cc, kc, fs, ist)]
    kj = cache[_row(j, active, cc, kc, fs, ist)]
    y, g, hbar, alpha, qd = fs[Y], fs[GRAD], fs[HBAR], fs[ALPHA], fs[QD]
    yi, yj = y[i], y[j]
    ci, cj = fs[BOUND, i], fs[BOUND, j]
    old_i, old_j = alpha[i], alpha[j]
    ai, aj = old_i, old_j
    quad = qd[i] + qd[j] - 2.0 * ki[j]
    if quad <= 0.0:
        quad = TAU
    if yi != yj:
        delta = (yi * g[i] + yj * g[j]) / quad  # (-G_i - G_j) / quad
        diff = ai - aj
        ai += delta
        aj += delta
        if diff > 0.0:
            if aj < 0.0:
                aj = 0.0
                ai = diff
        elif ai < 0.0:
            ai = 0.0
            aj = -diff
        if diff > ci - cj:
            if ai > ci:
                ai = ci
                aj = ci - diff
        elif aj > cj:
            aj = cj
            ai = cj + diff
    else:
        delta = (yj * g[j] - yi * g[i]) / quad  # (G_i - G_j) / quad
        total = ai + aj
        ai -= delta
        aj += delta
        if total > ci:
            if ai > ci:
                ai = ci
                aj = total - ci
        elif aj < 0.0:
            aj = 0.0
            ai = total
        if total > cj:
            if aj > cj:
                aj = cj
                ai = total - cj
        elif ai < 0.0:
            ai = 0.0
            aj = total
    alpha[i], alpha[j] = ai, aj
    si, sj = yi * (ai - old_i), yj * (aj - old_j)
    for t in range(active):
        g[t] -= si * ki[t] + sj * kj[t]
    upper_i, upper_j = cs[STATUS, i] == UPPER, cs[STATUS, j] == UPPER
    _set_status(i, fs, cs)
    _set_status(j, fs, cs)
    if upper_i != (cs[STATUS, i] == UPPER):
        row = cache[_row(i, l, cc, kc, fs, ist)]
        step = -ci * yi if upper_i else ci * yi
        for t in range(l):
            hbar[t] -= step * row[t]
    if upper_j != (cs[STATUS, j] == UPPER):
        row = cache[_row(j, l, cc, kc, fs, ist)]
        step = -cj * yj if upper_j else cj * yj
        for t in range(l):
            hbar[t] -= step * row[t]


@njit(void(i8, i8, A2, I2, C2, CC, KC), cache=True, nogil=True)
def _reconstruct(lo, hi, fs, ist, cs, cc, kc):
    """Recompute ``g`` at positions ``lo <= t < hi`` from ``hbar`` and the free variables (all
    below ``lo``), in libsvm's cheaper order of the two loops."""
    if lo >= hi:
        return
    cache = cc[0]
    y, g, hbar, alpha = fs[Y], fs[GRAD], fs[HBAR], fs[ALPHA]
    status = cs[STATUS]
    m = hi - lo
    g_new, hbar_new, y_new = g[lo:hi], hbar[lo:hi], y[lo:hi]
    for t in range(m):
        g_new[t] = hbar_new[t] + y_new[t]  # G = G_bar + p, p = -1
    n_free = 0
    for t in range(lo):
        if status[t] == FREE:
            n_free += 1
    if n_free * hi > 2 * lo * (hi - lo):
        for i in range(lo, hi):
            row = cache[_row(i, lo, cc, kc, fs, ist)]
            for t in range(lo):
                if status[t] == FREE:
                    g[i] -= alpha[t] * y[t] * row[t]
    else:
        for t in range(lo):
            if status[t] == FREE:
                row = cache[_row(t, hi, cc, kc, fs, ist)][lo:hi]
                coef = alpha[t] * y[t]
                for i in range(m):
                    g_new[i] -= coef * row[i]


@njit(b1(i8, f8, f8, A2, C2), cache=True, nogil=True)
def _be_shrunk(t, g_max1, g_max2, fs, cs):
    """libsvm's be_shrunk: a bounded variable that no violating pair can include."""
    if cs[STATUS, t] == FREE:
        return False
    g = fs[GRAD, t]
    if cs[UP, t]:  # in I_up only
        return -g > g_max2
    return g > g_max1  # in I_low only


@njit(types.Tuple((i8, b1))(i8, b1, f8, A2, I2, C2, A2, CC, KC), cache=True, nogil=True)
def _shrink(active, unshrink, tol, fs, ist, cs, XT, cc, kc):
    """libsvm's do_shrinking; return the new ``(active, unshrink)``."""
    g, up, low = fs[GRAD], cs[UP], cs[LOW]
    g_max1, g_max2 = -_INF, -_INF
    for t in range(active):
        if up[t] and g[t] >= g_max1:
            g_max1 = g[t]
        if low[t] and -g[t] >= g_max2:
            g_max2 = -g[t]
    if not unshrink and g_max1 + g_max2 <= tol * 10.0:
        unshrink = True
        _reconstruct(active, fs.shape[1], fs, ist, cs, cc, kc)
        active = fs.shape[1]
    t = 0
    while t < active:
        if _be_shrunk(t, g_max1, g_max2, fs, cs):
            active -= 1
            while active > t:
                if not _be_shrunk(active, g_max1, g_max2, fs, cs):
                    _swap(t, active, fs, ist, cs, XT, cc)
                    break
                active -= 1
        t += 1
    return active, unshrink


_SMO_SIG = types.Tuple((i8, f8, f8, b1))(R2, R1, RF2, RI1, R1, R1, f8, f8, i8, f8, i8, i8, i8, A1, A1, A1, i8)


@njit(_SMO_SIG, cache=True, nogil=True)
def smo(
    XT_in,
    sq_in,
    K,
    gidx_in,
    y_in,
    w_in,
    C,
    gamma,
    kind,
    tol,
    max_iter,
    shrink_every,
    cache_bytes,
    alpha_io,
    G_io,
    Gbar_io,
    warm,
):
    """Solve ``min 1/2 a^T Q a - sum(a)``, ``0 <= a_i <= C w_i``, ``y^T a = 0``; return ``(iterations, rho,
    objective, converged)`` and write ``alpha``, ``G = Q a - 1`` and ``G_bar`` (libsvm's gradient
    of the variables at C) into the ``*_io`` arrays, in the order of ``gidx_in``.

    ``XT_in`` (F, N) and ``sq_in`` (N,): transposed features and squared norms of every sample the
    problem may index (RBF, linear); ``K`` (N, N): the float32 kernel matrix (precomputed kernel);
    ``gidx_in`` (l,): the problem's samples (indices into those); ``y_in`` (l,): labels +1/-1;
    ``w_in`` (l,): the factors ``w_i > 0`` of each variable's upper bound.
    ``warm``: 0 cold start; 1 ``alpha``, ``G`` and ``G_bar`` given; 2 ``alpha`` given (gradient
    computed). Stops at libsvm's maximal violating pair gap ``< tol`` or after ``max_iter``
    iterations (``-1``: no cap). Shrinks every ``shrink_every`` iterations (libsvm: 1000; 0: never);
    ``cache_bytes`` bounds the kernel-row cache (at least two rows).
    """
    l = y_in.shape[0]
    fs = np.zeros((7, l))
    ist = np.empty((4, l), dtype=np.int64)
    cs = np.empty((3, l), dtype=np.int8)
    y = fs[Y]
    for t in range(l):
        y[t] = y_in[t]
        fs[BOUND, t] = C * w_in[t]
        ist[GIDX, t] = gidx_in[t]
        ist[ASET, t] = t
        ist[SLOT, t] = -1
        ist[FILLED, t] = 0
    gidx, sq, qd = ist[GIDX], fs[SQ], fs[QD]
    if kind == PRECOMPUTED:
        XT = np.empty((0, l))
        for t in range(l):
            qd[t] = K[gidx[t], gidx[t]]
    else:
        XT = np.empty((XT_in.shape[0], l))
        for f in range(XT_in.shape[0]):
            src, dst = XT_in[f], XT[f]
            for t in range(l):
                dst[t] = src[gidx[t]]
        for t in range(l):
            sq[t] = sq_in[gidx[t]]
            qd[t] = 1.0 if kind == RBF else sq[t]
    alpha = fs[ALPHA]
    if warm > 0:
        for t in range(l):
            alpha[t] = alpha_io[t]
    for t in range(l):
        _set_status(t, fs, cs)

    n_slots = max(2, min(l, cache_bytes // (4 * l)))
    cc = (
        np.empty((n_slots, l), dtype=np.float32),
        np.full((2, l + 1), l, dtype=np.int64),
        np.arange(n_slots)[::-1].copy(),
        np.array([n_slots]),
    )
    kc = (kind, gamma, XT, K, np.empty(l), np.empty(l))

    g, hbar = fs[GRAD], fs[HBAR]
    if warm == 1:
        for t in range(l):
            g[t] = -y[t] * G_io[t]
            hbar[t] = -y[t] * Gbar_io[t]
    else:
        for t in range(l):
            g[t] = y[t]  # G = -1
        if warm == 2:
            for i in range(l):
                if cs[STATUS, i] != LOWER:
                    row = cc[0][_row(i, l, cc, kc, fs, ist)]
                    coef = alpha[i] * y[i]
                    for t in range(l):
                        g[t] -= coef * row[t]
                    if cs[STATUS, i] == UPPER:
                        for t in range(l):
                            hbar[t] -= fs[BOUND, i] * y[i] * row[t]

    active = l
    unshrink = False
    n_iter = 0
    every = shrink_every if shrink_every > 0 else l + 1
    counter = min(l, every) + 1
    converged = False
    while max_iter < 0 or n_iter < max_iter:
        counter -= 1
        if counter == 0:
            counter = min(l, every)
            if shrink_every > 0:
                active, unshrink = _shrink(active, unshrink, tol, fs, ist, cs, XT, cc, kc)
        i, j = _select(active, tol, fs, ist, cs, cc, kc)
        if i < 0:
            _reconstruct(active, l, fs, ist, cs, cc, kc)
            active = l
            i, j = _select(active, tol, fs, ist, cs, cc, kc)
            if i < 0:
                converged = True
                break
            counter = 1  # shrink at the next iteration
        n_iter += 1
        _update(i, j, active, fs, ist, cs, cc, kc)

    if active < l:  # stopped by max_iter: make g exact everywhere
        _reconstruct(active, l, fs, ist, cs, cc, kc)
        active = l
    rho = _rho(active, fs, cs)
    obj = 0.0
    for t in range(l):
        obj += alpha[t] * (-y[t] * g[t] - 1.0)
    aset = ist[ASET]
    for t in range(l):
        alpha_io[aset[t]] = alpha[t]
        G_io[aset[t]] = -y[t] * g[t]
        Gbar_io[aset[t]] = -y[t] * hbar[t]
    return n_iter, rho, obj / 2.0, converged


@njit(
    void(
        R2,
        R1,
        RF2,
        RI1,
        R1,
        R1,
        RI1,
        RI1,
        f8,
        f8,
        i8,
        f8,
        i8,
        i8,
        i8,
        R1,
        R1,
        R1,
        f8,
        A1,
        A1,
        A1,
        I1,
        A1,
        A1,
        types.Array(b1, 1, "C"),
    ),
    cache=True,
    nogil=True,
)
def smo_many(
    XT,
    sq,
    K,
    rows,
    y,
    weight,
    offsets,
    which,
    C,
    gamma,
    kind,
    tol,
    max_iter,
    shrink_every,
    cache_bytes,
    alpha_prev,
    grad_prev,
    grad_bar_prev,
    ratio,
    alpha,
    grad,
    grad_bar,
    n_iter,
    rho,
    objective,
    converged,
):
    """Run :func:`smo` on the problems ``which`` of a set stored end to end.

    Problem ``p`` is ``rows[offsets[p]:offsets[p + 1]]`` with labels ``y[...]`` and bound factors
    ``weight[...]`` (the upper bound of a variable is ``C * weight``); its solution goes
    to the same slice of ``alpha``, ``grad`` and ``grad_bar``, its iterations, ``rho``, objective
    and convergence to ``n_iter[p]``, ``rho[p]``, ``objective[p]``, ``converged[p]``. ``ratio > 0``
    warm-starts each problem from its solution at ``C / ratio`` in the ``*_prev`` arrays (``alpha``
    and ``G_bar`` scale with C, and so does ``G + 1``); ``ratio = 0``: cold starts. One call for
    many small problems (one-vs-one pairs, tree nodes) spares a Python round trip per problem.
    """
    warm = 1 if ratio > 0.0 else 0
    for k in range(which.shape[0]):
        p = which[k]
        a, b = offsets[p], offsets[p + 1]
        for t in range(a, b):
            if warm:
                alpha[t] = alpha_prev[t] * ratio
                grad[t] = (grad_prev[t] + 1.0) * ratio - 1.0
                grad_bar[t] = grad_bar_prev[t] * ratio
            else:
                alpha[t] = 0.0
        n_iter[p], rho[p], objective[p], converged[p] = smo(
            XT,
            sq,
            K,
            rows[a:b],
            y[a:b],
            weight[a:b],
            C,
            gamma,
            kind,
            tol,
            max_iter,
            shrink_every,
            cache_bytes,
            alpha[a:b],
            grad[a:b],
            grad_bar[a:b],
            warm,
        )


# --------------------------------------------------------------------------------------------------
# kernel blocks and decision values
# --------------------------------------------------------------------------------------------------


@njit(void(R2, R1, R2, R1, f8, i8, F2, i8, i8), cache=True, nogil=True)
def kernel_block(XA, sqA, XBT, sqB, gamma, kind, out, start, stop):
    """Write ``K(XA[a], XB[b])`` as float32 into ``out[a, b]`` for ``start <= a < stop``.

    Computed exactly as the solver computes a kernel row (same products, same order), so a
    precomputed kernel gives the solver the same float32 values as its own rows.
    """
    nb = XBT.shape[1]
    tmp = np.empty(nb)
    scratch = np.empty(nb)
    for a in range(start, stop):
        for b in range(nb):
            tmp[b] = 0.0
        for f in range(XBT.shape[0]):
            xf = XA[a, f]
            xrow = XBT[f]
            for b in range(nb):
                tmp[b] += xf * xrow[b]
        if kind == RBF:
            sa = sqA[a]
            for b in range(nb):
                tmp[b] = -gamma * (sa + sqB[b] - 2.0 * tmp[b])
            _exp_inplace(tmp, scratch)
        orow = out[a]
        for b in range(nb):
            orow[b] = tmp[b]


@njit(void(R1, R2, R1, f8, i8, A1, A1), cache=True, nogil=True)
def _kernel_to_support(x, SVT, sv_sq, gamma, kind, k, scratch):
    """``k[s] = K(x, sv_s)``, the RBF distance clamped at 0 as :func:`tactile_torch.svm.kernel_matrix`."""
    n_sv = SVT.shape[1]
    for s in range(n_sv):
        k[s] = 0.0
    xs = 0.0
    for f in range(SVT.shape[0]):
        xf = x[f]
        xs += xf * xf
        svrow = SVT[f]
        for s in range(n_sv):
            k[s] += xf * svrow[s]
    if kind == RBF:
        for s in range(n_sv):
            k[s] = -gamma * max(xs + sv_sq[s] - 2.0 * k[s], 0.0)
        _exp_inplace(k, scratch)


@njit(void(R2, R2, R1, R2, R1, f8, i8, A2), cache=True, nogil=True)
def decision_dense(X, SVT, sv_sq, coef, intercept, gamma, kind, out):
    """``out[b, p] = sum_s coef[s, p] K(X[b], sv_s) + intercept[p]`` (binary, one-vs-rest, tree)."""
    n_sv, n_out = coef.shape
    k, scratch = np.empty(n_sv), np.empty(n_sv)
    for b in range(X.shape[0]):
        _kernel_to_support(X[b], SVT, sv_sq, gamma, kind, k, scratch)
        orow = out[b]
        for p in range(n_out):
            orow[p] = intercept[p]
        for s in range(n_sv):
            ks = k[s]
            crow = coef[s]
            for p in range(n_out):
                orow[p] += ks * crow[p]


@njit(void(R2, R2, R1, R2, RI1, R1, f8, i8, A2), cache=True, nogil=True)
def decision_ovo(X, SVT, sv_sq, coef, starts, intercept, gamma, kind, out):
    """libsvm's one-vs-one decision values: ``out[b, p]`` for the pairs ``(i, j)``, ``i < j``, in
    order. The support vectors are grouped by class (``starts``: class boundaries) and ``coef`` is
    the transpose of libsvm's ``dual_coef_`` (shape (n_SV, K - 1)): the coefficient of a class-``i``
    support vector in the pair ``(i, j)`` is in column ``j - 1``, that of a class-``j`` one in column
    ``i``. Each class's terms for its ``K - 1`` pairs are summed at once (a vector update per
    support vector), then each pair adds its two classes' sums."""
    n_class = starts.shape[0] - 1
    n_sv, n_other = coef.shape
    k, scratch = np.empty(n_sv), np.empty(n_sv)
    terms = np.empty((n_class, n_other))
    for b in range(X.shape[0]):
        _kernel_to_support(X[b], SVT, sv_sq, gamma, kind, k, scratch)
        for c in range(n_class):
            row = terms[c]
            for q in range(n_other):
                row[q] = 0.0
            for s in range(starts[c], starts[c + 1]):
                ks = k[s]
                crow = coef[s]
                for q in range(n_other):
                    row[q] += ks * crow[q]
        p = 0
        for i in range(n_class):
            for j in range(i + 1, n_class):
                out[b, p] = terms[i, j - 1] + terms[j, i] + intercept[p]
                p += 1


@njit(void(R2, i8, I1, A2), cache=True, nogil=True)
def ovo_votes(dec, n_class, labels, scores):
    """From pairwise decisions ``dec`` (B, P): libsvm's labels (a pair ``(i, j)`` votes for ``i`` if
    its decision is > 0, else for ``j``; most votes wins, the first class on ties) and scikit-learn's
    one-vs-rest-shaped scores (votes with decision >= 0 for ``i``, plus each class's summed
    decisions ``s`` squashed to ``s / (3 (|s| + 1))``)."""
    votes = np.empty(n_class)
    for b in range(dec.shape[0]):
        for c in range(n_class):
            votes[c] = 0.0
            scores[b, c] = 0.0
        row = scores[b]
        p = 0
        for i in range(n_class):
            for j in range(i + 1, n_class):
                d = dec[b, p]
                if d > 0:
                    votes[i] += 1.0
                else:
                    votes[j] += 1.0
                row[i] += d
                row[j] -= d
                p += 1
        best = 0
        for c in range(1, n_class):
            if votes[c] > votes[best]:
                best = c
        labels[b] = best
        for c in range(n_class):
            row[c] /= 3.0 * (abs(row[c]) + 1.0)
        p = 0
        for i in range(n_class):
            for j in range(i + 1, n_class):
                if dec[b, p] >= 0:
                    row[i] += 1.0
                else:
                    row[j] += 1.0
                p += 1
