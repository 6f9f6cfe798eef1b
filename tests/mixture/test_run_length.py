"""Tests of the run length of ``n_iter="auto"`` (sized from the diagnostics), its budgets and warning, and the
near-neighbour pairs of the split-merge move (exact: the prior is sampled unchanged)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from tactile_torch.mixture import PitmanYorGMM
from tactile_torch.mixture._chains import auto_burn_in, diagnostics, neighbours, next_length
from tests.mixture_data import PYP, assert_samples_prior_of_k, batch_se, exact_mfm_prior_k


def _ar1(rng, n_chains, n, phi):
    """Gaussian AR(1) traces (n_chains, n) with lag-1 autocorrelation ``phi``."""
    x = np.zeros((n_chains, n))
    e = rng.normal(size=(n_chains, n)) * math.sqrt(1 - phi**2)
    x[:, 0] = rng.normal(size=n_chains)
    for t in range(1, n):
        x[:, t] = phi * x[:, t - 1] + e[:, t]
    return x


def _runs(trace_k: np.ndarray) -> list[dict]:
    """Chain results as run_chain's, with ``trace_k`` (n_chains, n) as the K column."""
    out = []
    for row in trace_k:
        trace = np.zeros((row.size, 5))
        trace[:, 0] = row
        out.append({"trace": trace})
    return out


def test_next_round_is_sized_from_the_ess_of_k():
    # ESS grows linearly with the run: 1.2 x 400 / ESS, clamped to [1.25, 2], rounded up to 500 sweeps
    assert next_length(1000, 100.0, 40000) == 2000  # far off: at most doubled
    assert next_length(1000, 300.0, 40000) == 2000  # x 1.6 -> 1600 -> 2000
    assert next_length(4000, 300.0, 40000) == 6500  # x 1.6 -> 6400 -> 6500
    assert next_length(8000, 390.0, 40000) == 10000  # x 1.23 -> clamped to x 1.25
    assert next_length(1000, float("nan"), 40000) == 2000  # no estimate: doubled
    assert next_length(30000, 100.0, 40000) == 40000  # the budget caps it
    assert auto_burn_in(8000, 250) == 1000 and auto_burn_in(1000, 250) == 250


def test_diagnostics_of_synthetic_traces_drive_the_rule():
    rng = np.random.default_rng(0)
    # slowly mixing chains: the ESS is low, and the next round is longer by about 400 / ESS
    slow = _ar1(rng, 4, 2000, 0.99)
    d = diagnostics(_runs(slow), 250, ("n_clusters",))
    assert d["ess"] < 150 and next_length(2000, d["ess"], 40000) == 4000
    # nearly independent draws: R-hat near 1 and ESS above 400, the targets hold
    fast = _ar1(rng, 4, 2000, 0.1)
    d = diagnostics(_runs(fast), 250, ("n_clusters",))
    assert d["n_clusters"] < 1.01 and d["ess"] > 400
    # chains that disagree (one shifted): R-hat far above 1.01 whatever the ESS
    fast[0] += 3.0
    assert diagnostics(_runs(fast), 250, ("n_clusters",))["n_clusters"] > 1.1


def test_stopped_by_and_the_warning_only_when_a_budget_ran_out():
    # (converged, no warning: tests/test_mixture.py::test_auto_run_length_stops_at_the_targets)
    # chains stuck in different places (no split-merge, one-cluster start): the sweep budget runs out
    rng = np.random.default_rng(0)
    Y = np.concatenate([rng.normal(m, 0.3, size=(40, 1)) for m in range(0, 40, 4)])
    stuck = PitmanYorGMM(
        **PYP,
        n_chains=3,
        n_split_merge=0,
        init="one",
        max_iter=40,
        burn_in=10,
        random_state=0,
        progress=False,
    )
    with pytest.warns(
        RuntimeWarning,
        match=r"after 40 sweeps per chain, when the budget max_iter ran out \(now 40\).*max_iter=80",
    ):
        stuck.fit(Y)
    assert stuck.stopped_by_ == "max_iter" and stuck.budget_exhausted_
    # the time budget: the first round alone exceeds it, so the run stops there and names max_seconds
    with pytest.warns(RuntimeWarning, match=r"budget max_seconds ran out \(now 0.001\).*max_seconds=0.002"):
        stuck.set_params(max_iter=40000, max_seconds=0.001).fit(Y)
    assert stuck.stopped_by_ == "max_seconds" and stuck.n_iter_ == 1000
    # a fixed run says so
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        assert stuck.set_params(n_iter=60).fit(Y).stopped_by_ == "n_iter"


def test_neighbours_exclude_the_point_itself():
    X = np.array([[0.0], [0.0], [1.0], [3.0], [7.0]])
    nbr = neighbours(X, 2)
    assert nbr.shape == (5, 2) and all(i not in nbr[i] for i in range(5))
    assert set(nbr[3]) == {2, 1} or set(nbr[3]) == {2, 0}
    assert neighbours(X[:1], 5).shape == (1, 0)


def test_near_pairs_split_merge_samples_the_mfm_prior():
    # every pair a near pair (near_pairs=1), likelihood off: the chain must still sample the prior of K
    n = 8
    X = np.random.default_rng(0).normal(size=(n, 2))
    model = PitmanYorGMM(
        k_prior_mean=3.0, near_pairs=1.0, n_iter=6000, burn_in=200, n_chains=1, prior_only=True,
        random_state=3, progress=False,
    ).fit(X)  # fmt: skip
    assert_samples_prior_of_k(model, exact_mfm_prior_k(n, 1.0, 3.0))


def test_near_pairs_split_merge_leaves_the_posterior_unchanged():
    # with the likelihood: near pairs against single-site Gibbs alone (which mixes on this 1-D data)
    rng = np.random.default_rng(5)
    X = np.concatenate([rng.normal(m, 1.0, size=(10, 1)) for m in (-2.5, 0.0, 2.5)])
    common = dict(model="mfm", n_iter=8000, burn_in=500, n_chains=1, progress=False)
    with_moves = PitmanYorGMM(n_split_merge=3, near_pairs=1.0, random_state=1, **common).fit(X)
    without = PitmanYorGMM(n_split_merge=0, random_state=2, **common).fit(X).n_clusters_samples_
    a_all = with_moves.n_clusters_samples_
    assert with_moves.split_merge_stats_["merge_accepted"] > 100
    se = math.hypot(batch_se(a_all), batch_se(without))
    assert abs(a_all.mean() - without.mean()) < 4 * se
    for k in (1, 2, 3):
        a, b = (a_all == k).astype(float), (without == k).astype(float)
        assert abs(a.mean() - b.mean()) < 4 * math.hypot(batch_se(a), batch_se(b)) + 0.01


def _plan(**kw):
    from tactile_torch.mixture._chains import RunLength

    return RunLength(
        **{"max_iter": 40000, "max_seconds": 300.0, "burn_in": 10, "quantities": ("n_clusters",)} | kw
    )


def _labelled_runs(trace_k: np.ndarray, n: int = 50) -> list[dict]:
    runs = _runs(trace_k)
    for r in runs:
        r["labels"] = np.zeros((1, n), dtype=np.int32)
    return runs


def test_chains_stuck_in_different_modes_stop_early_with_the_evidence():
    from tactile_torch.mixture._chains import hopeless, stuck_groups

    rng = np.random.default_rng(1)
    # chain 0 holds K = 1, chains 1-3 move between 2 and 3: two groups, none drifting
    k = np.vstack([np.ones(1000), 2 + (rng.random((3, 1000)) < 0.3)])
    assert stuck_groups(k[:, 10:]) == [[0], [1, 2, 3]]
    runs = _labelled_runs(k)
    diag = diagnostics(runs, 125, ("n_clusters",))
    stop, why = hopeless(runs, 125, diag, _plan(), elapsed=2.0)
    assert stop == "stuck"
    assert "chain 0: K 1; chains 1, 2, 3: K 2-3" in why and "none moved between them in 875 sweeps" in why
    assert "R-hat of K" in why and "Next:" in why
    # a chain still drifting (its halves do not overlap) may yet join the others: not stuck
    drifting = k.copy()
    drifting[0, 125 + 875 // 2 :] = 0  # K 1 in the first half after the burn-in, 0 in the second
    assert hopeless(_labelled_runs(drifting), 125, diag, _plan(), elapsed=2.0) is None
    # chains that share a value connect, however much they disagree
    assert stuck_groups(np.array([[1, 2, 2], [2, 3, 3], [3, 4, 4]])) == [[0, 1, 2]]
    # a budget large enough for the switches mixing needs: keep going
    assert hopeless(runs, 125, diag, _plan(max_iter=10**9, max_seconds=None), elapsed=2.0) is None


def test_a_budget_that_cannot_reach_the_ess_target_stops_early_and_says_how_much_it_needs():
    from tactile_torch.mixture._chains import hopeless

    slow = _ar1(np.random.default_rng(2), 4, 1000, 0.995)  # ESS of about 10 per 1,000 sweeps
    runs = _labelled_runs(np.round(3 * slow))
    diag = diagnostics(runs, 125, ("n_clusters",))
    diag["n_clusters"] = 1.0  # R-hat is fine: only the ESS is short
    stop, why = hopeless(runs, 125, diag, _plan(max_iter=5000), elapsed=1.0)
    assert stop == "projected" and "more than twice the budget (max_iter=5000, max_seconds=300)" in why
    # the same ESS with a budget that affords the projected run: keep going
    assert hopeless(runs, 125, diag, _plan(max_iter=10**7, max_seconds=None), elapsed=1.0) is None
    # by time: 1,000 sweeps took 60 s, so the projected run needs far more than twice 300 s
    assert hopeless(runs, 125, diag, _plan(max_iter=10**7), elapsed=60.0)[0] == "projected"


def test_k_at_the_priors_ceiling_stops_early():
    from tactile_torch.mixture._chains import hopeless
    from tactile_torch.mixture._mfm import k_ceiling

    assert k_ceiling(10) == 11 and k_ceiling(1680) == 4 * 82 + 60
    k = np.full((2, 400), 30.0)
    k[1, 300:] = 60
    runs = _labelled_runs(k)
    stop, why = hopeless(runs, 50, diagnostics(runs, 50, ("n_clusters",)), _plan(k_ceiling=60), elapsed=1.0)
    assert stop == "ceiling" and "K reached 60, the ceiling of the prior's table" in why
