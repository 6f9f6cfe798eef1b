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
