import copy
import warnings

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.base import clone
from sklearn.datasets import make_blobs, make_classification, make_moons
from sklearn.exceptions import ConvergenceWarning, NotFittedError
from sklearn.model_selection import GridSearchCV, cross_val_score
from sklearn.svm import SVC as LibSVC

from tactile_torch.export import export_onnx, run_onnx
from tactile_torch.svm import (
    SVC,
    HierarchicalSVC,
    SVMInference,
    kernel_matrix,
    path_scores,
    scale_gamma,
    split_classes,
    tree_descent,
)
from tactile_torch.svm.kernels import KernelData
from tactile_torch.svm.solver import ProblemSet, solve_dual, solve_set
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


def test_precomputed_kernel_matches_scipy_in_float32():
    X = np.random.default_rng(1).normal(size=(300, 6))
    data = KernelData.precomputed(X, "rbf", 0.2, threads=2)  # several row blocks, two threads
    np.testing.assert_allclose(data.K, ref.kernel(X, X, "rbf", 0.2), rtol=2e-7, atol=1e-7)


def test_gamma_scale_equals_scikit_learn():
    X, y = BINARY["classification"]
    X = X * np.arange(1, 9)  # unequal feature scales
    assert scale_gamma(X) == pytest.approx(LibSVC(gamma="scale").fit(X, y)._gamma, rel=1e-12)
    assert SVC().fit(X, y).gamma_ == pytest.approx(1.0 / (8 * X.var()), rel=1e-12)
    assert scale_gamma(np.ones((4, 3))) == 1.0  # zero variance: scikit-learn's fallback


@pytest.mark.parametrize("name", sorted(BINARY))
@pytest.mark.parametrize("kind,C", [("rbf", 0.5), ("rbf", 20.0), ("linear", 1.0)])
def test_compiled_smo_takes_libsvm_steps(name, kind, C):
    # With libsvm's shrinking interval the port repeats libsvm's iterations: same count, same rho,
    # same dual variables (up to the last bits of exp and the dot products).
    X, y = BINARY[name]
    gamma = scale_gamma(X)
    lib = ref.libsvm(X, y, C=C, kind=kind, gamma=gamma)
    problem = ProblemSet.of([(np.flatnonzero(y == 0), np.flatnonzero(y == 1))])
    (sol,) = solve_set(KernelData.of(X, kind, gamma), problem, [C], shrink_every=1000)
    assert sol.n_iter[0] == lib.n_iter_[0]
    assert sol.rho[0] == pytest.approx(-lib._intercept_[0], abs=1e-9)
    coef = np.zeros(X.shape[0])
    coef[problem.rows] = sol.alpha * problem.y
    np.testing.assert_allclose(coef[lib.support_], lib._dual_coef_[0], atol=1e-8)


@pytest.mark.parametrize("name", sorted(BINARY))
@pytest.mark.parametrize("kind,C", [("rbf", 0.5), ("rbf", 20.0), ("linear", 1.0)])
def test_binary_svc_matches_libsvm(name, kind, C):
    X, y = BINARY[name]
    X_train, X_test, y_train = X[:200], X[200:], y[:200]
    gamma = scale_gamma(X_train)
    ours = SVC(C=C, kernel=kind).fit(X_train, y_train)
    lib = ref.libsvm(X_train, y_train, C=C, kind=kind, gamma=gamma)
    cmp = ref.compare_binary(ours, lib, X_train, X_test, kind=kind, gamma=gamma)
    assert cmp["objective_rel"] < 1e-3
    assert cmp["agreement"] >= 0.995
    assert cmp["support_other"] == 0, cmp  # same support set up to ties
    assert cmp["support_ties"] <= 3, cmp
    # The intercept follows libsvm's rule; both solutions are within tol of the optimum.
    assert abs(ours.intercept_[0] - lib.intercept_[0]) < 0.05
    assert ours.n_support_.tolist() == [int((y_train[ours.support_] == c).sum()) for c in (0, 1)]


def test_solution_satisfies_libsvm_stopping_rule_and_bias():
    X, y = BINARY["classification"]
    yy = np.where(y[:200] == 1, 1.0, -1.0)
    sol = solve_dual(torch.tensor(X[:200]), torch.tensor(yy), 2.0, gamma=0.1, tol=1e-3)
    a = sol.alpha
    assert 0.0 <= a.min() and a.max() <= 2.0 and sol.converged
    assert abs(float(yy @ a)) < 1e-9  # sum y_i a_i = 0
    # Recompute libsvm's gap and bias independently with SciPy.
    K = ref.kernel(X[:200], X[:200], "rbf", 0.1)
    grad = yy * (K @ (a * yy)) - 1.0
    up = ((yy > 0) & (a < 2.0)) | ((yy < 0) & (a > 0))
    low = ((yy > 0) & (a > 0)) | ((yy < 0) & (a < 2.0))
    assert (-yy * grad)[up].max() - (-yy * grad)[low].min() < 1e-3
    free = (a > 0) & (a < 2.0)
    assert sol.intercept == pytest.approx(-np.mean((yy * grad)[free]), abs=1e-6)
    np.testing.assert_allclose(sol.grad, grad, atol=1e-5)  # float32 kernel rows, as libsvm's
    assert sol.objective == pytest.approx(0.5 * (a * yy) @ K @ (a * yy) - a.sum(), rel=1e-6)


def test_warm_start_along_C_reaches_the_cold_solution():
    X, y = BINARY["moons"]
    data = KernelData.of(X, "rbf", 0.5)
    half = X.shape[0] // 2  # two problems solved together: the first and the second half
    sides = [(np.flatnonzero(y[:half] == 0), np.flatnonzero(y[:half] == 1))]
    sides.append((half + np.flatnonzero(y[half:] == 0), half + np.flatnonzero(y[half:] == 1)))
    problems = ProblemSet.of(sides)
    path = solve_set(data, problems, [0.5, 4.0, 32.0], threads=2)
    for warm in path:
        (cold,) = solve_set(data, problems, [warm.C])
        np.testing.assert_allclose(warm.objective, cold.objective, rtol=1e-3)
        assert warm.alpha.max() <= warm.C and warm.converged.all()


def test_duplicated_samples_and_constant_feature_work():
    X, y = BINARY["moons"]
    X = np.hstack([X[:150], np.full((150, 1), 3.0)])  # a constant feature
    y = y[:150]
    X = np.vstack([X, X[:40]])  # 40 repeated samples
    y = np.concatenate([y, y[:40]])
    gamma = scale_gamma(X)
    ours = SVC(C=5.0).fit(X, y)
    lib = ref.libsvm(X, y, C=5.0, kind="rbf", gamma=gamma)
    cmp = ref.compare_binary(ours, lib, X, X, kind="rbf", gamma=gamma)
    # Repeats make the dual variables non-unique (any split between copies): compare what is
    # unique, the objective and the decision function.
    assert cmp["objective_rel"] < 1e-3
    assert cmp["agreement"] >= 0.995
    assert cmp["decision_max_diff"] < 0.05


_MULTI = {
    "blobs": make_blobs(500, centers=5, cluster_std=2.0, random_state=0),
    "classification": make_classification(
        500, n_features=10, n_informative=6, n_classes=4, n_clusters_per_class=1, random_state=3
    ),
}


@pytest.mark.parametrize("name", sorted(_MULTI))
def test_one_vs_one_equals_libsvm(name):
    X, y = _MULTI[name]
    X_train, X_test, y_train = X[:350], X[350:], y[:350]
    ours = SVC(C=4.0).fit(X_train, y_train)
    lib = LibSVC(C=4.0, gamma=ours.gamma_).fit(X_train, y_train)
    np.testing.assert_array_equal(ours.predict(X_test), lib.predict(X_test))
    np.testing.assert_array_equal(ours.support_, lib.support_)  # grouped by class, libsvm's order
    np.testing.assert_array_equal(ours.n_support_, lib.n_support_)
    assert ours.dual_coef_.shape == lib.dual_coef_.shape and ours.intercept_.shape == lib.intercept_.shape
    np.testing.assert_allclose(ours.intercept_, lib.intercept_, atol=5e-3)
    np.testing.assert_allclose(ours.decision_function(X_test), lib.decision_function(X_test), atol=5e-3)
    ours.set_params(decision_function_shape="ovo")
    lib.set_params(decision_function_shape="ovo")
    np.testing.assert_allclose(ours.decision_function(X_test), lib.decision_function(X_test), atol=5e-3)


def test_one_vs_rest_is_one_binary_svc_per_class():
    X, y = make_blobs(240, centers=4, cluster_std=2.0, random_state=0)
    model = SVC(C=4.0, multi_class="ovr").fit(X, y)
    scores = model.decision_function(X)
    assert scores.shape == (240, 4) and model.dual_coef_.shape[0] == 4
    for k in range(4):
        single = SVC(C=4.0, gamma=model.gamma_).fit(X, y == k)
        np.testing.assert_allclose(scores[:, k], single.decision_function(X), atol=1e-6)
    np.testing.assert_array_equal(model.predict(X), model.classes_[scores.argmax(1)])


def test_threads_and_fit_path_give_the_same_models():
    X, y = _MULTI["blobs"]
    one = HierarchicalSVC(C=8.0, random_state=0, n_jobs=1).fit(X, y)
    two = HierarchicalSVC(C=8.0, random_state=0, n_jobs=2).fit(X, y)
    np.testing.assert_array_equal(one.dual_coef_, two.dual_coef_)  # threads do not change the result
    path = HierarchicalSVC(random_state=0).fit_path(X, y, [32.0, 0.5, 8.0])
    assert [m.C for m in path] == [0.5, 8.0, 32.0]
    np.testing.assert_array_equal(path[1].predict(X), one.predict(X))
    np.testing.assert_allclose(path[1].objective_, one.objective_, rtol=1e-3)
    ovo = SVC(C=8.0).fit_path(X, y, [8.0, 1.0])
    np.testing.assert_allclose(ovo[1].objective_, SVC(C=8.0).fit(X, y).objective_, rtol=1e-3)


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
        rows = np.isin(names, node.classes)  # and each node is libsvm's SVM on its two groups
        lib = LibSVC(C=5.0, gamma=model.gamma_).fit(X[rows], np.isin(names[rows], node.right.classes))
        assert np.mean(lib.predict(X[rows]) == node.svc.predict(X[rows])) >= 0.99
    scores = model.decision_function(X)
    np.testing.assert_array_equal(model.classes_[scores.argmax(1)], pred)
    assert (scores.max(1) >= 0).all() and (np.sort(scores, 1)[:, -2] <= 0).all()
    text = model.describe()
    assert "node 0: {cork, felt, foam, glass, paper, wood} (300 samples" in text and "leaf" in text
    assert str(model.tree_) in text


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
    for est in (SVC(C=2.0), HierarchicalSVC(C=2.0, random_state=0)):
        twin = clone(est)
        assert twin.get_params() == est.get_params() and not hasattr(twin, "support_")
        scores = cross_val_score(est, X, y, cv=3)
        assert scores.shape == (3,) and scores.min() > 0.6
    search = GridSearchCV(HierarchicalSVC(random_state=0), {"C": [0.1, 10.0], "gamma": [0.05, "scale"]}, cv=3)
    search.fit(X, y)
    assert search.best_params_["C"] in (0.1, 10.0) and hasattr(search.best_estimator_, "tree_")


_X5, _y5 = make_blobs(200, centers=5, cluster_std=1.5, random_state=3)
_FITTED = {
    "svc": SVC(C=3.0).fit(_X5[:, :2], _y5 == 0),
    "ovr": SVC(C=3.0, multi_class="ovr").fit(_X5, _y5),
    "ovo": SVC(C=3.0).fit(_X5, _y5),
    "hm": HierarchicalSVC(C=3.0, random_state=0).fit(_X5[:, :2], _y5),
}


@settings(max_examples=15, deadline=None)
@given(st.integers(1, 150), st.integers(0, 1000))
def test_batched_prediction_equals_per_sample(batch, seed):
    X_test = np.random.default_rng(seed).normal(size=(batch, 5)) * 4
    for model in _FITTED.values():
        x = X_test[:, : model.n_features_in_]
        together = model.decision_function(x)  # several threads above 64 rows
        alone = np.concatenate([model.decision_function(row[None]) for row in x])
        np.testing.assert_allclose(together, alone, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", sorted(_FITTED))
def test_inference_module_matches_the_estimator(name):
    model = _FITTED[name]
    X = np.random.default_rng(0).normal(size=(50, model.n_features_in_)) * 3
    module = model.to_module()
    labels, scores = module(torch.tensor(X))
    np.testing.assert_array_equal(model.classes_[labels.numpy()], model.predict(X))
    want = model.decision_function(X)
    if name == "svc":
        want = np.stack([-want, want], 1)
    np.testing.assert_allclose(scores.numpy(), want, rtol=1e-12, atol=1e-12)
    state = {k: v.clone() for k, v in module.state_dict().items()}
    again = SVMInference.from_state(
        state, mode=module.mode, kernel=module.kernel, gamma=module.gamma, depth=module.depth
    )
    assert torch.equal(again(torch.tensor(X))[1], scores)


@pytest.mark.parametrize("name", ["svc", "ovo", "hm"])
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
        SVC(C=10.0, max_iter=2).fit(X, y)


def test_no_warning_when_converged():
    X, y = BINARY["moons"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        SVC().fit(X, y)


# --- bad input: one test per documented error -------------------------------------------------


@pytest.mark.parametrize("est", [SVC, HierarchicalSVC])
def test_one_class_only_raises(est):
    with pytest.raises(ValueError, match="at least 2 classes, got one class: \\[1\\]"):
        est().fit(np.random.default_rng(0).normal(size=(5, 2)), np.ones(5, dtype=int))


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
    with pytest.raises(ValueError, match="inconsistent numbers of samples: \\[6, 5\\]"):
        HierarchicalSVC().fit(np.zeros((6, 2)), [0, 0, 1, 1, 2])


@pytest.mark.parametrize(
    "param,value",
    [
        ("C", 0.0),
        ("C", -1.0),
        ("kernel", "poly"),
        ("gamma", "auto"),
        ("gamma", -0.5),
        ("tol", 0.0),
        ("max_iter", 0),
        ("cache_size", 0),
        ("multi_class", "crammer"),
        ("decision_function_shape", "pairs"),
        ("n_jobs", 0),
    ],
)
def test_bad_hyper_parameters_raise_at_fit(param, value):
    model = SVC(**{param: value})  # stored unchanged, validated at fit
    assert model.get_params()[param] == value
    with pytest.raises(ValueError, match=f"The '{param}' parameter of SVC must be .* Got {value!r}"):
        model.fit(*BINARY["moons"])


def test_bad_n_init_raises_at_fit():
    with pytest.raises(ValueError, match="The 'n_init' parameter of HierarchicalSVC must be"):
        HierarchicalSVC(n_init=0).fit(*BINARY["moons"])


def test_wrong_shapes_raise():
    with pytest.raises(ValueError, match="X must have shape \\(n_samples, n_features\\), got \\(4,\\)"):
        SVC().fit(np.zeros(4), [0, 0, 1, 1])
    with pytest.raises(ValueError, match="y should be a 1d array"):
        SVC().fit(np.zeros((4, 2)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="X has 5 features, but HierarchicalSVC is expecting 2 features"):
        _FITTED["hm"].predict(np.zeros((3, 5)))


@pytest.mark.parametrize("est", [SVC, HierarchicalSVC])
def test_predict_before_fit_raises(est):
    with pytest.raises(NotFittedError):
        est().predict(np.zeros((2, 2)))
    with pytest.raises(NotFittedError):
        est().to_module()


def test_predict_descends_rows_with_a_zero_margin(monkeypatch):
    model = copy.deepcopy(_FITTED["hm"])
    margins = np.zeros((4, model.dual_coef_.shape[0]))
    margins[1], margins[2], margins[3, 0] = 1.0, -1.0, 0.5  # rows 0 and 3 hold exact zeros
    monkeypatch.setattr(model, "node_decision_function", lambda X: margins)
    t = model._tree_tensors()
    want = tree_descent(
        torch.from_numpy(margins), t["left"], t["right"], t["column"], t["leaf_label"], model.depth_
    )
    np.testing.assert_array_equal(model.predict(np.zeros((4, 2))), model.classes_[want.numpy()])


# --- vibration windows: the real accelerometer sets, and the synthetic generator as fallback ------


def _vibration_windows(rec, size):
    from tactile_torch.signal import FeatureScaler, window_features

    ds = rec.windows(size)
    position = ds.position.numpy()
    train, test = np.flatnonzero(position % 2 == 0), np.flatnonzero(position % 2 == 1)
    feats = window_features(ds.windows).double()
    X = FeatureScaler().fit(feats[torch.from_numpy(train)]).transform(feats).numpy()
    y = ds.labels.numpy()
    return X[train], y[train], X[test]


def _check_against_libsvm(rec, size):
    X_train, y_train, X_test = _vibration_windows(rec, size)
    gamma = scale_gamma(X_train)
    for k in range(min(3, len(rec.class_names))):
        for C in (1.0, 16.0):
            ours = SVC(C=C, gamma=gamma).fit(X_train, y_train == k)
            lib = ref.libsvm(X_train, y_train == k, C=C, kind="rbf", gamma=gamma)
            cmp = ref.compare_binary(ours, lib, X_train, X_test, kind="rbf", gamma=gamma)
            assert cmp["objective_rel"] < 1e-3 and cmp["agreement"] >= 0.995, cmp
            assert cmp["support_other"] == 0, cmp
    ovo = SVC(C=16.0, gamma=gamma).fit(X_train, y_train)
    lib = LibSVC(C=16.0, gamma=gamma).fit(X_train, y_train)
    assert np.mean(ovo.predict(X_test) == lib.predict(X_test)) >= 0.995


@pytest.mark.parametrize("name", ["hapmat_imu5", "borealtc_imu"])
def test_svc_matches_libsvm_on_real_vibration_windows(name, shared_data):
    from tactile_torch import data

    root = shared_data(name)
    rec = data.load_hapmat_imu5(root) if name == "hapmat_imu5" else data.load_borealtc_imu(root)
    _check_against_libsvm(rec, 100)


def test_svc_matches_libsvm_on_synthetic_vibration_windows():
    from tactile_torch.data.stylus import make_vibration_recordings

    _check_against_libsvm(make_vibration_recordings(6, duration_s=20.0, random_state=0), 400)


def test_run_blocks_keeps_order_and_raises_the_first_error():
    from tactile_torch.svm.threads import resolve_threads, run_blocks

    assert run_blocks(lambda b: b * b, list(range(20)), threads=3) == [b * b for b in range(20)]
    assert run_blocks(lambda b: b, [], threads=2) == []
    assert resolve_threads(None) == torch.get_num_threads() and resolve_threads(3) == 3

    def fail(b):
        if b == 7:
            raise RuntimeError("block 7")
        return b

    with pytest.raises(RuntimeError, match="block 7"):
        run_blocks(fail, list(range(12)), threads=2)


def test_one_vs_one_graph_exported_with_free_sizes_serves_another_number_of_classes(tmp_path):
    # The tradeoff study exports one head graph per structure, every fitted tensor an input of free
    # size, and binds each candidate's tensors: no reshape in the graph may depend on K.
    import onnx
    import onnxruntime as ort

    from tactile_torch.export.parts import bind_head, export_head

    Xa, ya = make_blobs(240, centers=6, n_features=4, random_state=0)
    Xb, yb = make_blobs(120, centers=3, n_features=4, random_state=1)
    models = [(SVC(C=3.0, gamma=0.1).fit(Xa, ya), Xa), (SVC(C=3.0, gamma=0.1).fit(Xb, yb), Xb)]
    template = onnx.load(str(export_head([models[0][0].to_module()], 4, tmp_path / "head.onnx")))
    for model, X in models:
        bound = bind_head(template, [model.to_module()])
        labels, scores = ort.InferenceSession(bound.SerializeToString()).run(
            None, {"features": X[:9].astype(np.float32)}
        )
        want_labels, want_scores = model.to_module()(torch.tensor(X[:9].astype(np.float32)))
        np.testing.assert_array_equal(labels, want_labels.numpy())
        np.testing.assert_allclose(scores, want_scores.numpy(), rtol=1e-6, atol=1e-6)
