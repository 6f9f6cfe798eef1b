"""Tests of tactile_torch.signal: equivalence with the NumPy/SciPy reference, exact crossings (ties),
degenerate windows, errors, batching properties, gradients, the fitted modules and ONNX parity."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.exceptions import NotFittedError

import tactile_torch.signal as signal
from tactile_torch.data.stylus import make_vibration_recordings
from tactile_torch.data.vibration import QUANTUM_G
from tactile_torch.signal import (
    FEATURE_NAMES,
    ClusteringTransform,
    FeatureScaler,
    WindowFeatures,
    _features,
    clustering_features,
    sliding_windows,
    window_features,
)
from tests import reference_signal as ref

RTOL = {np.float32: 1e-5, np.float64: 1e-10}
SIZES = [200, 400, 800, 1600, 201, 333]
CROSS = [FEATURE_NAMES.index(f"{a}_cross") for a in "xyz"]


def assert_features_match(ours, want, dtype, windows):
    """The project's tolerances: relative ``rtol`` (1e-5 float32, 1e-10 float64) on every feature.

    The standardised moments are dimensionless and of order one, so their tolerance is ``rtol``
    absolute as well (a symmetric window's skewness is ~0, where a relative test means nothing);
    ``hf`` also gets the float64 FFT's own rounding, ``1e-13 W max|a|``, absolute (the reference
    gives 4e-15 instead of 0 for a constant window); crossings are integers and must be equal.
    """
    rtol = RTOL[dtype]
    fft_noise = 1e-13 * windows.shape[-1] * float(np.abs(windows).max())
    ours = np.asarray(ours, dtype=np.float64).reshape(-1, 3, 7)
    want = np.asarray(want, dtype=np.float64).reshape(-1, 3, 7)
    assert np.isfinite(ours).all()
    np.testing.assert_array_equal(ours[..., 5], want[..., 5], err_msg="crossings")
    for k, name in enumerate(("var", "skew", "kurt", "m5", "tv", "cross", "hf")):
        atol = rtol if name in ("skew", "kurt", "m5") else fft_noise if name == "hf" else 0.0
        np.testing.assert_allclose(ours[..., k], want[..., k], rtol=rtol, atol=atol, err_msg=name)


@pytest.fixture(scope="module")
def surfaces():
    """2.1 s of every synthetic surface: quantised to 3.9 mg (many exact ties), gravity, impacts, clipping."""
    return make_vibration_recordings(28, duration_s=2.1, random_state=7)


def _test_windows(surfaces, size, dtype):
    """Synthetic windows of every surface, plus Gaussian, constant, spike, clipped and heavy-tailed ones."""
    rng = np.random.default_rng(size)
    synthetic = np.stack([s[:size].T for s in surfaces.signals])
    extra = np.empty((5, 3, size))
    extra[0] = rng.normal(1.0, 0.3, (3, size))  # continuous values, offset
    extra[4] = (
        np.round(0.02 * rng.standard_t(3, (3, size)) / QUANTUM_G) * QUANTUM_G
    )  # heavy tails: m5 ill-conditioned
    extra[1] = 0.25  # constant: a stylus at rest
    extra[2] = 0.0
    extra[2, :, size // 3] = [3.0, -2.0, 0.5]  # one spike per axis
    extra[3] = np.clip(8.0 * np.sin(np.linspace(0, 9, size))[None], -5.0, 5.0)  # clipping at ±5 g
    return np.concatenate([synthetic, extra]).astype(dtype)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("size", SIZES)
def test_matches_reference(surfaces, size, dtype):
    x = _test_windows(surfaces, size, dtype)
    ours = window_features(torch.from_numpy(x))
    assert ours.dtype == torch.from_numpy(x).dtype and ours.shape == (len(x), 21)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # scipy on the constant window
        assert_features_match(ours, ref.window_features_vectorized(x), dtype, x)
    # The per-window loop (what a researcher writes) on a few windows, crossings by an explicit loop.
    few = x[:: max(1, len(x) // 6)]
    assert_features_match(window_features(torch.from_numpy(few)), ref.window_features_loop(few), dtype, few)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_export_path_matches_reference(surfaces, dtype, monkeypatch):
    # What the ONNX graph computes (DFT as a MatMul with the upper-half basis, crossings by
    # bisection), run eagerly: the same numbers as the reference, for even and odd W.
    monkeypatch.setattr(torch.compiler, "is_exporting", lambda: True)
    for size in (200, 201):
        x = _test_windows(surfaces, size, dtype)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            assert_features_match(
                window_features(torch.from_numpy(x)), ref.window_features_vectorized(x), dtype, x
            )


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_crossings_exact_when_samples_lie_on_thresholds(dtype):
    # Integer signals with range 21 * m put every threshold on an integer: most samples equal one.
    rng = np.random.default_rng(0)
    m = rng.integers(1, 4, size=(64, 3, 1))
    base = rng.integers(-50, 50, size=(64, 3, 1))
    steps = rng.integers(0, 22, size=(64, 3, 300))
    steps[..., 0], steps[..., 1] = 0, 21  # range exactly 21 m: th_k = base + k m, exactly
    x = (base + steps * m).astype(dtype)
    want = np.array([[ref.crossings_loop(axis) for axis in w] for w in x])
    assert ((steps >= 1) & (steps <= 20)).mean() > 0.8  # most samples lie on a threshold
    ours = window_features(torch.from_numpy(x))[:, CROSS].numpy()
    np.testing.assert_array_equal(ours, want)
    rows = torch.from_numpy(x).reshape(-1, 300)
    lo_t, spread = rows.amin(-1, keepdim=True), rows.amax(-1, keepdim=True) - rows.amin(-1, keepdim=True)
    bisect = _features._crossings(rows, lo_t, spread, exact=True).reshape(64, 3).numpy()
    np.testing.assert_array_equal(bisect, want)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_crossings_exact_for_tiny_ranges(dtype):
    # Ranges a few hundred eps of the magnitude: the thresholds collapse onto few floats. Below the
    # estimate's safe bound the rows fall back to bisection, just above it they do not; both exact.
    eps = np.finfo(dtype).eps
    rng = np.random.default_rng(1)
    rows = []
    for factor in (2, 20, 300, 511, 513, 600, 2000):
        steps = rng.integers(0, 40, size=(3, 200))
        rows.append(1000.0 + steps * (factor * eps * 1000.0 / 39))
    x = np.stack(rows).astype(dtype)
    want = np.array([[ref.crossings_loop(axis) for axis in w] for w in x])
    np.testing.assert_array_equal(window_features(torch.from_numpy(x))[:, CROSS].numpy(), want)


def test_crossing_conventions():
    # Touching a threshold and turning back is no crossing; passing through it is one.
    w = torch.tensor([0.0, 1.0, 0.0, 21.0, 21.0], dtype=torch.float64).expand(1, 3, 5)  # th_k = k
    # 0 -> 1 reaches th_1 without going above it, 1 -> 0 back: no crossing; 0 -> 21 crosses all 20.
    assert window_features(w)[0, CROSS].tolist() == [20.0, 20.0, 20.0]
    w = torch.tensor([0.0, 1.0, 1.5, 21.0], dtype=torch.float64).expand(1, 3, 4)
    # 1 -> 1.5 leaves th_1 upwards: th_1 is crossed once, between samples 1 and 2.
    assert window_features(w)[0, CROSS].tolist() == [20.0, 20.0, 20.0]


def test_constant_window_is_defined_and_finite():
    w = torch.full((2, 3, 800), 0.98)
    feats = window_features(w)
    assert torch.equal(feats, torch.zeros(2, 21))
    logs = clustering_features(feats)
    assert torch.isfinite(logs).all()
    assert logs[0, :4].tolist() == pytest.approx([0.0, np.log(1e-6), 0.0, np.log(1e-6)], rel=1e-6)


def test_spike_window():
    size = 400
    w = torch.zeros(1, 3, size, dtype=torch.float64)
    w[0, 0, 100] = 2.0  # interior spike: 20 thresholds up and down
    w[0, 1, 0] = 2.0  # spike at the first sample: down only
    w[0, 2, :] = 1.0
    w[0, 2, 50] = -4.0
    feats = window_features(w).reshape(3, 7)
    assert feats[:, 5].tolist() == [40.0, 20.0, 40.0]
    # one nonzero value among W: skew = (W - 2) / sqrt(W - 1), kurt = skew^2 + 1 (biased moments)
    skew = (size - 2) / np.sqrt(size - 1)
    assert feats[0, 1].item() == pytest.approx(skew, rel=1e-12)
    assert feats[0, 2].item() == pytest.approx(skew**2 + 1, rel=1e-12)
    assert feats[2, 1].item() == pytest.approx(-skew, rel=1e-12)
    assert torch.isfinite(clustering_features(feats.reshape(1, 21))).all()


def test_extreme_scales_stay_finite_and_accurate():
    rng = np.random.default_rng(3)
    base = rng.normal(size=(4, 3, 256))
    for scale, offset in ((1e15, 0.0), (1e-15, 0.0), (1.0, 1e6), (1e-3, 1.0)):
        x = (base * scale + offset).astype(np.float32)
        ours = window_features(torch.from_numpy(x)).numpy()
        want = ref.window_features_vectorized(x)
        assert np.isfinite(ours).all()
        for k in (1, 2, 3):  # standardised moments: scale- and offset-free
            np.testing.assert_allclose(
                ours.reshape(-1, 3, 7)[..., k], want.reshape(-1, 3, 7)[..., k], atol=1e-4
            )
        np.testing.assert_allclose(ours.reshape(-1, 3, 7)[..., 0], want.reshape(-1, 3, 7)[..., 0], rtol=1e-4)


def test_upper_half_bins():
    # A pure tone in bin k counts in hf iff k > W / 4 (the Nyquist bin of an even W included).
    for size, k, inside in (
        (800, 200, False),
        (800, 201, True),
        (800, 400, True),
        (201, 50, False),
        (201, 51, True),
    ):
        t = torch.arange(size, dtype=torch.float64)
        w = torch.cos(2 * np.pi * k * t / size).expand(1, 3, size)
        hf = window_features(w)[0, 6].item()
        amplitude = np.abs(np.fft.rfft(w[0, 0].numpy()))[k]
        assert bool(hf > 0.5 * amplitude) is inside, (size, k)


# --------------------------------------------------------------------------------------------
# errors, one per documented error
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("windows", "error", "match"),
    [
        (np.zeros((2, 3, 10)), TypeError, "must be a torch.Tensor"),
        (torch.zeros(2, 3, 10, dtype=torch.int64), TypeError, "float32 or float64"),
        (torch.zeros(2, 3, 10, dtype=torch.float16), TypeError, "float32 or float64"),
        (torch.zeros(2, 800, 3), ValueError, r"shape \(\*, 3, W\)"),
        (torch.zeros(800), ValueError, r"shape \(\*, 3, W\)"),
        (torch.zeros(2, 3, 1), ValueError, "at least 2 samples"),
        (torch.zeros(2, 3, 10).index_fill_(2, torch.tensor([4]), float("nan")), ValueError, "finite"),
        (torch.zeros(2, 3, 10).index_fill_(2, torch.tensor([4]), float("inf")), ValueError, "finite"),
    ],
)
def test_window_features_errors(windows, error, match):
    with pytest.raises(error, match=match):
        window_features(windows)


@pytest.mark.parametrize(
    ("recording", "size", "step", "error", "match"),
    [
        (np.zeros((100, 3)), 10, 5, TypeError, "torch.Tensor"),
        (torch.zeros(100), 10, 5, ValueError, r"\(n, 3\) or \(B, n, 3\)"),
        (torch.zeros(100, 4), 10, 5, ValueError, r"\(n, 3\) or \(B, n, 3\)"),
        (torch.zeros(100, 3), 1, 1, ValueError, "size must be >= 2"),
        (torch.zeros(100, 3), 10.5, 5, TypeError, "size must be an integer"),
        (torch.zeros(100, 3), 10, 0, ValueError, "step must be > 0"),
        (torch.zeros(5, 3), 10, 5, ValueError, "at least size=10 samples"),
    ],
)
def test_sliding_windows_errors(recording, size, step, error, match):
    with pytest.raises(error, match=match):
        sliding_windows(recording, size, step)


# --------------------------------------------------------------------------------------------
# windows, batching, gradients
# --------------------------------------------------------------------------------------------


def test_sliding_windows_layout_and_view():
    rec = torch.arange(30.0).reshape(10, 3)
    w = sliding_windows(rec, 4, 3)
    assert w.shape == (3, 3, 4)
    for i in range(3):
        assert torch.equal(w[i], rec[3 * i : 3 * i + 4].T)
    assert w.data_ptr() == rec.data_ptr()  # a view, no copy
    assert sliding_windows(rec, 5).shape == (2, 3, 5)  # default step = size
    batch = torch.stack([rec, rec + 100])
    wb = sliding_windows(batch, 4, 3)
    assert wb.shape == (2, 3, 3, 4) and torch.equal(wb[1], sliding_windows(rec + 100, 4, 3))
    assert window_features(wb).shape == (2, 3, 21)
    assert window_features(torch.zeros(0, 3, 50)).shape == (0, 21)  # no window, no error


@settings(max_examples=25, deadline=None)
@given(
    batch=st.integers(1, 5),
    size=st.integers(2, 120),
    quantised=st.booleans(),
    seed=st.integers(0, 2**16),
)
def test_batched_equals_per_window(batch, size, quantised, seed):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(batch, 3, size, generator=g) * 0.2 + 1.0
    if quantised:
        x = torch.round(x / QUANTUM_G) * QUANTUM_G
    together = window_features(x)
    apart = torch.cat([window_features(x[i : i + 1]) for i in range(batch)])
    torch.testing.assert_close(together, apart, rtol=1e-6, atol=1e-6)
    assert torch.equal(together[:, CROSS], apart[:, CROSS])
    # leading dimensions pass through
    assert torch.equal(window_features(x.reshape(1, batch, 3, size))[0], together)


def test_blocking_does_not_change_results(monkeypatch):
    x = torch.randn(40, 3, 100, generator=torch.Generator().manual_seed(0))
    whole = window_features(x)
    monkeypatch.setattr(_features, "_BLOCK_SAMPLES", 300)  # one window per block
    torch.testing.assert_close(window_features(x), whole, rtol=1e-6, atol=1e-7)


def test_gradcheck_float64():
    x = torch.randn(2, 3, 12, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    x.requires_grad_(True)
    smooth = [i for i in range(21) if i not in CROSS]
    assert torch.autograd.gradcheck(lambda w: window_features(w)[:, smooth], (x,))
    (grad,) = torch.autograd.grad(window_features(x)[:, CROSS].sum(), x, allow_unused=True)
    assert grad is None or torch.equal(grad, torch.zeros_like(x))


# --------------------------------------------------------------------------------------------
# scaler and unsupervised transform
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def features(surfaces):
    x = torch.from_numpy(
        np.stack([s[:400].T for s in surfaces.signals] + [s[400:800].T for s in surfaces.signals])
    )
    return window_features(torch.cat([x, torch.full((2, 3, 400), 1.0)]))  # with two windows at rest


def test_feature_scaler(features):
    scaler = FeatureScaler().fit(features)
    scaled = scaler.transform(features)
    assert isinstance(scaled, torch.Tensor) and scaled.dtype == features.dtype
    std = scaled.std(0, correction=1)
    constant = features.std(0) == 0
    torch.testing.assert_close(std[~constant], torch.ones(int((~constant).sum())), rtol=1e-5, atol=0)
    assert np.array_equal(scaler.mean_, np.zeros(21))
    want = np.std(features.double().numpy(), axis=0, ddof=1)
    np.testing.assert_allclose(scaler.scale_[~constant.numpy()], want[~constant.numpy()], rtol=1e-12)
    centred = FeatureScaler(center=True).fit(features).transform(features)
    torch.testing.assert_close(centred.mean(0), torch.zeros(21), atol=1e-4, rtol=0)
    # a constant feature gets scale 1 rather than a division by zero
    const = FeatureScaler().fit(np.ones((5, 3)))
    assert np.array_equal(const.scale_, np.ones(3))
    # arrays in, arrays out; the module form gives the same numbers
    np.testing.assert_allclose(scaler.transform(features.numpy()), scaled.numpy(), rtol=0, atol=0)
    torch.testing.assert_close(scaler.to_module()(features), scaled, rtol=0, atol=0)
    # the module's buffers restore it: a state dict round trip
    module = signal.ScaleFeatures(torch.zeros(21), torch.ones(21))
    module.load_state_dict(scaler.to_module().state_dict())
    torch.testing.assert_close(module(features), scaled, rtol=0, atol=0)


def test_transforms_keep_gradients(features):
    x = features[:6].double().requires_grad_()
    scaler = FeatureScaler().fit(features.double())
    transform = ClusteringTransform().fit(features.double())
    assert torch.autograd.gradcheck(scaler.transform, (x,))
    assert torch.autograd.gradcheck(transform.transform, (x,))


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda: FeatureScaler().transform(torch.zeros(2, 21)), NotFittedError, "not fitted"),
        (lambda: FeatureScaler().to_module(), NotFittedError, "not fitted"),
        (lambda: FeatureScaler().fit(torch.zeros(1, 21)), ValueError, "1 sample"),
        (
            lambda: FeatureScaler().fit(torch.zeros(4, 21, dtype=torch.int64)),
            TypeError,
            "X must have a floating",
        ),
        (lambda: FeatureScaler().fit(torch.full((4, 21), float("nan"))), ValueError, "NaN"),
        (lambda: FeatureScaler(center="yes").fit(torch.ones(4, 21)), ValueError, "'center' parameter"),
        (
            lambda: (
                FeatureScaler()
                .fit(torch.ones(4, 21) * torch.arange(4.0)[:, None])
                .transform(torch.zeros(2, 20))
            ),
            ValueError,
            "X has 20 features, but FeatureScaler is expecting 21",
        ),
        (lambda: ClusteringTransform().transform(torch.zeros(2, 21)), NotFittedError, "not fitted"),
        (lambda: ClusteringTransform(n_components=0).fit(torch.ones(4, 21)), ValueError, "'n_components'"),
        (lambda: ClusteringTransform(eps=0.0).fit(torch.ones(4, 21)), ValueError, "'eps' parameter"),
        (lambda: ClusteringTransform(features="raw").fit(torch.ones(4, 21)), ValueError, "'features'"),
        (
            lambda: ClusteringTransform(n_components=13).fit(torch.ones(20, 21)),
            ValueError,
            "n_components must be <= ",
        ),
        (lambda: ClusteringTransform().fit(torch.zeros(5, 20)), ValueError, "21 window features"),
        (lambda: ClusteringTransform().fit(-torch.ones(5, 21)), ValueError, ">= 0"),
        (lambda: clustering_features(-torch.ones(2, 21)), ValueError, ">= 0"),
        (lambda: clustering_features(torch.ones(2, 21), eps=0.0), ValueError, "eps must be > 0"),
    ],
)
def test_transform_errors(call, error, match):
    with pytest.raises(error, match=match):
        call()


def test_hyper_parameters_are_stored_unchanged_and_validated_at_fit():
    transform = ClusteringTransform(n_components=-1, eps=-1.0)  # nothing is checked in __init__
    assert transform.get_params() == {
        "n_components": -1,
        "standardize": True,
        "eps": -1.0,
        "features": "window",
    }
    with pytest.raises(ValueError, match="parameter of ClusteringTransform must be"):
        transform.fit(torch.ones(4, 21))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_clustering_transform_matches_reference(features, dtype):
    train, test = features[::2].to(dtype), features[1::2].to(dtype)
    transform = ClusteringTransform(n_components=3).fit(train)
    ours = transform.transform(test)
    assert ours.dtype == dtype
    want = ref.clustering_pca(train.double().numpy(), test.double().numpy(), n_components=3)
    tol = 1e-4 if dtype == torch.float32 else 1e-9
    np.testing.assert_allclose(ours.double().numpy(), want, rtol=tol, atol=tol)
    assert torch.isfinite(ours).all()
    ratio = transform.explained_variance_ratio_
    assert (ratio[:-1] >= ratio[1:]).all() and float(ratio.sum()) <= 1.0 + 1e-6
    assert transform.fit_transform(train).shape == (len(train), 3)
    np.testing.assert_allclose(transform.transform(test.numpy()), ours.numpy(), rtol=0, atol=0)
    # features="passthrough" on the mapped features is the same projection
    mapped = clustering_features(train.double())
    passthrough = ClusteringTransform(n_components=3, features="passthrough").fit(mapped)
    np.testing.assert_allclose(passthrough.components_, transform.components_, rtol=1e-9, atol=1e-12)


# --------------------------------------------------------------------------------------------
# ONNX: raw window -> features -> scaler and transform, one graph
# --------------------------------------------------------------------------------------------


class _Inference(torch.nn.Module):
    def __init__(self, size, scaler, transform):
        super().__init__()
        self.features = WindowFeatures(size)
        self.scaler = scaler
        self.transform = transform

    def forward(self, windows):
        feats = self.features(windows)
        return feats, self.scaler(feats), self.transform(feats)


def test_onnx_parity(surfaces, tmp_path):
    import onnx

    from tactile_torch.export import export_onnx, run_onnx

    size = 400
    x = torch.from_numpy(_test_windows(surfaces, size, np.float32))
    feats = window_features(x)
    model = _Inference(
        size, FeatureScaler().fit(feats).to_module(), ClusteringTransform().fit(feats).to_module()
    )
    path = export_onnx(model, (x[:2],), tmp_path / "features.onnx", input_names=["windows"])
    ops = {node.op_type for node in onnx.load(str(path)).graph.node}
    assert "DFT" not in ops and "MatMul" in ops  # the spectrum is a MatMul with the upper-half basis
    got = run_onnx(path, x)  # a batch size other than the export's
    want = model(x)
    assert_features_match(got[0], want[0].numpy(), np.float32, x.numpy())
    for g, w in zip(got[1:], want[1:], strict=True):
        np.testing.assert_allclose(g, w.numpy(), rtol=1e-5, atol=1e-4)
