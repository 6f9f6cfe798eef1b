"""tactile_torch.features: the feature transformers (per-taxel features, the ranked selector, pressure maps)."""

import numpy as np
import pytest
import torch

from tactile_torch.features.transformers import (
    PressedFrames,
    PressureImageFeatures,
    RankedFeatureSelector,
    TaxelFeatureTransformer,
    taxel_features,
)
from tactile_torch.image import relative_erosion
from tactile_torch.signal import window_features


def test_taxel_features_are_each_taxels_window_features():
    rng = np.random.default_rng(0)
    maps = torch.from_numpy(rng.normal(size=(3, 20, 2, 5)))  # 10 taxels: padding to 12
    got = taxel_features(maps)
    series = maps.reshape(3, 20, 10).transpose(1, 2)  # (B, taxel, T)
    for j in range(10):
        triple = torch.stack([series[:, j], series[:, j], series[:, j]], 1)
        np.testing.assert_allclose(got[:, 7 * j : 7 * j + 7], window_features(triple)[:, :7], rtol=1e-12)
    assert TaxelFeatureTransformer().fit_transform(maps.numpy()).shape == (3, 70)


def test_ranked_selector_keeps_the_informative_columns():
    rng = np.random.default_rng(1)
    y = np.arange(90) % 3
    X = rng.normal(size=(90, 6))
    X[:, 4] += 3 * y
    X[:, 1] += 1.5 * y
    sel = RankedFeatureSelector(2).fit(X, y)
    assert sel.columns_.tolist() == [4, 1]
    with pytest.raises(ValueError, match="k must be an integer"):
        RankedFeatureSelector(7).fit(X, y)


def test_pressure_maps_scale_with_the_array_and_the_data():
    assert (relative_erosion(96, 96), relative_erosion(4, 4)) == (10, 1)
    rng = np.random.default_rng(2)
    maps = 500.0 + rng.normal(0, 1, size=(6, 5, 4, 4))  # 4 x 4 array, raw counts around 500
    maps[:, 3:, 1:3, 1:3] += 80.0  # contact in the middle in the last two frames
    t = PressureImageFeatures().fit(maps)
    assert t.sign_ == 1.0 and t.factor_ == 12 and t.erosion_ == 5  # 48 x 48 display, erosion relative to it
    assert 0 < t.level_ < 80
    frames = t._pressed()(torch.from_numpy(maps.astype(np.float32)))
    assert frames.shape == (6, 5, 3, 48, 48) and 0 < float((frames == 0).float().mean()) < 0.5
    lowered = PressureImageFeatures(contact="lowers").fit(1000.0 - maps)  # iCub-like: contact lowers it
    np.testing.assert_allclose(lowered.transform(1000.0 - maps), t.transform(maps), atol=1e-5)
    assert PressureImageFeatures(contact="auto").fit(1000.0 - maps).sign_ == -1.0
    with pytest.raises(ValueError, match="contact: the readings do not show"):
        PressureImageFeatures(contact="auto").fit(np.full((4, 5, 4, 4), 3.0))
    with pytest.raises(ValueError, match="contact: the pressure maps never rise"):
        PressureImageFeatures().fit(np.full((3, 4, 4, 4), 7.0))
    assert isinstance(t.to_module()[0], PressedFrames)
