"""Tests of tactile_torch.data.images (synthetic explorations, .npz io) and of the image_features study."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from tactile_torch import image
from tactile_torch.data.images import (
    CLASS_NAMES,
    DISPLAY_FLOOR,
    NEAR_DUPLICATES,
    OBJECTS,
    ImageExplorations,
    SurfaceObject,
    jet,
    load_explorations,
    make_explorations,
    render_pressure,
    save_explorations,
)
from tactile_torch.studies import run_report


@pytest.fixture(scope="module")
def small():
    return make_explorations(2, n_frames=15, frame_size=64, sensels=16, random_state=11, keep_pressure=True)


def test_generator_shapes_labels_and_objects(small):
    assert small.frames.shape == (8, 15, 3, 64, 64) and small.frames.dtype == torch.uint8
    assert small.labels.tolist() == [0, 0, 1, 1, 2, 2, 3, 3]
    assert small.class_names == CLASS_NAMES
    for label, group in zip(small.labels.tolist(), small.groups.tolist(), strict=True):
        assert OBJECTS[group].pattern == CLASS_NAMES[label]
    assert small.pressure.shape == (8, 15, 16, 16) and len(small) == 8


def test_generator_is_seeded():
    a = make_explorations(1, n_frames=6, frame_size=32, sensels=8, random_state=5)
    b = make_explorations(1, n_frames=6, frame_size=32, sensels=8, random_state=5)
    c = make_explorations(1, n_frames=6, frame_size=32, sensels=8, random_state=6)
    assert torch.equal(a.frames, b.frames) and torch.equal(a.groups, b.groups)
    assert not torch.equal(a.frames, c.frames)


def test_frames_look_like_a_pressure_display(small):
    frames = small.frames
    white = (frames == 255).all(2)
    pressed = image.pressure_mask(image.to_grayscale(frames))
    # white exactly where nothing is pressed: no colour of the map reaches the 240/255 threshold
    assert torch.equal(pressed == 0, white)
    share = pressed.mean().item()
    assert 0.01 < share < 0.6  # a fingertip-sized contact, not an empty or full frame
    # the sensels: readings quantised to counts in [0, 255], zero below the noise threshold
    p = small.pressure
    assert torch.equal(p, p.round()) and p.max() <= 255 and not bool(((p > 0) & (p < 3)).any())
    # contact force varies over the exploration: the pressed area is not constant in time
    area = pressed.sum((-1, -2)).float()
    assert bool((area.std(1) > 0).all())


def test_render_pressure_white_background_and_jet_colours():
    pressure = torch.zeros(1, 1, 4, 4)
    pressure[0, 0, 1:3, 1:3] = 255.0
    rgb = render_pressure(pressure, 8)
    assert rgb.shape == (1, 1, 3, 8, 8)
    assert bool((rgb[0, 0, :, 0, 0] == 255).all())  # no pressure: white
    assert rgb[0, 0, :, 4, 4].tolist() == [128, 0, 0]  # saturated: jet's dark red
    np.testing.assert_allclose(jet(torch.tensor([0.0, 0.5])).numpy(), [[0, 0, 0.5], [0.5, 1, 0.5]])
    below = render_pressure(torch.full((1, 1, 2, 2), DISPLAY_FLOOR - 1), saturation=255.0)
    assert bool((below == 255).all())


def test_render_pressure_equals_jet_of_the_upsampled_maps():
    """The in-place renderer gives the bytes of the plain formula: white below the floor, else jet."""
    g = torch.Generator().manual_seed(5)
    pressure = (torch.rand(3, 7, 6, 6, generator=g) * 320.0 - 10.0).clamp(min=0.0)
    up = torch.nn.functional.interpolate(
        pressure.reshape(21, 1, 6, 6) / 255.0, size=(10, 12), mode="bilinear", align_corners=False
    ).reshape(3, 7, 10, 12)
    expected = torch.where((up < DISPLAY_FLOOR / 255.0).unsqueeze(2), 1.0, jet(up).movedim(-1, 2))
    expected = torch.round(expected * 255.0).to(torch.uint8)
    assert torch.equal(render_pressure(pressure, (10, 12)), expected)


def test_npz_round_trip(tmp_path, small):
    path = save_explorations(tmp_path / "set.npz", small)
    with np.load(path) as npz:
        assert npz["frames"].shape == (8, 15, 64, 64, 3) and npz["frames"].dtype == np.uint8
        assert npz["labels"].dtype == np.int64
    back = load_explorations(path)
    assert torch.equal(back.frames, small.frames) and torch.equal(back.labels, small.labels)
    assert back.class_names == CLASS_NAMES and torch.equal(back.groups, small.groups)


def test_npz_with_raw_pressure_maps_is_rendered(tmp_path, small):
    path = tmp_path / "pressure.npz"
    np.savez(
        path, frames=small.pressure.numpy(), labels=small.labels.numpy(), class_names=np.array(CLASS_NAMES)
    )
    back = load_explorations(path, frame_size=64)
    assert back.frames.shape == (8, 15, 3, 64, 64) and back.groups is None
    assert torch.equal(back.frames, small.frames)  # the generator renders the same way
    assert torch.equal(back.pressure, small.pressure)


@pytest.mark.parametrize(
    ("arrays", "match"),
    [
        ({"labels": np.zeros(1, np.int64), "class_names": np.array(["a"])}, r"bad\.npz: missing 'frames'"),
        (
            {
                "frames": np.zeros((1, 2, 4, 4, 3), np.float32),
                "labels": np.zeros(1),
                "class_names": np.array(["a"]),
            },
            r"frames must be uint8 RGB \(N, T, H, W, 3\)",
        ),
        (
            {
                "frames": np.zeros((2, 2, 4, 4, 3), np.uint8),
                "labels": np.zeros(3, np.int64),
                "class_names": np.array(["a"]),
            },
            r"labels must be integers of shape \(2,\)",
        ),
        (
            {
                "frames": np.zeros((1, 2, 4, 4, 3), np.uint8),
                "labels": np.array([4]),
                "class_names": np.array(["a"]),
            },
            "labels must index class_names",
        ),
        (
            {
                "frames": np.zeros((1, 2, 4, 4, 3), np.uint8),
                "labels": np.array([0]),
                "class_names": np.array(["a"]),
                "groups": np.zeros(2, np.int64),
            },
            r"groups must be integers of shape \(1,\)",
        ),
    ],
)
def test_load_explorations_rejects_malformed_files(tmp_path, arrays, match):
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ValueError, match=match):
        load_explorations(tmp_path / "bad.npz")


def test_generator_rejects_bad_arguments():
    with pytest.raises(ValueError, match="n_per_class must be > 0"):
        make_explorations(0)
    with pytest.raises(ValueError, match="need 4 <= sensels <= frame_size"):
        make_explorations(1, frame_size=16, sensels=24)
    with pytest.raises(ValueError, match="objects must include every class"):
        make_explorations(1, objects=OBJECTS[:4])
    with pytest.raises(ValueError, match="objects must have patterns among"):
        make_explorations(1, objects=(*OBJECTS, SurfaceObject("x", "waves", 5.0, 2.0, 1.0)))
    with pytest.raises(ValueError, match=r"pressure must have shape \(N, T, h, w\)"):
        render_pressure(torch.zeros(4, 4))


def test_generator_knobs_change_the_sensor_and_the_surfaces():
    base = dict(n_frames=4, frame_size=32, sensels=8, random_state=3, keep_pressure=True)
    plain = make_explorations(2, **base)
    explicit = make_explorations(
        2,
        sensel_pitch_mm=4 / 3,
        contact_mm=(6.0, 9.0),
        texture_scale=1.0,
        near_duplicates=0.0,
        noise_counts=1.5,
        **base,
    )
    assert torch.equal(plain.frames, explicit.frames)  # the defaults are the documented values
    for knob in (
        {"sensel_pitch_mm": 2.5},
        {"contact_mm": (10.0, 12.0)},
        {"texture_scale": 0.5},
        {"noise_counts": 8.0},
    ):
        assert not torch.equal(make_explorations(2, **base, **knob).pressure, plain.pressure), knob
    alike = make_explorations(4, near_duplicates=0.5, **base)
    objects = (*OBJECTS, *NEAR_DUPLICATES)
    for label, group in zip(alike.labels.tolist(), alike.groups.tolist(), strict=True):
        assert objects[group].pattern == CLASS_NAMES[label]
    assert (alike.groups >= len(OBJECTS)).sum().item() == 8  # half of each class's 4
    quiet = make_explorations(2, noise_counts=0.0, **base)
    assert quiet.pressure[quiet.pressure > 0].min() >= 3.0  # readings below the noise threshold stay 0


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"sensel_pitch_mm": 0.0}, ValueError, "sensel_pitch_mm must be > 0"),
        ({"texture_scale": -1.0}, ValueError, "texture_scale must be > 0"),
        ({"noise_counts": -0.5}, ValueError, "noise_counts must be >= 0"),
        ({"contact_mm": (9.0, 6.0)}, ValueError, r"contact_mm must be a range \(low, high\)"),
        ({"near_duplicates": 1.5}, ValueError, r"near_duplicates must be a share in \[0, 1\]"),
    ],
)
def test_generator_knob_errors(kwargs, error, match):
    with pytest.raises(error, match=match):
        make_explorations(1, n_frames=2, frame_size=16, sensels=8, **kwargs)


def test_image_features_study_quick_writes_figures_and_tables(tmp_path):
    path = run_report(tmp_path, quick=True, only=["image_features"], log=lambda s: None)
    text = path.read_text()
    assert "## Method 1: tactile-image features" in text
    for name in ("image-pipeline-stages", "image-fused-per-class"):
        png = tmp_path / "figures" / f"{name}.png"
        assert png.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert f"figures/{name}.png" in text
    tables = json.loads((tmp_path / "report.json").read_text())["sections"][0]["tables"]
    per_class, accuracy = tables
    assert [row["class"] for row in per_class["rows"]] == list(CLASS_NAMES)
    assert {row["features"] for row in accuracy["rows"]} == {"fused (12)", "unfused (240)"}
    assert "tactile-torch report --only image_features" in text
    with np.load(tmp_path / "image_features.npz") as saved:
        assert saved["fused"].shape == (12, 12) and saved["unfused"].shape == (12, 20 * 12)
        assert saved["feature_names"].tolist() == list(image.FEATURE_NAMES)


def test_image_explorations_container():
    data = ImageExplorations(torch.zeros(2, 1, 3, 4, 4, dtype=torch.uint8), torch.tensor([0, 1]), ("a", "b"))
    assert len(data) == 2 and data.groups is None


def test_load_drimus_grasps(shared_data, tmp_path):
    from tactile_torch.data.grasps import DRIMUS, load_drimus_grasps

    data = load_drimus_grasps(shared_data(DRIMUS), n_frames=10, scale=2)
    assert data.frames.shape == (51, 10, 3, 28, 12) and len(data.class_names) == 5
    assert torch.bincount(data.labels).tolist() == [10, 10, 10, 12, 9]  # PROVENANCE.md's counts
    assert float(data.pressure.min()) == 0.0
    with pytest.raises(FileNotFoundError, match="drimus_sdh_tactile"):
        load_drimus_grasps(tmp_path)
    with pytest.raises(ValueError, match="sensor must be one of the arrays"):
        load_drimus_grasps(shared_data(DRIMUS), sensor="ts9")
