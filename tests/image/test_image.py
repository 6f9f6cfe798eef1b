"""Tests of tactile_torch.image: equivalence with the SciPy reference, batching, soft mode, errors, ONNX."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.ndimage as ndi
import scipy.stats
import torch
import torch.nn.functional as F
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_torch import image
from tactile_torch.data.images import make_explorations
from tactile_torch.export import export_onnx, run_onnx
from tactile_torch.image import _integer_cut, _kernels, _scheduler
from tests import reference_image as ref

# The project's tolerances: float64 1e-10; float32 1e-5 relative (plus 1e-5 absolute for features near 0,
# e.g. a direction mean of 0.004 that sums thousands of values up to pi in float32).
TOL = {torch.float64: {"rtol": 1e-10, "atol": 1e-10}, torch.float32: {"rtol": 1e-5, "atol": 1e-5}}
NP_DTYPE = {torch.float64: np.float64, torch.float32: np.float32}


def blobby_frames(batch, n_frames, height, width, *, seed=0, dtype=torch.uint8):
    """Random explorations with pressed blobs touching the borders (white elsewhere)."""
    g = torch.Generator().manual_seed(seed)
    low = torch.rand(batch * n_frames, 1, 5, 5, generator=g)
    p = F.interpolate(low, size=(height, width), mode="bilinear", align_corners=False)
    p = p.view(batch, n_frames, 1, height, width)
    colour = torch.rand(batch, n_frames, 3, 1, 1, generator=g) * 0.8
    rgb = torch.where(p > 0.55, colour * p, torch.ones(()))
    if dtype == torch.uint8:
        return torch.round(rgb * 255).to(torch.uint8)
    return rgb.to(dtype)


@pytest.fixture(scope="module")
def realistic():
    """Four synthetic explorations (one per class): 12 frames at 64 x 64 from the middle of 3 s."""
    return make_explorations(1, n_frames=30, frame_size=64, sensels=16, random_state=3).frames[:, 12:24]


# ----------------------------------------------------------------------------------- single steps
@pytest.mark.parametrize("dtype", [torch.uint8, torch.float32, torch.float64])
def test_to_grayscale_matches_reference(dtype):
    frames = blobby_frames(1, 3, 9, 11, dtype=dtype)
    got = image.to_grayscale(frames)
    np_dtype = np.float32 if dtype == torch.uint8 else NP_DTYPE[dtype]
    want = np.stack([ref.grayscale(f, np_dtype) for f in frames[0].numpy()])
    np.testing.assert_array_equal(got[0].numpy(), want)
    assert got.dtype == (torch.float32 if dtype == torch.uint8 else dtype)


@pytest.mark.parametrize("size", [1, 2, 3, 4, 5, 10, 11])
def test_erode_binary_matches_scipy_including_borders_and_even_sizes(size):
    g = torch.Generator().manual_seed(size)
    mask = (torch.rand(6, 23, 17, generator=g) > 0.2).double()
    mask[0] = 1.0  # all pressed: nothing is eroded from the border
    mask[1, :, :3] = 1.0  # a region touching the left border
    got = image.erode(mask, size)
    want = np.stack([ref.erode(m, size) for m in mask.numpy()])
    np.testing.assert_array_equal(got.numpy(), want.astype(np.float64))
    assert bool((got[0] == 1).all())


@pytest.mark.parametrize("size", [2, 7])
def test_erode_grey_matches_scipy_grey_erosion(size):
    x = torch.rand(3, 15, 12, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    got = image.erode(x, size)
    want = np.stack([ndi.grey_erosion(a, size=(size, size), mode="constant", cval=np.inf) for a in x.numpy()])
    np.testing.assert_array_equal(got.numpy(), want)


def test_sobel_edges_matches_reference_and_gradient_matches_scipy_sobel():
    g = torch.Generator().manual_seed(2)
    mask = (F.interpolate(torch.rand(4, 1, 4, 4, generator=g), size=(20, 13), mode="bilinear") > 0.5).double()
    edges = image.sobel_edges(mask[:, 0])
    want = np.stack([ref.edges(m) for m in mask[:, 0].numpy()])
    np.testing.assert_array_equal(edges.numpy(), want.astype(np.float64))
    x = torch.rand(3, 10, 9, generator=g, dtype=torch.float64)
    x[0] = 0.0  # flat: direction 0 by convention
    x[1, :, :] = torch.arange(9.0, 0, -1, dtype=torch.float64)  # gy = 0, gx < 0: direction pi, not -pi
    magnitude, direction = image.gradient(x)
    for k, a in enumerate(x.numpy()):
        m_ref, a_ref = ref.gradient(a)
        np.testing.assert_allclose(magnitude[k].numpy(), m_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(direction[k].numpy(), a_ref, rtol=1e-12, atol=1e-12)
    assert bool((direction[0] == 0).all())
    assert bool((direction[1] == math.pi).all())
    assert float(direction.min()) > -math.pi and float(direction.max()) <= math.pi


def test_sobel_is_unnormalised_with_reflect_border():
    ramp = torch.arange(6.0, dtype=torch.float64).expand(5, 6).clone()
    gx, gy = _kernels._sobel(ramp)
    np.testing.assert_array_equal(gx.numpy(), ndi.sobel(ramp.numpy(), axis=1))
    assert float(gx[2, 2]) == 8.0 and float(gx[2, 0]) == 4.0 and float(gy.abs().max()) == 0.0


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_gradient_statistics_match_scipy(dtype):
    g = torch.Generator().manual_seed(4)
    x = torch.randn(5, 13, 7, generator=g, dtype=torch.float64).exp().to(dtype)  # skewed
    x[1] = (x[1] > 1).to(dtype)  # binary
    got = image.gradient_statistics(x)
    want = np.stack([ref.statistics(a.astype(np.float64)) for a in x.numpy()])
    np.testing.assert_allclose(got.double().numpy(), want, **TOL[dtype])
    # the conventions of docs/image.md, spelled out once against scipy/numpy directly
    v = x[0].double().numpy().ravel()
    np.testing.assert_allclose(
        got[0].double().numpy(),
        [
            v.mean(),
            v.std(ddof=1),
            scipy.stats.skew(v),
            scipy.stats.kurtosis(v, fisher=False),
            np.percentile(v, 95),
            np.abs(v - v.mean()).mean(),
        ],
        **TOL[dtype],
    )


@pytest.mark.parametrize("value", [0.0, 0.1, 3.0])
def test_gradient_statistics_of_constant_and_one_pixel_images_are_finite(value):
    stats = image.gradient_statistics(torch.full((2, 6, 5), value, dtype=torch.float64))
    np.testing.assert_allclose(stats[0].numpy(), [value, 0.0, 0.0, 0.0, value, 0.0], atol=1e-15)
    one = image.gradient_statistics(torch.full((1, 1, 1), value))
    assert torch.isfinite(one).all() and float(one[0, 1]) == 0.0


def test_otsu_matches_reference_and_splits_two_modes():
    frames = blobby_frames(3, 4, 16, 16, seed=5, dtype=torch.float64)
    gray = image.to_grayscale(frames)
    got = image.otsu_threshold(gray)
    want = [ref.otsu(a) for a in gray.numpy()]
    np.testing.assert_allclose(got.numpy(), want, rtol=0, atol=1e-12)
    two = torch.tensor([[0.2] * 10 + [0.8] * 10], dtype=torch.float64)
    assert abs(float(image.otsu_threshold(two)[0]) - 0.5) < 1 / 255  # middle of the empty plateau
    blank = torch.ones(1, 2, 4, 4)
    assert float(image.otsu_threshold(blank)[0]) == pytest.approx(0.5 / 255)
    assert not bool(image.pressure_mask(blank, "otsu").any())


def test_pressure_mask_fixed_and_per_exploration_thresholds():
    gray = torch.tensor([0.1, 0.5, 0.94, 0.95]).view(1, 1, 1, 4).expand(2, 1, 1, 4).clone()
    assert image.pressure_mask(gray)[0, 0, 0].tolist() == [1.0, 1.0, 1.0, 0.0]
    per = image.pressure_mask(gray, torch.tensor([0.3, 0.6]))
    assert per[0, 0, 0].tolist() == [1.0, 0.0, 0.0, 0.0] and per[1, 0, 0].tolist() == [1.0, 1.0, 0.0, 0.0]


def _colours_near(threshold, width=200):
    """Every uint8 RGB colour whose exact gray is within ``width`` / 2550000 of ``threshold``."""
    r, g = (a.ravel() for a in np.meshgrid(np.arange(256), np.arange(256), indexing="ij"))
    cut = float(np.float32(threshold)) * 2_550_000
    centre = (cut - 2989 * r - 5870 * g) / 1140
    colours = []
    for shift in range(-1, 2):  # width / 1140 < 1: the nearest blue levels suffice
        b = np.round(centre).astype(int) + shift
        keep = (b >= 0) & (b <= 255) & (np.abs(2989 * r + 5870 * g + 1140 * b - cut) <= width)
        colours.append(np.stack([r[keep], g[keep], b[keep]]))
    return np.unique(np.concatenate(colours, axis=1), axis=1).astype(np.uint8)  # (3, n)


@pytest.mark.parametrize("threshold", [240 / 255, 0.5, 100.5 / 255, 0.123456, 0.122])
def test_uint8_pressed_region_equals_float32_reference_at_the_threshold(threshold):
    # The uint8 path decides on the integer 2989 R + 5870 G + 1140 B: by one cut where some integer
    # cut is exact, else (0.122) by the float32 formula for the pixels within a band around the
    # threshold. Every colour near the threshold must match the reference.
    assert (_integer_cut.integer_cut(float(np.float32(threshold))) is None) == (threshold == 0.122)
    colours = _colours_near(threshold)
    assert colours.shape[1] > 100
    frames = torch.from_numpy(colours).view(1, 1, 3, 1, -1)
    got = _scheduler.pressed(frames, torch.tensor(threshold, dtype=torch.float32), torch.float32, None)
    want = ref.grayscale(colours[:, None, :], np.float32) < np.float32(threshold)
    assert got.dtype == torch.int8
    np.testing.assert_array_equal(got.view(-1).numpy(), want.ravel())
    assert 0 < want.sum() < want.size  # colours on both sides


def test_integer_cut_uses_the_float32_grayscale_of_every_colour():
    # integer_cut decides the colours near a threshold with a NumPy copy of the float32 grayscale (so
    # that it is the same eagerly and while tracing for export): it must equal the torch kernel's
    # gray, bit for bit, on all 2^24 uint8 colours
    code = torch.arange(1 << 24, dtype=torch.int32)
    colours = torch.stack([code >> 16, (code >> 8) & 255, code & 255], dim=1).to(torch.uint8)
    ours = _kernels._gray(colours.view(-1, 3, 1, 1), torch.float32).view(-1).numpy()
    np.testing.assert_array_equal(_integer_cut.gray_float32(colours.numpy()), ours)


def test_uint8_pressed_region_with_per_exploration_thresholds():
    thresholds = (0.6, 240 / 255, 0.31)
    columns = [_colours_near(t) for t in thresholds]
    n = min(c.shape[1] for c in columns)
    frames = torch.from_numpy(np.stack([c[:, :n] for c in columns])).view(3, 1, 3, 1, n)
    per = torch.tensor(thresholds, dtype=torch.float32)
    got = _scheduler.pressed(frames, per, torch.float32, None)
    naive_errors = 0
    for k, t in enumerate(thresholds):
        want = ref.grayscale(columns[k][:, None, :n], np.float32) < np.float32(t)
        np.testing.assert_array_equal(got[k].view(-1).numpy(), want.ravel())
        exact = columns[k][:, :n].astype(np.int64).T @ np.array([2989, 5870, 1140])
        naive_errors += int(np.sum((exact < float(np.float32(t)) * 2_550_000) != want.ravel()))
    assert naive_errors > 0  # the integer rule alone would be wrong here: the fallback is exercised


def test_threaded_blocks_equal_one_thread_and_leave_the_thread_count(realistic):
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        serial = image.exploration_features(
            realistic, frames_per_chunk=2, threshold=torch.tensor([0.9, 0.8, 0.7, 0.6])
        )
        torch.set_num_threads(2)
        threaded = image.exploration_features(
            realistic, frames_per_chunk=2, threshold=torch.tensor([0.9, 0.8, 0.7, 0.6])
        )
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
    torch.testing.assert_close(threaded, serial, rtol=0, atol=0)


def test_fuse_edges_is_logical_or():
    edges = (torch.rand(3, 5, 6, 7, generator=torch.Generator().manual_seed(6)) > 0.8).float()
    np.testing.assert_array_equal(
        image.fuse_edges(edges).numpy(), np.logical_or.reduce(edges.numpy() > 0, axis=1)
    )


# ------------------------------------------------------------------------------------ full pipeline
@pytest.mark.parametrize("dtype", [torch.uint8, torch.float32, torch.float64])
@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize("erosion", [1, 4, 5, 10])
def test_exploration_features_match_reference_on_random_input(dtype, fuse, erosion):
    frames = blobby_frames(2, 5, 30, 27, seed=erosion, dtype=dtype)
    got = image.exploration_features(frames, fuse=fuse, erosion=erosion, frames_per_chunk=2)
    np_dtype = np.float32 if dtype == torch.uint8 else NP_DTYPE[dtype]
    want = ref.exploration_features(frames.numpy(), fuse=fuse, erosion=erosion, dtype=np_dtype)
    assert got.shape == ((2, 12) if fuse else (2, 5 * 12))
    tol = TOL[torch.float32 if dtype == torch.uint8 else dtype]
    np.testing.assert_allclose(got.double().numpy(), want, **tol)


@pytest.mark.parametrize(("threshold", "edge_threshold"), [(240 / 255, 0.5), (0.8, 2.5), ("otsu", 0.5)])
@pytest.mark.parametrize("fuse", [True, False])
def test_exploration_features_match_reference_on_realistic_input(realistic, threshold, edge_threshold, fuse):
    kwargs = {"fuse": fuse, "threshold": threshold, "edge_threshold": edge_threshold}
    got = image.exploration_features(realistic, frames_per_chunk=5, **kwargs)
    want = ref.exploration_features(realistic.numpy(), dtype=np.float32, **kwargs)
    np.testing.assert_allclose(got.double().numpy(), want, **TOL[torch.float32])
    assert float(np.abs(want).sum()) > 0  # the explorations have edges


@settings(max_examples=25, deadline=None)
@given(
    batch=st.integers(1, 3),
    n_frames=st.integers(1, 4),
    height=st.integers(1, 12),
    width=st.integers(1, 12),
    erosion=st.integers(1, 5),
    chunk=st.integers(1, 4),
    fuse=st.booleans(),
    seed=st.integers(0, 100),
)
def test_batched_equals_per_sample_and_chunking_is_invisible(
    batch, n_frames, height, width, erosion, chunk, fuse, seed
):
    frames = blobby_frames(batch, n_frames, height, width, seed=seed, dtype=torch.float64)
    kwargs = {"fuse": fuse, "erosion": erosion}
    batched = image.exploration_features(frames, frames_per_chunk=chunk, **kwargs)
    single = torch.cat([image.exploration_features(frames[b : b + 1], **kwargs) for b in range(batch)])
    torch.testing.assert_close(batched, single, rtol=1e-12, atol=1e-12)
    assert torch.isfinite(batched).all()


def test_blank_exploration_gives_zero_features():
    blank = torch.full((2, 6, 3, 20, 20), 255, dtype=torch.uint8)
    assert image.exploration_features(blank).abs().max() == 0
    assert image.exploration_features(blank, fuse=False).abs().max() == 0
    assert image.exploration_features(blank, threshold="otsu").abs().max() == 0
    soft = image.exploration_features(blank.double() / 255, temperature=0.05)
    assert torch.isfinite(soft).all()


def test_modules_are_thin_wrappers(realistic):
    frames = realistic[:2, :3]
    gray = image.ToGrayscale()(frames)
    mask = image.PressureMask(0.9)(gray)
    eroded = image.Erode(4)(mask)
    edges = image.SobelEdges()(eroded)
    fused = image.FuseEdges()(edges)
    magnitude, direction = image.Gradient()(fused)
    stats = torch.cat([image.GradientStatistics()(magnitude), image.GradientStatistics()(direction)], -1)
    torch.testing.assert_close(stats, image.ExplorationFeatures(threshold=0.9, erosion=4)(frames))
    assert len(image.FEATURE_NAMES) == 12 and image.FEATURE_NAMES[0] == "M_mean"


# ---------------------------------------------------------------------------------------- soft mode
def test_soft_pipeline_gradcheck_reaches_frames_and_threshold():
    g = torch.Generator().manual_seed(7)
    frames = (0.3 + 0.4 * torch.rand(1, 2, 3, 6, 6, generator=g, dtype=torch.float64)).requires_grad_()
    threshold = torch.tensor(0.5, dtype=torch.float64, requires_grad=True)

    def features(x, thr):
        return image.exploration_features(x, threshold=thr, erosion=2, temperature=0.1)

    assert torch.autograd.gradcheck(features, (frames, threshold), eps=1e-6, atol=1e-5)
    out = features(frames, threshold).sum()
    grad_frames, grad_thr = torch.autograd.grad(out, (frames, threshold))
    assert grad_frames.abs().sum() > 0 and grad_thr.abs() > 0


def test_soft_steps_gradcheck():
    g = torch.Generator().manual_seed(8)
    x = torch.rand(2, 3, 5, 5, generator=g, dtype=torch.float64).requires_grad_()
    assert torch.autograd.gradcheck(lambda m: image.erode(m, 3, temperature=0.2), (x,))
    assert torch.autograd.gradcheck(lambda m: image.sobel_edges(m, temperature=0.5), (x,))
    assert torch.autograd.gradcheck(lambda m: image.fuse_edges(m, soft=True), (x,))
    assert torch.autograd.gradcheck(lambda m: image.pressure_mask(m, 0.5, temperature=0.1), (x,))


@pytest.mark.parametrize("fuse", [True, False])
def test_soft_features_converge_to_hard_as_temperature_goes_to_zero(realistic, fuse):
    frames = realistic[:, :4].double() / 255
    hard = image.exploration_features(frames, fuse=fuse, erosion=4)
    errors = [
        float((image.exploration_features(frames, fuse=fuse, erosion=4, temperature=t) - hard).abs().max())
        for t in (1e-1, 1e-2, 1e-3, 1e-4)
    ]
    assert errors[-1] < 1e-6 * float(hard.abs().max())
    assert errors[0] > errors[-1]


# ------------------------------------------------------------------------------------------- errors
@pytest.mark.parametrize(
    ("frames", "error", "match"),
    [
        ([[0.0]], TypeError, "frames must be a torch.Tensor, got list"),
        (
            torch.zeros(2, 3, 8, 8),
            ValueError,
            r"frames must have shape \(B, T, 3, H, W\), got \(2, 3, 8, 8\)",
        ),
        (torch.zeros(1, 2, 4, 8, 8), ValueError, r"frames must have shape \(B, T, 3, H, W\)"),
        (torch.zeros(1, 0, 3, 8, 8), ValueError, r"at least one frame per exploration \(T >= 1\)"),
        (torch.zeros(1, 2, 3, 8, 8, dtype=torch.int64), TypeError, "uint8 .* or float"),
        (torch.full((1, 2, 3, 4, 4), float("nan")), ValueError, "frames must be finite, got 96 NaN"),
        (torch.full((1, 2, 3, 4, 4), 255.0), ValueError, r"float in \[0, 1\].*got values in \[255, 255\]"),
    ],
)
def test_exploration_features_rejects_bad_frames(frames, error, match):
    with pytest.raises(error, match=match):
        image.exploration_features(frames)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"threshold": "auto"}, ValueError, "threshold must be a number in \\(0, 1\\], a tensor or 'otsu'"),
        ({"threshold": 240}, ValueError, "threshold must be in \\(0, 1\\]"),
        (
            {"threshold": torch.ones(3)},
            ValueError,
            "threshold must be a scalar tensor or have shape \\(2,\\)",
        ),
        ({"erosion": 0}, ValueError, "erosion must be > 0"),
        ({"erosion": 2.5}, TypeError, "erosion must be an integer"),
        ({"temperature": 0.0}, ValueError, "temperature must be > 0"),
        ({"edge_threshold": -1.0}, ValueError, "edge_threshold must be >= 0"),
        ({"frames_per_chunk": 0}, ValueError, "frames_per_chunk must be > 0"),
    ],
)
def test_exploration_features_rejects_bad_arguments(kwargs, error, match):
    with pytest.raises(error, match=match):
        image.exploration_features(torch.zeros(2, 2, 3, 8, 8), **kwargs)


def test_single_step_functions_validate_their_input():
    with pytest.raises(ValueError, match=r"gray must have shape \(B, T, H, W\)"):
        image.pressure_mask(torch.zeros(4, 4))
    with pytest.raises(TypeError, match="mask must have a floating dtype"):
        image.erode(torch.zeros(4, 4, dtype=torch.bool))
    with pytest.raises(ValueError, match="mask must be finite"):
        image.sobel_edges(torch.full((4, 4), float("inf")))
    with pytest.raises(ValueError, match=r"edges must have shape \(B, T, H, W\)"):
        image.fuse_edges(torch.zeros(4, 4))
    with pytest.raises(ValueError, match="image must have non-empty dimensions"):
        image.gradient_statistics(torch.zeros(2, 0, 4))
    with pytest.raises(TypeError, match=r"image must be a torch\.Tensor"):
        image.gradient(np.zeros((4, 4)))
    with pytest.raises(ValueError, match=r"frames must have shape \(\*, 3, H, W\)"):
        image.to_grayscale(torch.zeros(2, 4, 4))
    with pytest.raises(ValueError, match=r"gray must be float in \[0, 1\]"):
        image.otsu_threshold(torch.full((1, 4), 2.0))


# --------------------------------------------------------------------------------------------- ONNX
class _PlainFunction(torch.nn.Module):
    def forward(self, frames):
        return image.exploration_features(frames, erosion=4)


def test_onnx_export_of_the_inference_path_matches_onnxruntime(tmp_path, realistic):
    import onnx
    from onnx import numpy_helper

    # The plain function, not the module: nothing has to be prepared before tracing. The graph holds
    # the integer gray 2989 R + 5870 G + 1140 B (the exact integer cut, a pure function of the
    # threshold), whatever ran before in this process.
    module = _PlainFunction()
    path = export_onnx(module, (realistic[:2, :6],), tmp_path / "features.onnx", input_names=["frames"])
    weights = [numpy_helper.to_array(t).ravel().tolist() for t in onnx.load(str(path)).graph.initializer]
    assert [2989.0, 5870.0, 1140.0] in weights
    frames = realistic[:, 6:]  # another batch size and other frames
    (got,) = run_onnx(path, frames)
    np.testing.assert_allclose(got, module(frames).numpy(), rtol=1e-5, atol=1e-5)
    unfused = image.ExplorationFeatures(fuse=False, erosion=4)
    path = export_onnx(unfused, (realistic[:2, :6],), tmp_path / "unfused.onnx", input_names=["frames"])
    (got,) = run_onnx(path, frames)
    np.testing.assert_allclose(got, unfused(frames).numpy(), rtol=1e-5, atol=1e-5)


def test_exploration_features_match_reference_on_real_grasps(shared_data):
    # real pressure-array recordings (the synthetic-data tests above cover the same code)
    from tactile_torch.data.grasps import DRIMUS, load_drimus_grasps

    data = load_drimus_grasps(shared_data(DRIMUS), n_frames=20)
    frames = data.frames[torch.arange(0, len(data), 10)]  # one grasp of each object
    for fuse in (True, False):
        got = image.exploration_features(frames, fuse=fuse, erosion=3)
        want = ref.exploration_features(frames.numpy(), fuse=fuse, erosion=3, dtype=np.float32)
        np.testing.assert_allclose(got.double().numpy(), want, **TOL[torch.float32])
    assert float(np.abs(want).sum()) > 0
