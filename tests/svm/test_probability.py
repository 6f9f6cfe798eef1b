"""``probability=True``: Platt scaling by internal cross-validation, pairwise coupling, the tree's
product of branch probabilities, ONNX export, and pandas input to the SVMs and the class report."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch
from scipy.optimize import minimize
from sklearn.base import clone
from sklearn.datasets import make_blobs
from sklearn.svm import SVC as LibSVC

from tactile_torch.export import export_onnx, run_onnx
from tactile_torch.metrics import class_report
from tactile_torch.svm import SVC, HierarchicalSVC, SVMInference
from tactile_torch.svm.inference import ovo_tables
from tactile_torch.svm.probability import couple_pairwise, fit_sigmoid

_X, _y = make_blobs(240, centers=4, cluster_std=2.5, random_state=0)
_X_test, _y_test = make_blobs(160, centers=4, cluster_std=2.5, random_state=0, shuffle=True)
_FITTED = {
    "binary": SVC(C=3.0, probability=True, random_state=0).fit(_X, _y == 0),
    "ovo": SVC(C=3.0, probability=True, random_state=0).fit(_X, _y),
    "ovr": SVC(C=3.0, multi_class="ovr", probability=True, random_state=0).fit(_X, _y),
    "tree": HierarchicalSVC(C=3.0, probability=True, random_state=0).fit(_X, _y),
}


def _platt_reference(f, positive):
    """Platt's objective with the smoothed targets, minimised by a general-purpose optimiser."""
    n_pos, n_neg = positive.sum(), (~positive).sum()
    t = np.where(positive, (n_pos + 1) / (n_pos + 2), 1 / (n_neg + 2))

    def nll(ab):
        z = f * ab[0] + ab[1]
        return np.sum(t * z + np.logaddexp(0, -z))

    return minimize(nll, [0.0, 0.0], method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-12}).x


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fit_sigmoid_minimises_platts_objective(seed):
    rng = np.random.default_rng(seed)
    positive = rng.random(120) < 0.4
    f = np.where(positive, 1.0, -1.0) * rng.gamma(2.0, 0.8, 120) + rng.normal(0, 0.8, 120)
    np.testing.assert_allclose(fit_sigmoid(f, positive), _platt_reference(f, positive), atol=1e-4)


def _coupling_reference(r):
    """Wu, Lin and Weng's method 2 from its KKT system ``[Q 1; 1^T 0] [p; b] = [0; 1]``."""
    k = r.shape[0]
    Q = np.zeros((k, k))
    for t in range(k):
        for j in range(k):
            if j != t:
                Q[t, t] += r[j, t] ** 2
                Q[t, j] = -r[j, t] * r[t, j]
    kkt = np.block([[Q, np.ones((k, 1))], [np.ones((1, k)), np.zeros((1, 1))]])
    return np.linalg.solve(kkt, np.r_[np.zeros(k), 1.0])[:k]


def _pairwise(r_full, k):
    first, second = np.triu_indices(k, 1)
    return r_full[first, second]


@pytest.mark.parametrize("k", [2, 3, 5, 9])
def test_pairwise_coupling_solves_wu_lin_weng_method_2(k):
    rng = np.random.default_rng(k)
    tables = ovo_tables(torch.ones(k, dtype=torch.long), torch.float64)
    batch = []
    for _ in range(4):
        upper = rng.uniform(0.02, 0.98, (k, k))
        r = np.triu(upper, 1) + np.tril(1 - upper.T, -1)
        batch.append(r)
    got = couple_pairwise(torch.tensor(np.stack([_pairwise(r, k) for r in batch])), tables["pair_classes"])
    want = np.stack([_coupling_reference(r) for r in batch])
    np.testing.assert_allclose(got.numpy(), want, atol=1e-10)
    # consistent pairwise probabilities give back the distribution they came from
    p = rng.dirichlet(np.ones(k), size=3)
    consistent = [_pairwise(p_i[:, None] / (p_i[:, None] + p_i[None, :]), k) for p_i in p]
    back = couple_pairwise(torch.tensor(np.stack(consistent)), tables["pair_classes"])
    np.testing.assert_allclose(back.numpy(), p, atol=1e-6)


@pytest.mark.parametrize("name", sorted(_FITTED))
def test_probabilities_are_distributions_close_to_the_decisions(name):
    model = _FITTED[name]
    proba = model.predict_proba(_X_test)
    assert proba.shape == (len(_X_test), len(model.classes_))
    assert proba.min() >= 0 and np.allclose(proba.sum(1), 1.0, atol=1e-12)
    # the most probable class is the predicted one but for a few samples near a boundary
    assert (model.classes_[proba.argmax(1)] == model.predict(_X_test)).mean() > 0.85
    np.testing.assert_allclose(np.exp(model.predict_log_proba(_X_test)), proba, rtol=1e-12)


@pytest.mark.filterwarnings("ignore:The `probability` parameter was deprecated:FutureWarning")
@pytest.mark.filterwarnings("ignore:Attribute `prob:FutureWarning")
def test_one_vs_one_probabilities_agree_with_libsvm():
    """Same method as libsvm's ``-b 1`` (other random folds, and libsvm iterates the coupling to a
    tolerance): the sigmoids and the probabilities agree closely, and held-out log-loss is as good."""
    ours = _FITTED["ovo"]
    theirs = LibSVC(C=3.0, probability=True, random_state=0).fit(_X, _y)
    np.testing.assert_allclose(ours.probA_, theirs.probA_, rtol=0.25)
    p_ours, p_theirs = ours.predict_proba(_X_test), theirs.predict_proba(_X_test)
    assert np.abs(p_ours - p_theirs).mean() < 0.02
    truth = np.searchsorted(ours.classes_, _y_test)
    log_loss = [-np.log(p[np.arange(len(truth)), truth]).mean() for p in (p_ours, p_theirs)]
    assert log_loss[0] < log_loss[1] + 0.05


def test_tree_probability_is_the_product_of_node_probabilities():
    model = _FITTED["tree"]
    margins = model.node_decision_function(_X_test)
    right = 1 / (1 + np.exp(margins * model.probA_ + model.probB_))
    want = np.ones((len(_X_test), len(model.classes_)))
    for node in model.tree_.nodes():
        if node.is_leaf:
            continue
        for child, p in ((node.left, 1 - right[:, node.column]), (node.right, right[:, node.column])):
            want[:, child.members] *= p[:, None]
    np.testing.assert_allclose(model.predict_proba(_X_test), want, rtol=1e-10)


def test_same_seed_same_probabilities_and_clone():
    again = SVC(C=3.0, probability=True, random_state=0).fit(_X, _y)
    np.testing.assert_array_equal(again.probA_, _FITTED["ovo"].probA_)
    twin = clone(_FITTED["tree"])
    assert twin.get_params()["probability"] is True and not hasattr(twin, "probA_")


@pytest.mark.parametrize("name", sorted(_FITTED))
def test_probability_module_matches_predict_proba(name):
    model = _FITTED[name]
    labels, proba = model.to_module(probability=True)(torch.tensor(_X_test))
    np.testing.assert_allclose(proba.numpy(), model.predict_proba(_X_test), rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(model.classes_[labels.numpy()], model.predict(_X_test))
    module = model.to_module(probability=True)
    again = SVMInference.from_state(
        module.state_dict(), mode=module.mode, kernel=module.kernel, gamma=module.gamma, depth=module.depth
    )
    assert again.probability and torch.equal(again(torch.tensor(_X_test))[1], proba)


@pytest.mark.parametrize("name", sorted(_FITTED))
def test_probability_graph_exports_to_onnx(name, tmp_path):
    model = _FITTED[name]
    module = model.to_module(torch.float32, probability=True)
    path = export_onnx(
        module,
        (torch.zeros(3, model.n_features_in_, dtype=torch.float32),),
        tmp_path / "svm.onnx",
        input_names=["features"],
        output_names=["labels", "scores"],
    )
    X = torch.tensor(_X_test[:37], dtype=torch.float32)  # another batch size than the export's
    got_labels, got_proba = run_onnx(path, X)
    np.testing.assert_allclose(got_proba, model.predict_proba(_X_test[:37]), atol=1e-4)
    np.testing.assert_array_equal(got_labels, module(X)[0].numpy())


def test_predict_proba_needs_probability_true():
    model = SVC(C=3.0).fit(_X, _y)
    assert not hasattr(model, "predict_proba")
    with pytest.raises(AttributeError, match="no attribute 'predict_proba'") as caught:
        model.predict_proba(_X)
    assert "only when probability=True" in str(caught.value.__cause__)
    with pytest.raises(
        ValueError, match=r"to_module\(probability=True\) needs a model fitted with probability=True"
    ):
        model.to_module(probability=True)


def test_refit_without_probability_drops_the_sigmoids():
    model = clone(_FITTED["ovo"]).fit(_X, _y)
    assert hasattr(model, "probA_")
    model.set_params(probability=False).fit(_X, _y)
    assert not hasattr(model, "probA_")


@pytest.mark.parametrize("est", [SVC(C=3.0), HierarchicalSVC(C=3.0, random_state=0)])
def test_pandas_data_frames_are_accepted(est):
    frame = pd.DataFrame(_X, columns=["a", "b"])
    labels = pd.Series(np.array(["cork", "felt", "foam", "wood"])[_y], name="surface")
    model = clone(est).fit(frame, labels)
    assert model.feature_names_in_.tolist() == ["a", "b"]
    np.testing.assert_array_equal(model.predict(frame), clone(est).fit(_X, labels.to_numpy()).predict(_X))
    report = class_report(labels, pd.Series(model.predict(frame)))
    assert report.names == ("cork", "felt", "foam", "wood")
    assert report.to_dict()["samples"] == [60, 60, 60, 60]
    one_column = class_report(labels.to_frame(), model.predict(frame))
    np.testing.assert_array_equal(one_column.confusion, report.confusion)
    table = pd.DataFrame(report.to_dict(mean_row=True))
    assert table["class"].tolist()[-1] == "mean" and table.shape == (5, 5)


def test_class_report_prints_a_table_without_non_finite_numbers():
    report = class_report(["felt", "felt", "cork"], ["felt", "cork", "cork"], labels=["cork", "felt", "wool"])
    text = str(report)
    lines = text.splitlines()
    assert lines[0].split() == ["class", "samples", "accuracy", "type", "I", "type", "II"]
    assert lines[3].split() == ["wool", "0", "n/a", "0.0000", "n/a"]  # absent from y_true
    assert lines[-1] == "overall accuracy 0.6667" and "nan" not in text
