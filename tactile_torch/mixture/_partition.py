"""The posterior over partitions: prior of K, posterior similarity matrix, and the point estimate that
minimises the posterior expected loss (Variation of Information or Binder's loss).

A Gibbs sampler leaves a list of partitions; component numbers mean nothing across them (label
switching), so no average of labels exists. What does exist (Wade & Ghahramani 2018):

- the *posterior similarity matrix* ``P[i, j]`` = share of saved partitions in which points ``i`` and
  ``j`` share a component;
- a *point estimate*: the partition ``c`` that minimises the posterior expected loss
  ``E[loss(c, c') | data]``, estimated by the mean over the saved partitions ``c'``. For Variation of
  Information this is computed exactly over the saved partitions (not through Wade & Ghahramani's
  lower bound); Binder's loss with equal costs depends on ``P`` only.

The search is Wade & Ghahramani's greedy search: start from the best of several candidates (the MAP
sample, saved samples, an average-linkage cut of ``1 - P``), then move single points to the cluster
(or a new one) that lowers the expected loss most, and merge pairs of clusters when that lowers it,
until nothing improves. It finds a local minimum; the candidates make it a good one.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

from ..exceptions import InputTypeError

_I1 = types.Array(types.int64, 1, "C")
_I2 = types.Array(types.int64, 2, "C")
_A2 = types.Array(types.float64, 2, "C")
_f8, _i8 = types.float64, types.int64
_LOG2 = math.log(2.0)


def pitman_yor_prior_k(n: int, alpha: float, discount: float) -> np.ndarray:
    """Return the prior distribution of the number of clusters K of n points under a Pitman-Yor prior.

    Chinese-restaurant recursion: customer ``m + 1`` opens a new table with probability
    ``(alpha + K d) / (alpha + m)``. Entry ``k`` of the result (length ``n + 1``) is ``P(K = k)``.

    Examples
    --------
    >>> p = pitman_yor_prior_k(3, 1.0, 0.0)  # DP, alpha = 1: P(K=1) = 1/3, P(K=3) = 1/6
    >>> [round(float(v), 4) for v in p]
    [0.0, 0.3333, 0.5, 0.1667]
    """
    if not (0.0 <= discount < 1.0) or not alpha > -discount:
        raise ValueError(
            f"need 0 <= discount < 1 and alpha > -discount, got alpha={alpha}, discount={discount}"
        )
    p = np.zeros(n + 1)
    p[1] = 1.0
    k = np.arange(n + 1)
    for m in range(1, n):
        new = np.zeros(n + 1)
        new[1:] = p[:-1] * (alpha + k[:-1] * discount) / (alpha + m)
        p = p * (m - k * discount) / (alpha + m) + new
    return p


def _compact(labels: np.ndarray) -> np.ndarray:
    return np.unique(np.asarray(labels), return_inverse=True)[1].astype(np.int64).reshape(-1)


def _check_samples(samples: object) -> np.ndarray:
    arr = np.asarray(samples)
    if arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"samples must have shape (n_samples, n_points) with both >= 1, got {arr.shape}")
    if not np.issubdtype(arr.dtype, np.integer):
        raise InputTypeError(f"samples must hold integer labels, got dtype {arr.dtype}")
    return np.ascontiguousarray(np.stack([_compact(row) for row in arr]))


# --------------------------------------------------------------------------------------------------
# compiled kernels
# --------------------------------------------------------------------------------------------------
@njit(_A2(_I2), cache=True)
def _similarity(samples):
    """Co-clustering frequencies of compact label rows: ``P[i, j]`` = share of rows with z_i == z_j."""
    S, n = samples.shape
    P = np.zeros((n, n))
    order = np.empty(n, dtype=np.int64)
    for s in range(S):
        z = samples[s]
        K = 0
        for i in range(n):
            K = max(K, z[i] + 1)
        start = np.zeros(K + 1, dtype=np.int64)
        for i in range(n):
            start[z[i] + 1] += 1
        for k in range(K):
            start[k + 1] += start[k]
        fill = start[:K].copy()
        for i in range(n):
            order[fill[z[i]]] = i
            fill[z[i]] += 1
        for k in range(K):
            for a in range(start[k], start[k + 1]):
                ia = order[a]
                for b in range(start[k], start[k + 1]):
                    P[ia, order[b]] += 1.0
    return P / S


@njit(cache=True)
def _xlogx_table(n):
    g = np.zeros(n + 2)
    for x in range(1, n + 2):
        g[x] = x * math.log(x)
    return g


@njit(_f8(_I2, _I1), cache=True)
def _vi_objective(samples, c):
    """Mean VI (nats) between compact labels ``c`` and every row of ``samples``."""
    S, n = samples.shape
    g = _xlogx_table(n)
    K = c.max() + 1
    own = np.zeros(K, dtype=np.int64)
    for i in range(n):
        own[c[i]] += 1
    h_c = 0.0
    for k in range(K):
        h_c += g[own[k]]
    total = 0.0
    for s in range(S):
        z = samples[s]
        L = z.max() + 1
        table = np.zeros((K, L), dtype=np.int64)
        other = np.zeros(L, dtype=np.int64)
        for i in range(n):
            table[c[i], z[i]] += 1
            other[z[i]] += 1
        joint = 0.0
        for k in range(K):
            for m in range(L):
                joint += g[table[k, m]]
        h_s = 0.0
        for m in range(L):
            h_s += g[other[m]]
        total += h_c + h_s - 2.0 * joint
    return total / (S * n)


@njit(cache=True)
def _relabel(c):
    """Labels numbered 0 .. K-1 in order of first appearance."""
    n = c.shape[0]
    m = c.max() + 1
    new = -np.ones(m, dtype=np.int64)
    out = np.empty(n, dtype=np.int64)
    k = 0
    for i in range(n):
        if new[c[i]] < 0:
            new[c[i]] = k
            k += 1
        out[i] = new[c[i]]
    return out


@njit(_f8(_A2, _I1), cache=True)
def _binder_objective(P, c):
    """Mean over point pairs of Binder's loss with equal costs: expected share of misclassified pairs."""
    n = c.shape[0]
    if n < 2:
        return 0.0
    total = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            total += (1.0 - P[i, j]) if c[i] == c[j] else P[i, j]
    return total / (0.5 * n * (n - 1))


# The greedy search is one loop for both losses; what depends on the loss is how a point's cost of
# joining each cluster and the gain of merging two clusters are computed. VI keeps, per cluster, the
# counts N[k, s, m] of its points in component m of saved sample s; Binder's loss needs only P.


@njit(cache=True)
def _take_out(vi, i, a, c, N, samples, P, h):
    """Take point ``i`` out of cluster ``a``: VI, out of its counts; Binder, fill ``h[k]`` = sum of ``1 - 2 P[i, j]`` over k's points."""
    if vi:
        for s in range(samples.shape[0]):
            N[a, s, samples[s, i]] -= 1
    else:
        h[:] = 0.0
        for j in range(P.shape[0]):
            if j != i:
                h[c[j]] += 1.0 - 2.0 * P[i, j]


@njit(cache=True)
def _put_in(vi, i, k, N, samples):
    """Put point ``i`` into cluster ``k``'s counts (VI; Binder keeps none)."""
    if vi:
        for s in range(samples.shape[0]):
            N[k, s, samples[s, i]] += 1


@njit(cache=True)
def _move_cost(vi, k, i, size, N, samples, g, two_s, h):
    """Change of the loss when point ``i`` (taken out) joins cluster ``k``; 0 for an empty cluster."""
    if size[k] == 0:
        return 0.0
    if not vi:
        return h[k]
    acc = 0.0
    for s in range(samples.shape[0]):
        m = N[k, s, samples[s, i]]
        acc += g[m + 1] - g[m]
    return g[size[k] + 1] - g[size[k]] - two_s * acc


@njit(cache=True)
def _merge_gains(vi, c, size, N, g, two_s, P):
    """(K, K) change of the loss when clusters a < b (both non-empty) merge; K = last non-empty cluster + 1."""
    K = 0
    for k in range(size.shape[0]):
        if size[k] > 0:
            K = k + 1
    gain = np.zeros((K, K))
    if vi:
        for a in range(K):
            if size[a] == 0:
                continue
            for b in range(a + 1, K):
                if size[b] == 0:
                    continue
                d = g[size[a] + size[b]] - g[size[a]] - g[size[b]]
                acc = 0.0
                for s in range(N.shape[1]):
                    for m in range(N.shape[2]):
                        x, y = N[a, s, m], N[b, s, m]
                        if x > 0 and y > 0:
                            acc += g[x + y] - g[x] - g[y]
                d -= two_s * acc
                gain[a, b] = d
    else:
        n = c.shape[0]
        for i in range(n):
            for j in range(i + 1, n):
                if c[i] != c[j]:
                    a, b = min(c[i], c[j]), max(c[i], c[j])
                    gain[a, b] += 1.0 - 2.0 * P[i, j]
    return gain


@njit(types.Tuple((_I1, _f8))(_I2, _A2, _I1, _i8, types.boolean), cache=True)
def _greedy_search(samples, P, c0, max_rounds, vi):
    """Greedy minimisation of the expected loss from compact labels ``c0``; return (labels, loss).

    ``vi``: the mean VI (nats) to the rows of ``samples`` (``P`` unused); else Binder's loss from
    the similarity matrix ``P`` (``samples`` unused). Rounds of single-point moves (to the
    cheapest cluster, or a new one when every move costs) until none moves, then the best merge.
    """
    n = c0.shape[0]
    c = c0.copy()
    g = _xlogx_table(n)
    S = samples.shape[0] if vi else 0
    two_s = 2.0 / S if vi else 0.0
    if vi:
        L = samples.max() + 1  # every saved sample's clusters, and room for new clusters of c
        cap = min(n, max(2 * L, c0.max() + 1) + 10)
    else:
        L = 0
        cap = n
    N = np.zeros((cap if vi else 0, S, L), dtype=np.int32)
    size = np.zeros(cap, dtype=np.int64)
    h = np.zeros(cap)
    for i in range(n):
        size[c[i]] += 1
        _put_in(vi, i, c[i], N, samples)
    for _round in range(max_rounds):
        changed = False
        for _sweep in range(100):
            moved = 0
            for i in range(n):
                a = c[i]
                size[a] -= 1
                _take_out(vi, i, a, c, N, samples, P, h)
                # stay (or, if alone, a cluster of its own: it costs 0), else the cheapest move
                best, best_cost = a, _move_cost(vi, a, i, size, N, samples, g, two_s, h)
                empty = -1
                for k in range(cap):
                    if size[k] == 0:
                        if empty < 0 and k != a:
                            empty = k
                    elif k != a:
                        cost = _move_cost(vi, k, i, size, N, samples, g, two_s, h)
                        if cost < best_cost - 1e-12:
                            best, best_cost = k, cost
                if best_cost > 1e-12 and size[a] > 0 and empty >= 0:
                    best = empty
                c[i] = best
                size[best] += 1
                _put_in(vi, i, best, N, samples)
                if best != a:
                    moved += 1
            if moved == 0:
                break
            changed = True
        # merge the pair of clusters whose union lowers the loss most
        gain = _merge_gains(vi, c, size, N, g, two_s, P)
        best_gain = -1e-12
        ba, bb = -1, -1
        for a in range(gain.shape[0]):
            if size[a] == 0:
                continue
            for b in range(a + 1, gain.shape[0]):
                if size[b] > 0 and gain[a, b] < best_gain:
                    best_gain, ba, bb = gain[a, b], a, b
        if ba >= 0:
            for i in range(n):
                if c[i] == bb:
                    c[i] = ba
            size[ba] += size[bb]
            size[bb] = 0
            if vi:
                for s in range(S):
                    for m in range(L):
                        N[ba, s, m] += N[bb, s, m]
                        N[bb, s, m] = 0
            changed = True
        if not changed:
            break
    # (VI returns its cluster numbers as they are, Binder's renumbered: the callers' order of
    # equal-sized clusters depends on it)
    if vi:
        return c, _vi_objective(samples, _relabel(c))
    c = _relabel(c)
    return c, _binder_objective(P, c)


# --------------------------------------------------------------------------------------------------
# public functions
# --------------------------------------------------------------------------------------------------
def posterior_similarity(samples: object) -> np.ndarray:
    """Return the posterior similarity matrix of saved partitions: ``P[i, j]`` = share with ``z_i == z_j``.

    Parameters
    ----------
    samples : array-like of int, shape (n_samples, n_points)
        One partition per row (any integer labels; only equality within a row matters).

    Returns
    -------
    ndarray of shape (n_points, n_points)
        Symmetric, ones on the diagonal.

    Examples
    --------
    >>> posterior_similarity([[0, 0, 1], [3, 4, 4]]).tolist()
    [[1.0, 0.5, 0.0], [0.5, 1.0, 0.5], [0.0, 0.5, 1.0]]
    """
    return _similarity(_check_samples(samples))


def variation_of_information(a: object, b: object) -> float:
    """Return the Variation of Information between two partitions of the same points, in bits.

    ``VI(a, b) = H(a) + H(b) - 2 I(a, b)`` (Meilă 2007): 0 for the same partition, at most
    ``log2 n``.

    >>> round(variation_of_information([0, 0, 1, 1], [0, 0, 0, 0]), 12)  # one bit: which half
    1.0
    """
    a, b = np.asarray(a), np.asarray(b)
    if a.ndim != 1 or a.shape != b.shape or a.size == 0:
        raise ValueError(
            f"a and b must be label vectors of the same length >= 1, got {a.shape} and {b.shape}"
        )
    return float(_vi_objective(_check_samples(b[None]), _compact(a))) / _LOG2


def expected_loss(
    labels: object, samples: object, loss: str = "vi", *, similarity: np.ndarray | None = None
) -> float:
    """Return the posterior expected loss of ``labels`` estimated by the mean over ``samples``.

    ``loss="vi"``: mean Variation of Information in bits; ``"binder"``: Binder's loss with equal
    costs as the expected share of misclassified point pairs (``1 -`` expected pairwise accuracy).
    """
    c = _compact(labels)
    if loss == "vi":
        return float(_vi_objective(_check_samples(samples), c)) / _LOG2
    if loss == "binder":
        P = posterior_similarity(samples) if similarity is None else similarity
        return float(_binder_objective(np.ascontiguousarray(P, dtype=np.float64), c))
    raise ValueError(f"loss must be 'vi' or 'binder', got {loss!r}")


def minimize_expected_loss(
    samples: object,
    loss: str = "vi",
    *,
    candidates: list[np.ndarray] | None = None,
    similarity: np.ndarray | None = None,
    max_rounds: int = 50,
    n_draws: int = 20,
) -> tuple[np.ndarray, float]:
    """Return the partition minimising the posterior expected loss over ``samples``, and that loss.

    Parameters
    ----------
    samples : array-like of int, shape (n_samples, n_points)
        Saved partitions (post burn-in).
    loss : {"vi", "binder"}
        Variation of Information (exact mean over the samples, Wade & Ghahramani 2018) or Binder's
        loss with equal costs (a function of the similarity matrix).
    candidates : list of label vectors, optional
        Extra starting partitions (e.g. the MAP sample).
    similarity : ndarray (n, n), optional
        The posterior similarity matrix, if already computed.
    max_rounds : int
        Rounds of (point moves, then one merge) at most.
    n_draws : int
        Saved samples (evenly spaced) tried as starting partitions, besides the average-linkage cut
        of ``1 - similarity`` at the posterior median number of clusters.

    Returns
    -------
    labels : ndarray of shape (n_points,)
        Numbered 0 .. K-1 by decreasing cluster size.
    loss : float
        Its expected loss (VI in bits, or Binder's as a share of pairs).
    """
    from scipy.cluster.hierarchy import fcluster, linkage
    from scipy.spatial.distance import squareform

    S = _check_samples(samples)
    n = S.shape[1]
    if loss not in ("vi", "binder"):
        raise ValueError(f"loss must be 'vi' or 'binder', got {loss!r}")
    P = _similarity(S) if similarity is None else np.ascontiguousarray(similarity, dtype=np.float64)
    starts = [_compact(c) for c in (candidates or [])]
    starts += [S[i].copy() for i in np.unique(np.linspace(0, len(S) - 1, min(n_draws, len(S))).astype(int))]
    if n > 2:
        k = int(np.median(S.max(axis=1) + 1))
        tree = linkage(squareform(1.0 - P, checks=False), method="average")
        starts.append(_compact(fcluster(tree, t=k, criterion="maxclust")))
    score = (lambda c: _vi_objective(S, c)) if loss == "vi" else (lambda c: _binder_objective(P, c))
    ranked = sorted(starts, key=score)[:2]
    best_c, best_v = None, np.inf
    for c0 in ranked:
        c, v = _greedy_search(S, P, c0, max_rounds, loss == "vi")
        if v < best_v:
            best_c, best_v = c, v
    sizes = np.bincount(best_c)
    order = np.argsort(-sizes, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    labels = rank[best_c]
    return labels, float(best_v / _LOG2 if loss == "vi" else best_v)
