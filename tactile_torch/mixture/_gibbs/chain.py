"""The driver of one chain: its settings in one structure, the initial component draws, and a run of sweeps.

One sweep = ``n_split_merge`` split-merge moves (sequentially allocated, :mod:`.sequential`, or by
restricted Gibbs sampling, :mod:`.split_merge`), Neal's algorithm 8 over every point, a Gibbs update
of every component, then of the hyperparameters; :func:`run_sweeps` runs many of them in compiled
code, saves the partition at the sweeps asked for, and releases the GIL, so that chains run in
parallel threads.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, types

from .allocation import _component_stats, allocate, component_terms, update_components
from .conditionals import component_step
from .hyper import update_hyper
from .linalg import A1, A2, I1, I2, J2, RNG, b1, f8, i8, void
from .sequential import sequential_moves
from .sessions import offset_data, update_offsets
from .split_merge import split_merge_moves
from .state import STATE, copy_state, log_prior_terms


class Settings(NamedTuple):
    """What a sweep does (fixed for a run)."""

    n_aux: int
    """Auxiliary components of algorithm 8."""
    n_split_merge: int
    """Split-merge moves per sweep."""
    n_launch: int
    """Intermediate restricted Gibbs scans of a split-merge launch state."""
    use_lik: bool
    """False: the likelihood is switched off (the chain samples the prior)."""
    fit_alpha: bool
    fit_d: bool
    allocate: bool
    """False: the partition stays fixed (component and hyperparameter updates only)."""
    d_low: float
    """Lower end of the support of d (``max(0, -alpha)`` when alpha is fixed and negative)."""
    w_min: float
    """Floor on the eigenvalues of W."""
    burn_in: int
    """Sweeps before which the MAP sample is not tracked."""
    near: float
    """Share of split-merge pairs drawn among a point's nearest neighbours (0: uniform pairs)."""
    sequential: bool
    """True: sequentially-allocated merge-split moves; False: restricted Gibbs (Jain & Neal)."""
    refresh: int
    """Algorithm 8's auxiliary means are drawn afresh every ``refresh`` points (1: every point)."""
    fit_lambda: bool = False
    """Sample the variance ratio of the session effects (``sc[5] > 0``); False keeps it fixed."""


SETTINGS = types.NamedTuple((i8, i8, i8, b1, b1, b1, b1, f8, f8, i8, f8, b1, i8, b1), Settings)
"""numba type of :class:`Settings`."""

TRACE_NAMES = ("n_clusters", "alpha", "discount", "beta", "log_posterior", "session_scale", "offset_variance")
"""Columns of the per-sweep trace written by :func:`run_sweeps`."""


@njit(void(A2, STATE, b1, RNG), cache=True)
def init_components(X, st, use_lik, rng):
    """Draw every active component's (S, mu) from its conditional given its points, centred on their mean."""
    D = X.shape[1]
    K = st.ist[0]
    means = np.zeros((K, D))
    scats = np.zeros((K, D, D))
    me = np.zeros((K, D))
    se = np.zeros((K, D, D))
    Es = np.zeros(K)
    pens = np.zeros(K)
    _component_stats(X, st.z, st.pos, K, st.cnt, st.act, means, scats)
    component_terms(X, st, K, means, scats, me, se, Es, pens)
    Rxi = st.R @ st.xi
    zero_mean = np.zeros(D)
    zero_scat = np.zeros((D, D))
    for t in range(K):
        j = st.act[t]
        if use_lik:
            st.ldet[j] = component_step(
                st.cnt[j], Es[t], me[t], se[t], me[t].copy(), st.sc[2], st.W, st.R, Rxi, True,
                st.mu[j], st.L[j], 0.0, st.sc[3], rng,
            )[1]  # fmt: skip
        else:
            st.ldet[j] = component_step(
                0,
                0.0,
                zero_mean,
                zero_scat,
                zero_mean,
                st.sc[2],
                st.W,
                st.R,
                Rxi,
                True,
                st.mu[j],
                st.L[j],
                0.0,
                1.0,
                rng,
            )[1]


@njit(void(A2, STATE, SETTINGS, RNG, i8, i8, A2, I1, STATE, A1, I2, I1, J2), cache=True, nogil=True)
def run_sweeps(X, st, cfg, rng, start, count, trace, counters, best, best_val, nbr, snaps, labels):
    """Run sweeps ``start .. start + count - 1`` on ``st``; write their rows of ``trace`` (see TRACE_NAMES).

    ``nbr`` (n, k): each point's k nearest neighbours, from which a share ``cfg.near`` of the
    split-merge pairs is drawn. ``snaps`` (increasing sweep numbers): after sweep ``snaps[r]`` the
    partition is written to ``labels[r]`` (int32, components numbered 0 .. K-1 in slot order).

    ``counters`` accumulates the split-merge statistics; from sweep ``cfg.burn_in`` on, a state whose
    log joint density exceeds ``best_val[0]`` is copied into ``best`` (the MAP sample). With session
    effects (``sc[5] > 0``) the moves, the allocation and the component updates see ``X`` minus the
    sessions' offsets, which are updated after the allocation (:func:`~.sessions.update_offsets`).
    """
    n = X.shape[0]
    relabel = np.zeros(st.cnt.shape[0], dtype=np.int32)
    r = 0
    while r < snaps.shape[0] and snaps[r] < start:
        r += 1
    sessions = st.sc[5] > 0.0
    Xc = offset_data(X, st) if sessions else X  # what the kernels see: X minus the sessions' offsets
    for s in range(start, start + count):
        if cfg.allocate:
            if cfg.n_split_merge > 0:
                if cfg.sequential:
                    sequential_moves(cfg.n_split_merge, Xc, st, cfg.use_lik, rng, counters, nbr, cfg.near)
                else:
                    split_merge_moves(
                        cfg.n_split_merge, Xc, st, cfg.n_launch, cfg.use_lik, rng, counters, nbr, cfg.near
                    )
            allocate(Xc, st, cfg.n_aux, cfg.use_lik, rng, cfg.refresh)
        if sessions and cfg.fit_lambda:
            update_offsets(X, st, rng, cfg.use_lik)
            Xc = offset_data(X, st)
        loglik = update_components(Xc, st, cfg.use_lik, rng, cfg.fit_lambda)
        update_hyper(st, n, cfg.fit_alpha, cfg.fit_d, cfg.d_low, cfg.w_min, rng)
        lj = loglik + log_prior_terms(st)
        trace[s, 0] = st.ist[0]
        trace[s, 1] = st.sc[0]
        trace[s, 2] = st.sc[1]
        trace[s, 3] = st.sc[2]
        trace[s, 4] = lj
        trace[s, 5] = st.sc[5]
        trace[s, 6] = st.sc[6]
        if s >= cfg.burn_in and lj > best_val[0]:
            best_val[0] = lj
            copy_state(st, best)
        if r < snaps.shape[0] and snaps[r] == s:
            for t in range(st.ist[0]):
                relabel[st.act[t]] = t
            for i in range(n):
                labels[r, i] = relabel[st.z[i]]
            r += 1
