"""The state of one chain in one structure, the bookkeeping of its component slots, and its log density.

:class:`ChainState` holds every array the kernels update in place (``cap = n + 1`` component slots;
the active ones listed in ``act[:ist[0]]``):

- ``z[i]``: slot of point ``i``; ``cnt[j]``: number of points in slot ``j``;
- ``mu[j]`` component mean, ``L[j]`` lower Cholesky factor of its *precision* ``S_j = L_j L_j^T``,
  ``ldet[j] = log|S_j|`` (kept from the log-domain draw, so that it stays finite when a factor underflows);
- ``pos[j]`` position of slot ``j`` in ``act`` (-1 if free); ``fre[:ist[1]]`` stack of free slots;
- ``ist = [K, number of free slots]``; ``sc = [alpha, d, beta, zeta, gamma, lambda, omega]``: the
  Pitman-Yor parameters, beta, the power ``zeta`` of the likelihood (1: the standard posterior; < 1
  the coarsened posterior), ``gamma`` (0: Pitman-Yor prior on the partition; > 0: the mixture of
  finite mixtures, whose weights are ``n_j + gamma``, stored as ``d = -gamma``), ``lambda``, the
  variance ratio of the session-by-component effects, and ``omega``, the variance of the session
  offsets (both 0: no sessions);
- ``sess[i]``: session of point ``i`` (0 .. S - 1; all 0 without sessions); ``off`` (S, D): the
  sessions' offsets. With ``lambda > 0`` a point of session s in component j is ``mu_j + c_s +
  b_(s,j) + e``, ``c_s ~ N(0, omega I)``, ``b_(s,j) ~ N(0, lambda S_j^{-1})``, ``e ~ N(0, S_j^{-1})``;
  the effects ``b`` are integrated out, the offsets ``c`` sampled (:mod:`.sessions`);
- ``lv`` (n + 2,): ``log V_n(t)`` of the mixture of finite mixtures for t = 0 .. n + 1 (unused
  under the Pitman-Yor prior);
- ``xi`` (D,), ``R``, ``W`` (D, D) and ``GR``/``GW`` their lower Cholesky factors.

It is a ``NamedTuple`` of arrays, which numba passes to compiled code as one argument (its fields
are mutable arrays, so the kernels update the state in place).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, types

from .conditionals import base_logpdf
from .densities import _log_prior_alpha, _log_prior_beta, log_eppf, log_eppf_mfm, wishart_logpdf
from .linalg import A1, A2, A3, I1, LOG2PI, _logdet_chol, _quad_rows
from .sessions import group_quadratics, log_prior_lambda, log_prior_offsets, offset_data


class ChainState(NamedTuple):
    """Every variable of one chain (see the module docstring for the layout)."""

    z: np.ndarray
    cnt: np.ndarray
    mu: np.ndarray
    L: np.ndarray
    ldet: np.ndarray
    act: np.ndarray
    pos: np.ndarray
    fre: np.ndarray
    ist: np.ndarray
    sc: np.ndarray
    xi: np.ndarray
    R: np.ndarray
    GR: np.ndarray
    W: np.ndarray
    GW: np.ndarray
    lv: np.ndarray
    sess: np.ndarray
    off: np.ndarray


STATE = types.NamedTuple((I1, I1, A2, A3, A1, I1, I1, I1, I1, A1, A1, A2, A2, A2, A2, A1, I1, A2), ChainState)
"""numba type of :class:`ChainState`."""


def new_state(
    z: np.ndarray,
    D: int,
    alpha: float,
    discount: float,
    zeta: float = 1.0,
    gamma: float = 0.0,
    lv: np.ndarray | None = None,
    sessions: np.ndarray | None = None,
    lam: float = 0.0,
) -> ChainState:
    """Return a state with the partition ``z`` (labels ``0 .. K-1``), identity hyperparameters, beta = D.

    ``gamma > 0`` selects the mixture of finite mixtures (then ``discount`` must be ``-gamma`` and
    ``lv`` its ``log V_n(t)``, shape (n + 2,)); ``zeta`` is the power of the likelihood.
    ``sessions`` (n,) int, 0 .. S - 1, with ``lam > 0``: the session of every point and the
    starting variance ratio of the session effects (``lam = 0``: no session effects); the offsets
    start at 0 with ``omega = lam``. Component parameters are left at zero: the caller draws them
    (``init_components``).
    """
    n = z.shape[0]
    cap = n + 1
    K = int(z.max()) + 1
    cnt = np.zeros(cap, dtype=np.int64)
    np.add.at(cnt, z, 1)
    act = np.zeros(cap, dtype=np.int64)
    act[:K] = np.arange(K)
    pos = -np.ones(cap, dtype=np.int64)
    pos[:K] = np.arange(K)
    fre = np.zeros(cap, dtype=np.int64)
    free_slots = np.arange(cap - 1, K - 1, -1)
    fre[: free_slots.size] = free_slots
    return ChainState(
        z=np.ascontiguousarray(z, dtype=np.int64),
        cnt=cnt,
        mu=np.zeros((cap, D)),
        L=np.zeros((cap, D, D)),
        ldet=np.zeros(cap),
        act=act,
        pos=pos,
        fre=fre,
        ist=np.array([K, free_slots.size], dtype=np.int64),
        sc=np.array([alpha, discount, float(D), zeta, gamma, lam, lam]),
        xi=np.zeros(D),
        R=np.eye(D),
        GR=np.eye(D),
        W=np.eye(D),
        GW=np.eye(D),
        lv=np.zeros(n + 2) if lv is None else np.ascontiguousarray(lv, dtype=np.float64),
        sess=np.zeros(n, dtype=np.int64)
        if sessions is None
        else np.ascontiguousarray(sessions, dtype=np.int64),
        off=np.zeros((1 if sessions is None else int(np.max(sessions, initial=0)) + 1, D)),
    )


@njit(cache=True)
def copy_state(src, dst):
    """Copy every array of ``src`` into ``dst`` (same shapes)."""
    dst.z[:] = src.z
    dst.cnt[:] = src.cnt
    dst.mu[:] = src.mu
    dst.L[:] = src.L
    dst.ldet[:] = src.ldet
    dst.act[:] = src.act
    dst.pos[:] = src.pos
    dst.fre[:] = src.fre
    dst.ist[:] = src.ist
    dst.sc[:] = src.sc
    dst.xi[:] = src.xi
    dst.R[:] = src.R
    dst.GR[:] = src.GR
    dst.W[:] = src.W
    dst.GW[:] = src.GW
    dst.lv[:] = src.lv
    dst.sess[:] = src.sess
    dst.off[:] = src.off


# --------------------------------------------------------------------------------------------------
# bookkeeping of component slots
# --------------------------------------------------------------------------------------------------
@njit(cache=True)
def activate(j, st):
    """Mark the free slot ``j`` (already popped) active."""
    ist = st.ist
    st.act[ist[0]] = j
    st.pos[j] = ist[0]
    ist[0] += 1


@njit(cache=True)
def deactivate(j, st):
    """Free the active slot ``j``."""
    ist, act, pos = st.ist, st.act, st.pos
    p = pos[j]
    last = act[ist[0] - 1]
    act[p] = last
    pos[last] = p
    pos[j] = -1
    ist[0] -= 1
    st.fre[ist[1]] = j
    ist[1] += 1


@njit(cache=True)
def pop_free(st):
    """Take a free slot off the stack and return it."""
    st.ist[1] -= 1
    return st.fre[st.ist[1]]


# --------------------------------------------------------------------------------------------------
# log joint density (for the MAP sample)
# --------------------------------------------------------------------------------------------------
@njit(cache=True)
def log_joint(X, st, use_lik):
    """Unnormalised log density of the whole state (labels, components, hyperparameters) given X.

    With session effects (``sc[5] = lambda > 0``) the likelihood is the one with the effects
    integrated out (:mod:`.sessions`): per (component, session) group of ``m`` points with residual
    sum ``r``, ``- D/2 log(1 + lambda m) + lambda / (2 (1 + lambda m)) r^T S r`` on top of the
    plain terms.
    """
    z, L, mu, ldet = st.z, st.L, st.mu, st.ldet
    zeta, lam = st.sc[3], st.sc[5]
    if lam > 0.0:
        X = offset_data(X, st)
    n, D = X.shape
    out = 0.0
    if use_lik:
        half = 0.5 * D * LOG2PI
        for i in range(n):
            j = z[i]
            out += zeta * (0.5 * ldet[j] - half - 0.5 * _quad_rows(L, j, mu, j, X, i))
        if lam > 0.0:  # each group's sum of residuals r = m (mean - mu): r^T S r = m^2 q
            ms, qs, P = group_quadratics(X, st, st.ist[0])
            for p in range(P):
                m = ms[p]
                out += -0.5 * D * math.log1p(lam * m) + 0.5 * lam * m * m / (1.0 + lam * m) * qs[p]
    return out + log_prior_terms(st)


@njit(cache=True)
def log_prior_terms(st):
    """The log joint density of the state without the likelihood: partition, components, hyperparameters."""
    cnt, mu, L, ldet, act = st.cnt, st.mu, st.L, st.ldet, st.act
    K = st.ist[0]
    D = mu.shape[1]
    n = st.z.shape[0]
    alpha, d, beta = st.sc[0], st.sc[1], st.sc[2]
    out = 0.0
    if st.sc[4] > 0.0:
        out += log_eppf_mfm(cnt, act, K, st.sc[4], st.lv)
    else:
        out += log_eppf(cnt, act, K, n, alpha, d)
    ldet_w = _logdet_chol(st.GW)
    for t in range(K):
        j = act[t]
        out += base_logpdf(mu[j], L[j], ldet[j], beta, st.W, ldet_w, st.xi, st.GR)
    eye_d = np.zeros((D, D))
    for a in range(D):
        eye_d[a, a] = D
    xx = 0.0
    for a in range(D):
        xx += st.xi[a] * st.xi[a]
    out += -0.5 * D * LOG2PI - 0.5 * xx
    out += wishart_logpdf(st.GR, _logdet_chol(st.GR), D, eye_d, D * math.log(D))
    out += wishart_logpdf(st.GW, ldet_w, D, eye_d, D * math.log(D))
    out += _log_prior_beta(beta, D)
    if alpha > 0.0:
        out += _log_prior_alpha(alpha)
    if st.sc[5] > 0.0:
        out += log_prior_lambda(st.sc[5]) + log_prior_offsets(st.off, st.sc[6])
    return out
