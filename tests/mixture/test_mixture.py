"""Tests of tactile_torch.mixture's estimator (PitmanYorGMM): degenerate data, reproducibility, point
estimates, posterior predictive, diagnostics against ArviZ, scikit-learn conventions and errors.

The compiled Gibbs sampler is tested in tests/mixture/test_sampler.py, the clustering report section in
tests/studies/test_clustering.py, the cluster command in tests/cli/test_cluster.py, novelty discovery in tests/robot/stream/test_discovery.py."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import torch
from scipy import stats
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
from tests.mixture_data import PYP, blobs

# Short chains in these tests: their R-hat warnings are expected, not failures.
pytestmark = pytest.mark.filterwarnings("ignore:PitmanYorGMM. R-hat:RuntimeWarning")


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
    labels, _, novel, score = model.to_module().double()(torch.as_tensor(far))
    np.testing.assert_allclose(
        score.numpy(), model.novelty_score(far), rtol=1e-6, atol=1e-5
    )  # float32 buffers
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
    with pytest.warns(
        RuntimeWarning,
        match=r"after 40 sweeps per chain, when the budget max_iter ran out \(now 40\).*max_iter=80",
    ):
        stuck.set_params(n_iter="auto", max_iter=40, burn_in=10).fit(Y)
    assert stuck.budget_exhausted_ and stuck.n_iter_ == 40 and stuck.stopped_by_ == "max_iter"


def test_auto_run_length_stops_at_the_targets():
    X, _ = blobs(n_clusters=3, per=20, dim=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # converged: no warning
        model = PitmanYorGMM(n_chains=2, random_state=0, progress=False).fit(X)
    assert model.stopped_by_ == "converged" and not model.budget_exhausted_
    conv = {r["quantity"]: r for r in model.convergence_}
    assert conv["K"]["R-hat"] < 1.01 and conv["K"]["ESS bulk"] >= 400
    assert model.labels_samples_.shape[1] <= 200 and model.labels_sweeps_.min() >= model.n_iter_ // 8


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


@pytest.mark.slow  # 10 s on a quiet 2-core machine: keeps the default run under 10 minutes
def test_map_component_module_exports_to_onnx(tmp_path):
    from tactile_torch.export import export_onnx, run_onnx

    X, _ = blobs(n_clusters=3, per=20, dim=3, spread=0.5, box=5.0)
    model = PitmanYorGMM(n_iter=60, burn_in=20, n_chains=2, random_state=0, progress=False).fit(X)
    module = model.to_module()
    assert isinstance(module, GaussianMixtureClassifier)
    path = export_onnx(module, (torch.zeros(2, 3),), tmp_path / "map.onnx", input_names=["features"])
    x = torch.as_tensor(
        np.concatenate([X[:15], [[50.0, 50.0, 50.0], [-60.0, 0.0, 0.0]]]), dtype=torch.float32
    )
    labels, log_resp, novel, _ = run_onnx(path, x)  # batch 17, exported with 2
    want_labels, want_log_resp, want_novel, _ = module(x)
    np.testing.assert_array_equal(labels, want_labels.numpy())
    np.testing.assert_array_equal(novel, want_novel.numpy())
    np.testing.assert_array_equal(labels[:15], model.predict(X[:15], using="point"))
    assert novel.tolist() == [False] * 15 + [True, True]
    np.testing.assert_allclose(log_resp[:15], want_log_resp[:15].numpy(), rtol=1e-5, atol=1e-4)
    # the two far rows' scores are differences of terms near 1e4: float32 keeps about 1e-3 of them
    np.testing.assert_allclose(log_resp[15:], want_log_resp[15:].numpy(), rtol=1e-4, atol=1e-3)


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
