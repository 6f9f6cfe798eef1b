"""Tests of tactile_torch.mixture: the Pitman-Yor Gaussian mixture sampler, its densities and its outputs."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import torch
from scipy import stats
from scipy.special import gammaln, multigammaln
from sklearn.base import clone
from sklearn.exceptions import NotFittedError

from tactile_torch.metrics import pairwise_accuracy
from tactile_torch.mixture import (
    GaussianMixtureClassifier,
    PitmanYorGMM,
    baseline_clusterings,
    ess_bulk,
    ess_tail,
    expected_loss,
    gaussian_mixture_scores,
    minimize_expected_loss,
    pitman_yor_prior_k,
    posterior_similarity,
    rhat,
    variation_of_information,
)
from tactile_torch.mixture._gibbs import conditionals, densities, linalg
from tactile_torch.robot.discovery import SurfaceDiscovery
from tactile_torch.studies.clustering import have_vibration_features

from .reference_mixture import reference_gibbs

PYP = {"model": "pyp", "coarsen": None}
"""The study's Pitman-Yor mixture (the estimator's default model is the mixture of finite mixtures)."""

# Short chains in these tests: their R-hat warnings are expected, not failures.
pytestmark = pytest.mark.filterwarnings("ignore:PitmanYorGMM. R-hat:RuntimeWarning")


def blobs(n_clusters=28, per=50, dim=3, spread=0.3, box=20.0, seed=0):
    """Well-separated Gaussian clusters (the study's 28 surfaces x 50 windows in PCA-3 space)."""
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-box, box, size=(n_clusters, dim))
    while True:  # keep the centres at least 3 units apart so that the clusters are well separated
        d = np.linalg.norm(centers[:, None] - centers[None], axis=-1) + np.eye(n_clusters) * 1e9
        if d.min() > 3.0:
            break
        centers[np.argmin(d.min(1))] = rng.uniform(-box, box, size=dim)
    X = np.concatenate([rng.normal(c, spread, size=(per, dim)) for c in centers])
    return X, np.repeat(np.arange(n_clusters), per)


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
        7, mean, scat, mu0, beta, W, R, R @ xi, True, mu, L, 0.0, zeta, rng
    )
    S = L @ L.T
    P = beta * W + zeta * (pts - mu0).T @ (pts - mu0)
    want = stats.wishart(df=beta + zeta * 7, scale=np.linalg.inv(P)).logpdf(S)
    lam = R + zeta * 7 * S
    m = np.linalg.solve(lam, R @ xi + zeta * S @ pts.sum(0))
    want += stats.multivariate_normal(m, np.linalg.inv(lam)).logpdf(mu)
    np.testing.assert_allclose(logq, want, rtol=1e-9)
    again, _ = conditionals.component_step(
        7, mean, scat, mu0, beta, W, R, R @ xi, False, mu, L, ldet, zeta, rng
    )
    np.testing.assert_allclose(again, logq, rtol=1e-12)


# ------------------------------------------------------------------------------------------------
# the sampler against the known prior (likelihood switched off)
# ------------------------------------------------------------------------------------------------
def _batch_se(x, n_batches=40):
    b = np.asarray(x, dtype=np.float64)[: len(x) // n_batches * n_batches].reshape(n_batches, -1).mean(1)
    return b.std(ddof=1) / math.sqrt(n_batches)


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
    ks = model.n_clusters_samples_
    exact = pitman_yor_prior_k(n, alpha, discount)
    # mean of K within 4 batch-means standard errors (autocorrelation accounted for)
    mean_k = (np.arange(n + 1) * exact).sum()
    assert abs(ks.mean() - mean_k) < 4 * _batch_se(ks)
    # every frequency within 4.5 batch-means standard errors (+ a floor for values rarely seen)
    for k in range(1, n + 1):
        ind = (ks == k).astype(float)
        se = max(_batch_se(ind), math.sqrt(exact[k] * (1 - exact[k]) / len(ks)), 1e-3)
        assert abs(ind.mean() - exact[k]) < 4.5 * se, (k, ind.mean(), exact[k])
    st = model.split_merge_stats_
    assert st["split_accepted"] > 100 and st["merge_accepted"] > 100  # the moves were exercised


def test_prior_only_chain_samples_the_hyperpriors():
    n, D = 10, 2
    X = np.random.default_rng(0).normal(size=(n, D))
    model = PitmanYorGMM(
        **PYP, n_iter=12000, burn_in=500, n_chains=1, prior_only=True, random_state=2, progress=False
    ).fit(X)
    thin = slice(None, None, 20)
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
    assert abs(ks.mean() - mean_k) < 4 * _batch_se(ks) + 0.02


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
    se = math.hypot(_batch_se(with_moves), _batch_se(without))
    assert abs(with_moves.mean() - without.mean()) < 4 * se
    for k in (1, 2, 3):
        a, b = (with_moves == k).astype(float), (without == k).astype(float)
        assert abs(a.mean() - b.mean()) < 4 * math.hypot(_batch_se(a), _batch_se(b)) + 0.01


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
    assert abs(ks.mean() - ks_ref.mean()) < 4 * math.hypot(_batch_se(ks), _batch_se(ks_ref, 20))
    al, al_ref = np.log(ours.alpha_samples_), np.log(ref["alpha"][200:])
    assert abs(al.mean() - al_ref.mean()) < 4 * math.hypot(_batch_se(al), _batch_se(al_ref, 20))


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
# degenerate data, reproducibility, outputs
# ------------------------------------------------------------------------------------------------
def _assert_finite_chain(model):
    for name, tr in model.trace_.items():
        assert np.all(np.isfinite(tr)), name
    assert np.all(np.isfinite(model.means_)) and np.all(np.isfinite(model.covariances_))


@pytest.mark.parametrize(
    "case",
    ["duplicated", "identical", "single", "one_dim", "constant_feature"],
)
def test_degenerate_data_give_finite_defined_results(case, n_iter=300):
    rng = np.random.default_rng(0)
    X = {
        "duplicated": np.repeat(rng.normal(size=(20, 3)) * [1, 5, 9], 2, axis=0),
        "identical": np.full((30, 2), 3.5),
        "single": np.array([[1.0, -2.0, 0.5]]),
        "one_dim": np.concatenate([rng.normal(0, 0.1, (20, 1)), rng.normal(5, 0.1, (20, 1))]),
        "constant_feature": np.column_stack([rng.normal(size=40), np.ones(40)]),
    }[case]
    model = PitmanYorGMM(n_iter=n_iter, burn_in=n_iter // 2, random_state=0, progress=False).fit(X)
    _assert_finite_chain(model)
    assert np.all(np.isfinite(model.score_samples(X)))
    proba = model.predict_proba(X)
    np.testing.assert_allclose(proba.sum(1), 1.0, rtol=1e-12)
    if case == "single":
        assert model.n_clusters_ == 1 and model.labels_.tolist() == [0]
    if case == "one_dim":
        assert model.n_clusters_ == 2


@pytest.mark.slow
@pytest.mark.parametrize("case", ["duplicated", "identical", "single", "one_dim", "constant_feature"])
def test_degenerate_data_long_chains(case):
    test_degenerate_data_give_finite_defined_results(case, n_iter=10000)


def test_seeded_runs_are_reproducible_whatever_the_threads():
    X, _ = blobs(n_clusters=4, per=15, dim=2)
    common = dict(n_iter=60, burn_in=10, n_chains=2, progress=False)
    a = PitmanYorGMM(random_state=11, n_jobs=1, **common).fit(X)
    b = PitmanYorGMM(random_state=11, n_jobs=2, **common).fit(X)
    c = PitmanYorGMM(random_state=12, **common).fit(X)
    for k in a.trace_:
        np.testing.assert_array_equal(a.trace_[k], b.trace_[k])
    np.testing.assert_array_equal(a.labels_samples_, b.labels_samples_)
    np.testing.assert_array_equal(a.predict(X), b.predict(X))
    assert not np.array_equal(a.trace_["beta"], c.trace_["beta"])
    assert a.trace_["n_clusters"].shape == (2, 60) and a.n_clusters_samples_.shape == (100,)
    gen = PitmanYorGMM(n_iter=20, burn_in=5, random_state=torch.Generator().manual_seed(3), progress=False)
    assert gen.fit(X).n_iter_ == 20


def test_point_estimate_components_match_scipy_and_the_torch_graph():
    X, _ = blobs(n_clusters=3, per=20, dim=2, spread=1.0, box=4.0)
    model = PitmanYorGMM(n_iter=100, burn_in=50, n_chains=2, random_state=0, progress=False).fit(X)
    Xt = np.random.default_rng(9).normal(size=(25, 2)) * 4
    comps = np.stack(
        [
            np.log(w) + stats.multivariate_normal(m, c).logpdf(Xt)
            for w, m, c in zip(model.weights_, model.means_, model.covariances_, strict=True)
        ],
        axis=1,
    )
    np.testing.assert_allclose(model.score_samples(Xt), np.logaddexp.reduce(comps, axis=1), rtol=1e-10)
    want = np.exp(comps - np.logaddexp.reduce(comps, axis=1)[:, None])
    np.testing.assert_allclose(model.predict_proba(Xt, using="point"), want, atol=1e-10)
    np.testing.assert_allclose(model.weights_.sum(), 1.0)
    # the point estimate's components are the posterior means given labels_: close to each cluster's mean
    for k in range(model.n_clusters_):
        np.testing.assert_allclose(model.means_[k], X[model.labels_ == k].mean(0), atol=0.5)
    for U, C in zip(model.precisions_cholesky_, model.covariances_, strict=True):
        np.testing.assert_allclose(U @ U.T, np.linalg.inv(C), rtol=1e-8)
    s = gaussian_mixture_scores(
        torch.as_tensor(Xt),
        torch.as_tensor(model.means_),
        torch.as_tensor(model.precisions_cholesky_),
        torch.as_tensor(np.log(model.weights_)),
    )
    np.testing.assert_allclose(s.numpy(), comps, rtol=1e-10)
    # novelty of the graph (float64) = predict(using="point") == -1
    far = np.concatenate([Xt, [[40.0, -40.0], [60.0, 60.0]]])
    labels, _, novel = model.to_module().double()(torch.as_tensor(far))
    point = model.predict(far, using="point")
    np.testing.assert_array_equal(novel.numpy(), point == -1)
    np.testing.assert_array_equal(labels.numpy()[point >= 0], point[point >= 0])
    assert novel[-2:].all()


def test_posterior_predictive_averages_the_samples_and_flags_withheld_clusters():
    X, y = blobs(n_clusters=6, per=30, dim=3, seed=4)
    train, new = y < 5, y == 5
    model = PitmanYorGMM(n_iter=200, burn_in=80, n_chains=2, random_state=0, progress=False).fit(X[train])
    proba = model.predict_proba(X)
    np.testing.assert_allclose(proba.sum(1), 1.0, rtol=1e-12)
    assert proba.shape == (len(X), model.n_clusters_) and np.all(proba >= 0)
    labels = model.predict(X)
    assert pairwise_accuracy(y[train], labels[train]) == 1.0 and np.all(labels[train] >= 0)
    # the withheld surface: novel (label -1), by the sampled posterior and by the point estimate
    assert np.mean(labels[new] == -1) > 0.9
    assert np.mean(model.predict(X[new], using="point") == -1) > 0.9
    p_new = model.novelty_proba(X)
    assert p_new[new].min() > 0.5 > p_new[train].max()


def test_point_estimate_is_central_in_the_posterior_of_k_with_near_duplicate_clusters():
    # pairs of clusters whose centres are 1.5 standard deviations apart: the posterior hesitates
    # between merging and splitting each pair; the reported K must sit in its central part
    rng = np.random.default_rng(3)
    centres = np.array([[0, 0], [8, 0], [0, 8], [8, 8]], dtype=float)
    X = np.concatenate(
        [rng.normal(c + off, 1.0, size=(40, 2)) for c in centres for off in ([0, 0], [1.5, 0])]
    )
    model = PitmanYorGMM(n_iter=600, burn_in=200, random_state=1, progress=False).fit(X)
    ks = model.n_clusters_samples_
    lo, hi = np.quantile(ks, [0.1, 0.9])
    summary = model.n_clusters_summary_
    assert lo <= summary["mode"] <= hi and lo <= summary["median"] <= hi
    assert lo <= model.n_clusters_ <= hi, (model.n_clusters_, lo, hi, model.summary())
    assert "K, posterior: mode" in model.summary().splitlines()[1]


def test_posterior_similarity_matches_its_definition():
    rng = np.random.default_rng(0)
    samples = rng.integers(0, 4, size=(30, 12))
    want = (samples[:, :, None] == samples[:, None, :]).mean(0)
    np.testing.assert_allclose(posterior_similarity(samples), want, rtol=1e-12)


def test_variation_of_information_matches_scikit_learn_entropies():
    from sklearn.metrics import mutual_info_score

    rng = np.random.default_rng(1)
    a, b = rng.integers(0, 5, 200), rng.integers(0, 3, 200)

    def entropy(z):
        p = np.bincount(z) / z.size
        p = p[p > 0]
        return -(p * np.log(p)).sum()

    want = (entropy(a) + entropy(b) - 2 * mutual_info_score(a, b)) / math.log(2)
    np.testing.assert_allclose(variation_of_information(a, b), want, rtol=1e-10)
    assert variation_of_information(a, a + 7) == 0.0


def _partitions(n):
    if n == 0:
        yield []
        return
    for part in _partitions(n - 1):
        for k in range(max(part, default=-1) + 2):
            yield [*part, k]


@pytest.mark.parametrize("loss", ["vi", "binder"])
def test_greedy_point_estimate_finds_the_minimum_over_every_partition(loss):
    # 7 points: all 877 partitions enumerated; samples drawn around two competing answers
    rng = np.random.default_rng(2)
    base = [np.array([0, 0, 0, 1, 1, 2, 2]), np.array([0, 0, 1, 1, 1, 2, 2])]
    samples = np.stack(
        [np.where(rng.random(7) < 0.15, rng.integers(0, 4, 7), base[i % 2]) for i in range(40)]
    )
    every = [np.array(p) for p in _partitions(7)]
    assert len(every) == 877  # Bell number B_7
    losses = [expected_loss(p, samples, loss) for p in every]
    labels, value = minimize_expected_loss(samples, loss)
    assert value == pytest.approx(min(losses), abs=1e-12)
    assert expected_loss(labels, samples, loss) == pytest.approx(value, abs=1e-12)


# R-hat and ESS against ArviZ: the values below were computed with arviz_stats 0.8.0
# (``array_stats.rhat(x, method="rank")``, ``ess(x, method="bulk")``,
# ``ess(x, method="tail", prob=(0.05, 0.95))``) on the draws of _arviz_draws().
_ARVIZ = {
    "x": (1.024211179933232, 136.11173569495955, 269.4108379393411),
    "k": (1.0229377501769332, 138.26162396527627, 306.20633148099245),
}


def _arviz_draws():
    rng = np.random.default_rng(7)
    e = rng.standard_normal((4, 301))
    x = np.zeros_like(e)
    for t in range(1, e.shape[1]):
        x[:, t] = 0.8 * x[:, t - 1] + e[:, t]
    x[1] += 0.4  # one chain off: R-hat > 1
    return {"x": x, "k": np.round(2 * x)}  # k: integer-valued with ties, like K


@pytest.mark.parametrize("name", ["x", "k"])
def test_rhat_and_ess_match_arviz(name):
    draws = _arviz_draws()[name]
    want_rhat, want_bulk, want_tail = _ARVIZ[name]
    assert rhat(draws) == pytest.approx(want_rhat, rel=1e-10)
    assert ess_bulk(draws) == pytest.approx(want_bulk, rel=1e-10)
    assert ess_tail(draws) == pytest.approx(want_tail, rel=1e-10)


def test_convergence_diagnostics_are_reported_and_warned():
    X, _ = blobs(n_clusters=4, per=20, dim=2)
    model = PitmanYorGMM(**PYP, n_iter=120, burn_in=40, random_state=0, progress=False).fit(X)
    assert [r["quantity"] for r in model.convergence_] == ["K", "alpha", "d"]
    assert [
        r["quantity"]
        for r in PitmanYorGMM(n_iter=120, burn_in=40, random_state=0, progress=False).fit(X).convergence_
    ] == ["K"]
    assert "R-hat" in model.summary() and "ESS" in model.summary()
    # chains stuck in different places (no split-merge, one-cluster vs k-means starts are not mixed)
    rng = np.random.default_rng(0)
    Y = np.concatenate([rng.normal(m, 0.3, size=(40, 1)) for m in range(0, 40, 4)])
    stuck = PitmanYorGMM(
        **PYP, n_iter=60, burn_in=20, n_split_merge=0, init="one", random_state=0, progress=False
    )
    with pytest.warns(RuntimeWarning, match=r"R-hat > 1.01 .* after 60 sweeps per chain.*n_iter='auto'"):
        stuck.set_params(n_chains=3).fit(Y)
    assert "WARNING: R-hat > 1.01" in stuck.summary()
    # n_iter="auto": the warning only when the budget ran out, and it names the budget
    with pytest.warns(RuntimeWarning, match=r"after 40 sweeps per chain.*raise max_iter \(now 40\)"):
        stuck.set_params(n_iter="auto", max_iter=40, burn_in=10).fit(Y)
    assert stuck.budget_exhausted_ and stuck.n_iter_ == 40


def test_auto_run_length_stops_at_the_targets():
    X, _ = blobs(n_clusters=3, per=20, dim=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # converged: no warning
        model = PitmanYorGMM(n_chains=2, random_state=0, progress=False).fit(X)
    assert model.n_iter_ == 1000 and not model.budget_exhausted_  # the first round was enough
    conv = {r["quantity"]: r for r in model.convergence_}
    assert conv["K"]["R-hat"] < 1.01
    assert model.labels_samples_.shape[1] <= 200 and model.labels_sweeps_.min() >= 250


def test_map_and_binder_point_estimates_are_available():
    X, y = blobs(n_clusters=3, per=15, dim=2)
    common = dict(n_iter=80, burn_in=20, n_chains=2, random_state=0, progress=False)
    vi = PitmanYorGMM(**common).fit(X)
    binder = PitmanYorGMM(point_estimate="binder", **common).fit(X)
    map_ = PitmanYorGMM(point_estimate="map", **common).fit(X)
    np.testing.assert_array_equal(map_.labels_, vi.map_labels_)
    for m in (vi, binder, map_):
        assert pairwise_accuracy(y, m.labels_) == 1.0
    assert 0.0 <= binder.expected_loss_ <= 1.0


def test_map_component_module_exports_to_onnx(tmp_path):
    from tactile_torch._onnx import export_onnx, run_onnx

    X, _ = blobs(n_clusters=3, per=20, dim=3, spread=0.5, box=5.0)
    model = PitmanYorGMM(n_iter=60, burn_in=20, n_chains=2, random_state=0, progress=False).fit(X)
    module = model.to_module()
    assert isinstance(module, GaussianMixtureClassifier)
    path = export_onnx(module, (torch.zeros(2, 3),), tmp_path / "map.onnx", input_names=["features"])
    x = torch.as_tensor(
        np.concatenate([X[:15], [[50.0, 50.0, 50.0], [-60.0, 0.0, 0.0]]]), dtype=torch.float32
    )
    labels, log_resp, novel = run_onnx(path, x)  # batch 17, exported with 2
    want_labels, want_log_resp, want_novel = module(x)
    np.testing.assert_array_equal(labels, want_labels.numpy())
    np.testing.assert_array_equal(novel, want_novel.numpy())
    np.testing.assert_array_equal(labels[:15], model.predict(X[:15], using="point"))
    assert novel.tolist() == [False] * 15 + [True, True]
    np.testing.assert_allclose(log_resp, want_log_resp.numpy(), rtol=1e-5, atol=1e-4)


def test_scikit_learn_conventions_and_tensor_input():
    X, y = blobs(n_clusters=3, per=15, dim=2)
    model = PitmanYorGMM(**PYP, alpha=1.0, n_iter=50, burn_in=10, n_chains=2, random_state=0, progress=False)
    twin = clone(model)
    assert twin.get_params() == model.get_params()
    labels = model.fit_predict(torch.as_tensor(X, dtype=torch.float32))
    assert pairwise_accuracy(y, labels) == 1.0
    assert np.all(model.alpha_samples_ == 1.0)


def test_baselines_come_from_scikit_learn():
    X, y = blobs(n_clusters=4, per=25, dim=3)
    out = baseline_clusterings(X, 4, max_components=6, random_state=0)
    assert set(out) == {"kmeans", "em", "em_bic", "variational_dp"}
    for name, res in out.items():
        assert res["labels"].shape == (100,) and res["seconds"] >= 0
        if name != "variational_dp":
            assert pairwise_accuracy(y, res["labels"]) == 1.0, name
    assert out["em_bic"]["n_clusters"] == 4


def test_surface_discovery_proposes_after_n_consecutive_novel_windows():
    d = SurfaceDiscovery(n_consecutive=3, known_names=["a", "b"])
    flags = [False, True, True, False, True, True, True, True, False, True, True, True]
    verdicts = [d.update(0, f) for f in flags]
    assert [v.proposed for v in verdicts].count(True) == 2
    assert [v.name for v in verdicts][4:9] == ["a", "a", "new surface 1", "new surface 1", "a"]
    assert d.proposals == [
        {"name": "new surface 1", "first_window": 4, "windows": 4},
        {"name": "new surface 2", "first_window": 9, "windows": 3},
    ]
    with pytest.raises(ValueError, match="n_consecutive must be an int >= 1, got 0"):
        SurfaceDiscovery(n_consecutive=0)


# ------------------------------------------------------------------------------------------------
# errors
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        (dict(n_iter=0), ValueError, "'n_iter' parameter of PitmanYorGMM must be an int in the range"),
        (dict(n_iter=10, burn_in=10), ValueError, "burn_in must be < n_iter"),
        (dict(n_iter=2.5), TypeError, "'n_iter' parameter of PitmanYorGMM must be an int"),
        (dict(n_aux=0), ValueError, "'n_aux' parameter"),
        (dict(n_chains=0), ValueError, "'n_chains' parameter"),
        (dict(n_split_merge=-1), ValueError, "'n_split_merge' parameter"),
        (dict(thin=0), ValueError, "'thin' parameter"),
        (
            dict(discount=1.0),
            ValueError,
            r"'discount' parameter of PitmanYorGMM must be a float in the range \[0.0, 1.0\)",
        ),
        (dict(discount=0.3, alpha=-0.5), ValueError, "alpha must be > -discount"),
        (dict(alpha="big"), TypeError, "'alpha' parameter"),
        (dict(init="spectral"), ValueError, "'init' parameter"),
        (dict(point_estimate="mean"), ValueError, "'point_estimate' parameter"),
        (dict(init=np.zeros(3)), ValueError, r"init as labels must have shape \(20,\)"),
        (dict(random_state="seed"), ValueError, "'random_state' parameter"),
        (dict(n_iter="long"), ValueError, "'n_iter' parameter of PitmanYorGMM must be an int"),
        (dict(model="dp"), ValueError, "'model' parameter"),
        (dict(coarsen=0.0), ValueError, "'coarsen' parameter"),
        (dict(model="mfm", alpha=1.0), ValueError, "alpha and discount apply to model='pyp'"),
        (dict(n_iter="auto", max_iter=10, burn_in=10), ValueError, "burn_in must be < max_iter"),
    ],
)
def test_bad_parameters_raise(kwargs, exc, match):
    X = np.random.default_rng(0).normal(size=(20, 2))
    params = dict(n_iter=5, burn_in=1, n_chains=1, progress=False) | kwargs
    if "alpha" in kwargs or "discount" in kwargs:
        params = PYP | params
    model = PitmanYorGMM(**params)  # nothing is validated before fit
    with pytest.raises(exc, match=match):
        model.fit(X)


@pytest.mark.parametrize(
    ("X", "match"),
    [
        (np.zeros(5), "Expected 2D array, got 1D array instead"),
        (np.zeros((0, 3)), "minimum of 1 is required"),
        (np.array([[0.0, np.nan]]), "Input X contains NaN"),
    ],
)
def test_bad_data_raise(X, match):
    with pytest.raises(ValueError, match=match):
        PitmanYorGMM(n_iter=3, burn_in=0, n_chains=1, progress=False).fit(X)


def test_predict_before_fit_and_wrong_width_raise():
    model = PitmanYorGMM(n_iter=5, burn_in=1, n_chains=1, progress=False)
    for method in (model.predict, model.predict_proba, model.novelty_proba, model.score_samples):
        with pytest.raises(NotFittedError, match="not fitted yet"):
            method(np.zeros((2, 2)))
    model.fit(np.random.default_rng(0).normal(size=(10, 2)))
    with pytest.raises(ValueError, match="X has 3 features, but PitmanYorGMM is expecting 2 features"):
        model.predict(np.zeros((4, 3)))
    with pytest.raises(ValueError, match="using must be 'samples' or 'point', got 'map'"):
        model.predict(np.zeros((4, 2)), using="map")


def test_prior_k_rejects_bad_parameters():
    with pytest.raises(ValueError, match="alpha > -discount"):
        pitman_yor_prior_k(5, -0.5, 0.2)


# ------------------------------------------------------------------------------------------------
# command line and report
# ------------------------------------------------------------------------------------------------
def test_cli_cluster_writes_the_clustering(tmp_path, capsys):
    from tactile_torch.cli import main

    X, y = blobs(n_clusters=3, per=15, dim=2)
    np.savez(tmp_path / "f.npz", features=X, labels=y)
    out = tmp_path / "out"
    args = [
        "cluster",
        "--data",
        str(tmp_path / "f.npz"),
        "--out",
        str(out),
        "--n-iter",
        "40",
        "--burn-in",
        "10",
    ]
    assert main([*args, "--quiet", "--seed", "3", "--chains", "2"]) == 0
    res = np.load(out / "clustering.npz")
    assert pairwise_accuracy(y, res["labels"]) == 1.0 and res["means"].shape == (3, 2)
    assert res["n_clusters_samples"].shape == (60,)  # 2 chains x 30 sweeps after burn-in
    summary = (out / "summary.txt").read_text()
    assert summary.splitlines()[1].startswith("K, posterior: mode 3")
    assert "pairwise accuracy: point estimate 1.0000" in summary
    assert (out / "model.npz").is_file()  # for tactile-torch export (tests/test_pipeline.py)
    np.savez(tmp_path / "bad.npz", X=X)
    assert main(["cluster", "--data", str(tmp_path / "bad.npz"), "--out", str(out)]) == 2
    assert "or a feature matrix ('features'), found keys ['X']" in capsys.readouterr().err


def test_cli_cluster_says_in_one_line_what_a_recordings_file_lacks(tmp_path, capsys):
    from tactile_torch.cli import BAD_INPUT_EXIT, main
    from tactile_torch.data.stylus import make_vibration_recordings

    rec = make_vibration_recordings(3, duration_s=1.0, random_state=0)
    signals = np.stack(rec.signals)
    common = ["--window", "400", "--n-iter", "30", "--burn-in", "10", "--quiet", "--out", str(tmp_path / "o")]
    for name, arrays, missing in (
        ("nolabels.npz", dict(signals=signals, rate_hz=rec.rate_hz), "'labels', 'class_names'"),
        ("norate.npz", dict(signals=signals, labels=rec.labels, class_names=rec.class_names), "'rate_hz'"),
    ):
        np.savez(tmp_path / name, **arrays)
        assert main(["cluster", "--data", str(tmp_path / name), *common]) == BAD_INPUT_EXIT
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and f"missing {missing}" in err, err


def test_clustering_study_quick_mode_writes_its_section(tmp_path):
    import json

    from tactile_torch.studies import run_report

    path = run_report(tmp_path, quick=True, only=["clustering"], log=lambda s: None)
    text = path.read_text()
    assert "## Clustering: how many surfaces" in text
    assert "Pitman-Yor mixture: point estimate" in text and "variational DP mixture" in text
    assert "Table 1" in text and "Novelty" in text and "R-hat" in text
    for name in (
        "clustering-posterior-k",
        "clustering-similarity",
        "clustering-accuracy-along-chain",
        "clustering-discount",
        "clustering-confusion",
        "clustering-learning-curve",
    ):
        assert (tmp_path / "figures" / f"{name}.png").exists(), name
    tables = json.loads((tmp_path / "report.json").read_text())["sections"][0]["tables"]
    pyp, kmeans = tables[0]["rows"][0], tables[0]["rows"][2]
    # a smoke run on 6 windows of 6 surfaces (two pairs deliberately alike): a plausible K and accuracy
    assert pyp["method"].startswith("Pitman-Yor") and 2 <= pyp["K found"] <= 2 * kmeans["K found"]
    assert pyp["pairwise accuracy"] > 0.7


def test_learning_curve_rows():
    from tactile_torch.studies.clustering import learning_curve, synthetic_clusters

    X, y = synthetic_clusters(4, 6, seed=1)
    rows = learning_curve(X, y, [1, 6], n_iter=40, burn_in=10, random_state=0)
    assert [(r["per class"], r["prior"], r["points"]) for r in rows] == [
        (1, "DP", 4),
        (1, "PYP", 4),
        (6, "DP", 24),
        (6, "PYP", 24),
    ]
    assert rows[-1]["pairwise accuracy"] == 1.0 and rows[-1]["K point estimate"] == 4


@pytest.mark.slow
def test_real_accelerometer_sets_go_through_the_clustering_study(shared_data, tmp_path):
    # real-data counterpart of test_clustering_study_quick_mode_writes_its_section (synthetic data)
    if not have_vibration_features():
        pytest.skip("tactile_torch.signal (the vibration features) is not installed")
    from tactile_torch.report import Report
    from tactile_torch.studies import RunContext
    from tactile_torch.studies.clustering import real_data

    shared_data("hapmat_imu5")
    section = Report(tmp_path).section("real")
    real_data(section, RunContext(quick=True), n_iter=40, burn_in=15)
    k_rows, novelty_rows = section.tables[-2]["rows"], section.tables[-1]["rows"]
    row = next(r for r in k_rows if r["data set"] == "hapmat_imu5")
    assert row["classes"] == 5 and 0.0 <= row["pairwise accuracy (point estimate)"] <= 1.0
    lo, hi = (float(v) for v in row["K 95% interval"].strip("[]").split(","))
    assert lo <= row["K posterior mode"] <= hi
    nov = next(r for r in novelty_rows if r["data"] == "hapmat_imu5")
    assert 0.0 <= nov["recall (samples)"] <= 1.0 and 0.0 <= nov["false alarms (samples)"] <= 1.0


def test_cli_stream_discover_proposes_a_surface_the_clustering_never_saw(tmp_path, monkeypatch, capsys):
    import io

    import serial

    from tactile_torch.cli import main
    from tactile_torch.data.stylus import SURFACES, make_vibration_recordings
    from tactile_torch.robot.stream import format_sample

    known = [SURFACES[0], SURFACES[5], SURFACES[7]]  # glass, cork, rubber
    rec = make_vibration_recordings(surfaces=known, duration_s=8.0, random_state=0)
    np.savez(
        tmp_path / "rec.npz",
        signals=np.stack(rec.signals),
        rate_hz=rec.rate_hz,
        labels=rec.labels,
        class_names=np.array(rec.class_names),
    )
    out = tmp_path / "cl"
    common = ["--window", "400", "--n-iter", "60", "--burn-in", "20", "--chains", "2", "--quiet"]
    assert main(["cluster", "--data", str(tmp_path / "rec.npz"), "--out", str(out), *common]) == 0
    assert main(["export", "--model", str(out / "model.npz"), "--out", str(tmp_path / "cl.onnx")]) == 0
    # the stream: a known surface, then one the clustering never saw (the coarsest sandpaper)
    unseen = make_vibration_recordings(surfaces=[SURFACES[27]], duration_s=4.0, random_state=1).signals[0]
    stream = np.concatenate([rec.signals[0][:2000], unseen])
    lines = b"".join(format_sample(s) for s in stream)
    monkeypatch.setattr(serial, "serial_for_url", lambda *a, **k: io.BytesIO(lines))
    capsys.readouterr()
    args = [
        "stream",
        "--model",
        str(tmp_path / "cl.onnx"),
        "--port",
        "test://",
        "--step",
        "400",
        "--max-windows",
        "13",
    ]
    assert main([*args, "--discover", "3"]) == 0
    printed = capsys.readouterr().out
    assert "new surface proposed: new surface 1" in printed
    lines = printed.splitlines()
    novel = [i for i, line in enumerate(lines) if line.startswith("  novel window")]
    assert len(novel) >= 3 and lines[novel[-1]] == "  novel window -> new surface 1"
    assert novel[0] > 5  # the first windows (a known surface) are not novel


# ------------------------------------------------------------------------------------------------
# the mixture of finite mixtures and the coarsened posterior (issue 22)
# ------------------------------------------------------------------------------------------------
def _set_partitions(n):
    """Every set partition of n items as a restricted growth string (labels 0 .. K-1)."""
    z = [0] * n

    def rec(i, k):
        if i == n:
            yield list(z)
            return
        for c in range(k + 1):
            z[i] = c
            yield from rec(i + 1, max(k, c + 1))

    yield from rec(1, 1) if n > 1 else iter([[0]])


def _exact_prior_k(n, gamma, k_mean):
    """P(K) of the MFM partition prior by enumerating every set partition of n items."""
    from tactile_torch.mixture._mfm import log_v

    lv = log_v(n, gamma, k_mean)
    p = np.zeros(n + 1)
    for z in _set_partitions(n):
        counts = np.bincount(z)
        t = counts.size
        p[t] += math.exp(lv[t] + (gammaln(counts + gamma) - gammaln(gamma)).sum())
    return p / p.sum()


def test_mfm_log_v_matches_the_lah_numbers_for_gamma_one():
    # gamma = 1: sum over partitions with t blocks of prod n_c! is the Lah number C(n-1, t-1) n!/t!,
    # so V_n(t) L(n, t) must be a distribution over t
    from tactile_torch.mixture._mfm import log_v

    n = 9
    lv = log_v(n, 1.0, 4.0)
    lah = [math.comb(n - 1, t - 1) * math.factorial(n) / math.factorial(t) for t in range(1, n + 1)]
    p = np.exp(lv[1 : n + 1]) * lah
    np.testing.assert_allclose(p.sum(), 1.0, rtol=1e-10)
    np.testing.assert_allclose(p, _exact_prior_k(n, 1.0, 4.0)[1:], rtol=1e-9)


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
    ks = model.n_clusters_samples_
    exact = _exact_prior_k(n, gamma, 3.0)
    assert abs(ks.mean() - (np.arange(n + 1) * exact).sum()) < 4 * _batch_se(ks)
    for k in range(1, n + 1):
        ind = (ks == k).astype(float)
        se = max(_batch_se(ind), math.sqrt(exact[k] * (1 - exact[k]) / len(ks)), 1e-3)
        assert abs(ind.mean() - exact[k]) < 4.5 * se, (k, ind.mean(), exact[k])
    st = model.split_merge_stats_
    assert st["split_accepted"] > 100 and st["merge_accepted"] > 100


def test_coarsened_split_merge_moves_leave_the_posterior_unchanged():
    # the Metropolis-Hastings ratio with the tempered likelihood against single-site Gibbs
    rng = np.random.default_rng(5)
    X = np.concatenate([rng.normal(m, 1.0, size=(10, 1)) for m in (-2.5, 0.0, 2.5)])
    common = dict(model="mfm", coarsen=20.0, n_iter=8000, burn_in=500, n_chains=1, progress=False)
    with_moves = PitmanYorGMM(n_split_merge=3, random_state=1, **common).fit(X).n_clusters_samples_
    without = PitmanYorGMM(n_split_merge=0, random_state=2, **common).fit(X).n_clusters_samples_
    se = math.hypot(_batch_se(with_moves), _batch_se(without))
    assert abs(with_moves.mean() - without.mean()) < 4 * se
    for k in (1, 2, 3):
        a, b = (with_moves == k).astype(float), (without == k).astype(float)
        assert abs(a.mean() - b.mean()) < 4 * math.hypot(_batch_se(a), _batch_se(b)) + 0.01


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


@pytest.mark.parametrize("model_name", ["mfm", "pyp"])
def test_predictions_are_finite_for_every_finite_input(model_name):
    X, _ = blobs(n_clusters=3, per=15, dim=2)
    kw = {"model": model_name} | ({"coarsen": None} if model_name == "pyp" else {})
    model = PitmanYorGMM(n_iter=60, burn_in=20, n_chains=2, random_state=0, progress=False, **kw).fit(X)
    far = np.array([[1e6, -1e6], [1e200, 1e200], [-1e300, 3.0], [0.0, 0.0]])
    with np.errstate(divide="raise", invalid="raise"), warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        for using in ("samples", "point"):
            proba = model.predict_proba(far, using=using)
            assert np.all(np.isfinite(proba)), using
            np.testing.assert_allclose(proba.sum(1), 1.0, rtol=1e-12)
            assert np.all(np.isfinite(model.novelty_proba(far, using=using)))
            labels = model.predict(far, using=using)
            assert labels[0] == -1 and labels[1] == -1  # far away: a new component
        assert np.all(np.isfinite(model.score_samples(far)))
    assert model.score_samples(far)[1] < model.score_samples(far)[0] < model.score_samples(far)[3]


def test_summary_words_and_interval_are_computed_from_the_fit():
    X, _ = blobs(n_clusters=3, per=15, dim=2)
    model = PitmanYorGMM(n_iter=80, burn_in=20, n_chains=2, random_state=0, progress=False).fit(X)
    ks = model.n_clusters_summary_
    lo, hi = ks["interval"]
    assert isinstance(lo, int) and isinstance(hi, int) and lo in model.n_clusters_samples_
    text = model.summary()
    assert f"95% interval [{lo}, {hi}]" in text
    assert "under-counts" not in text
    k = model.map_n_clusters_
    side = "equal to" if k == ks["mode"] else "below" if k < ks["mode"] else "above"
    assert f"K = {k}, {side} the posterior mode {ks['mode']}" in text
    # the interval of a posterior whose quantile falls between two values is still made of integers
    from tactile_torch.mixture._summaries import n_clusters_summary

    s = n_clusters_summary(np.array([3] * 50 + [6] * 1 + [4] * 49), 3, 5)
    assert s["interval"] == (3, 4)
