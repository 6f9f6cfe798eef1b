import warnings

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.base import clone
from sklearn.datasets import make_blobs, make_classification, make_moons
from sklearn.exceptions import ConvergenceWarning
from sklearn.model_selection import GridSearchCV, cross_val_score
from sklearn.svm import SVC as LibSVC

from tactile_torch._onnx import export_onnx, run_onnx
from tactile_torch.svm import (
    SVC,
    HierarchicalSVC,
    kernel_matrix,
    path_scores,
    scale_gamma,
    solve_dual,
    split_classes,
    tree_descent,
)
from tests import reference_svm as ref


def _binary_sets():
    X1, y1 = make_moons(260, noise=0.3, random_state=0)
    X2, y2 = make_classification(
        260, n_features=8, n_informative=4, flip_y=0.05, class_sep=0.8, random_state=1
    )
    X3, y3 = make_blobs(260, centers=[[0, 0, 0], [2, 1, 0]], cluster_std=1.2, random_state=2)
    return {"moons": (X1, y1), "classification": (X2, y2), "blobs": (X3, y3)}


BINARY = _binary_sets()


def test_kernel_matrix_matches_scipy():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(7, 5)), rng.normal(size=(4, 5))
    for kind, gamma in (("rbf", 0.3), ("linear", 1.0)):
        got = kernel_matrix(torch.tensor(a), torch.tensor(b), kernel=kind, gamma=gamma).numpy()
        np.testing.assert_allclose(got, ref.kernel(a, b, kind, gamma), rtol=1e-10, atol=1e-12)
    # A point against itself: distance clamped at 0, never a kernel value above 1.
    same = kernel_matrix(torch.tensor(a), torch.tensor(a), gamma=5.0)
    assert float(same.max()) <= 1.0 and torch.allclose(same.diagonal(), torch.ones(7, dtype=torch.float64))


def test_gamma_scale_equals_scikit_learn():
    X, y = BINARY["classification"]
    X = X * np.arange(1, 9)  # unequal feature scales
    assert scale_gamma(X) == pytest.approx(LibSVC(gamma="scale").fit(X, y)._gamma, rel=1e-12)
    assert SVC(random_state=0).fit(X, y).gamma_ == pytest.approx(1.0 / (8 * X.var()), rel=1e-12)
    assert scale_gamma(np.ones((4, 3))) == 1.0  # zero variance: scikit-learn's fallback


@pytest.mark.parametrize("name", sorted(BINARY))
@pytest.mark.parametrize("kind,C", [("rbf", 0.5), ("rbf", 20.0), ("linear", 1.0)])
def test_binary_svc_matches_libsvm(name, kind, C):
    X, y = BINARY[name]
    X_train, X_test, y_train = X[:200], X[200:], y[:200]
    gamma = scale_gamma(X_train)
    ours = SVC(C=C, kernel=kind, random_state=0).fit(X_train, y_train)
    lib = ref.libsvm(X_train, y_train, C=C, kind=kind, gamma=gamma)
    cmp = ref.compare_binary(ours, lib, X_train, X_test, kind=kind, gamma=gamma)
    assert cmp["objective_rel"] < 1e-3
    assert cmp["agreement"] >= 0.995
    assert cmp["support_other"] == 0, cmp  # same support set up to ties
    assert cmp["support_ties"] <= 3, cmp
    # The intercept follows libsvm's rule; both solutions are within tol of the optimum.
    assert abs(ours.intercept_[0] - lib.intercept_[0]) < 0.05


def test_smo_solver_matches_libsvm_and_the_active_set_solver():
    X, y = BINARY["moons"]
    X, y = X[:120], y[:120]
    gamma = scale_gamma(X)
    smo = SVC(C=3.0, solver="smo").fit(X, y)
    fast = SVC(C=3.0, random_state=0).fit(X, y)
    lib = ref.libsvm(X, y, C=3.0, kind="rbf", gamma=gamma)
    for model in (smo, fast):
        cmp = ref.compare_binary(model, lib, X, X, kind="rbf", gamma=gamma)
        assert cmp["objective_rel"] < 1e-3 and cmp["agreement"] >= 0.995 and cmp["support_other"] == 0


def test_solution_satisfies_libsvm_stopping_rule_and_bias():
    X, y = BINARY["classification"]
    x = torch.tensor(X[:200])
    yy = torch.tensor(np.where(y[:200] == 1, 1.0, -1.0))
    sol = solve_dual(x, yy, 2.0, gamma=0.1, tol=1e-3, random_state=0)
    assert 0.0 <= float(sol.alpha.min()) and float(sol.alpha.max()) <= 2.0
    assert abs(float(yy @ sol.alpha)) < 1e-9  # sum y_i a_i = 0
    # Recompute libsvm's gap independently with SciPy.
    K = ref.kernel(X[:200], X[:200], "rbf", 0.1)
    a, t = sol.alpha.numpy(), yy.numpy()
    grad = t * (K @ (a * t)) - 1.0
    up = ((t > 0) & (a < 2.0)) | ((t < 0) & (a > 0))
    low = ((t > 0) & (a > 0)) | ((t < 0) & (a < 2.0))
    gap = (-t * grad)[up].max() - (-t * grad)[low].min()
    assert gap <= 1e-3 and sol.gap == pytest.approx(gap, abs=1e-9)
    free = (a > 0) & (a < 2.0)
    assert sol.intercept == pytest.approx(-np.mean((t * grad)[free]), abs=1e-9)


def test_duplicated_samples_and_constant_feature_work():
    X, y = BINARY["moons"]
    X = np.hstack([X[:150], np.full((150, 1), 3.0)])  # a constant feature
    y = y[:150]
    X = np.vstack([X, X[:40]])  # 40 repeated samples
    y = np.concatenate([y, y[:40]])
    gamma = scale_gamma(X)
    ours = SVC(C=5.0, random_state=0).fit(X, y)
    lib = ref.libsvm(X, y, C=5.0, kind="rbf", gamma=gamma)
    cmp = ref.compare_binary(ours, lib, X, X, kind="rbf", gamma=gamma)
    # Repeats make the dual variables non-unique (any split between copies): compare what is
    # unique, the objective and the decision function.
    assert cmp["objective_rel"] < 1e-3
    assert cmp["agreement"] >= 0.995
    assert cmp["decision_max_diff"] < 0.05


def test_random_state_reproducible():
    X, y = BINARY["blobs"]
    a = SVC(C=2.0, random_state=3).fit(X, y)
    b = SVC(C=2.0, random_state=3).fit(X, y)
    np.testing.assert_array_equal(a.support_, b.support_)
    np.testing.assert_array_equal(a.dual_coef_, b.dual_coef_)


def test_one_vs_rest_is_one_binary_svc_per_class():
    X, y = make_blobs(240, centers=4, cluster_std=2.0, random_state=0)
    model = SVC(C=4.0, random_state=0).fit(X, y)
    scores = model.decision_function(X)
    assert scores.shape == (240, 4) and model.dual_coef_.shape[0] == 4
    for k in range(4):
        single = SVC(C=4.0, gamma=model.gamma_, random_state=0).fit(X, y == k)
        np.testing.assert_allclose(scores[:, k], single.decision_function(X), atol=1e-6)
    np.testing.assert_array_equal(model.predict(X), model.classes_[scores.argmax(1)])
    libsvm_ovo = LibSVC(C=4.0, gamma=model.gamma_).fit(X, y)
    assert np.mean(model.predict(X) == y) > np.mean(libsvm_ovo.predict(X) == y) - 0.05


def _walk(model: HierarchicalSVC, x: np.ndarray):
    """Descend the tree one sample at a time with each node's own SVC (a plain reference)."""
    node = model.tree_
    while not node.is_leaf:
        node = node.right if node.svc.decision_function(x[None])[0] > 0 else node.left
    return node.classes[0]


def test_hierarchical_svc_tree_and_descent():
    X, y = make_blobs(300, centers=6, cluster_std=1.8, random_state=0)
    names = np.array(["cork", "felt", "foam", "glass", "paper", "wood"])[y]
    model = HierarchicalSVC(C=5.0, random_state=0).fit(X, names)
    leaves = [n for n in model.tree_.nodes() if n.is_leaf]
    assert sorted(n.classes[0] for n in leaves) == sorted(set(names)) and all(
        len(n.classes) == 1 for n in leaves
    )
    internal = [n for n in model.tree_.nodes() if not n.is_leaf]
    assert len(internal) == 5 and model.dual_coef_.shape == (5, model.support_.size)
    for node in internal:  # children partition their parent's classes
        assert sorted(node.left.classes + node.right.classes) == sorted(node.classes)
    pred = model.predict(X)
    np.testing.assert_array_equal(pred, [_walk(model, x) for x in X])
    margins = model.node_decision_function(X)
    for node in internal:  # the merged support vectors give every node's own decision function
        np.testing.assert_allclose(margins[:, node.column], node.svc.decision_function(X), atol=1e-9)
    scores = model.decision_function(X)
    np.testing.assert_array_equal(model.classes_[scores.argmax(1)], pred)
    assert (scores.max(1) >= 0).all() and (np.sort(scores, 1)[:, -2] <= 0).all()
    text = model.describe()
    assert "node 0: {cork, felt, foam, glass, paper, wood} (300 samples" in text and "leaf" in text
    assert str(model.tree_) in text
    libsvm_ovo = LibSVC(C=5.0, gamma=model.gamma_).fit(X, names)
    assert np.mean(pred == names) > np.mean(libsvm_ovo.predict(X) == names) - 0.05


def test_hierarchical_svc_uses_one_gamma_and_is_reproducible():
    X, y = make_blobs(200, centers=4, random_state=1)
    a = HierarchicalSVC(C=2.0, random_state=0).fit(X, y)
    b = HierarchicalSVC(C=2.0, random_state=0).fit(X, y)
    assert all(n.svc.gamma == a.gamma_ for n in a.tree_.nodes() if not n.is_leaf)
    assert a.gamma_ == pytest.approx(scale_gamma(X))
    np.testing.assert_array_equal(a.dual_coef_, b.dual_coef_)


def test_split_classes():
    means = np.array([[0.0, 0.0], [0.2, 0.1], [9.0, 9.0], [9.1, 8.8], [0.1, 0.3]])
    assert split_classes(means, random_state=0).tolist() == [False, False, True, True, False]
    assert split_classes(means[:2], random_state=0).tolist() == [False, True]
    assert split_classes(np.zeros((5, 3)), random_state=0).tolist() == [False, False, True, True, True]


@settings(max_examples=40, deadline=None)
@given(st.integers(3, 9), st.integers(1, 4), st.integers(0, 2**31 - 1))
def test_split_classes_never_leaves_a_group_empty(k, dims, seed):
    rng = np.random.default_rng(seed)
    means = rng.integers(0, 3, size=(k, dims)).astype(float)  # many repeated means
    group = split_classes(means, n_init=3, random_state=seed)
    assert group.shape == (k,) and 0 < group.sum() < k
    np.testing.assert_array_equal(group, split_classes(means, n_init=3, random_state=seed))


def test_tree_descent_and_path_scores_on_a_hand_built_tree():
    # node 0 splits {A} | {B, C}; node 2 (column 1) splits {B} | {C}; leaves 1 (A), 3 (B), 4 (C).
    left = torch.tensor([1, 1, 3, 3, 4])
    right = torch.tensor([2, 1, 4, 3, 4])
    column = torch.tensor([0, 0, 1, 0, 0])
    leaf_label = torch.tensor([0, 0, 0, 1, 2])
    margins = torch.tensor([[-1.0, 5.0], [2.0, -0.5], [0.5, 3.0]])
    labels = tree_descent(margins, left, right, column, leaf_label, depth=2)
    assert labels.tolist() == [0, 1, 2]
    sign = torch.tensor([[-1, 0], [1, -1], [1, 1]])
    scores = path_scores(margins, sign)
    expected = torch.tensor([[1.0, -5.0, -1.0], [-2.0, 0.5, -0.5], [-0.5, -3.0, 0.5]])
    assert torch.equal(scores, expected)


def test_scikit_learn_conventions_clone_grid_search_cross_val():
    X, y = make_blobs(150, centers=3, cluster_std=2.0, random_state=0)
    for est in (SVC(C=2.0, random_state=0), HierarchicalSVC(C=2.0, random_state=0)):
        twin = clone(est)
        assert twin.get_params() == est.get_params() and not hasattr(twin, "support_")
        scores = cross_val_score(est, X, y, cv=3)
        assert scores.shape == (3,) and scores.min() > 0.6
    search = GridSearchCV(HierarchicalSVC(random_state=0), {"C": [0.1, 10.0], "gamma": [0.05, "scale"]}, cv=3)
    search.fit(X, y)
    assert search.best_params_["C"] in (0.1, 10.0) and hasattr(search.best_estimator_, "tree_")


@settings(max_examples=15, deadline=None)
@given(st.integers(1, 12), st.integers(0, 1000))
def test_batched_prediction_equals_per_sample(batch, seed):
    X_test = np.random.default_rng(seed).normal(size=(batch, 2)) * 4
    for model in (_FITTED["svc"], _FITTED["hm"]):
        together = model.decision_function(X_test)
        alone = np.concatenate([model.decision_function(x[None]) for x in X_test])
        np.testing.assert_allclose(together, alone, rtol=1e-12, atol=1e-12)


_X5, _y5 = make_blobs(200, centers=5, cluster_std=1.5, random_state=3)
_FITTED = {
    "svc": SVC(C=3.0, random_state=0).fit(_X5[:, :2], _y5 == 0),
    "ovr": SVC(C=3.0, random_state=0).fit(_X5, _y5),
    "hm": HierarchicalSVC(C=3.0, random_state=0).fit(_X5[:, :2], _y5),
}


@pytest.mark.parametrize("name", ["svc", "ovr", "hm"])
def test_inference_module_matches_the_estimator(name):
    model = _FITTED[name]
    X = np.random.default_rng(0).normal(size=(50, model.n_features_in_)) * 3
    labels, scores = model.to_module()(torch.tensor(X))
    np.testing.assert_array_equal(model.classes_[labels.numpy()], model.predict(X))
    want = model.decision_function(X)
    if name == "svc":
        want = np.stack([-want, want], 1)
    np.testing.assert_allclose(scores.numpy(), want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", ["svc", "hm"])
def test_inference_exports_to_onnx(name, tmp_path):
    model = _FITTED[name]
    module = model.to_module()
    path = export_onnx(
        module,
        (torch.zeros(3, model.n_features_in_, dtype=torch.float32),),
        tmp_path / "svm.onnx",
        input_names=["features"],
        output_names=["labels", "scores"],
    )
    X = torch.tensor(
        np.random.default_rng(1).normal(size=(37, model.n_features_in_)) * 3, dtype=torch.float32
    )
    got_labels, got_scores = run_onnx(path, X)
    labels, scores = module(X)
    np.testing.assert_array_equal(got_labels, labels.numpy())
    np.testing.assert_allclose(got_scores, scores.numpy(), rtol=1e-5, atol=1e-5)


def test_max_iter_warns():
    X, y = BINARY["classification"]
    with pytest.warns(ConvergenceWarning, match="max_iter=2"):
        SVC(C=10.0, max_iter=2, random_state=0).fit(X, y)


def test_no_warning_when_converged():
    X, y = BINARY["moons"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        SVC(random_state=0).fit(X, y)


# --- bad input: one test per documented error -------------------------------------------------


@pytest.mark.parametrize("est", [SVC, HierarchicalSVC])
def test_one_class_only_raises(est):
    with pytest.raises(ValueError, match="at least 2 classes, got only \\[1\\]"):
        est().fit(np.zeros((5, 2)), np.ones(5, dtype=int))


@pytest.mark.parametrize("est", [SVC, HierarchicalSVC])
def test_class_with_one_sample_raises(est):
    with pytest.raises(ValueError, match=r"at least 2 samples.*class\(es\) \[2\]"):
        est().fit(np.random.default_rng(0).normal(size=(5, 2)), [0, 0, 1, 1, 2])


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_features_raise(bad):
    X = np.random.default_rng(0).normal(size=(6, 2))
    X[3, 1] = bad
    with pytest.raises(
        ValueError, match="X must be finite, got 1 NaN/inf value\\(s\\) \\(first at index \\(3, 1\\)\\)"
    ):
        SVC().fit(X, [0, 0, 0, 1, 1, 1])
    with pytest.raises(ValueError, match="X must be finite"):
        _FITTED["svc"].predict(X)


def test_mismatched_lengths_raise():
    with pytest.raises(ValueError, match="same number of samples, got 6 and 5"):
        HierarchicalSVC().fit(np.zeros((6, 2)), [0, 0, 1, 1, 2])


@pytest.mark.parametrize("C", [0.0, -1.0])
def test_non_positive_C_raises(C):
    with pytest.raises(ValueError, match="C must be > 0"):
        SVC(C=C).fit(*BINARY["moons"])


def test_unknown_kernel_raises():
    with pytest.raises(ValueError, match="kernel must be one of \\('rbf', 'linear'\\), got 'poly'"):
        HierarchicalSVC(kernel="poly").fit(*BINARY["moons"])


@pytest.mark.parametrize("gamma,err", [("auto", ValueError), (-0.5, ValueError), ([1.0], TypeError)])
def test_bad_gamma_raises(gamma, err):
    with pytest.raises(err, match="gamma"):
        SVC(gamma=gamma).fit(*BINARY["moons"])


def test_bad_solver_tol_max_iter_raise():
    X, y = BINARY["moons"]
    with pytest.raises(ValueError, match="solver must be one of"):
        SVC(solver="newton").fit(X, y)
    with pytest.raises(ValueError, match="tol must be > 0"):
        SVC(tol=0.0).fit(X, y)
    with pytest.raises(ValueError, match="max_iter must be -1"):
        SVC(max_iter=0).fit(X, y)


def test_wrong_shapes_raise():
    with pytest.raises(ValueError, match="X must have shape \\(n_samples, n_features\\), got \\(4,\\)"):
        SVC().fit(np.zeros(4), [0, 0, 1, 1])
    with pytest.raises(ValueError, match="y must be a 1-D array"):
        SVC().fit(np.zeros((4, 2)), np.zeros((4, 1)))
    with pytest.raises(ValueError, match="X must have 2 features \\(as in fit\\), got shape \\(3, 5\\)"):
        _FITTED["hm"].predict(np.zeros((3, 5)))


def test_predict_before_fit_raises():
    from sklearn.exceptions import NotFittedError

    with pytest.raises(NotFittedError):
        SVC().predict(np.zeros((2, 2)))


def test_predict_descends_rows_with_a_zero_margin(monkeypatch):
    import copy

    model = copy.deepcopy(_FITTED["hm"])
    margins = np.zeros((4, model.dual_coef_.shape[0]))
    margins[1], margins[2], margins[3, 0] = 1.0, -1.0, 0.5  # rows 0 and 3 hold exact zeros
    monkeypatch.setattr(model, "_margins", lambda X: margins)
    t = model._tree_tensors()
    want = tree_descent(
        torch.from_numpy(margins), t["left"], t["right"], t["column"], t["leaf_label"], model.depth_
    )
    np.testing.assert_array_equal(model.predict(np.zeros((4, 2))), model.classes_[want.numpy()])


# --- vibration windows: the real accelerometer sets, and the synthetic generator as fallback ------


def _vibration_binary_tasks(rec, size):
    from tactile_torch.signal import FeatureScaler, window_features

    ds = rec.windows(size)
    position = ds.position.numpy()
    train, test = np.flatnonzero(position % 2 == 0), np.flatnonzero(position % 2 == 1)
    feats = window_features(ds.windows).double()
    X = FeatureScaler().fit(feats[torch.from_numpy(train)]).transform(feats).numpy()
    y = ds.labels.numpy()
    for k in range(min(3, len(rec.class_names))):
        yield X[train], y[train] == k, X[test]


def _check_against_libsvm(rec, size):
    for X_train, y_train, X_test in _vibration_binary_tasks(rec, size):
        gamma = scale_gamma(X_train)
        for C in (1.0, 16.0):
            ours = SVC(C=C, gamma=gamma, random_state=0).fit(X_train, y_train)
            lib = ref.libsvm(X_train, y_train, C=C, kind="rbf", gamma=gamma)
            cmp = ref.compare_binary(ours, lib, X_train, X_test, kind="rbf", gamma=gamma)
            assert cmp["objective_rel"] < 1e-3 and cmp["agreement"] >= 0.995, cmp
            assert cmp["support_other"] == 0, cmp


@pytest.mark.parametrize("name", ["hapmat_imu5", "borealtc_imu"])
def test_svc_matches_libsvm_on_real_vibration_windows(name, shared_data):
    from tactile_torch import data

    root = shared_data(name)
    rec = data.load_hapmat_imu5(root) if name == "hapmat_imu5" else data.load_borealtc_imu(root)
    _check_against_libsvm(rec, 100)


def test_svc_matches_libsvm_on_synthetic_vibration_windows():
    from tactile_torch.data.stylus import make_vibration_recordings

    _check_against_libsvm(make_vibration_recordings(6, duration_s=20.0, random_state=0), 400)
