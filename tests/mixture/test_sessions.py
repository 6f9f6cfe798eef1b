"""Tests of the session effects of the mixture (``PitmanYorGMM.fit(X, sessions=...)``).

A point of session s in component k is ``mu_k + b_(s,k) + e`` with ``b_(s,k) ~ N(0, lambda S_k^{-1})``;
the effects are integrated out (``tactile_torch/mixture/_gibbs/sessions.py``). Checked here: the
effective statistics give the matrix-normal likelihood (against SciPy), the log joint density the
chains track equals its direct per-point form, the chain samples the exact prior with the likelihood
off, the posterior agrees with the plain NumPy reference sampler and with single-site Gibbs, and
what the model is for: K counts surfaces across shifted sessions, real surfaces within a session
are kept apart, a single session is the plain model.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats
from sklearn.metrics import adjusted_rand_score

from tactile_torch.mixture import PitmanYorGMM
from tactile_torch.mixture._gibbs import conditionals, sessions
from tests.mixture_data import assert_samples_prior_of_k, batch_se, exact_mfm_prior_k
from tests.reference_mixture import reference_gibbs, whiten

pytestmark = pytest.mark.filterwarnings("ignore:PitmanYorGMM. R-hat:RuntimeWarning")


def shifted_sessions(
    n_sessions=4, per=15, shift=1.0, spread=0.4, centres=((0, 0), (4, 0), (2, 3.5)), common=0.0, seed=0
):
    """Clusters whose centre moves by N(0, shift^2) per (cluster, session) and N(0, common^2) per session: (X, labels, sessions)."""
    rng = np.random.default_rng(seed)
    X, y, s = [], [], []
    for k in range(n_sessions):
        offset = rng.normal(0.0, common, size=len(centres[0]))
        for c, centre in enumerate(centres):
            moved = np.asarray(centre, dtype=float) + offset + rng.normal(0.0, shift, size=len(centre))
            X.append(rng.normal(moved, spread, size=(per, len(centre))))
            y += [c] * per
            s += [k] * per
    return np.concatenate(X), np.array(y), np.array(s)


@pytest.mark.parametrize("lam", [0.0, 0.3, 7.0])
def test_effective_statistics_give_the_matrix_normal_likelihood(lam):
    # a component's points in three sessions: sum over sessions of log N(vec X_s | 1 mu, A_s (x) S^{-1})
    # with A_s = I + lambda 1 1^T, against group_loglik of the effective statistics minus D/2 pen
    rng = np.random.default_rng(1)
    D = 3
    counts = np.array([4, 1, 6])
    pts = [rng.normal(size=(m, D)) + rng.normal(size=D) for m in counts]
    X = np.concatenate(pts)
    A = rng.normal(size=(D, D))
    P = A @ A.T + D * np.eye(D)
    L = np.linalg.cholesky(P)
    mu = rng.normal(size=D)
    want = 0.0
    for g in pts:
        m = len(g)
        cov = np.kron(np.eye(m) + lam * np.ones((m, m)), np.linalg.inv(P))  # rows of g stacked
        want += stats.multivariate_normal(np.tile(mu, m), cov).logpdf(g.ravel())
    mean = X.mean(0)
    scat = (X - mean).T @ (X - mean)
    sums = np.stack([g.sum(0) for g in pts])
    mean_e, scat_e = np.empty(D), np.empty((D, D))
    E, pen = sessions.effective_stats(len(X), mean, scat, counts, sums, lam, mean_e, scat_e)
    got = (
        conditionals.group_loglik(len(X), E, mean_e, scat_e, mu, L, np.linalg.slogdet(P)[1], 1.0)
        - 0.5 * D * pen
    )
    np.testing.assert_allclose(got, want, rtol=1e-10)
    np.testing.assert_allclose(E, sum(m / (1 + lam * m) for m in counts), rtol=1e-12)


def test_log_joint_of_the_map_state_is_the_tracked_density():
    # the chains track the log joint from the effective statistics; log_joint sums the per-point
    # Gaussian terms and adds each group's correction: the two must agree on the MAP state
    from tactile_torch.mixture._gibbs import log_joint

    X, _, s = shifted_sessions(n_sessions=3, per=8)
    model = PitmanYorGMM(n_iter=60, burn_in=10, n_chains=2, random_state=0, progress=False).fit(X, sessions=s)
    Xw = np.ascontiguousarray(np.linalg.solve(model.data_scale_, (X - model.data_mean_).T).T)
    state = model._map_state
    assert state.sc[5] > 0
    np.testing.assert_allclose(log_joint(Xw, state, True), model.map_log_posterior_, rtol=1e-9)


def test_prior_only_chain_samples_the_partition_prior_and_the_priors_of_the_session_terms():
    # the likelihood off: K follows the MFM prior (exact enumeration) with the moves on,
    # lambda / (1 + lambda) is uniform on (0, 1) and sqrt(omega) half-Cauchy
    n = 8
    X = np.random.default_rng(0).normal(size=(n, 2))
    s = np.array([0, 0, 1, 1, 2, 2, 0, 1])
    model = PitmanYorGMM(
        k_prior_mean=3.0,
        n_iter=6000,
        burn_in=200,
        n_chains=1,
        prior_only=True,
        random_state=1,
        progress=False,
    ).fit(X, sessions=s)
    assert_samples_prior_of_k(model, exact_mfm_prior_k(n, 1.0, 3.0))
    rho = model.session_scale_samples_ / (1.0 + model.session_scale_samples_)
    assert stats.kstest(rho[::20], "uniform").pvalue > 1e-3
    # the offsets' variance: sqrt(omega) ~ half-Cauchy(0, 1)
    assert stats.kstest(np.sqrt(model.offset_variance_samples_[::20]), stats.halfcauchy.cdf).pvalue > 1e-3


def test_posterior_agrees_with_the_numpy_reference_with_sessions():
    # single-site Gibbs (no split-merge moves) against the independent reference, lambda and omega
    # sampled; the sessions move both clusters alike (offsets) and each a little (effects)
    X, _, s = shifted_sessions(n_sessions=3, per=5, centres=((0, 0), (3, 0)), shift=0.3, common=1.5, seed=2)
    common = dict(n_iter=4000, burn_in=300, n_chains=1, n_split_merge=0, progress=False)
    ours = PitmanYorGMM(random_state=3, model="pyp", discount=0.0, **common).fit(X, sessions=s)
    ref = reference_gibbs(X, n_iter=400, discount=0.0, random_state=4, sessions=s)
    ks, ks_ref = ours.n_clusters_samples_, ref["n_clusters"][80:]
    assert abs(ks.mean() - ks_ref.mean()) < 4 * math.hypot(batch_se(ks), batch_se(ks_ref, 20))
    ll, ll_ref = np.log(ours.session_scale_samples_), np.log(ref["session_scale"][80:])
    assert abs(ll.mean() - ll_ref.mean()) < 4 * math.hypot(batch_se(ll), batch_se(ll_ref, 20))
    lo, lo_ref = np.log(ours.offset_variance_samples_), np.log(ref["offset_variance"][80:])
    assert abs(lo.mean() - lo_ref.mean()) < 4 * math.hypot(batch_se(lo), batch_se(lo_ref, 20))


def test_split_merge_moves_with_sessions_leave_the_posterior_unchanged():
    # the sequential moves with the effective statistics against single-site Gibbs alone
    X, _, s = shifted_sessions(
        n_sessions=3, per=4, centres=((0,), (2.0,), (4.0,)), shift=0.6, spread=0.7, seed=5
    )
    common = dict(n_iter=8000, burn_in=500, n_chains=1, progress=False)
    with_moves = PitmanYorGMM(n_split_merge=3, random_state=1, **common).fit(X, sessions=s)
    without = PitmanYorGMM(n_split_merge=0, random_state=2, **common).fit(X, sessions=s)
    a, b = with_moves.n_clusters_samples_, without.n_clusters_samples_
    assert with_moves.split_merge_stats_["split_accepted"] > 100
    assert abs(a.mean() - b.mean()) < 4 * math.hypot(batch_se(a), batch_se(b))
    la, lb = np.log(with_moves.session_scale_samples_), np.log(without.session_scale_samples_)
    assert abs(la.mean() - lb.mean()) < 4 * math.hypot(batch_se(la), batch_se(lb))


def test_k_counts_surfaces_across_shifted_sessions():
    # three clusters whose centres move by a session effect larger than their spread: without
    # sessions the mixture counts (cluster, session) blobs; with them, three clusters
    X, y, s = shifted_sessions(n_sessions=4, per=15, shift=1.0, spread=0.4, seed=0)
    fit = dict(n_iter=400, burn_in=100, n_chains=2, random_state=0, progress=False)
    plain = PitmanYorGMM(**fit).fit(X)
    model = PitmanYorGMM(**fit).fit(X, sessions=s)
    lo, hi = model.n_clusters_summary_["interval"]
    assert lo <= 3 <= hi and hi - lo <= 1 and model.n_clusters_ == 3
    assert adjusted_rand_score(y, model.labels_) == 1.0
    assert plain.n_clusters_summary_["interval"][0] > 3  # the blobs, counted
    assert model.n_sessions_ == 4 and model.session_scale_ > 1.0
    # prediction: a window of a new session, its effect integrated out, joins its surface
    new = np.random.default_rng(9).normal([4.3, 0.4], 0.4, size=(20, 2))
    assert (model.predict(new) == model.labels_[y == 1][0]).mean() > 0.9


def test_two_surfaces_closer_than_a_days_shift_stay_two_when_both_are_in_every_session():
    # the surfaces are 1.6 apart, the session shifts have sd 1.5: a shift could move one onto the
    # other, but within every session both are there, and one component has one effect per session.
    # K is 2, and within every session the two surfaces are told apart; which blob of one session
    # is which of another is then not identifiable (the shift is as large as the difference), so
    # the labels may swap between sessions: the answer docs/mixture.md states
    X, y, s = shifted_sessions(
        n_sessions=4, per=15, shift=1.5, spread=0.3, centres=((0, 0), (1.6, 0)), seed=3
    )
    model = PitmanYorGMM(n_iter=400, burn_in=100, n_chains=2, random_state=0, progress=False).fit(
        X, sessions=s
    )
    assert model.n_clusters_summary_["mode"] == 2 and model.n_clusters_ == 2
    for k in range(4):
        assert adjusted_rand_score(y[s == k], model.labels_[s == k]) == 1.0


def test_a_single_session_is_the_plain_model():
    X, _, _ = shifted_sessions(n_sessions=1, per=20)
    fit = dict(n_iter=80, burn_in=20, n_chains=2, random_state=0, progress=False)
    plain = PitmanYorGMM(**fit).fit(X)
    one = PitmanYorGMM(**fit).fit(X, sessions=np.full(len(X), "day1"))
    assert one.n_sessions_ == 1 and one.session_scale_ is None and one.session_scale_samples_ is None
    np.testing.assert_array_equal(plain.labels_, one.labels_)
    np.testing.assert_array_equal(plain.trace_["n_clusters"], one.trace_["n_clusters"])


def test_session_arguments_are_checked():
    X, _, s = shifted_sessions(n_sessions=2, per=5)
    with pytest.raises(ValueError, match=r"sessions must have shape \(30,\)"):
        PitmanYorGMM(n_iter=5, burn_in=1, progress=False).fit(X, sessions=s[:-1])
    with pytest.raises(ValueError, match="coarsen cannot be combined with sessions"):
        PitmanYorGMM(coarsen=100.0, n_iter=5, burn_in=1, progress=False).fit(X, sessions=s)
    with pytest.raises(ValueError, match="sessions need split_merge='sequential'"):
        PitmanYorGMM(split_merge="restricted", n_iter=5, burn_in=1, progress=False).fit(X, sessions=s)
    with pytest.raises(ValueError, match="sessions must hold labels"):
        PitmanYorGMM(n_iter=5, burn_in=1, progress=False).fit(X, sessions=s + 0.5)


def test_whitening_of_the_reference_is_the_estimators():
    # the reference whitens as the estimator does, so their posteriors are comparable
    X, _, _ = shifted_sessions(n_sessions=2, per=6)
    model = PitmanYorGMM(n_iter=3, burn_in=1, n_chains=1, progress=False).fit(X)
    np.testing.assert_allclose(
        whiten(X), np.linalg.solve(model.data_scale_, (X - model.data_mean_).T).T, atol=1e-9
    )
