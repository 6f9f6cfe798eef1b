"""Per-session standardisation (issue 22, point 1): a gain shift per session no longer splits surfaces."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.signal.sessions import standardise_per_session


def test_a_shift_per_session_is_removed_and_the_surfaces_stay_apart():
    rng = np.random.default_rng(0)
    surfaces = np.repeat(np.arange(3), 40)
    X0 = rng.normal(size=(120, 2)) * 0.3 + np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]])[surfaces]
    out = []
    for shift in (-3.0, 0.0, 5.0):  # each session: every surface, moved by the session's shift
        out.append(standardise_per_session(X0 + shift, np.zeros(120)))
    np.testing.assert_allclose(out[0], out[2], atol=1e-12)
    sessions = np.repeat([0, 1, 2], 120)
    Z = standardise_per_session(np.concatenate([X0 - 3.0, X0, X0 + 5.0]), sessions)
    np.testing.assert_allclose(Z[:120], Z[240:], atol=1e-12)
    for s in range(3):
        np.testing.assert_allclose(Z[sessions == s].mean(0), 0.0, atol=1e-12)
        np.testing.assert_allclose(Z[sessions == s].std(0), 1.0, rtol=1e-12)


def test_a_constant_feature_is_only_centred():
    Z = standardise_per_session(np.array([[1.0, 2.0], [3.0, 2.0]]), [0, 0])
    assert Z.tolist() == [[-1.0, 0.0], [1.0, 0.0]]


@pytest.mark.parametrize(
    ("X", "sessions", "match"),
    [
        (np.zeros(3), [0, 0, 0], "X must be a 2-D array"),
        (np.zeros((3, 2)), [0, 0], "sessions must have one entry per row of X"),
        (np.array([[0.0], [np.nan]]), [0, 0], "X must be finite"),
    ],
)
def test_bad_input_raises(X, sessions, match):
    with pytest.raises(ValueError, match=match):
        standardise_per_session(X, sessions)
