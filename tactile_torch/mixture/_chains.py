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
from dataclasses import dataclass

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
# Partition snapshots per call of the compiled sweeps (the components are saved once per call).
SNAPSHOTS_PER_CALL = 4


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


def warm_up(Xw, st, cfg, rng, sweeps: int) -> None:
    """Run ``sweeps`` sweeps on ``st`` with its partition held fixed: the components and hyperparameters adapt to it.

    Part of a chain's initialisation (before its first recorded sweep): starting hyperparameters
    (W = I, beta = D) far from the partition's would otherwise let the first split-merge moves
    merge well-separated clusters into components too broad to split again.
    """
    if sweeps <= 0:
        return
    n = Xw.shape[0]
    fixed = cfg._replace(allocate=False, burn_in=sweeps)
    g.run_sweeps(
        Xw, st, fixed, rng, 0, sweeps, np.zeros((sweeps, len(g.TRACE_NAMES))), np.zeros(4, dtype=np.int64),
        g.ChainState(*(a.copy() for a in st)), np.array([np.inf]), np.zeros((n, 0), dtype=np.int64),
        np.zeros(0, dtype=np.int64), np.zeros((0, n), dtype=np.int32),
    )  # fmt: skip


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


def keep_after_burn_in(runs: list[dict], sweeps: np.ndarray, burn_in: int) -> np.ndarray:
    """Drop the saved partitions and samples before ``burn_in`` and thin each to ``_KEEP_PER_CHAIN``; return the kept sweeps."""
    after = np.flatnonzero(sweeps >= burn_in)
    pick = after[np.unique(np.linspace(0, after.size - 1, min(after.size, _KEEP_PER_CHAIN)).astype(int))]
    for r in runs:
        r["labels"] = r["labels"][pick]
        kept = [smp for smp in r["samples"] if smp["sweep"] >= burn_in]
        take = np.unique(np.linspace(0, len(kept) - 1, min(len(kept), _KEEP_PER_CHAIN)).astype(int))
        r["samples"] = [kept[i] for i in take] if kept else []
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


@dataclass(frozen=True)
class Chains:
    """The chains of one fit: their data, states, settings and random streams, and where they run."""

    Xw: np.ndarray
    """Whitened data (n, D)."""
    states: list
    """One :class:`~tactile_torch.mixture._gibbs.ChainState` per chain (updated in place)."""
    cfg: g.Settings
    rngs: list
    """One ``numpy.random.Generator`` per chain."""
    nbr: np.ndarray
    """Nearest neighbours of each point (n, k) for the split-merge pairs."""
    workers: int
    """Threads running the chains."""
    progress: bool
    """Show a progress bar."""


@dataclass(frozen=True)
class RunLength:
    """How ``n_iter="auto"`` sizes and ends a run (see :func:`run_chains_until`)."""

    max_iter: int
    max_seconds: float | None
    burn_in: int
    """Least burn-in; the first eighth of every chain is discarded (:func:`auto_burn_in`)."""
    quantities: tuple[str, ...]
    """Trace columns whose R-hat must be below 1.01 (K, and alpha and d when sampled)."""
    k_ceiling: int | None = None
    """K beyond which the prior puts no mass the sampler can use (mixture of finite mixtures), or None."""
    first: int = AUTO_FIRST
    every: int = AUTO_EVERY


def run_chains(chains: Chains, n_iter: int, snap_sweeps: np.ndarray) -> list[dict]:
    """Run every chain ``n_iter`` sweeps in ``chains.workers`` threads; return :func:`run_chain`'s results.

    The compiled sweeps release the GIL, so chains run in parallel; a tqdm bar shows progress when
    ``chains.progress`` is set and the run lasts more than a second.
    """
    n_chains = len(chains.states)
    with progress_pool(n_chains, n_chains * n_iter, chains.workers, chains.progress) as (pool, bar):
        return list(pool.map(lambda c: run_chain(chains, c, n_iter, snap_sweeps, bar), range(n_chains)))


def run_chain(chains: Chains, c: int, n_iter: int, snap_sweeps, bar, previous: dict | None = None) -> dict:
    """Run chain ``c`` (in a worker thread); return its trace, MAP state and saved samples.

    The partition is saved at the sweeps ``snap_sweeps`` (by the compiled sweeps themselves); the
    sweeps run in blocks of ``SNAPSHOTS_PER_CALL`` snapshots, and from ``cfg.burn_in`` on the
    components at the end of each block are saved too (with that sweep's partition: the samples of
    the posterior predictive). ``previous``: the result of an earlier call on the same chain,
    continued from its last sweep up to ``n_iter`` sweeps in all (its trace, counters, MAP state and
    saved samples are extended).
    """
    Xw, st, cfg, rng, nbr = chains.Xw, chains.states[c], chains.cfg, chains.rngs[c], chains.nbr
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
    snap_sweeps = np.ascontiguousarray(snap_sweeps, dtype=np.int64)
    labels = np.zeros((snap_sweeps.size, Xw.shape[0]), dtype=np.int32)
    samples = []
    seconds = 0.0
    for b0 in range(0, snap_sweeps.size, SNAPSHOTS_PER_CALL):
        block = snap_sweeps[b0 : b0 + SNAPSHOTS_PER_CALL]
        end = int(block[-1])
        t0 = time.perf_counter()
        g.run_sweeps(
            Xw, st, cfg, rng, start, end + 1 - start, trace, counters, best, best_val, nbr, block,
            labels[b0 : b0 + block.size],
        )  # fmt: skip
        seconds += time.perf_counter() - t0
        bar.update(end + 1 - start)
        start = end + 1
        if end >= cfg.burn_in:
            slots = st.act[: int(st.ist[0])]
            samples.append(
                {
                    "sweep": end,
                    "labels": labels[b0 + block.size - 1].copy(),
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
    chains: Chains, plan: RunLength
) -> tuple[list[dict], np.ndarray, str, dict[str, object]]:
    """Run every chain ``plan.first`` sweeps, then longer rounds (:func:`next_length`) until the targets hold.

    After each round the diagnostics (:func:`diagnostics`, burn-in :func:`auto_burn_in`) are
    computed, and the run stops

    - when the targets hold (``"converged"``);
    - at ``max_iter`` sweeps (``"max_iter"``), or once ``max_seconds`` of wall time have passed
      (``"max_seconds"``; a round is shortened to what the remaining time affords at the sweep
      rate measured so far);
    - as soon as the evidence says that the budget cannot reach the targets (:func:`hopeless`):
      chains stuck in different modes of K (``"stuck"``), K at the prior's ceiling
      (``"ceiling"``), or a bulk ESS of K growing too slowly for either budget (``"projected"``).

    The partition is saved every ``plan.every`` sweeps. Returns (the chains' results as
    :func:`run_chain`'s, the saved sweeps, why the run stopped, the last diagnostics with, for an
    early stop, its ``"reason"``). Unless the time budget decides, a run with the same seed stops at
    the same sweep whatever the machine or the number of threads.
    """
    t0 = time.perf_counter()
    n_chains = len(chains.states)
    runs: list[dict | None] = [None] * n_chains
    saved = []
    total = 0
    target = min(plan.first, plan.max_iter)
    with progress_pool(n_chains, n_chains * target, chains.workers, chains.progress) as (pool, bar):
        while True:
            snaps = np.arange(total, target)
            snaps = snaps[(snaps + 1) % plan.every == 0]
            if snaps.size == 0 or snaps[-1] != target - 1:
                snaps = np.r_[snaps, target - 1]
            runs = list(
                pool.map(
                    lambda c, t=target, sn=snaps, prev=runs: run_chain(chains, c, t, sn, bar, prev[c]),
                    range(n_chains),
                )
            )
            saved.append(snaps)
            total = target
            burn_in = auto_burn_in(total, plan.burn_in)
            diag = diagnostics(runs, burn_in, plan.quantities)
            if _met(diag, plan.quantities):
                stopped = "converged"
                break
            if total >= plan.max_iter:
                stopped = "max_iter"
                break
            elapsed = time.perf_counter() - t0
            target = next_length(total, diag["ess"], plan.max_iter)
            if plan.max_seconds is not None:
                affordable = int((plan.max_seconds - elapsed) / (elapsed / total))
                if affordable < AUTO_ROUND // 5:
                    stopped = "max_seconds"
                    break
                target = min(target, total + affordable)
            verdict = hopeless(runs, burn_in, diag, plan, elapsed)
            if verdict is not None:
                stopped, diag["reason"] = verdict
                break
            bar.total = n_chains * target
            bar.refresh()
    return runs, np.concatenate(saved), stopped, diag


# Mode switches per chain that R-hat < 1.01 needs when the chains' spread is that of modes: with
# p the share of a mode, between-chain variance / within ~ 1 / (switches per chain), and R-hat - 1
# ~ half of that: about 50 switches; a factor 2 covers their randomness.
_SWITCHES_NEEDED = 100
# An early stop needs the projected run to exceed the budget by this factor (the ESS of a short
# run is a noisy estimate).
_PROJECTION_SLACK = 2.0


def run_to_targets(
    chains: Chains,
    n_iter: int,
    burn_in: int,
    snap_sweeps: np.ndarray,
    quantities: tuple[str, ...],
    auto: bool,
    max_seconds: float | None,
    ceiling: int | None,
) -> tuple:
    """Run the chains ``n_iter`` sweeps, or with ``auto`` until the targets are met or a stop (``max_seconds``,
    the run length ``n_iter``, an early stop; ``ceiling``: the MFM's bound on K).

    Return (runs, snapshot sweeps, sweeps per chain, burn-in, stopped_by, stop reason or None, whether the
    targets were missed).
    """
    if auto:
        plan = RunLength(n_iter, max_seconds, burn_in, quantities, ceiling)
        runs, snap_sweeps, stopped_by, diag = run_chains_until(chains, plan)
        n_iter = runs[0]["trace"].shape[0]
        burn_in = auto_burn_in(n_iter, burn_in)
        snap_sweeps = keep_after_burn_in(runs, snap_sweeps, burn_in)
        return runs, snap_sweeps, n_iter, burn_in, stopped_by, diag.get("reason"), stopped_by != "converged"
    runs = run_chains(chains, n_iter, snap_sweeps)
    return runs, snap_sweeps, n_iter, burn_in, "n_iter", None, not targets_met(runs, burn_in, quantities)


def stuck_groups(k: np.ndarray) -> list[list[int]]:
    """Return the chains grouped by the K values they visited: chains that share a value are in one group.

    ``k``: (n_chains, n_draws). One group: the chains connect (they may still disagree); several:
    no chain has visited a value of another group.
    """
    groups: list[tuple[set, list[int]]] = []
    for c, row in enumerate(k):
        values, members = set(np.unique(row).tolist()), [c]
        for other in [g_ for g_ in groups if g_[0] & values]:
            groups.remove(other)
            values |= other[0]
            members += other[1]
        groups.append((values, sorted(members)))
    return sorted((m for _, m in groups), key=lambda m: m[0])


def hopeless(
    runs: list[dict], burn_in: int, diag: dict, plan: RunLength, elapsed: float
) -> tuple[str, str] | None:
    """Return ``(stop reason, one line of evidence and the next step)`` when the budget cannot reach the targets, else None.

    - ``"stuck"``: the chains fall into groups that never visited each other's values of K after
      the burn-in, while none is still drifting (the values of the two halves of every chain
      overlap). Mixing them needs about ``_SWITCHES_NEEDED`` moves between groups per chain;
      with none seen in T sweeps of every chain the rate is below ``3 / (n_chains T)`` (95 %), so
      at least ``_SWITCHES_NEEDED n_chains T / 3`` sweeps per chain: stop when that is beyond the
      budget.
    - ``"ceiling"``: K reached the largest number of components the prior's table allows
      (``plan.k_ceiling``), where every further component costs exp(-700).
    - ``"projected"``: R-hat is not the problem but the bulk ESS of K grows too slowly: the run
      that would reach 400 (ESS grows about linearly) exceeds twice ``max_iter`` or twice
      ``max_seconds`` at the rate measured so far.
    """
    trace = np.stack([r["trace"][burn_in:, g.TRACE_NAMES.index("n_clusters")] for r in runs])
    total = runs[0]["trace"].shape[0]
    per_sweep = elapsed / total  # wall seconds per sweep of every chain (the chains run side by side)
    if plan.k_ceiling is not None and trace.max() >= plan.k_ceiling:
        return "ceiling", (
            f"K reached {int(trace.max())}, the ceiling of the prior's table ({plan.k_ceiling} components for "
            f"these {len(runs[0]['labels'][0])} points): nearly every point opens a component; the data are not "
            "clustered in these features (scale or choose them), or raise k_prior_mean"
        )
    groups = stuck_groups(trace)
    half = trace.shape[1] // 2
    settled = all(  # no chain still drifting: the K values of its two halves overlap
        min(row[:half].max(), row[half:].max()) >= max(row[:half].min(), row[half:].min()) for row in trace
    )
    if len(groups) > 1 and settled:
        T = trace.shape[1]
        needed = _SWITCHES_NEEDED * len(runs) * T / 3.0
        if needed > plan.max_iter - total or (
            plan.max_seconds is not None and needed * per_sweep > plan.max_seconds - elapsed
        ):
            where = "; ".join(
                f"chain{'s' if len(m) > 1 else ''} {', '.join(map(str, m))}: K " + _span(trace[m])
                for m in groups
            )
            return "stuck", (
                f"the chains are stuck in different modes of K ({where}; R-hat of K {diag['n_clusters']:.2f}): "
                f"none moved between them in {T} sweeps after the burn-in, so mixing would take over "
                f"{needed:,.0f} sweeps per chain; the pooled posterior of K is not converged. Next: fewer "
                "features (principal components), more data per cluster, or compare the modes' fit"
            )
    ess = diag["ess"]
    rhat_ok = all(np.isfinite(diag[q]) and diag[q] < RHAT_THRESHOLD for q in plan.quantities)
    if rhat_ok and np.isfinite(ess) and ess > 0:
        sweeps = total * AUTO_MARGIN * _ESS_TARGET / ess
        over_iter = sweeps > _PROJECTION_SLACK * plan.max_iter
        over_time = plan.max_seconds is not None and sweeps * per_sweep > _PROJECTION_SLACK * plan.max_seconds
        if over_iter or over_time:
            return "projected", (
                f"the bulk ESS of K grows by {1000 * ess / total:.1f} per 1,000 sweeps: reaching "
                f"{_ESS_TARGET:.0f} needs about {sweeps:,.0f} sweeps per chain ({sweeps * per_sweep:,.0f} s here), "
                f"more than twice the budget (max_iter={plan.max_iter}"
                + (f", max_seconds={plan.max_seconds:g}" if plan.max_seconds is not None else "")
                + "); raise it accordingly, or use the posterior as it is"
            )
    return None


def _span(k: np.ndarray) -> str:
    lo, hi = int(k.min()), int(k.max())
    return str(lo) if lo == hi else f"{lo}-{hi}"


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
    out["session_scale_samples_"] = post["session_scale"].ravel()
    out["offset_variance_samples_"] = post["offset_variance"].ravel()
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
