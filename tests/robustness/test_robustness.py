"""Breaking points (tactile_torch.robustness): the engine against hand computations, every factor's code
path on tiny inputs, and one test per documented error."""

import dataclasses
import itertools
import math
import re

import numpy as np
import pytest
import torch
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.neighbors import KNeighborsClassifier, NearestCentroid
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import FunctionTransformer, StandardScaler

from tactile_torch import model_selection as engine
from tactile_torch.robustness import _evaluation
from tactile_torch.robustness.charts import plot_factor, plot_factors, plot_grid
from tactile_torch.robustness.degradations import FACTORS, Degradation, factor, factors_for
from tactile_torch.robustness.output import breaking_table
from tactile_torch.robustness.sweeps import breaking_points, infer_kind, recording_blocks, sweep

# Degraded tiny inputs give constant features; NearestCentroid warns about them (expected here).
pytestmark = pytest.mark.filterwarnings(
    "ignore:self.within_class_std_dev_:UserWarning", "ignore:.*encountered in divide:RuntimeWarning"
)


def _blobs(n_per_class=20, n_classes=3, n_features=4, spread=3.0, seed=0):
    rng = np.random.default_rng(seed)
    centres = np.eye(n_classes, n_features) * spread
    X = rng.normal(size=(n_per_class * n_classes, n_features)) + np.repeat(centres, n_per_class, axis=0)
    return X, np.repeat(np.arange(n_classes), n_per_class)


def _mean_features(x):
    """Per-channel mean and std of windows (N, 3, W) or frames (N, T, ...): a cheap stateless feature step."""
    x = (
        torch.as_tensor(x).double().flatten(2)
        if torch.as_tensor(x).ndim == 3
        else torch.as_tensor(x).double()
    )
    flat = x.reshape(x.shape[0], x.shape[1], -1) if x.ndim > 3 else x
    return torch.cat([flat.mean(-1), flat.std(-1)], 1).reshape(x.shape[0], -1)[:, :6].numpy()


def _pipe(func=_mean_features, classifier=None):
    return Pipeline(
        [
            ("features", FunctionTransformer(func)),
            ("scaler", StandardScaler()),
            ("classifier", classifier or NearestCentroid()),
        ]
    )


def test_crossing_interpolates_the_first_fall_below_halfway():
    acc = np.array([[1.0, 0.9, 0.6, 0.2, 0.1], [1.0, 0.9, 0.8, 0.7, 0.6], [0.2, 0.1, 0.1, 0.1, 0.1]]).T
    pos = _evaluation.crossing(acc, chance=0.0)
    assert pos[0] == pytest.approx(2 + (0.6 - 0.5) / (0.6 - 0.2))
    assert math.isinf(pos[1])
    assert _evaluation.crossing(acc[:, 2:], chance=0.25)[0] == 0.0  # clean at chance: nothing to break
    exact = _evaluation.crossing(np.array([[0.8], [0.5], [0.1]]), chance=0.2)  # threshold 0.5 hit exactly
    assert exact[0] == pytest.approx(1.0)


def test_level_text_in_value_log_and_label_space():
    snr = factor("feature SNR")
    assert _evaluation.level_text(snr, [30, 20, 10], 2.5) == ("15 dB", 15.0)
    assert _evaluation.level_text(snr, [30, 20, 10], 0.5)[0] == "before 30 dB"
    assert _evaluation.level_text(snr, [30, 20, 10], math.inf)[0] == "beyond 10 dB"
    # an interval's ends in numeric order, the end past the sweep in words (dB fall as they get harsher)
    assert (
        _evaluation.interval_text(snr, [30, 20, 10], 1.5, math.inf) == "[< 10 dB (beyond the sweep), 25 dB]"
    )
    assert _evaluation.interval_text(snr, [30, 20, 10], 0.5, 2.5) == "[15 dB, > 30 dB]"
    noise = factor("sensor noise")  # log axis: geometric interpolation
    assert _evaluation.level_text(noise, [0.01, 0.1], 1.5)[1] == pytest.approx(math.sqrt(0.01 * 0.1))
    grid = factor("image noise")
    text, value = _evaluation.level_text(grid, [(0.1, 0.01), (0.2, 0.03)], 1.5)
    assert text == "between (0.1, 0.01) and (0.2, 0.03)" and value is None


def test_bootstrap_of_constant_rows_and_reproducibility():
    hits = np.array([[3.0, 2.0, 4.0], [1.0, 1.0, 2.0]])
    count = np.array([[3.0, 2.0, 4.0], [3.0, 2.0, 4.0]])
    boot = _evaluation.bootstrap(hits, count, 200, seed=1)
    assert boot.shape == (2, 200) and np.allclose(boot[0], 1.0)
    assert np.array_equal(boot, _evaluation.bootstrap(hits, count, 200, seed=1))
    assert boot[1].min() >= 1 / 3 - 1e-12 and boot[1].max() <= 1 / 2 + 1e-12  # between the groups' rates


def test_recording_blocks_and_infer_kind():
    assert recording_blocks([0, 0, 0, 0, 1, 1], [0, 1, 2, 3, 0, 1], n_blocks=2).tolist() == [0, 0, 1, 1, 2, 3]
    ids = recording_blocks(np.repeat([3, 7], 10), np.tile(np.arange(10), 2), n_blocks=5)
    assert ids.tolist() == [i // 2 for i in range(10)] + [5 + i // 2 for i in range(10)]
    with pytest.raises(ValueError, match="recording and position must be 1-D of one length"):
        recording_blocks([0, 1], [0])
    assert infer_kind(torch.zeros(2, 3, 3, 4, 4)) == "image"
    assert infer_kind(np.zeros((2, 3, 4, 4))) == "image"
    assert infer_kind(np.zeros((2, 3, 50))) == "vibration"
    assert infer_kind(np.zeros((2, 21))) == "features"
    with pytest.raises(ValueError, match=r"X must be frames .* got shape \(2,\)"):
        infer_kind(np.zeros(2))


def test_factors_are_declared_for_their_kinds():
    names = [f.name for f in FACTORS]
    assert len(set(names)) == len(names)
    assert {f.name for f in factors_for("image")} == {
        "feature SNR",
        "image noise",
        "frames",
        "sensel grid",
        "erosion / pitch",
        "training samples",
    }
    assert {f.name for f in factors_for("vibration")} >= {"window", "sensor noise", "quantisation", "drift"}
    assert len(factor("image noise").levels) == 25 and len(factor("image noise").path) == 5
    from tactile_torch.robustness.degradations import QUICK_LEVELS

    for name, levels in QUICK_LEVELS.items():  # quick lists are sublists of the records', mildest first
        full = factor(name).levels
        assert all(v in full for v in levels), name
        assert [full.index(v) for v in levels] == sorted(full.index(v) for v in levels), name
    with pytest.raises(ValueError, match="factor must be one of"):
        factor("nope")
    with pytest.raises(ValueError, match="kind must be one of"):
        factors_for("audio")


def test_test_stage_accuracy_equals_a_hand_computation():
    """A deterministic test-time shift: the sweep's pooled accuracy equals fitting and predicting by hand."""
    X, y = _blobs()
    shift = Degradation(
        "shift",
        ("features",),
        "test",
        (1.0, 2.0, 4.0),
        "",
        "add a constant to the first feature",
        lambda x, level, generator: x + torch.tensor([level, 0.0, 0.0, 0.0], dtype=x.dtype),
    )
    model = NearestCentroid()
    result = sweep({"nc": model}, X, y, factors=[shift], n_splits=4, random_state=5)
    seed = int(np.random.default_rng(5).integers(2**62))
    folds = engine.make_folds(y, np.arange(len(y)), 4, seed)
    for level, got in zip(shift.levels, result.curves[0].accuracy, strict=True):
        hits = 0
        for tr, te in folds:
            fitted = NearestCentroid().fit(X[tr], y[tr])
            Xt = X[te].copy()
            Xt[:, 0] += level
            hits += int((fitted.predict(Xt) == y[te]).sum())
        assert got == pytest.approx(hits / len(y))
    curve = result.curves[0]
    assert curve.low.shape == curve.accuracy.shape and np.all(curve.low <= curve.accuracy + 1e-12)
    assert curve.clean_low <= curve.clean <= curve.clean_high


def test_feature_snr_breaks_and_is_reproducible():
    X, y = _blobs()
    first = breaking_points(_pipe(lambda x: x), X, y, factors=["feature SNR"], random_state=0)
    again = breaking_points(_pipe(lambda x: x), X, y, factors=["feature SNR"], random_state=0)
    assert np.array_equal(first[0].accuracy, again[0].accuracy)
    bp = first[0].breaking
    assert bp.status == "reached" and bp.level is not None
    assert bp.low <= bp.position <= bp.high
    lowest = min(first[0].accuracy)
    assert lowest < first[0].clean  # noise at -3 dB must hurt
    rows = breaking_table(first)
    assert rows[0]["factor"] == "feature SNR" and "dB" in rows[0]["breaks at [95 % CI]"]


def test_shared_features_step_runs_once_per_data_variant():
    calls = []

    def counted(x):
        calls.append(len(x))
        return np.asarray(x)

    X, y = _blobs()
    models = {"nc": _pipe(counted), "knn": _pipe(counted, KNeighborsClassifier(3))}
    sweep(models, X, y, factors=["feature SNR"], n_splits=3, n_trials=1, random_state=0)
    assert calls == [len(y)]  # one whole-set transform shared by both models; SNR reuses it


def test_learning_curve_fit_failure_stops_the_curve():
    X, y = _blobs(n_per_class=12)
    result = sweep(
        {"knn5": KNeighborsClassifier(5)},
        X,
        y,
        factors=[dataclasses.replace(factor("training samples"), levels=(5, 2, 1))],
        n_splits=3,
        random_state=0,
    )
    curve = result.curves[0]
    assert curve.levels == (5, 2)  # 2 per class x 3 classes = 6 samples: fine; 1 per class: 3 < 5 neighbours
    assert curve.note.startswith("cannot be fitted at 1 per class")


class _NeedsLarge(ClassifierMixin, BaseEstimator):
    """A classifier that refuses training sets of fewer than 10 samples."""

    def fit(self, X, y):
        if len(y) < 10:
            raise ValueError("needs 10 samples")
        self.model_ = NearestCentroid().fit(X, y)
        self.classes_ = self.model_.classes_
        return self

    def predict(self, X):
        return self.model_.predict(X)


def test_a_model_that_cannot_be_fitted_breaks_there():
    X, y = _blobs(n_per_class=12)
    f = dataclasses.replace(factor("training samples"), levels=(6, 3, 2))
    curve = sweep({"m": _NeedsLarge()}, X, y, factors=[f], n_splits=3, random_state=0).curves[0]
    assert curve.levels == (6,) and curve.breaking.status == "fit failed"
    assert "3 per class" in curve.breaking.text and "needs 10 samples" in curve.note
    first = dataclasses.replace(f, levels=(3, 2))  # cannot be fitted at the first level already
    curve = sweep({"m": _NeedsLarge()}, X, y, factors=[first], n_splits=3, random_state=0).curves[0]
    assert (
        curve.levels == ()
        and curve.breaking.status == "fit failed"
        and curve.breaking.text.startswith("3 per")
    )


def _overlapping_tick_labels(fig) -> list[str]:
    """The x tick labels of ``fig`` that overlap their neighbour once drawn."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    found = []
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in ax.get_xticklabels() if t.get_text()]
        for (name, a), (_, b) in itertools.pairwise(boxes):
            if a.overlaps(b):
                found.append(f"{ax.get_title()}: {name}")
    return found


def test_axis_titles_say_the_unit_once():
    """The ticks are bare numbers; the title holds the unit (the drift panel's "0.51 of the recording" ticks overlapped)."""
    from tactile_torch.robustness.charts import axis_title
    from tactile_torch.robustness.degradations import FACTORS

    for f in FACTORS:
        words = re.findall(r"[\w±]+", axis_title(f))
        assert len(words) == len(set(words)), axis_title(f)  # no word twice, e.g. "frames (frames)"
    assert axis_title(factor("drift")) == "test segment centre (share of the recording)"


def _tiny_frames(n_per_class=4, seed=0):
    gen = torch.Generator().manual_seed(seed)
    frames = torch.full((2 * n_per_class, 6, 3, 16, 16), 255, dtype=torch.uint8)
    frames[n_per_class:, :, :, 4:12, 4:12] = 40  # class 1 presses a square
    frames[:, :, :, ::5, ::5] = torch.randint(0, 255, (1,), generator=gen).to(torch.uint8)
    return frames, np.repeat([0, 1], n_per_class)


def test_every_image_factor_runs_on_tiny_frames():
    from tactile_torch.studies._models import image_features

    frames, y = _tiny_frames()
    model = _pipe(image_features, NearestCentroid())
    model.set_params(features__kw_args={"erosion": 2})
    result = sweep(
        {"fused": model},
        frames,
        y,
        context={"pitch_px": 4.0},
        n_splits=2,
        n_trials=1,
        n_bootstrap=20,
        random_state=0,
    )
    by = result.by_factor()
    assert set(by) == {f.name for f in factors_for("image")} - {"training samples"}
    assert ("training samples", "no level applies to X of shape (8, 6, 3, 16, 16)") in result.skipped
    assert all(v < 6 for v in by["frames"][0].levels)  # fewer frames than recorded
    assert all(v <= 8 for v in by["sensel grid"][0].levels)
    assert len(by["image noise"][0].levels) == 25 and len(by["image noise"][0].path()[0]) == 5
    fig = plot_factor(by["frames"])
    ax = fig.axes[0]
    assert ax.get_xlabel() == "frames per exploration"  # the unit said once, not "frames (frames)"
    ticks = [t.get_text() for t in ax.get_xticklabels()]
    assert ticks[0] == "clean" and not any("frames" in t for t in ticks[1:])
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [
        "fused", "chance", "halfway to chance (model's colour)", "breaking point"
    ]  # fmt: skip
    panels = plot_factors(result.curves)
    assert len(panels.legends) == 1 and all(a.get_legend() is None for a in panels.axes)
    assert not _overlapping_tick_labels(panels)
    plot_grid(by["image noise"][0], (0.1, 0.2, 0.3, 0.4, 0.5), (0.01, 0.03, 0.05, 0.07, 0.09))
    # without the texture pitch the erosion factor is skipped, not guessed
    skipped = sweep(
        {"fused": model}, frames, y, factors=["erosion / pitch"], n_splits=2, random_state=0
    ).skipped
    assert skipped == [
        (
            "erosion / pitch",
            "needs the texture's pitch in pixels (a data file does not say it), which these data do not give",
        )
    ]


def test_parameter_factor_skips_models_without_the_parameter():
    from tactile_torch.studies._models import image_features

    fused = _pipe(image_features)  # a FunctionTransformer whose function takes erosion: kw_args get it
    assert engine.with_params(fused.steps[0][1], {"erosion": 3}).kw_args == {"erosion": 3}
    with pytest.raises(ValueError, match=r"has no parameter\(s\) \['erosion'\]"):
        engine.with_params(_pipe(_mean_features).steps[0][1], {"erosion": 3})  # its function takes none
    frames, y = _tiny_frames()
    result = sweep(
        {"plain": _pipe(_mean_features)},
        frames,
        y,
        factors=["erosion / pitch"],
        context={"pitch_px": 4},
        n_splits=2,
    )
    assert result.curves == [] and result.skipped[0][0] == "erosion / pitch for plain"
    scaler_first = Pipeline([("features", StandardScaler()), ("c", NearestCentroid())])
    X, yb = _blobs()
    result = sweep(
        {"s": scaler_first}, X, yb, factors=["erosion / pitch"], context={"pitch_px": 4}, random_state=0
    )
    assert result.curves == []  # features kind: the factor does not apply
    with pytest.raises(ValueError, match="has no parameter"):
        engine.with_params(StandardScaler(), {"erosion": 3})


def _drifting_windows(n_rec=2, n_win=20, width=64, seed=0):
    """Two classes whose amplitude grows along every recording (drift), windows in time order."""
    rng = np.random.default_rng(seed)
    windows, labels, recording, position = [], [], [], []
    for r in range(2 * n_rec):
        cls = r % 2
        for k in range(n_win):
            gain = (1.0 + cls) * (1.0 + 3.0 * k / n_win)
            windows.append(rng.normal(scale=gain, size=(3, width)))
            labels.append(cls)
            recording.append(r)
            position.append(k)
    return np.array(windows), np.array(labels), np.array(recording), np.array(position)


def test_every_vibration_factor_runs_and_drift_is_detected():
    X, y, recording, position = _drifting_windows()
    frac = (position + 0.5) / 20
    model = _pipe(_mean_features, NearestCentroid())
    result = sweep(
        {"m": model},
        torch.from_numpy(X).float(),
        y,
        recording_blocks(recording, position, 5),
        context={"position": frac, "recording": recording},
        n_splits=2,
        n_trials=1,
        n_bootstrap=50,
        random_state=0,
    )
    by = result.by_factor()
    assert set(by) == {f.name for f in factors_for("vibration")}
    drift = by["drift"][0]
    assert drift.levels == (0.51, 0.65, 0.79, 0.93)
    assert drift.accuracy[-1] < drift.clean  # the gain drifted away from the training part
    assert all(v < 64 for v in by["window"][0].levels)
    assert not _overlapping_tick_labels(plot_factors(result.curves))  # the drift panel's once did


def test_drift_on_too_short_recordings_is_skipped():
    X, y, recording, position = _drifting_windows(n_win=2)
    result = sweep(
        {"m": _pipe()},
        X,
        y,
        recording,
        factors=["drift"],
        context={"position": (position + 0.5) / 2, "recording": recording},
        random_state=0,
    )
    assert result.skipped == [("drift", "recordings too short: fewer than two test segments hold samples")]


@pytest.mark.parametrize(
    ("kwargs", "err", "match"),
    [
        ({"X": [[0.0]]}, TypeError, "X must be a torch.Tensor or numpy.ndarray, got list"),
        ({"y": np.zeros(5)}, ValueError, r"y must have shape \(60,\)"),
        ({"y": np.zeros(60)}, ValueError, "y must hold at least 2 classes"),
        ({"groups": np.zeros(3)}, ValueError, r"groups must have shape \(60,\)"),
        ({"groups": np.repeat(np.arange(3), 20)}, ValueError, "every class at least 2 groups"),
        ({"kind": "image"}, ValueError, "kind must be one of .* and match X"),
        ({"factors": ["nope"]}, ValueError, "factor must be one of"),
        ({"models": {}}, ValueError, "models must hold at least one estimator"),
        ({"n_trials": 0}, ValueError, "n_trials must be > 0"),
        ({"models": {"bad": _NeedsLarge()}, "n_splits": 2, "y": np.repeat([0, 1, 2], 20)}, None, None),
    ],
)
def test_documented_errors(kwargs, err, match):
    X, y = _blobs()
    args = {"models": {"nc": NearestCentroid()}, "X": X, "y": y} | kwargs
    if err is None:  # 40 training samples: fits; then a training-samples level below 10 fails, no error
        assert sweep(**args, factors=["training samples"], random_state=0).curves
        return
    with pytest.raises(err, match=match):
        sweep(**args, random_state=0)


def test_a_model_failing_on_clean_folds_is_an_error():
    X, y = _blobs(n_per_class=4)
    with pytest.raises(ValueError, match=r"models\['m'\] could not be fitted on the clean folds"):
        sweep({"m": _NeedsLarge()}, X, y, n_splits=4, random_state=0)


def test_drift_positions_outside_the_recording_are_an_error():
    X, y, recording, position = _drifting_windows(n_win=5)
    with pytest.raises(
        ValueError, match=r"context position must be the fraction of the recording in \[0, 1\)"
    ):
        sweep(
            {"m": _pipe()},
            X,
            y,
            recording,
            factors=["drift"],
            context={"position": position, "recording": recording},
        )


def test_docs_list_every_factor():
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "robustness.md").read_text()
    for f in FACTORS:
        assert f"| {f.name} |" in text, f.name


def test_write_breaking_points(tmp_path):
    import json

    from tactile_torch.robustness.output import breaking_summary, write_breaking_points

    X, y = _blobs()
    result = sweep(
        {"nc": NearestCentroid()}, X, y, factors=["feature SNR", "drift"], n_trials=1, random_state=0
    )
    md = write_breaking_points(result, tmp_path / "out")
    text = md.read_text()
    assert "| feature SNR | nc |" in text and "not swept: drift" in text
    assert (tmp_path / "out" / "breaking-feature-snr.png").read_bytes()[:4] == b"\x89PNG"
    data = json.loads((tmp_path / "out" / "breaking_points.json").read_text())
    assert data["curves"][0]["accuracy"] == result.curves[0].accuracy.tolist()
    assert write_breaking_points(result.curves, tmp_path / "curves").exists()  # the curves of breaking_points
    summary = breaking_summary(result, tmp_path / "hook")  # tradeoff's results hook: rows and figures
    assert summary["rows"] == breaking_table(result.curves) and summary["skipped"][0][0] == "drift"
    assert [p.rsplit("/", 1)[1] for p in summary["figures"]] == ["breaking-feature-snr.png"]


def test_trials_per_factor():
    X, y = _blobs()
    one = sweep(
        {"nc": NearestCentroid()}, X, y, factors=["feature SNR"], n_trials={"feature SNR": 1}, random_state=0
    )
    same = sweep({"nc": NearestCentroid()}, X, y, factors=["feature SNR"], n_trials=1, random_state=0)
    assert np.array_equal(one.curves[0].accuracy, same.curves[0].accuracy)
    with pytest.raises(ValueError, match=r"n_trials\['feature SNR'\] must be > 0"):
        sweep({"nc": NearestCentroid()}, X, y, n_trials={"feature SNR": 0})
