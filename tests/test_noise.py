import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.metrics import rand_score

from tactile_torch.metrics import pairwise_accuracy
from tactile_torch.noise import awgn, gaussian_image_noise, gaussian_noise


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 4), st.integers(0, 6)), min_size=2, max_size=60))
def test_pairwise_accuracy_equals_rand_index(pairs):
    a, b = (np.array(v) for v in zip(*pairs, strict=True))
    assert pairwise_accuracy(a, b) == pytest.approx(rand_score(a, b), abs=1e-12)


def test_pairwise_accuracy_by_brute_force_and_edge_cases():
    rng = np.random.default_rng(0)
    a, b = rng.integers(0, 3, 25), rng.integers(0, 4, 25)
    same_a = a[:, None] == a[None, :]
    same_b = b[:, None] == b[None, :]
    iu = np.triu_indices(25, 1)
    assert pairwise_accuracy(a, b) == pytest.approx(np.mean(same_a[iu] == same_b[iu]))
    assert pairwise_accuracy(torch.tensor([1, 1, 2]), ["x", "x", "y"]) == 1.0
    assert pairwise_accuracy([3], [4]) == 1.0
    with pytest.raises(ValueError, match="same length, got 3 and 2"):
        pairwise_accuracy([0, 1, 2], [0, 1])
    with pytest.raises(ValueError, match="labels_true must be a 1-D array"):
        pairwise_accuracy(np.zeros((2, 2)), [0, 1])


def test_awgn_reaches_the_requested_snr_per_row():
    x = (
        torch.randn(200, 4000, dtype=torch.float64)
        * torch.linspace(0.5, 3.0, 200, dtype=torch.float64)[:, None]
    )
    for snr in (30.0, 8.0, 1.0):
        noisy = awgn(x, snr, generator=1)
        measured = 10 * torch.log10(x.pow(2).mean(1) / (noisy - x).pow(2).mean(1))
        # 4000 noise samples per row estimate the noise power to ~2 % (0.1 dB): 0.5 dB is 5 sigma.
        assert torch.allclose(measured, torch.full_like(measured, snr), atol=0.5)
        assert measured.mean().item() == pytest.approx(snr, abs=0.05)
    assert torch.equal(awgn(x, 5.0, generator=3), awgn(x, 5.0, generator=3))
    assert not torch.equal(awgn(x, 5.0, generator=3), awgn(x, 5.0, generator=4))
    zeros = torch.zeros(2, 5)
    assert torch.equal(awgn(zeros, 10.0, generator=0), zeros)


@pytest.mark.parametrize(
    ("x", "snr", "err", "match"),
    [
        (np.zeros((2, 3)), 1.0, TypeError, "x must be a torch.Tensor"),
        (torch.zeros(3), 1.0, ValueError, r"x must have shape \(B, F\), got \(3,\)"),
        (torch.zeros(2, 3, dtype=torch.int64), 1.0, TypeError, "floating dtype"),
        (torch.tensor([[float("nan")]]), 1.0, ValueError, "x must be finite"),
        (torch.zeros(2, 3), float("nan"), ValueError, "snr_db must be a finite"),
    ],
)
def test_awgn_errors(x, snr, err, match):
    with pytest.raises(err, match=match):
        awgn(x, snr)


def test_gaussian_image_noise_moments_and_clipping():
    frames = torch.full((2, 3, 3, 40, 40), 0.5, dtype=torch.float64)
    noisy = gaussian_image_noise(frames, 0.1, 0.01, generator=0)
    assert noisy.shape == frames.shape and noisy.dtype == torch.float64
    assert (noisy - frames).mean().item() == pytest.approx(0.1, abs=0.005)
    assert (noisy - frames).var().item() == pytest.approx(0.01, rel=0.05)
    heavy = gaussian_image_noise(torch.full((1, 1, 3, 8, 8), 255, dtype=torch.uint8), 0.5, 0.09, generator=0)
    assert heavy.dtype == torch.float32 and heavy.min() >= 0 and heavy.max() == 1.0
    with pytest.raises(ValueError, match=r"frames must have shape \(B, T, 3, H, W\)"):
        gaussian_image_noise(torch.zeros(2, 3, 8, 8), 0.1, 0.01)
    with pytest.raises(ValueError, match="var must be a finite variance"):
        gaussian_image_noise(frames, 0.1, -0.01)


def test_gaussian_noise_moments_determinism_and_zero():
    x = torch.zeros(50, 3, 2000, dtype=torch.float64)
    noisy = gaussian_noise(x, 0.02, generator=1)
    assert noisy.std().item() == pytest.approx(0.02, rel=0.01)
    assert abs(noisy.mean().item()) < 1e-4
    assert torch.equal(noisy, gaussian_noise(x, 0.02, generator=1))
    assert not torch.equal(noisy, gaussian_noise(x, 0.02, generator=2))
    assert torch.equal(gaussian_noise(x + 1.0, 0.0, generator=0), x + 1.0)


@pytest.mark.parametrize(
    ("call", "err", "match"),
    [
        (lambda: gaussian_noise(np.zeros(3), 0.1), TypeError, "x must be a torch.Tensor"),
        (
            lambda: gaussian_noise(torch.zeros(3), -0.1),
            ValueError,
            "std must be a finite standard deviation >= 0",
        ),
        (lambda: gaussian_noise(torch.tensor([float("nan")]), 0.1), ValueError, "x must be finite"),
    ],
)
def test_gaussian_noise_errors(call, err, match):
    with pytest.raises(err, match=match):
        call()
