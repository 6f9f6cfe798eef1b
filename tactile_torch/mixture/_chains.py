"""The chains of a :class:`PitmanYorGMM` fit: run in parallel threads, with their traces and saved samples.

Importing this module loads the compiled sampler (:mod:`tactile_torch._gibbs`); the estimator
imports it at its first fit, so that importing :mod:`tactile_torch.mixture` does not.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .. import _gibbs as g


def run_chains(Xw, states, cfg, rngs, n_iter, snap_sweeps, workers, progress) -> list[dict]:
    """Run every chain (``states[c]`` with ``rngs[c]``) in ``workers`` threads; return :func:`run_chain`'s results.

    The compiled sweeps release the GIL, so chains run in parallel; a tqdm bar shows progress when
    ``progress`` is set and the run lasts more than a second.
    """
    from tqdm.auto import tqdm

    n_chains = len(states)
    bar = tqdm(
        total=n_chains * n_iter,
        disable=not progress,
        delay=1.0,
        unit="sweep",
        desc="PitmanYorGMM",
        leave=False,
    )
    try:
        with ThreadPoolExecutor(max_workers=min(workers, n_chains)) as pool:
            return list(
                pool.map(
                    lambda c: run_chain(Xw, states[c], cfg, rngs[c], n_iter, snap_sweeps, bar),
                    range(n_chains),
                )
            )
    finally:
        bar.close()


def run_chain(Xw, st, cfg, rng, n_iter, snap_sweeps, bar) -> dict:
    """Run one chain (in a worker thread); return its trace, MAP state and saved samples.

    The partition is saved at the sweeps ``snap_sweeps`` (components too from ``cfg.burn_in`` on).
    """
    trace = np.zeros((n_iter, len(g.TRACE_NAMES)))
    counters = np.zeros(4, dtype=np.int64)
    best = g.ChainState(*(a.copy() for a in st))
    best_val = np.array([-np.inf])
    labels = np.zeros((snap_sweeps.size, Xw.shape[0]), dtype=np.int32)
    samples = []
    start = 0
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
    return {
        "trace": trace,
        "counters": counters,
        "best": best,
        "best_val": float(best_val[0]),
        "labels": labels,
        "samples": samples,
        "seconds": seconds,
    }
