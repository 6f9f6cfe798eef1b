"""The chains of a :class:`PitmanYorGMM` fit: run in parallel threads, with their traces and saved samples.

Importing this module loads the compiled sampler (:mod:`tactile_torch.mixture._gibbs`); the estimator
imports it at its first fit, so that importing :mod:`tactile_torch.mixture` does not.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import numpy as np

from . import _gibbs as g
from ._diagnostics import RHAT_THRESHOLD, ess_bulk, rhat

# n_iter="auto": first run, snapshot spacing (sweeps), and the targets.
AUTO_FIRST, AUTO_EVERY = 1000, 10
_ESS_TARGET = 400.0
# At most this many saved partitions per chain are kept (the point estimate uses 200 in all).
_KEEP_PER_CHAIN = 200


def targets_met(runs: list[dict], burn_in: int, quantities: tuple[str, ...]) -> bool:
    """Whether R-hat < 1.01 for every quantity and bulk ESS of K >= 400 after ``burn_in`` sweeps."""
    trace = np.stack([r["trace"][burn_in:] for r in runs])
    k = trace[:, :, g.TRACE_NAMES.index("n_clusters")]
    if np.ptp(k) == 0 and k.size >= _ESS_TARGET:
        k_ok = True  # every chain on the same K throughout: nothing left to mix
    else:
        k_ok = ess_bulk(k) >= _ESS_TARGET
    if len(runs) < 2:
        return bool(k_ok)
    for name in quantities:
        r = rhat(trace[:, :, g.TRACE_NAMES.index(name)])
        if not (np.isfinite(r) and r < RHAT_THRESHOLD):
            return False
    return bool(k_ok)


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


def run_chains(Xw, states, cfg, rngs, n_iter, snap_sweeps, workers, progress) -> list[dict]:
    """Run every chain (``states[c]`` with ``rngs[c]``) in ``workers`` threads; return :func:`run_chain`'s results.

    The compiled sweeps release the GIL, so chains run in parallel; a tqdm bar shows progress when
    ``progress`` is set and the run lasts more than a second.
    """
    n_chains = len(states)
    with progress_pool(n_chains, n_chains * n_iter, workers, progress) as (pool, bar):
        return list(
            pool.map(
                lambda c: run_chain(Xw, states[c], cfg, rngs[c], n_iter, snap_sweeps, bar),
                range(n_chains),
            )
        )


def run_chain(Xw, st, cfg, rng, n_iter, snap_sweeps, bar, previous: dict | None = None) -> dict:
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
        g.run_sweeps(Xw, st, cfg, rng, start, s + 1 - start, trace, counters, best, best_val)
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
    Xw, states, cfg, rngs, first, max_iter, every, workers, progress, done
) -> tuple[list[dict], np.ndarray]:
    """Run every chain ``first`` sweeps, then keep doubling the run until ``done(runs)`` or ``max_iter``.

    The partition is saved every ``every`` sweeps. Returns (the chains' results as :func:`run_chain`'s,
    the saved sweeps). ``done`` sees the results after each round; a run with the same seed stops at
    the same sweep whatever the machine (the budget counts sweeps, not seconds).
    """
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
                        Xw, states[c], cfg, rngs[c], t, sn, bar, prev[c]
                    ),
                    range(n_chains),
                )
            )
            saved.append(snaps)
            total = target
            if total >= max_iter or done(runs):
                break
            target = min(2 * total, max_iter)
            bar.total = n_chains * target
            bar.refresh()
    return runs, np.concatenate(saved)


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
