"""The contract of tactile_torch.data.out_of_distribution.out_of_distribution_signals, the one generator of signals no surface gives.

Its windows feed the "unknown" measurements (tests/export/test_model_graph.py, export/measure_unknown.py and the
numbers of docs/export.md), so they must not drift: the reference below is the plain formula, drawn in
the documented order from one numpy generator.
"""

import numpy as np
import pytest

from tactile_torch.data.out_of_distribution import OUT_OF_DISTRIBUTION_KINDS, out_of_distribution_signals


def reference_signals(n, window, rate, rng, with_small_noise=True):
    """The documented draws, written out: tone parameters first, then each kind in order."""
    t = np.arange(window) / rate
    freq = rng.uniform(5, rate / 2.2, (n, 1, 1))
    phase = rng.uniform(0, 2 * np.pi, (n, 3, 1))
    amp = rng.uniform(0.05, 4, (n, 1, 1))
    signals = {
        "zeros": np.zeros((n, 3, window)),
        "constant": np.zeros((n, 3, window)) + rng.uniform(-4, 4, (n, 3, 1)),
        "constant 1 g": np.zeros((n, 3, window)) + np.array([0.0, 0.0, 1.0])[:, None],
        "white noise 4.9 g": rng.uniform(-4.9, 4.9, (n, 3, window)),
    }
    if with_small_noise:
        signals["white noise sd 0.01 g"] = rng.normal(0, 0.01, (n, 3, window))
    signals["white noise sd 0.1 g"] = rng.normal(0, 0.1, (n, 3, window))
    signals["white noise sd 1 g"] = rng.normal(0, 1.0, (n, 3, window)).clip(-5, 5)
    signals["pure tone"] = amp * np.sin(2 * np.pi * freq * t + phase)
    signals["square wave"] = amp * np.sign(np.sin(2 * np.pi * freq * t + phase))
    tilt = np.deg2rad(rng.uniform(0.0, 30.0, n))
    gravity = np.stack([np.sin(tilt), np.zeros(n), np.cos(tilt)], axis=1)[:, :, None]
    signals["still sensor"] = np.round((gravity + rng.normal(0, 0.0047, (n, 3, window))) / 0.0039) * 0.0039
    return {name: x.astype(np.float32) for name, x in signals.items()}


@pytest.mark.parametrize(("n", "window", "rate"), [(5, 64, 800.0), (3, 10, 100.0)])
def test_signals_are_the_documented_draws(n, window, rate):
    got = out_of_distribution_signals(n, window, rate, random_state=7)
    want = reference_signals(n, window, rate, np.random.default_rng(7))
    assert list(got) == list(OUT_OF_DISTRIBUTION_KINDS) == list(want)
    for kind in want:
        assert got[kind].dtype == np.float32 and got[kind].shape == (n, 3, window)
        np.testing.assert_array_equal(got[kind], want[kind], err_msg=kind)
    # a kind left out draws nothing: the kinds after it are those of a generator that never drew it
    kinds = [k for k in OUT_OF_DISTRIBUTION_KINDS if k != "white noise sd 0.01 g"]
    rng = np.random.default_rng(7)
    subset = out_of_distribution_signals(n, window, rate, rng, kinds=kinds)
    want = reference_signals(n, window, rate, np.random.default_rng(7), with_small_noise=False)
    assert list(subset) == kinds
    for kind in kinds:
        np.testing.assert_array_equal(subset[kind], want[kind], err_msg=kind)
    assert rng.bit_generator.state != np.random.default_rng(7).bit_generator.state  # drawn from as is


def test_signals_are_what_their_names_say():
    x = out_of_distribution_signals(50, 200, 800.0, random_state=0)
    assert not x["zeros"].any()
    for kind in ("constant", "constant 1 g"):  # a stuck sensor: every axis constant
        assert (x[kind].max(axis=2) == x[kind].min(axis=2)).all()
    assert np.abs(x["constant"]).max() <= 4.0
    np.testing.assert_array_equal(x["constant 1 g"][:, :, 0], np.tile([0.0, 0.0, 1.0], (50, 1)))
    assert np.abs(x["white noise 4.9 g"]).max() <= 4.9
    for kind, sd in (("white noise sd 0.01 g", 0.01), ("white noise sd 0.1 g", 0.1)):
        assert x[kind].std() == pytest.approx(sd, rel=0.02)
    assert np.abs(x["white noise sd 1 g"]).max() <= 5.0
    amp = np.abs(x["square wave"]).max(axis=(1, 2))  # a square wave of the tone's amplitude
    assert ((amp >= 0.05) & (amp <= 4.0)).all()
    assert (np.abs(x["pure tone"]).max(axis=(1, 2)) <= amp * (1 + 1e-6)).all()
    levels = np.abs(x["square wave"]) / np.abs(x["square wave"]).max(axis=(1, 2), keepdims=True)
    assert np.isin(levels, [0.0, 1.0]).all()
    # the tones' frequency lies below rate / 2.2: at least ~2 samples per half period
    crossings = (np.diff(np.sign(x["pure tone"]), axis=2) != 0).sum(axis=2)
    assert crossings.max() <= 2 * 200 / 2.2 * 1.05 + 2
    still = x["still sensor"].astype(np.float64)  # at rest: 1 g, small noise, multiples of 3.9 mg
    np.testing.assert_allclose(np.linalg.norm(still.mean(axis=2), axis=1), 1.0, atol=0.002)
    assert 0.003 < still.std(axis=2).mean() < 0.006 and not (still.max(axis=2) == still.min(axis=2)).all()
    np.testing.assert_allclose(still / 0.0039, np.round(still / 0.0039), atol=1e-3)
    same = out_of_distribution_signals(50, 200, 800.0, random_state=0, kinds=["pure tone", "zeros"])
    assert list(same) == ["pure tone", "zeros"]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n": 0}, "n must be an int >= 1, got 0"),
        ({"window": 0}, "window must be an int >= 1, got 0"),
        ({"rate_hz": 0.0}, "rate_hz"),
        ({"kinds": ["zeros", "pink noise"]}, r"kinds must be a non-empty list of \['zeros'"),
        ({"kinds": []}, "kinds must be a non-empty list"),
    ],
)
def test_bad_arguments_are_named(kwargs, match):
    args = {"n": 2, "window": 8, "rate_hz": 100.0, **kwargs}
    with pytest.raises(ValueError, match=match):
        out_of_distribution_signals(**args)
