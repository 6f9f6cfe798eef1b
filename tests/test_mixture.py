"""Tests of tactile_torch.mixture: the Pitman-Yor Gaussian mixture sampler, its densities and its outputs."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy import stats
from scipy.special import gammaln, multigammaln
from sklearn.base import clone

from tactile_torch import _gibbs as g
from tactile_torch.metrics import pairwise_accuracy
from tactile_torch.mixture import (
    GaussianMixtureClassifier,
    PitmanYorGMM,
    baseline_clusterings,
    gaussian_mixture_scores,
    pitman_yor_prior_k,
)
from tactile_torch.studies.clustering import have_vibration_features

from .reference_mixture import reference_gibbs


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
    got = g.wishart_logpdf(L, np.linalg.slogdet(S)[1], nu, P, np.linalg.slogdet(P)[1])
    np.testing.assert_allclose(got, stats.wishart(df=nu, scale=V).logpdf(S), rtol=1e-10)
    x, m = rng.normal(size=D), rng.normal(size=D)
    want = stats.multivariate_normal(m, np.linalg.inv(S)).logpdf(x)
    np.testing.assert_allclose(g.normal_logpdf(x, m, L), want, rtol=1e-10)
    np.testing.assert_allclose(g._lmvgamma(3.3, D), multigammaln(3.3, D), rtol=1e-12)


def test_log_eppf_matches_its_definition():
    counts = np.array([5, 1, 3, 2], dtype=np.int64)
    act = np.arange(4, dtype=np.int64)
    for alpha, d in [(1.3, 0.0), (0.7, 0.4), (-0.2, 0.5)]:
        n, K = counts.sum(), counts.size
        # prod_{k<K} (alpha + k d) / (alpha + 1)_(n-1) * prod_j (1 - d)_(n_j - 1), rising factorials
        want = sum(math.log(alpha + k * d) for k in range(1, K))
        want -= sum(math.log(alpha + 1 + t) for t in range(n - 1))
        want += sum(math.log(1 - d + t) for c in counts for t in range(c - 1))
        np.testing.assert_allclose(g.log_eppf(counts, act, K, n, alpha, d), want, rtol=1e-12)


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
    ldet_v = -g._scale_factor(P, C)
    np.testing.assert_allclose(C @ C.T, V, rtol=1e-10, atol=1e-12)  # C C^T = P^{-1}
    L = np.empty((D, D))
    draws = np.empty((n, D, D))
    ldets = np.empty(n)
    gen = np.random.default_rng(2)
    for k in range(n):
        ldets[k] = g.wishart_draw(gen, C, ldet_v, nu, L)
        draws[k] = L @ L.T
    np.testing.assert_allclose(ldets, np.linalg.slogdet(draws)[1], rtol=1e-9)
    # mean nu V within 5 standard errors, entrywise (var of S_ab = nu (V_ab^2 + V_aa V_bb))
    se = np.sqrt(nu * (V**2 + np.outer(np.diag(V), np.diag(V))) / n)
    assert np.all(np.abs(draws.mean(0) - nu * V) < 5 * se)
    # E log|S| = log|V| + D log 2 + sum_a digamma((nu - a)/2)
    from scipy.special import digamma

    want = ldet_v + D * math.log(2) + digamma((nu - np.arange(D)) / 2).sum()
    assert abs(ldets.mean() - want) < 5 * ldets.std() / math.sqrt(n)


def test_component_step_density_is_the_product_of_its_conditionals():
    rng = np.random.default_rng(3)
    D = 3
    pts = rng.normal(size=(7, D))
    mean = pts.mean(0)
    scat = (pts - mean).T @ (pts - mean)
    mu0, xi = rng.normal(size=D), rng.normal(size=D)
    W, R = spd(rng, D) / 5, spd(rng, D) / 5
    beta = 4.2
    mu, L = np.empty(D), np.empty((D, D))
    logq, ldet = g.component_step(7, mean, scat, mu0, beta, W, R, R @ xi, True, mu, L, 0.0, rng)
    S = L @ L.T
    P = beta * W + (pts - mu0).T @ (pts - mu0)
    want = stats.wishart(df=beta + 7, scale=np.linalg.inv(P)).logpdf(S)
    lam = R + 7 * S
    m = np.linalg.solve(lam, R @ xi + S @ pts.sum(0))
    want += stats.multivariate_normal(m, np.linalg.inv(lam)).logpdf(mu)
    np.testing.assert_allclose(logq, want, rtol=1e-9)
    again, _ = g.component_step(7, mean, scat, mu0, beta, W, R, R @ xi, False, mu, L, ldet, rng)
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
        alpha=alpha,
        discount=discount,
        n_iter=6000,
        burn_in=200,
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
    model = PitmanYorGMM(n_iter=12000, burn_in=500, prior_only=True, random_state=2, progress=False).fit(X)
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
    model = PitmanYorGMM(n_iter=400, burn_in=200, init=init, random_state=0, progress=False).fit(X)
    post = model.n_clusters_posterior()
    assert max(post, key=post.get) == 28
    assert model.n_clusters_ == 28
    assert pairwise_accuracy(y, model.labels_) == 1.0
    assert pairwise_accuracy(y, model.predict(X)) == 1.0


def test_single_site_gibbs_alone_stays_stuck_from_one_cluster():
    # the reason for the split-merge moves: without them a merged start barely splits
    X, _ = blobs()
    model = PitmanYorGMM(
        n_iter=60, burn_in=30, init="one", n_split_merge=0, random_state=0, progress=False
    ).fit(X)
    assert model.n_clusters_samples_.max() < 28


def test_split_merge_moves_leave_the_posterior_unchanged():
    # 1-D, three overlapping groups: single-site Gibbs mixes here, so both chains can be compared
    rng = np.random.default_rng(5)
    X = np.concatenate([rng.normal(m, 1.0, size=(10, 1)) for m in (-2.5, 0.0, 2.5)])
    common = dict(alpha=1.0, discount=0.2, n_iter=8000, burn_in=500, progress=False)
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
        discount=0.0, n_iter=4000, burn_in=300, n_split_merge=0, random_state=3, progress=False
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
    assert 2 <= model.n_clusters_ <= 5
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


def test_seeded_runs_are_reproducible():
    X, _ = blobs(n_clusters=4, per=15, dim=2)
    a = PitmanYorGMM(n_iter=60, burn_in=10, random_state=11, progress=False).fit(X)
    b = PitmanYorGMM(n_iter=60, burn_in=10, random_state=11, progress=False).fit(X)
    c = PitmanYorGMM(n_iter=60, burn_in=10, random_state=12, progress=False).fit(X)
    for k in a.trace_:
        np.testing.assert_array_equal(a.trace_[k], b.trace_[k])
    np.testing.assert_array_equal(a.labels_samples_, b.labels_samples_)
    assert not np.array_equal(a.trace_["alpha"], c.trace_["alpha"])
    gen = PitmanYorGMM(n_iter=20, burn_in=5, random_state=torch.Generator().manual_seed(3), progress=False)
    assert gen.fit(X).n_iter_ == 20


def test_predict_proba_and_score_samples_match_scipy():
    X, _ = blobs(n_clusters=3, per=20, dim=2, spread=1.0, box=4.0)
    model = PitmanYorGMM(n_iter=100, burn_in=50, random_state=0, progress=False).fit(X)
    Xt = np.random.default_rng(9).normal(size=(25, 2)) * 4
    comps = np.stack(
        [
            np.log(w) + stats.multivariate_normal(m, c).logpdf(Xt)
            for w, m, c in zip(model.weights_, model.means_, model.covariances_, strict=True)
        ],
        axis=1,
    )
    np.testing.assert_allclose(model.score_samples(Xt), np.logaddexp.reduce(comps, axis=1), rtol=1e-10)
    np.testing.assert_allclose(
        model.predict_proba(Xt), np.exp(comps - np.logaddexp.reduce(comps, axis=1)[:, None]), atol=1e-10
    )
    np.testing.assert_array_equal(model.predict(Xt), comps.argmax(1))
    np.testing.assert_allclose(model.weights_.sum(), 1.0)
    # precisions_cholesky_ follows scikit-learn's convention: precision = U U^T
    for U, C in zip(model.precisions_cholesky_, model.covariances_, strict=True):
        np.testing.assert_allclose(U @ U.T, np.linalg.inv(C), rtol=1e-8)
    # torch scores (float64) equal the estimator's
    s = gaussian_mixture_scores(
        torch.as_tensor(Xt),
        torch.as_tensor(model.means_),
        torch.as_tensor(model.precisions_cholesky_),
        torch.as_tensor(np.log(model.weights_)),
    )
    np.testing.assert_allclose(s.numpy(), comps, rtol=1e-10)
    assert "K: mode" in model.summary() and sum(model.n_clusters_posterior().values()) == pytest.approx(1.0)


def test_map_component_module_exports_to_onnx(tmp_path):
    from tactile_torch._onnx import export_onnx, run_onnx

    X, _ = blobs(n_clusters=3, per=20, dim=3, spread=0.5, box=5.0)
    model = PitmanYorGMM(n_iter=60, burn_in=20, random_state=0, progress=False).fit(X)
    module = model.to_module()
    assert isinstance(module, GaussianMixtureClassifier)
    path = export_onnx(module, (torch.zeros(2, 3),), tmp_path / "map.onnx", input_names=["features"])
    x = torch.as_tensor(X[:17], dtype=torch.float32)
    labels, log_resp = run_onnx(path, x)
    want_labels, want_log_resp = module(x)
    np.testing.assert_array_equal(labels, want_labels.numpy())
    np.testing.assert_array_equal(labels, model.predict(X[:17]))
    np.testing.assert_allclose(log_resp, want_log_resp.numpy(), rtol=1e-5, atol=1e-4)


def test_scikit_learn_conventions_and_tensor_input():
    X, y = blobs(n_clusters=3, per=15, dim=2)
    model = PitmanYorGMM(alpha=1.0, n_iter=50, burn_in=10, random_state=0, progress=False)
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


# ------------------------------------------------------------------------------------------------
# errors
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        (dict(n_iter=0), ValueError, "n_iter must be >= 1"),
        (dict(n_iter=10, burn_in=10), ValueError, "burn_in must be < n_iter"),
        (dict(n_iter=2.5), TypeError, "n_iter must be an integer"),
        (dict(n_aux=0), ValueError, "n_aux must be >= 1"),
        (dict(n_split_merge=-1), ValueError, "n_split_merge must be >= 0"),
        (dict(thin=0), ValueError, "thin must be >= 1"),
        (dict(discount=1.0), ValueError, r"discount must lie in \[0.0, 1.0\)"),
        (dict(discount=0.3, alpha=-0.5), ValueError, "alpha must lie in"),
        (dict(alpha="big"), TypeError, "alpha must be a finite real number"),
        (dict(init="spectral"), ValueError, "init must be 'kmeans', 'one'"),
        (dict(init=np.zeros(3)), ValueError, r"init as labels must have shape \(20,\)"),
        (dict(random_state="seed"), TypeError, "random_state must be"),
    ],
)
def test_bad_parameters_raise(kwargs, exc, match):
    X = np.random.default_rng(0).normal(size=(20, 2))
    params = dict(n_iter=5, burn_in=1, progress=False) | kwargs
    with pytest.raises(exc, match=match):
        PitmanYorGMM(**params).fit(X)


@pytest.mark.parametrize(
    ("X", "match"),
    [
        (np.zeros(5), r"X must have shape \(n_samples, n_features\), got \(5,\)"),
        (np.zeros((0, 3)), "at least 1 sample"),
        (np.array([[0.0, np.nan]]), "X must be finite, got 1 NaN/inf"),
    ],
)
def test_bad_data_raise(X, match):
    with pytest.raises(ValueError, match=match):
        PitmanYorGMM(n_iter=3, burn_in=0, progress=False).fit(X)


def test_predict_before_fit_and_wrong_width_raise():
    model = PitmanYorGMM(n_iter=5, burn_in=1, progress=False)
    with pytest.raises(RuntimeError, match="not fitted yet"):
        model.predict(np.zeros((2, 2)))
    model.fit(np.random.default_rng(0).normal(size=(10, 2)))
    with pytest.raises(ValueError, match=r"X must have 2 features \(as in fit\), got shape \(4, 3\)"):
        model.predict(np.zeros((4, 3)))


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
    assert main([*args, "--quiet", "--seed", "3"]) == 0
    res = np.load(out / "clustering.npz")
    assert pairwise_accuracy(y, res["labels"]) == 1.0 and res["means"].shape == (3, 2)
    assert res["n_clusters_samples"].shape == (30,)
    assert "pairwise accuracy of the MAP labels: 1.0000" in (out / "summary.txt").read_text()
    assert (out / "model.npz").is_file()  # for tactile-torch export (tests/test_pipeline.py)
    np.savez(tmp_path / "bad.npz", X=X)
    assert main(["cluster", "--data", str(tmp_path / "bad.npz"), "--out", str(out)]) == 2
    assert "or a feature matrix ('features'), found keys ['X']" in capsys.readouterr().err


def test_clustering_study_quick_mode_writes_its_section(tmp_path):
    import json

    from tactile_torch.studies import run_report

    path = run_report(tmp_path, quick=True, only=["clustering"], log=lambda s: None)
    text = path.read_text()
    assert "## Clustering: how many surfaces" in text
    assert "Pitman-Yor mixture (MAP sample)" in text and "variational DP mixture" in text
    for name in ("clustering-posterior-k", "clustering-accuracy-along-chain", "clustering-discount"):
        assert (tmp_path / "figures" / f"{name}.png").exists()
    tables = json.loads((tmp_path / "report.json").read_text())["sections"][0]["tables"]
    pyp = tables[0]["rows"][0]
    kmeans = tables[0]["rows"][1]
    # a smoke run on few windows: the mixture must find a plausible K and do about as well as k-means given K
    assert pyp["method"].startswith("Pitman-Yor") and 2 <= pyp["K found"] <= 2 * kmeans["K found"]
    assert pyp["pairwise accuracy"] > min(0.85, kmeans["pairwise accuracy"] - 0.05)


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
    assert rows[-1]["pairwise accuracy (MAP)"] == 1.0 and rows[-1]["MAP K"] == 4


@pytest.mark.slow
@pytest.mark.skipif(
    not have_vibration_features(), reason="tactile_torch.signal (the vibration features) is not installed"
)
def test_real_accelerometer_sets_go_through_the_clustering_study(shared_data, tmp_path):
    # real-data counterpart of test_clustering_study_quick_mode_writes_its_section (synthetic data)
    from tactile_torch.report import Report
    from tactile_torch.studies import RunContext
    from tactile_torch.studies.clustering import real_data

    shared_data("hapmat_imu5")
    section = Report(tmp_path).section("real")
    real_data(section, RunContext(quick=True), n_iter=60, burn_in=20)
    rows = section.tables[-1]["rows"]
    pyp = [r for r in rows if r["data set"] == "hapmat_imu5" and r["method"].startswith("Pitman-Yor")]
    assert len(pyp) == 1 and pyp[0]["classes"] == 5 and 0.0 <= pyp[0]["pairwise accuracy"] <= 1.0
