"""Tests of tactile_torch.data.grasps: the iCub grasp loader on its real files and on a synthetic copy."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from tactile_torch.data.grasps import ICUB, load_icub_grasps


def _write_grasp(path, slices, rng):
    lines = ["-10000"]
    for _ in range(slices):
        lines.append(" ".join(f"{v:.4f}" for v in rng.uniform(0, 90, 9)))
        lines.append(" ".join(f"{v:.1f}" for v in rng.integers(0, 20, 5)))
        for _ in range(5):
            lines.append(" ".join(f"{v:.1f}" for v in rng.integers(200, 256, 12)))
    path.write_text("\n".join(lines) + "\n")


def test_icub_loader_on_files_in_its_layout(tmp_path):
    rng = np.random.default_rng(0)
    (tmp_path / "iCubGraspDataset").mkdir()
    rows = ["file,class_name,trial,n_slices,reliable"]
    for name, trial, slices, reliable in [
        ("book", 1, 5, True),
        ("book", 2, 6, True),
        ("cup", 1, 4, True),
        ("bad", 1, 4, False),
    ]:
        _write_grasp(tmp_path / "iCubGraspDataset" / f"{name}_{trial}.txt", slices, rng)
        rows.append(f"iCubGraspDataset/{name}_{trial}.txt,{name},{trial},{slices},{reliable}")
    (tmp_path / "index.csv").write_text("\n".join(rows) + "\n")
    data = load_icub_grasps(tmp_path, n_frames=3, scale=2)
    assert data.frames.shape == (3, 3, 3, 10, 24) and data.frames.dtype == torch.uint8
    assert data.class_names == ("book", "cup") and data.labels.tolist() == [0, 0, 1]
    assert data.pressure.shape == (3, 3, 5, 12) and float(data.pressure.min()) >= 0.0
    # pressure = resting level (maximum over the grasp) minus the reading
    lines = (tmp_path / "iCubGraspDataset" / "cup_1.txt").read_text().split("\n")[1:]
    taxels = np.array(
        [[[float(v) for v in lines[7 * s + 2 + f].split()] for f in range(5)] for s in range(4)]
    )
    np.testing.assert_allclose(data.pressure[2].numpy(), taxels.max(0) - taxels[-3:])
    assert len(load_icub_grasps(tmp_path, reliable_only=False).class_names) == 3
    with pytest.raises(ValueError, match=r"n_frames must be <= 4"):
        load_icub_grasps(tmp_path, n_frames=5)
    with pytest.raises(FileNotFoundError, match="icub_grasp"):
        load_icub_grasps(tmp_path / "nowhere")


def test_icub_loader_on_the_real_set(shared_data):
    data = load_icub_grasps(shared_data(ICUB))
    assert data.frames.shape == (203, 4, 3, 20, 48) and len(data.class_names) == 10
    assert "full_coke" not in data.class_names  # unreliable by the data set's README
    assert torch.bincount(data.labels).tolist() == [20, 20, 21, 20, 20, 20, 20, 20, 20, 22]
