"""The data package's loaders and savers go through the robot's formats (tactile_torch.robot.files.formats, whose own
tests, torch-free, are in tests/robot/files/test_formats.py): image explorations, the torch sliding windows, and the
real recordings and grasps round-tripped."""

import numpy as np
import pytest
import torch

from tactile_torch.data import load_borealtc_imu, load_vibration_npz
from tactile_torch.data.grasps import load_drimus_grasps
from tactile_torch.data.images import load_explorations, save_explorations
from tactile_torch.robot.files.formats import (
    ExplorationArrays,
    read_data,
    read_explorations,
    write_explorations,
)
from tactile_torch.robot.stream.windows import window_recordings
from tactile_torch.signal import sliding_windows
from tests.conftest import require_shared_data


@pytest.mark.parametrize(
    ("lengths", "size", "step"), [((50, 7, 90), 8, 3), ((40,), 40, 1), ((33, 64), 16, 16)]
)
def test_window_recordings_equals_the_torch_sliding_windows(lengths, size, step):
    rng = np.random.default_rng(size)
    signals = [rng.normal(size=(n, 3)).astype(np.float32) for n in lengths]
    reference = [sliding_windows(torch.from_numpy(s), size, step).numpy() for s in signals if len(s) >= size]
    np.testing.assert_array_equal(window_recordings(signals, size, step).windows, np.concatenate(reference))


def test_image_wrappers_go_through_the_format(tmp_path):
    from tactile_torch.data.images import make_explorations

    data = make_explorations(1, n_frames=3, frame_size=24, sensels=6, random_state=0)
    path = save_explorations(tmp_path / "set.npz", data)
    assert read_explorations(path).frames.shape == (4, 3, 24, 24, 3)  # channels last on disk
    back = load_explorations(path)
    assert torch.equal(back.frames, data.frames) and torch.equal(back.groups, data.groups)


def test_real_ragged_recordings_load_without_pickle(tmp_path):
    rec = load_borealtc_imu(require_shared_data("borealtc_imu"))  # 15 runs of 942 ... 8800 samples
    assert len({len(s) for s in rec.signals}) > 1
    path = rec.save(tmp_path / "borealtc.npz")
    with np.load(path, allow_pickle=False) as raw:
        assert raw["signals"].shape == (sum(len(s) for s in rec.signals), 3)
    back = load_vibration_npz(path)
    for a, b in zip(rec.signals, back.signals, strict=True):
        np.testing.assert_array_equal(a, b)
    assert list(back.session) == list(rec.session) and back.class_names == rec.class_names


def test_real_pressure_grasps_round_trip(tmp_path):
    grasps = load_drimus_grasps(require_shared_data("drimus_sdh_tactile"), n_frames=20)
    pressure = ExplorationArrays(None, grasps.pressure.numpy(), grasps.labels.numpy(), grasps.class_names)
    back = read_data(write_explorations(tmp_path / "drimus.npz", pressure))
    np.testing.assert_array_equal(back.pressure, grasps.pressure.numpy())
    rendered = load_explorations(tmp_path / "drimus.npz", frame_size=tuple(grasps.frames.shape[-2:]))
    assert torch.equal(rendered.frames, grasps.frames) and rendered.class_names == grasps.class_names
