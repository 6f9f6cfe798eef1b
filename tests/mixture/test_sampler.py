"""Tests of the mixture's compiled Gibbs sampler (tactile_torch.mixture._gibbs): densities and draws against SciPy,
chains that sample known priors (likelihood off), recovery and mixing on data, against the independent
NumPy reference, and the mixture of finite mixtures with the coarsened posterior."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats
from scipy.special import gammaln, multigammaln

from tactile_torch.metrics import pairwise_accuracy
from tactile_torch.mixture import (
    PitmanYorGMM,
    pitman_yor_prior_k,
)
from tactile_torch.mixture._gibbs import conditionals, densities, linalg
from tests.mixture_data import PYP, assert_samples_prior_of_k, batch_se, blobs, exact_mfm_prior_k
from tests.reference_mixture import reference_gibbs

# Short chains in these tests: their R-hat warnings are expected, not failures.
pytestmark = pytest.mark.filterwarnings("ignore:PitmanYorGMM. R-hat:RuntimeWarning")


def spd(rng, D):
    A = rng.normal(size=(D, D))
    return A @ A.T + D * np.eye(D)


# ------------------------------------------------------------------------------------------------
# densities and draws against SciPy
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("D", [1, 3])
def test_densities_match_scipy(D):
    rng = np.random.default_rng(D)
    V, S = spd(rng, D), spd(rng, D)
    L = np.linalg.cholesky(S)
    P = np.linalg.inv(V)
    nu = D + 1.7
    got = densities.wishart_logpdf(L, np.linalg.slogdet(S)[1], nu, P, np.linalg.slogdet(P)[1])
    np.testing.assert_allclose(got, stats.wishart(df=nu, scale=V).logpdf(S), rtol=1e-10)
    x, m = rng.normal(size=D), rng.normal(size=D)
    want = stats.multivariate_normal(m, np.linalg.inv(S)).logpdf(x)
    np.testing.assert_allclose(densities.normal_logpdf(x, m, L), want, rtol=1e-10)
    np.testing.assert_allclose(densities._lmvgamma(3.3, D), multigammaln(3.3, D), rtol=1e-12)


def test_log_eppf_matches_its_definition():
    counts = np.array([5, 1, 3, 2], dtype=np.int64)
    act = np.arange(4, dtype=np.int64)
    for alpha, d in [(1.3, 0.0), (0.7, 0.4), (-0.2, 0.5)]:
        n, K = counts.sum(), counts.size
        # prod_{k<K} (alpha + k d) / (alpha + 1)_(n-1) * prod_j (1 - d)_(n_j - 1), rising factorials
        want = sum(math.log(alpha + k * d) for k in range(1, K))
        want -= sum(math.log(alpha + 1 + t) for t in range(n - 1))
        want += sum(math.log(1 - d + t) for c in counts for t in range(c - 1))
        np.testing.assert_allclose(densities.log_eppf(counts, act, K, n, alpha, d), want, rtol=1e-12)


def test_prior_k_recursion_matches_enumeration_of_partitions():
    def partitions(items):
        if not items:
            yield []
            return
        first, rest = items[0], items[1:]
        for part in partitions(rest):
            yield [[first], *part]
            for i in range(len(part)):
                yield [*part[:i], [first, *part[i]], *part[i + 1 :]]

    n, alpha, d = 6, 0.8, 0.35
    probs = np.zeros(n + 1)
    parts = list(partitions(list(range(n))))
    assert len(parts) == 203  # Bell number B_6: the enumeration is complete
    for part in parts:
        K = len(part)
        lp = sum(math.log(alpha + k * d) for k in range(1, K)) - sum(
            math.log(alpha + 1 + t) for t in range(n - 1)
        )
        lp += sum(gammaln(len(b) - d) - gammaln(1 - d) for b in part)
        probs[K] += math.exp(lp)
    np.testing.assert_allclose(probs.sum(), 1.0, rtol=1e-12)
    np.testing.assert_allclose(pitman_yor_prior_k(n, alpha, d), probs, rtol=1e-10, atol=1e-15)


def test_wishart_draws_have_the_right_mean_and_logdet():
    rng = np.random.default_rng(1)
    D, nu, n = 3, 5.5, 4000
    V = spd(rng, D) / 3
    P = np.linalg.inv(V)
    C = np.empty((D, D))
    ldet_v = -linalg._scale_factor(P, C)
    np.testing.assert_allclose(C @ C.T, V, rtol=1e-10, atol=1e-12)  # C C^T = P^{-1}
    L = np.empty((D, D))
    draws = np.empty((n, D, D))
    ldets = np.empty(n)
    gen = np.random.default_rng(2)
    for k in range(n):
        ldets[k] = densities.wishart_draw(gen, C, ldet_v, nu, L)
        draws[k] = L @ L.T
    np.testing.assert_allclose(ldets, np.linalg.slogdet(draws)[1], rtol=1e-9)
    # mean nu V within 5 standard errors, entrywise (var of S_ab = nu (V_ab^2 + V_aa V_bb))
    se = np.sqrt(nu * (V**2 + np.outer(np.diag(V), np.diag(V))) / n)
    assert np.all(np.abs(draws.mean(0) - nu * V) < 5 * se)
    # E log|S| = log|V| + D log 2 + sum_a digamma((nu - a)/2)
    from scipy.special import digamma

    want = ldet_v + D * math.log(2) + digamma((nu - np.arange(D)) / 2).sum()
    assert abs(ldets.mean() - want) < 5 * ldets.std() / math.sqrt(n)


@pytest.mark.parametrize("zeta", [1.0, 0.4])
def test_component_step_density_is_the_product_of_its_conditionals(zeta):
    # zeta < 1 (coarsened posterior): the likelihood to the power zeta, i.e. every count and sum of
    # the points weighted by zeta; the conditionals stay Wishart x normal
    rng = np.random.default_rng(3)
    D = 3
    pts = rng.normal(size=(7, D))
    mean = pts.mean(0)
    scat = (pts - mean).T @ (pts - mean)
    mu0, xi = rng.normal(size=D), rng.normal(size=D)
    W, R = spd(rng, D) / 5, spd(rng, D) / 5
    beta = 4.2
    mu, L = np.empty(D), np.empty((D, D))
    logq, ldet = conditionals.component_step(
        7, 7, mean, scat, mu0, beta, W, R, R @ xi, True, mu, L, 0.0, zeta, rng
    )
    S = L @ L.T
    P = beta * W + zeta * (pts - mu0).T @ (pts - mu0)
    want = stats.wishart(df=beta + zeta * 7, scale=np.linalg.inv(P)).logpdf(S)
    lam = R + zeta * 7 * S
    m = np.linalg.solve(lam, R @ xi + zeta * S @ pts.sum(0))
    want += stats.multivariate_normal(m, np.linalg.inv(lam)).logpdf(mu)
    np.testing.assert_allclose(logq, want, rtol=1e-9)
    again, _ = conditionals.component_step(
        7, 7, mean, scat, mu0, beta, W, R, R @ xi, False, mu, L, ldet, zeta, rng
    )
    np.testing.assert_allclose(again, logq, rtol=1e-12)


# ------------------------------------------------------------------------------------------------
# the sampler against the known prior (likelihood switched off)
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("alpha", "discount"), [(1.5, 0.3), (2.0, 0.0)])
def test_prior_only_chain_samples_the_pitman_yor_prior_of_k(alpha, discount):
    n = 12
    X = np.random.default_rng(0).normal(size=(n, 2))
    model = PitmanYorGMM(
        **PYP,
        alpha=alpha,
        discount=discount,
        n_iter=6000,
        burn_in=200,
        n_chains=1,
        prior_only=True,
        random_state=1,
        progress=False,
    ).fit(X)
    assert_samples_prior_of_k(model, pitman_yor_prior_k(n, alpha, discount))


def test_prior_only_chain_samples_the_hyperpriors():
    n, D = 10, 2
    X = np.random.default_rng(0).normal(size=(n, D))
    model = PitmanYorGMM(
        **PYP, n_iter=12000, burn_in=500, n_chains=1, prior_only=True, random_state=2, progress=False
    ).fit(X)
    # beta's draws are autocorrelated over tens of sweeps; KS wants them independent
    thin = slice(None, None, 60)
    d = model.discount_samples_[thin]
    a = model.alpha_samples_[thin]
    b = model.beta_samples_[thin]
    assert np.all((model.discount_samples_ >= 0) & (model.discount_samples_ < 1))
    assert np.all(model.alpha_samples_ > 0) and np.all(model.beta_samples_ > D - 1)
    assert stats.kstest(d, "uniform").pvalue > 1e-3
    assert stats.kstest(1 / a, stats.gamma(0.5, scale=2.0).cdf).pvalue > 1e-3
    assert stats.kstest(1 / (b - D + 1), stats.gamma(0.5, scale=2.0 / D).cdf).pvalue > 1e-3
    # K marginal: the exact P(K | alpha, d) averaged over the priors of alpha and d
    rng = np.random.default_rng(3)
    draws = [pitman_yor_prior_k(n, 1 / rng.gamma(0.5, 2.0), rng.uniform()) for _ in range(3000)]
    mean_k = (np.arange(n + 1) * np.mean(draws, axis=0)).sum()
    ks = model.n_clusters_samples_
    assert abs(ks.mean() - mean_k) < 4 * batch_se(ks) + 0.02


# ------------------------------------------------------------------------------------------------
# recovery and mixing on data
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("init", ["one", "kmeans"])
def test_finds_28_well_separated_clusters_from_any_start(init):
    X, y = blobs()
    model = PitmanYorGMM(n_iter=300, burn_in=150, n_chains=2, init=init, random_state=0, progress=False).fit(
        X
    )
    post = model.n_clusters_posterior()
    summary = model.n_clusters_summary_
    # the headline (posterior mode and median), the point estimate and the MAP sample all equal the truth
    assert max(post, key=post.get) == summary["mode"] == 28 and summary["median"] == 28
    assert model.n_clusters_ == model.map_n_clusters_ == 28
    assert pairwise_accuracy(y, model.labels_) == 1.0
    assert pairwise_accuracy(y, model.predict(X)) == 1.0
    assert pairwise_accuracy(y, model.predict(X, using="point")) == 1.0


def test_single_site_gibbs_alone_stays_stuck_from_one_cluster():
    # the reason for the split-merge moves: without them a merged start barely splits
    X, _ = blobs()
    model = PitmanYorGMM(
        n_iter=60, burn_in=30, n_chains=1, init="one", n_split_merge=0, random_state=0, progress=False
    ).fit(X)
    assert model.n_clusters_samples_.max() < 28


def test_split_merge_moves_leave_the_posterior_unchanged():
    # 1-D, three overlapping groups: single-site Gibbs mixes here, so both chains can be compared
    rng = np.random.default_rng(5)
    X = np.concatenate([rng.normal(m, 1.0, size=(10, 1)) for m in (-2.5, 0.0, 2.5)])
    common = dict(**PYP, alpha=1.0, discount=0.2, n_iter=8000, burn_in=500, n_chains=1, progress=False)
    with_moves = PitmanYorGMM(n_split_merge=3, random_state=1, **common).fit(X).n_clusters_samples_
    without = PitmanYorGMM(n_split_merge=0, random_state=2, **common).fit(X).n_clusters_samples_
    se = math.hypot(batch_se(with_moves), batch_se(without))
    assert abs(with_moves.mean() - without.mean()) < 4 * se
    for k in (1, 2, 3):
        a, b = (with_moves == k).astype(float), (without == k).astype(float)
        assert abs(a.mean() - b.mean()) < 4 * math.hypot(batch_se(a), batch_se(b)) + 0.01


def test_posterior_of_k_agrees_with_the_independent_numpy_reference():
    rng = np.random.default_rng(6)
    X = np.concatenate([rng.normal(m, 0.6, size=(8, 2)) for m in ((-2, 0), (2, 0), (0, 2.5))])
    ours = PitmanYorGMM(
        **PYP,
        discount=0.0,
        n_iter=4000,
        burn_in=300,
        n_chains=1,
        n_split_merge=0,
        random_state=3,
        progress=False,
    )
    ks = ours.fit(X).n_clusters_samples_
    ref = reference_gibbs(X, n_iter=1000, discount=0.0, random_state=4)
    ks_ref = ref["n_clusters"][200:]
    assert abs(ks.mean() - ks_ref.mean()) < 4 * math.hypot(batch_se(ks), batch_se(ks_ref, 20))
    al, al_ref = np.log(ours.alpha_samples_), np.log(ref["alpha"][200:])
    assert abs(al.mean() - al_ref.mean()) < 4 * math.hypot(batch_se(al), batch_se(al_ref, 20))


def test_overlapping_clusters_give_a_sensible_answer():
    rng = np.random.default_rng(7)
    X = np.concatenate([rng.normal(m, 1.0, size=(60, 2)) for m in ((0, 0), (2.5, 0), (0, 2.5))])
    y = np.repeat(np.arange(3), 60)
    model = PitmanYorGMM(n_iter=600, burn_in=200, random_state=0, progress=False).fit(X)
    # the point estimate: three substantial clusters (a few outliers may sit alone), inside the posterior of K
    assert 2 <= (np.bincount(model.labels_) >= 9).sum() <= 4
    lo, hi = model.n_clusters_summary_["interval"]
    assert lo <= model.n_clusters_ <= hi
    assert pairwise_accuracy(y, model.labels_) > 0.8


# ------------------------------------------------------------------------------------------------
# the mixture of finite mixtures and the coarsened posterior (issue 22)
# ------------------------------------------------------------------------------------------------
def test_mfm_log_v_matches_the_lah_numbers_for_gamma_one():
    # gamma = 1: sum over partitions with t blocks of prod n_c! is the Lah number C(n-1, t-1) n!/t!,
    # so V_n(t) L(n, t) must be a distribution over t
    from tactile_torch.mixture._mfm import log_v

    n = 9
    lv = log_v(n, 1.0, 4.0)
    lah = [math.comb(n - 1, t - 1) * math.factorial(n) / math.factorial(t) for t in range(1, n + 1)]
    p = np.exp(lv[1 : n + 1]) * lah
    np.testing.assert_allclose(p.sum(), 1.0, rtol=1e-10)
    np.testing.assert_allclose(p, exact_mfm_prior_k(n, 1.0, 4.0)[1:], rtol=1e-9)


@pytest.mark.parametrize(("gamma", "coarsen"), [(1.0, None), (0.6, 8.0)])
def test_prior_only_chain_samples_the_mfm_partition_prior(gamma, coarsen):
    # allocation (algorithm 8 with the MFM weights) and split-merge against exact enumeration (the
    # coarsened posterior tempers the likelihood only: its prior is the same)
    n = 8
    X = np.random.default_rng(0).normal(size=(n, 2))
    model = PitmanYorGMM(
        model="mfm",
        coarsen=coarsen,
        weight_concentration=gamma,
        k_prior_mean=3.0,
        n_iter=6000,
        burn_in=200,
        n_chains=1,
        prior_only=True,
        random_state=1,
        progress=False,
    ).fit(X)
    assert_samples_prior_of_k(model, exact_mfm_prior_k(n, gamma, 3.0))


def test_coarsened_split_merge_moves_leave_the_posterior_unchanged():
    # the Metropolis-Hastings ratio with the tempered likelihood against single-site Gibbs
    rng = np.random.default_rng(5)
    X = np.concatenate([rng.normal(m, 1.0, size=(10, 1)) for m in (-2.5, 0.0, 2.5)])
    common = dict(model="mfm", coarsen=20.0, n_iter=8000, burn_in=500, n_chains=1, progress=False)
    with_moves = PitmanYorGMM(n_split_merge=3, random_state=1, **common).fit(X).n_clusters_samples_
    without = PitmanYorGMM(n_split_merge=0, random_state=2, **common).fit(X).n_clusters_samples_
    se = math.hypot(batch_se(with_moves), batch_se(without))
    assert abs(with_moves.mean() - without.mean()) < 4 * se
    for k in (1, 2, 3):
        a, b = (with_moves == k).astype(float), (without == k).astype(float)
        assert abs(a.mean() - b.mean()) < 4 * math.hypot(batch_se(a), batch_se(b)) + 0.01


def test_pitman_yor_option_reproduces_the_study_sampler():
    # model="pyp", coarsen=None runs the study's sampler: its chain agrees with the numpy reference
    # (above) and its zeta is 1; here: alpha and d are sampled and reported, as before
    X, _ = blobs(n_clusters=3, per=15, dim=2)
    model = PitmanYorGMM(
        model="pyp", coarsen=None, n_iter=60, burn_in=20, n_chains=2, random_state=0, progress=False
    )
    model.fit(X)
    assert model.zeta_ == 1.0
    assert {r["quantity"] for r in model.convergence_} == {"K", "alpha", "d"}
    assert np.ptp(model.alpha_samples_) > 0 and np.ptp(model.discount_samples_) > 0
    with pytest.raises(ValueError, match="coarsen needs model='mfm'"):
        PitmanYorGMM(model="pyp", coarsen=50.0, n_iter=5, burn_in=1, progress=False).fit(X)


def test_progress_pool_runs_chains_on_its_threads_and_closes_the_bar():
    """The one pool and progress bar of the chains (mixture._chains.progress_pool), on success and on error."""
    import threading

    from tactile_torch.mixture._chains import progress_pool

    with progress_pool(3, 30, workers=2, progress=True) as (pool, bar):
        names = set(pool.map(lambda _: (bar.update(10), threading.current_thread().name)[1], range(3)))
        assert bar.n == 30 and bar.total == 30 and not bar.disable and pool._max_workers == 2
    assert 1 <= len(names) <= 2 and threading.current_thread().name not in names
    assert pool._shutdown and bar.disable  # tqdm marks a closed bar disabled
    with pytest.raises(RuntimeError, match="a chain failed"), progress_pool(1, 5, 4, True) as (pool, bar):
        assert pool._max_workers == 1  # min(workers, chains)
        raise RuntimeError("a chain failed")
    assert pool._shutdown and bar.disable
    with progress_pool(2, 5, 2, progress=False) as (pool, bar):
        assert bar.disable


def test_components_given_clusters_recover_the_prior_of_k_from_the_prior_of_the_clusters():
    # Rao-Blackwellisation of K (Miller & Harrison 2018): sum_t P(K = k | T = t) P(T = t) must be the
    # geometric prior p(k), with P(T = t) from enumerating every partition
    from tactile_torch.mixture._mfm import components_given_clusters, log_prior_k

    n, gamma, k_mean = 7, 0.7, 3.0
    p_t = exact_mfm_prior_k(n, gamma, k_mean)
    span = 120
    p_k = sum(
        p_t[t] * components_given_clusters(n, gamma, k_mean, t, span)[: n + span - 10]
        for t in range(1, n + 1)
    )
    k = np.arange(1, 40)
    np.testing.assert_allclose(p_k[1:40], np.exp(log_prior_k(k, k_mean)), rtol=1e-9, atol=1e-15)


def test_restricted_split_merge_still_samples_the_mfm_prior():
    # the sequential moves are the default; the restricted-Gibbs ones (split_merge="restricted") stay exact
    n = 8
    X = np.random.default_rng(0).normal(size=(n, 2))
    model = PitmanYorGMM(
        model="mfm", k_prior_mean=3.0, split_merge="restricted", n_iter=6000, burn_in=200, n_chains=1,
        prior_only=True, random_state=1, progress=False,
    ).fit(X)  # fmt: skip
    assert model.split_merge_stats_["split_accepted"] > 100
    assert_samples_prior_of_k(model, exact_mfm_prior_k(n, 1.0, 3.0))
