"""A hand's continuous taxel log becomes training touches, cut by the live stream's own stages (issue 42, point 2).

Torch-free, as on the robot: :func:`tactile_torch.robot.stream.recorded_touches.recorded_touches` runs the
stream's sequencer and touch segmenter over each recording at the levels the bundle will carry.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from tactile_torch.robot.files.data_sources import read_source
from tactile_torch.robot.files.frame_recordings import FrameRecording, write_frame_recording
from tactile_torch.robot.stream.recorded_touches import recorded_touches
from tactile_torch.robot.stream.segments import Segments
from tactile_torch.robot.stream.sequencer import Sequencer
from tactile_torch.robot.stream.source import FRAME, ArraySource, ItemSpec
from tactile_torch.robot.stream.touch_segments import TouchSegmenter

CLASSES = ("denim", "felt", "silk")
RATE = 50.0


def _log(seed: int, n_touches: int = 12, *, t0: float = 0.0, labelled: bool = True, only: int | None = None):
    """A 4 x 4 array: rest (10 counts), then touches of 0.6-1.2 s whose pressure wave moves at each class's frequency."""
    rng = np.random.default_rng(seed)
    frames, labels = [], []
    for i in range(n_touches):
        c = i % len(CLASSES) if only is None else only
        rest = int(rng.uniform(0.4, 0.8) * RATE)
        frames.append(np.zeros((rest, 4, 4)))
        labels += [-1] * rest
        n = int(rng.uniform(0.6, 1.2) * RATE)
        tt = np.arange(n) / RATE
        envelope = np.minimum(1.0, np.minimum(tt / 0.1, (tt[-1] - tt) / 0.1 + 0.1))
        wave = 1 + 0.4 * np.sin(2 * np.pi * ((2.0, 5.0, 9.0)[c] * tt[:, None, None] - np.arange(4) / 4))
        frames.append(30 * rng.uniform(0.8, 1.2) * envelope[:, None, None] * wave * np.ones((1, 4, 1)))
        labels += [c] * n
    frames.append(np.zeros((20, 4, 4)))
    labels += [-1] * 20
    x = (np.concatenate(frames) + 10 + rng.normal(0, 0.3, (len(labels), 4, 4))).astype(np.float32)
    t = t0 + np.arange(len(x)) / RATE
    return FrameRecording(x, t, np.array(labels) if labelled else None, CLASSES if labelled else None)


def _runs(labels):
    edges = np.flatnonzero(np.diff(np.r_[-1, labels, -1]) != 0)
    return [(a, b, labels[a]) for a, b in itertools.pairwise(edges) if labels[a] >= 0]


def test_per_frame_labels_give_one_exploration_per_touch(tmp_path):
    rec = _log(0)
    path = write_frame_recording(tmp_path / "day1.npz", rec)
    data = read_source([path])
    assert data.kind == "frame recording" and data.class_names == CLASSES
    touches = recorded_touches(data)
    x = touches.explorations
    runs = _runs(rec.labels)
    assert x.pressure.shape == (len(runs), touches.n_frames, 4, 4) and x.labels.tolist() == [
        c for *_, c in runs
    ]
    assert touches.rate_hz == RATE and touches.n_frames == int(
        np.median([s.frames for s in touches.segments])
    )
    assert x.frame_rate_hz == RATE


def test_the_touches_are_those_the_live_stream_cuts_at_the_recorded_levels(tmp_path):
    rec = _log(1)
    touches = recorded_touches(read_source([write_frame_recording(tmp_path / "a.npz", rec)]))
    spec = ItemSpec(FRAME, (4, 4), rate_hz=RATE)
    live = TouchSegmenter(spec, touches.levels, touches.n_frames)
    ends = [s for s in Segments(ArraySource(rec.frames, spec, t=rec.t), live, Sequencer(RATE, item=FRAME))]
    assert [(s.start_item, s.frames) for s in ends] == [(s.start_item, s.frames) for s in touches.segments]
    # the bundle input of each touch at its end is the exploration training gets
    np.testing.assert_array_equal(np.concatenate([s.data for s in ends]), touches.explorations.pressure)


def test_one_label_per_file_from_the_folders(tmp_path):
    paths = []
    for c, name in enumerate(CLASSES):
        for day in (1, 2):
            paths.append(
                write_frame_recording(
                    tmp_path / name / f"day{day}.npz", _log(10 * c + day, 4, labelled=False, only=c)
                )
            )
    data = read_source(paths)
    assert data.class_names == CLASSES and data.file_labels.tolist() == [0, 0, 1, 1, 2, 2]
    touches = recorded_touches(data)
    x = touches.explorations
    assert np.bincount(x.labels).tolist() == [8, 8, 8]
    assert sorted(set(np.asarray(x.groups).tolist())) == [
        0,
        1,
    ]  # the sessions day1, day2 keep their touches apart


def test_the_frame_rate_comes_from_t_by_the_slope_rule(tmp_path):
    rec = _log(2, t0=1_762_430_000.0)
    rec.t = np.round(rec.t, 2) + np.random.default_rng(0).normal(0, 1e-4, len(rec.t))  # jittered epoch stamps
    rec.t = np.maximum.accumulate(rec.t + np.arange(len(rec.t)) * 1e-9)
    touches = recorded_touches(read_source([write_frame_recording(tmp_path / "epoch.npz", rec)]))
    assert touches.rate_hz == RATE


def test_a_gap_cuts_a_touch_and_the_cut_touch_does_not_train(tmp_path):
    rec = _log(3)
    a, b, _ = _runs(rec.labels)[2]
    rec.t[(a + b) // 2 :] += 1.0  # a 1 s gap in the middle of the third touch
    touches = recorded_touches(read_source([write_frame_recording(tmp_path / "gap.npz", rec)]))
    assert len(touches.explorations.labels) == len(_runs(rec.labels)) - 1
    assert any("gap" in note for note in touches.notes)


def test_recordings_at_two_rates_are_one_line(tmp_path):
    fast = _log(4)
    fast.t = fast.t / 2
    paths = [
        write_frame_recording(tmp_path / "a.npz", _log(5)),
        write_frame_recording(tmp_path / "b.npz", fast),
    ]
    with pytest.raises(
        ValueError, match=r"different frame rates \(.*a\.npz: 50 frames/s, .*b\.npz: 100 frames/s\)"
    ):
        recorded_touches(read_source(paths))


def test_frames_at_rest_only_are_one_line(tmp_path):
    still = FrameRecording(np.full((200, 4, 4), 10, np.float32), np.arange(200) / RATE)
    with pytest.raises(ValueError, match=r"still\.npz: no touch stands out of the frames' rest"):
        recorded_touches(read_source([write_frame_recording(tmp_path / "still.npz", still)]))
