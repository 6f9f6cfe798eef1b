"""The chains of a :class:`PitmanYorGMM` fit: run in parallel threads, with their traces and saved samples.

Importing this module loads the compiled sampler (:mod:`tactile_torch.mixture._gibbs`); the estimator
imports it at its first fit, so that importing :mod:`tactile_torch.mixture` does not.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import numpy as np

from . import _gibbs as g
from ._diagnostics import ESS_TARGET as _ESS_TARGET
from ._diagnostics import RHAT_THRESHOLD, ess_bulk, rhat

# n_iter="auto": first run, snapshot spacing (sweeps), and the targets.
AUTO_FIRST, AUTO_EVERY = 1000, 10
# n_iter="auto": each round multiplies the run by 1.2 x 400 / ESS of K, clamped to [1.25, 2], rounded up
# to a multiple of AUTO_ROUND sweeps; the burn-in is the first 1 / AUTO_BURN_IN_SHARE of every chain.
AUTO_MARGIN, AUTO_GROWTH, AUTO_ROUND, AUTO_BURN_IN_SHARE = 1.2, (1.25, 2.0), 500, 8
# At most this many saved partitions per chain are kept (the point estimate uses 200 in all).
_KEEP_PER_CHAIN = 200
# Nearest neighbours of a point among which the near split-merge pairs are drawn.
N_NEIGHBOURS = 5


def neighbours(Xw: np.ndarray, k: int = N_NEIGHBOURS) -> np.ndarray:
    """Return the ``k`` nearest neighbours (n, min(k, n - 1)) int64 of every row of ``Xw`` (itself excluded)."""
    from scipy.spatial import cKDTree

    n = Xw.shape[0]
    k = min(k, n - 1)
    if k < 1:
        return np.zeros((n, 0), dtype=np.int64)
    _, idx = cKDTree(Xw).query(Xw, k=k + 1)
    out = np.empty((n, k), dtype=np.int64)
    for i in range(n):  # drop the point itself (not always first when points coincide)
        row = idx[i][idx[i] != i]
        out[i] = row[:k]
    return out


def auto_burn_in(n_iter: int, burn_in: int) -> int:
    """Burn-in of an ``n_iter="auto"`` run of ``n_iter`` sweeps: its first eighth, at least ``burn_in``."""
    return max(int(burn_in), int(n_iter) // AUTO_BURN_IN_SHARE)


def next_length(current: int, ess: float, max_iter: int) -> int:
    """Sweeps per chain of the next ``n_iter="auto"`` round, from the bulk ESS of K after ``current`` sweeps.

    ESS grows about linearly with the run, so ``current x 400 / ESS`` would just reach the target;
    the margin 1.2 covers the noise of the estimate, the clamp keeps a round from being too short to
    matter (x 1.25) or overshooting a poor early estimate (x 2). Rounded up to a multiple of 500
    sweeps, at most ``max_iter``.
    """
    lo, hi = AUTO_GROWTH
    factor = AUTO_MARGIN * _ESS_TARGET / ess if np.isfinite(ess) and ess > 0 else hi
    target = current * min(hi, max(lo, factor))
    return int(min(max_iter, AUTO_ROUND * math.ceil(target / AUTO_ROUND)))


def diagnostics(runs: list[dict], burn_in: int, quantities: tuple[str, ...]) -> dict[str, float]:
    """Bulk ESS of K and R-hat of each of ``quantities`` after ``burn_in`` sweeps (R-hat NaN with one chain)."""
    trace = np.stack([r["trace"][burn_in:] for r in runs])
    k = trace[:, :, g.TRACE_NAMES.index("n_clusters")]
    if np.ptp(k) == 0:  # every chain on the same K throughout: nothing left to mix
        out = {"ess": float(k.size)}
    else:
        out = {"ess": float(ess_bulk(k))}
    for name in quantities:
        out[name] = float(rhat(trace[:, :, g.TRACE_NAMES.index(name)])) if len(runs) > 1 else 1.0
    return out


def targets_met(runs: list[dict], burn_in: int, quantities: tuple[str, ...]) -> bool:
    """Whether R-hat < 1.01 for every quantity and bulk ESS of K >= 400 after ``burn_in`` sweeps."""
    return _met(diagnostics(runs, burn_in, quantities), quantities)


def _met(diag: dict[str, float], quantities: tuple[str, ...]) -> bool:
    k_ok = np.isfinite(diag["ess"]) and diag["ess"] >= _ESS_TARGET
    return bool(k_ok) and all(np.isfinite(diag[q]) and diag[q] < RHAT_THRESHOLD for q in quantities)


def keep_after_burn_in(runs: list[dict], sweeps: np.ndarray, sample_from: int, burn_in: int) -> np.ndarray:
    """Drop the saved partitions and samples before ``burn_in`` and thin to ``_KEEP_PER_CHAIN``; return the kept sweeps."""
    after = np.flatnonzero(sweeps >= burn_in)
    pick = after[np.unique(np.linspace(0, after.size - 1, min(after.size, _KEEP_PER_CHAIN)).astype(int))]
    sampled = np.flatnonzero(sweeps >= sample_from)  # the snapshots whose components were saved
    position = {int(s): i for i, s in enumerate(sampled)}
    for r in runs:
        r["labels"] = r["labels"][pick]
        r["samples"] = [r["samples"][position[int(i)]] for i in pick]
    return sweeps[pick]


@contextmanager
def progress_pool(n_chains: int, total: int, workers: int, progress: bool) -> Iterator[tuple]:
    """Yield ``(pool, bar)``: a pool of ``min(workers, n_chains)`` threads and a tqdm bar of ``total`` sweeps.

    The bar shows when ``progress`` is set and the run lasts more than a second; the chains advance it
    (``bar.update``) and a caller that runs longer raises ``bar.total``. The pool is shut down, then
    the bar closed, on exit (an exception included).
    """
    from tqdm.auto import tqdm

    bar = tqdm(total=total, disable=not progress, delay=1.0, unit="sweep", desc="PitmanYorGMM", leave=False)
    try:
        with ThreadPoolExecutor(max_workers=min(workers, n_chains)) as pool:
            yield pool, bar
    finally:
        bar.close()


def run_chains(Xw, states, cfg, rngs, n_iter, snap_sweeps, workers, progress, nbr) -> list[dict]:
    """Run every chain (``states[c]`` with ``rngs[c]``) in ``workers`` threads; return :func:`run_chain`'s results.

    The compiled sweeps release the GIL, so chains run in parallel; a tqdm bar shows progress when
    ``progress`` is set and the run lasts more than a second.
    """
    n_chains = len(states)
    with progress_pool(n_chains, n_chains * n_iter, workers, progress) as (pool, bar):
        return list(
            pool.map(
                lambda c: run_chain(Xw, states[c], cfg, rngs[c], n_iter, snap_sweeps, bar, nbr),
                range(n_chains),
            )
        )


def run_chain(Xw, st, cfg, rng, n_iter, snap_sweeps, bar, nbr, previous: dict | None = None) -> dict:
    """Run one chain (in a worker thread); return its trace, MAP state and saved samples.

    The partition is saved at the sweeps ``snap_sweeps`` (components too from ``cfg.burn_in`` on).
    ``previous``: the result of an earlier call on the same chain, continued from its last sweep up
    to ``n_iter`` sweeps in all (its trace, counters, MAP state and saved samples are extended).
    """
    if previous is None:
        trace = np.zeros((n_iter, len(g.TRACE_NAMES)))
        counters = np.zeros(4, dtype=np.int64)
        best = g.ChainState(*(a.copy() for a in st))
        best_val = np.array([-np.inf])
        start = 0
    else:
        start = previous["trace"].shape[0]
        trace = np.zeros((n_iter, len(g.TRACE_NAMES)))
        trace[:start] = previous["trace"]
        counters, best, best_val = previous["counters"], previous["best"], np.array([previous["best_val"]])
    labels = np.zeros((snap_sweeps.size, Xw.shape[0]), dtype=np.int32)
    samples = []
    seconds = 0.0
    for k, s in enumerate(snap_sweeps):
        t0 = time.perf_counter()
        g.run_sweeps(Xw, st, cfg, rng, start, s + 1 - start, trace, counters, best, best_val, nbr)
        seconds += time.perf_counter() - t0
        bar.update(s + 1 - start)
        start = s + 1
        K = int(st.ist[0])
        slots = st.act[:K]
        relabel = np.zeros(st.cnt.shape[0], dtype=np.int64)
        relabel[slots] = np.arange(K)
        labels[k] = relabel[st.z]
        if s >= cfg.burn_in:
            samples.append(
                {
                    "mu": st.mu[slots].copy(),
                    "L": st.L[slots].copy(),
                    "ldet": st.ldet[slots].copy(),
                    "cnt": st.cnt[slots].copy(),
                    "sc": st.sc.copy(),
                    "xi": st.xi.copy(),
                    "GR": st.GR.copy(),
                    "GW": st.GW.copy(),
                }
            )
    out = {
        "trace": trace,
        "counters": counters,
        "best": best,
        "best_val": float(best_val[0]),
        "labels": labels,
        "samples": samples,
        "seconds": seconds,
    }
    if previous is not None:
        out["labels"] = np.concatenate([previous["labels"], labels])
        out["samples"] = previous["samples"] + samples
        out["seconds"] += previous["seconds"]
    return out


def run_chains_until(
    Xw, states, cfg, rngs, first, max_iter, every, workers, progress, quantities, burn_in, max_seconds, nbr
) -> tuple[list[dict], np.ndarray, str, dict[str, float]]:
    """Run every chain ``first`` sweeps, then longer rounds (:func:`next_length`) until the targets hold.

    After each round the diagnostics (:func:`diagnostics`, burn-in :func:`auto_burn_in`) are
    computed; the run stops when the targets hold (``"converged"``), at ``max_iter`` sweeps
    (``"max_iter"``) or once ``max_seconds`` of wall time have passed (``"max_seconds"``; a round is
    shortened to what the remaining time affords at the sweep rate measured so far). The partition
    is saved every ``every`` sweeps. Returns (the chains' results as :func:`run_chain`'s, the saved
    sweeps, why the run stopped, the last diagnostics). Unless the time budget stops it, a run with
    the same seed stops at the same sweep whatever the machine.
    """
    t0 = time.perf_counter()
    n_chains = len(states)
    runs: list[dict | None] = [None] * n_chains
    saved = []
    total = 0
    target = min(first, max_iter)
    with progress_pool(n_chains, n_chains * target, workers, progress) as (pool, bar):
        while True:
            snaps = np.arange(total, target)
            snaps = snaps[(snaps + 1) % every == 0]
            if snaps.size == 0 or snaps[-1] != target - 1:
                snaps = np.r_[snaps, target - 1]
            runs = list(
                pool.map(
                    lambda c, t=target, sn=snaps, prev=runs: run_chain(
                        Xw, states[c], cfg, rngs[c], t, sn, bar, nbr, prev[c]
                    ),
                    range(n_chains),
                )
            )
            saved.append(snaps)
            total = target
            diag = diagnostics(runs, auto_burn_in(total, burn_in), quantities)
            if _met(diag, quantities):
                stopped = "converged"
                break
            if total >= max_iter:
                stopped = "max_iter"
                break
            target = next_length(total, diag["ess"], max_iter)
            if max_seconds is not None:
                elapsed = time.perf_counter() - t0
                affordable = int((max_seconds - elapsed) / (elapsed / total))
                if affordable < AUTO_ROUND // 5:
                    stopped = "max_seconds"
                    break
                target = min(target, total + affordable)
            bar.total = n_chains * target
            bar.refresh()
    return runs, np.concatenate(saved), stopped, diag


def chain_attributes(
    runs: list[dict], snap_sweeps: np.ndarray, burn_in: int, fit_alpha: bool, fit_d: bool
) -> dict[str, object]:
    """Return the fitted attributes that summarise the chains: traces, post-burn-in samples, diagnostics, the MAP sample.

    Keys are the estimator's attribute names (``trace_``, ``n_clusters_samples_``, ...,
    ``convergence_``, ``map_labels_``, ...; ``_burn_in`` and ``_map_state`` for its own use).
    ``fit_alpha`` / ``fit_d``: whether alpha and d were sampled (their R-hat is then reported).
    """
    from ._diagnostics import convergence_table

    out: dict[str, object] = {}
    trace = np.stack([r["trace"] for r in runs])  # (chains, n_iter, 5)
    out["trace_"] = traces = {k: trace[:, :, c].copy() for c, k in enumerate(g.TRACE_NAMES)}
    traces["n_clusters"] = traces["n_clusters"].astype(np.int64)
    post = {k: v[:, burn_in:] for k, v in traces.items()}
    out["n_clusters_samples_"] = post["n_clusters"].ravel()
    out["alpha_samples_"] = post["alpha"].ravel()
    out["discount_samples_"] = post["discount"].ravel()
    out["beta_samples_"] = post["beta"].ravel()
    out["log_posterior_samples_"] = post["log_posterior"].ravel()
    out["labels_samples_"] = np.stack([r["labels"] for r in runs])
    out["labels_sweeps_"] = snap_sweeps
    out["_burn_in"] = burn_in
    counters = np.sum([r["counters"] for r in runs], axis=0)
    out["split_merge_stats_"] = {
        "split_proposed": int(counters[g.SPLIT_PROPOSED]),
        "split_accepted": int(counters[g.SPLIT_ACCEPTED]),
        "merge_proposed": int(counters[g.MERGE_PROPOSED]),
        "merge_accepted": int(counters[g.MERGE_ACCEPTED]),
    }
    chains = {"K": post["n_clusters"]}
    if fit_alpha:
        chains["alpha"] = post["alpha"]
    if fit_d:
        chains["d"] = post["discount"]
    out["convergence_"] = convergence_table(chains)
    # the MAP sample over all chains
    c = int(np.argmax([r["best_val"] for r in runs]))
    best = runs[c]["best"]
    K = int(best.ist[0])
    slots = best.act[:K]
    order = np.argsort(-best.cnt[slots], kind="stable")
    relabel = np.full(best.cnt.shape[0], -1, dtype=np.int64)
    relabel[slots[order]] = np.arange(K)
    out["map_labels_"] = relabel[best.z]
    out["map_n_clusters_"] = K
    out["map_chain_"] = c
    out["map_sweep_"] = int(burn_in + np.argmax(post["log_posterior"][c]))
    out["map_log_posterior_"] = float(runs[c]["best_val"])
    out["_map_state"] = best
    return out
