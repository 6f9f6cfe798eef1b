import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2 as chi2_dist
from sklearn.metrics import confusion_matrix, recall_score

from tactile_torch.metrics import CHI2_1DOF_95, class_report, mcnemar, time_per_sample


def test_class_report_hand_example():
    y_true = ["dots", "dots", "dots", "grid", "grid", "lines", "lines", "lines"]
    y_pred = ["dots", "grid", "dots", "grid", "dots", "lines", "lines", "grid"]
    rep = class_report(y_true, y_pred)
    assert rep.labels.tolist() == ["dots", "grid", "lines"]
    np.testing.assert_array_equal(rep.confusion, [[2, 1, 0], [1, 1, 0], [0, 1, 2]])
    np.testing.assert_allclose(rep.accuracy, [2 / 3, 1 / 2, 2 / 3])
    np.testing.assert_allclose(rep.type2, [1 / 3, 1 / 2, 1 / 3])
    # Type I: "dots" got 1 of the 5 other samples, "grid" 2 of 6, "lines" 0 of 5.
    np.testing.assert_allclose(rep.type1, [1 / 5, 2 / 6, 0.0])
    assert rep.overall_accuracy == pytest.approx(5 / 8)
    assert rep.mean_accuracy == pytest.approx((2 / 3 + 1 / 2 + 2 / 3) / 3)
    assert rep.mean_type1 == pytest.approx((1 / 5 + 2 / 6) / 3)
    rows = rep.rows()
    assert [r["class"] for r in rows] == ["dots", "grid", "lines", "mean"] and rows[-1]["samples"] == 8


@pytest.mark.filterwarnings("ignore:A single label was found")
@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 4), st.integers(0, 4)), min_size=1, max_size=80))
def test_class_report_matches_scikit_learn_and_brute_force(pairs):
    t, p = (np.array(v) for v in zip(*pairs, strict=True))
    rep = class_report(t, p)
    labels = rep.labels
    np.testing.assert_array_equal(rep.confusion, confusion_matrix(t, p, labels=list(labels)))
    present = np.isin(labels, t)
    recall = recall_score(t, p, labels=labels[present], average=None, zero_division=0)
    np.testing.assert_allclose(rep.accuracy[present], recall)
    for i, c in enumerate(labels):
        others = t != c
        want = np.mean(p[others] == c) if others.any() else np.nan
        np.testing.assert_allclose(rep.type1[i], want)


def test_class_report_absent_class_and_explicit_labels():
    rep = class_report(
        torch.tensor([0, 0, 1]), torch.tensor([0, 2, 1]), labels=[0, 1, 2], names=["a", "b", "c"]
    )
    assert math.isnan(rep.accuracy[2]) and math.isnan(rep.type2[2])  # class 2 never occurs
    assert rep.type1[2] == pytest.approx(1 / 3)
    assert rep.mean_accuracy == pytest.approx(0.75)  # NaN left out of the means
    assert rep.names == ("a", "b", "c")


def test_class_report_errors():
    with pytest.raises(ValueError, match="same length, got 3 and 2"):
        class_report([0, 1, 1], [0, 1])
    with pytest.raises(ValueError, match="at least one sample"):
        class_report([], [])
    with pytest.raises(ValueError, match="missing \\[2\\]"):
        class_report([0, 1, 2], [0, 1, 1], labels=[0, 1])
    with pytest.raises(ValueError, match="must not repeat"):
        class_report([0, 1], [0, 1], labels=[0, 1, 1])
    with pytest.raises(ValueError, match="names must have one entry per class \\(2\\), got 1"):
        class_report([0, 1], [0, 1], names=["x"])
    with pytest.raises(ValueError, match="y_true must be a 1-D array"):
        class_report(np.zeros((2, 2)), [0, 1])


def test_mcnemar_hand_computed():
    # 100 samples: both right on 60, both wrong on 10, A wrong / B right on 25, A right / B wrong on 5.
    y = np.zeros(100, dtype=int)
    a = np.r_[np.zeros(60), np.ones(10), np.ones(25), np.zeros(5)].astype(int)
    b = np.r_[np.zeros(60), np.ones(10), np.zeros(25), np.ones(5)].astype(int)
    r = mcnemar(y, a, b)
    assert (r.n01, r.n10) == (25, 5)
    assert r.chi2 == pytest.approx((20 - 1) ** 2 / 30)  # 12.0333...
    assert r.p_value == pytest.approx(chi2_dist.sf(361 / 30, 1), rel=1e-12)
    assert r.reject
    swapped = mcnemar(y, b, a)
    assert (swapped.n01, swapped.n10, swapped.chi2) == (5, 25, r.chi2)


@pytest.mark.parametrize("n01,n10", [(3, 2), (7, 1), (40, 25), (0, 6), (10, 10)])
def test_mcnemar_p_value_and_decision_match_chi_square(n01, n10):
    y = np.zeros(n01 + n10, dtype=int)
    a = np.r_[np.ones(n01), np.zeros(n10)].astype(int)
    b = 1 - a
    r = mcnemar(y, a, b)
    chi2 = (abs(n01 - n10) - 1) ** 2 / (n01 + n10)
    assert r.chi2 == pytest.approx(chi2)
    assert r.p_value == pytest.approx(chi2_dist.sf(chi2, 1), rel=1e-10)
    assert r.reject == (chi2 > 3.84) == (r.p_value < 0.05)
    assert CHI2_1DOF_95 == pytest.approx(chi2_dist.ppf(0.95, 1), rel=1e-12)


def test_mcnemar_without_discordant_samples():
    r = mcnemar([0, 1, 1], [0, 1, 0], [0, 1, 0])
    assert (r.n01, r.n10, r.chi2, r.p_value, r.reject) == (0, 0, 0.0, 1.0, False)


def test_mcnemar_errors():
    with pytest.raises(ValueError, match="same length, got 3, 3 and 2"):
        mcnemar([0, 1, 1], [0, 1, 0], [0, 1])


def test_time_per_sample():
    calls = []
    seconds = time_per_sample(lambda x: calls.append(len(x)), list(range(10)), repeat=3, min_time=0.0)
    assert 0.0 <= seconds < 1e-3 and calls[0] == 10 and len(calls) >= 4  # warm-up + 3
    with pytest.raises(ValueError, match="at least one sample"):
        time_per_sample(lambda x: x, [])


def test_the_cli_prints_an_absent_class_as_n_a_never_nan(capsys):
    # predict on a day's files that hold some of the model's classes: the others have no accuracy
    from tactile_torch.cli._output import print_class_report

    rep = class_report(
        torch.tensor([0, 0, 1]), torch.tensor([0, 2, 1]), labels=[0, 1, 2], names=["a", "b", "c"]
    )
    print_class_report(rep)
    out = capsys.readouterr().out
    assert "nan" not in out.lower()
    assert [line.split()[2] for line in out.splitlines() if line.startswith("c ")] == ["n/a"]
    assert out.rstrip().endswith("overall accuracy 0.6667")
