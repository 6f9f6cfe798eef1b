"""sample_weight and class_weight of the SVMs: per-sample upper bounds ``C_i`` in the compiled SMO,
checked against scikit-learn's libsvm (which has both) and against the equivalences they promise."""

import numpy as np
import pytest
from sklearn.datasets import make_blobs, make_classification
from sklearn.svm import SVC as LibSVC

from tactile_torch.svm import SVC, HierarchicalSVC
from tactile_torch.svm.kernels import scale_gamma
from tactile_torch.svm.solver import solve_dual
from tests import reference_svm as ref

X2, Y2 = make_classification(200, n_features=6, n_informative=4, flip_y=0.05, class_sep=0.8, random_state=3)
X4, Y4 = make_blobs(240, centers=4, cluster_std=2.5, random_state=4)
WEIGHT2 = np.random.default_rng(5).uniform(0.2, 3.0, size=Y2.shape[0])
WEIGHT4 = np.random.default_rng(6).uniform(0.2, 3.0, size=Y4.shape[0])


def test_weighted_dual_matches_libsvm_sample_weight():
    # scikit-learn's libsvm bounds a_i by C * sample_weight[i]: the same dual, solved the same way
    gamma = scale_gamma(X2)
    lib = LibSVC(C=2.0, gamma=gamma).fit(X2, Y2, sample_weight=WEIGHT2)
    y = np.where(Y2 == 0, 1.0, -1.0)  # libsvm's first class is +1
    order = np.argsort(-y, kind="stable")
    sol = solve_dual(X2[order], y[order], 2.0, gamma=gamma, sample_weight=WEIGHT2[order], shrink_every=1000)
    alpha = np.empty_like(sol.alpha)
    alpha[order] = sol.alpha
    assert (alpha <= 2.0 * WEIGHT2 + 1e-12).all() and (alpha > 2.0 + 1e-9).any()  # the bounds matter
    coef = np.zeros(X2.shape[0])
    coef[lib.support_] = np.abs(lib.dual_coef_[0])
    np.testing.assert_allclose(alpha, coef, atol=1e-6)
    assert sol.rho == pytest.approx(-lib._intercept_[0], abs=1e-6)  # libsvm's own sign


@pytest.mark.parametrize(
    ("class_weight", "use_sample_weight"),
    [({0: 3.0, 2: 0.5}, False), ("balanced", False), (None, True), ("balanced", True)],
)
def test_one_vs_one_with_weights_matches_libsvm(class_weight, use_sample_weight):
    X, y = X4[:200], np.where(np.arange(200) < 150, Y4[:200], 3)  # class 3 frequent: 'balanced' matters
    weight = WEIGHT4[:200] if use_sample_weight else None
    ours = SVC(C=4.0, class_weight=class_weight).fit(X, y, sample_weight=weight)
    lib = LibSVC(C=4.0, class_weight=class_weight, gamma=ours.gamma_).fit(X, y, sample_weight=weight)
    np.testing.assert_allclose(ours.class_weight_, lib.class_weight_, rtol=1e-12)
    assert ours.n_support_.tolist() == lib.n_support_.tolist()
    np.testing.assert_array_equal(ours.predict(X4[200:]), lib.predict(X4[200:]))
    # within the solvers' tolerance (tol=1e-3; ours shrinks every 100 iterations, libsvm every 1000)
    np.testing.assert_allclose(ours.decision_function(X4[200:]), lib.decision_function(X4[200:]), atol=5e-3)
    np.testing.assert_allclose(ours.intercept_, lib.intercept_, atol=5e-3)


def test_unit_weights_give_the_unweighted_model_exactly():
    plain = SVC(C=3.0).fit(X4, Y4)
    ones = SVC(C=3.0, class_weight={k: 1.0 for k in range(4)}).fit(X4, Y4, sample_weight=np.ones(240))
    np.testing.assert_array_equal(ones.dual_coef_, plain.dual_coef_)
    np.testing.assert_array_equal(ones.intercept_, plain.intercept_)
    np.testing.assert_array_equal(ones.class_weight_, np.ones(4))


@pytest.mark.parametrize("estimator", [SVC, HierarchicalSVC])
def test_zero_weight_equals_leaving_the_sample_out(estimator):
    keep = np.arange(240) % 3 != 0
    weight = keep.astype(float)
    gamma = scale_gamma(X4)  # a fixed gamma: "scale" is computed on all samples, unweighted
    weighted = estimator(C=2.0, gamma=gamma, random_state=0).fit(X4, Y4, sample_weight=weight)
    dropped = estimator(C=2.0, gamma=gamma, random_state=0).fit(X4[keep], Y4[keep])
    np.testing.assert_allclose(weighted.decision_function(X4), dropped.decision_function(X4), atol=1e-12)
    assert set(weighted.support_) <= set(np.flatnonzero(keep))


@pytest.mark.parametrize("estimator", [SVC, HierarchicalSVC])
def test_integer_weight_equals_repeating_the_sample(estimator):
    # k copies with bound C each = one sample with bound k C (the dual variables of copies add up)
    counts = np.random.default_rng(7).integers(1, 4, size=Y4.shape[0])
    gamma = scale_gamma(X4)
    weighted = estimator(C=1.0, gamma=gamma, tol=1e-6, random_state=0).fit(X4, Y4, sample_weight=counts)
    repeated = estimator(C=1.0, gamma=gamma, tol=1e-6, random_state=0).fit(
        np.repeat(X4, counts, axis=0), np.repeat(Y4, counts)
    )
    np.testing.assert_allclose(weighted.decision_function(X4), repeated.decision_function(X4), atol=1e-4)


def test_class_weight_moves_the_boundary_toward_the_light_class():
    X, y = X2, Y2
    heavy = SVC(C=1.0, class_weight={1: 10.0}).fit(X, y)
    plain = SVC(C=1.0).fit(X, y)
    assert (heavy.predict(X) == 1).sum() > (plain.predict(X) == 1).sum()
    lib = LibSVC(C=1.0, class_weight={1: 10.0}, gamma=heavy.gamma_).fit(X, y)
    assert ref.compare_binary(heavy, lib, X, X, kind="rbf", gamma=heavy.gamma_)["agreement"] >= 0.995


def test_hierarchical_tree_uses_weighted_class_means():
    # a class whose far samples weigh nothing is split as if they were absent
    X, y = X4.copy(), Y4.copy()
    far = (y == 0) & (np.arange(240) % 2 == 0)
    X[far] += 40.0
    weight = np.where(far, 0.0, 1.0)
    gamma = scale_gamma(X[~far])  # "scale" is computed on all samples, unweighted
    weighted = HierarchicalSVC(gamma=gamma, random_state=0).fit(X, y, sample_weight=weight)
    clean = HierarchicalSVC(gamma=gamma, random_state=0).fit(X[~far], y[~far])
    assert weighted.describe() == clean.describe()
    unweighted = HierarchicalSVC(gamma=gamma, random_state=0).fit(X, y)
    assert unweighted.describe() != clean.describe()  # the far samples do move the class mean


def test_probability_with_sample_weight_runs_and_sums_to_one():
    model = SVC(C=2.0, probability=True, random_state=0).fit(X4, Y4, sample_weight=WEIGHT4)
    proba = model.predict_proba(X4[:10])
    np.testing.assert_allclose(proba.sum(axis=1), 1.0, atol=1e-9)


@pytest.mark.parametrize(
    ("weight", "match"),
    [
        (np.r_[np.ones(150), -np.ones(50)], r"sample_weight must be >= 0, got -1 \(first at index 150\)"),
        (np.r_[np.ones(199), np.inf], "Input sample_weight contains infinity"),
        (np.r_[np.ones(199), np.nan], "Input sample_weight contains NaN"),
        (np.ones(7), r"sample_weight.shape == \(7,\), expected \(200,\)"),
        (np.where(Y2 == 1, 0.0, 1.0), r"fewer than 2 samples of positive weight .* of class\(es\) \[1\]"),
    ],
)
def test_bad_sample_weight_raises(weight, match):
    with pytest.raises(ValueError, match=match):
        SVC().fit(X2, Y2, sample_weight=weight)


def test_class_weight_of_an_unknown_class_raises():
    with pytest.raises(ValueError, match="not in class"):
        HierarchicalSVC(class_weight={7: 2.0}).fit(X4, Y4)
    with pytest.raises(ValueError, match="The 'class_weight' parameter of SVC must be"):
        SVC(class_weight="auto").fit(X4, Y4)
