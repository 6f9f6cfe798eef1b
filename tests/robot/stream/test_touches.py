"""Touches cut from frames (tactile_torch.robot.stream.touches) and the early-decision rule
(tactile_torch.robot.stream.early_decision): the state machine, the frames a bundle gets, the default levels
from training data, the calibration to a stated error rate. numpy only (the robot install)."""

import math

import numpy as np
import pytest

from tactile_torch.robot.stream.early_decision import (
    EarlyRule,
    calibrate_early_rule,
    checkpoints_for,
    first_decisions,
    score_margins,
)
from tactile_torch.robot.stream.touches import (
    END,
    NONE,
    SHORT,
    START,
    TouchLevels,
    TouchTracker,
    contact_sign,
    fit_frames,
    resting_level,
    touch_levels,
)


def test_the_tracker_cuts_touches_with_hysteresis_and_a_shortest_touch():
    tracker = TouchTracker(TouchLevels(onset=10.0, release=5.0, min_frames=3))
    # noise around the onset does not chop the contact; a 2-frame blip is not a touch
    codes = [tracker.update(a) for a in (0, 11, 9, 6, 12, 7, 4, 0, 10, 10, 1, 0)]
    assert codes == [NONE, START, NONE, NONE, NONE, NONE, END, NONE, START, NONE, SHORT, NONE]
    tracker.update(20)
    assert tracker.touching and tracker.frames == 1
    assert tracker.cut() == SHORT and not tracker.touching and tracker.cut() == NONE


def test_fit_frames_keeps_the_last_frames_or_stretches_a_short_touch():
    frames = np.arange(10)[:, None, None] * np.ones((1, 2, 2))
    assert fit_frames(frames, 4)[:, 0, 0].tolist() == [6, 7, 8, 9]  # the last T: the object held
    assert fit_frames(frames[:3], 8)[:, 0, 0].tolist() == [0, 0, 0, 1, 1, 1, 2, 2]  # each frame ~T/k times
    assert fit_frames(frames[:1], 3)[:, 0, 0].tolist() == [0, 0, 0]
    # a stretched touch keeps the OR of its frames and the total variation of every taxel's series
    rng = np.random.default_rng(0)
    short = rng.random((5, 3, 3))
    stretched = fit_frames(short, 12)
    assert np.array_equal((stretched > 0.5).any(axis=0), (short > 0.5).any(axis=0))
    assert np.allclose(np.abs(np.diff(stretched, axis=0)).sum(0), np.abs(np.diff(short, axis=0)).sum(0))
    with pytest.raises(ValueError, match="at least one frame"):
        fit_frames(frames[:0], 3)


def test_levels_pressure_and_activity_follow_the_contact_direction():
    rest = np.full((2, 2), -200.0)  # iCub: contact lowers a reading of ~200; rest in sign * reading units
    levels = TouchLevels(onset=30.0, release=10.0, sign=-1.0, rest=rest, floor=1.0)
    frame = np.array([[200.0, 180.0], [150.0, 201.0]], dtype=np.float32)
    assert levels.pressure(frame).tolist() == [[0.0, 19.0], [49.0, 0.0]]
    assert levels.activity(frame) == 68.0
    peak = TouchLevels(onset=30.0, release=10.0, sign=-1.0, rest=rest, floor=1.0, signal="peak")
    assert peak.activity(frame) == 49.0
    rgb = TouchLevels(onset=0.1, release=0.05, rgb=True)
    white, dark = np.full((2, 2, 3), 255.0), np.zeros((2, 2, 3))
    assert rgb.activity(white) == pytest.approx(0.0, abs=1e-3) and rgb.activity(dark) == pytest.approx(
        4.0, rel=1e-3
    )


def test_levels_travel_in_the_metadata_and_refuse_nonsense():
    levels = TouchLevels(onset=3.0, release=1.0, min_frames=4, sign=-1.0, rest=np.arange(6.0).reshape(2, 3))
    back = TouchLevels.from_metadata(levels.to_metadata(), (2, 3))
    assert (back.onset, back.release, back.min_frames, back.sign) == (3.0, 1.0, 4, -1.0)
    assert np.array_equal(back.rest, levels.rest)
    with pytest.raises(ValueError, match="rest must have shape"):
        TouchLevels.from_metadata(levels.to_metadata(), (3, 3))
    with pytest.raises(ValueError, match="release must be at most onset"):
        TouchLevels(onset=1.0, release=2.0)
    with pytest.raises(ValueError, match="touch_levels metadata"):
        TouchLevels.from_metadata('{"onset": "x"}')
    given = levels.with_overrides(onset=8.0)
    assert (given.onset, given.release, given.min_frames) == (8.0, 4.0, 4) and "given" in given.source


def test_default_levels_come_from_the_training_contacts():
    rng = np.random.default_rng(1)
    x = 100.0 + rng.normal(0, 1.0, (6, 10, 4, 4))  # resting readings with noise
    x[:, 2:, 1:3, 1:3] += 50.0  # most training frames hold a contact of 4 taxels; each taxel rests in some
    levels = touch_levels(x, frame_rate_hz=50.0)
    assert levels.sign == 1.0 and levels.min_frames == 5  # 0.1 s at 50 frames/s
    assert levels.rest.shape == (4, 4)
    contact, idle = x[0, 5], 100.0 + rng.normal(0, 1.0, (4, 4))
    assert levels.activity(contact) >= levels.onset > levels.release >= levels.activity(idle)
    lowered = touch_levels(-x, contact="lowers")
    assert lowered.sign == -1.0 and lowered.activity(-contact) >= lowered.onset
    assert contact_sign(np.where(rng.random((200, 2, 2)) < 0.1, 50.0, 0.0), "auto")[0] == 1.0
    assert np.allclose(resting_level(x), np.percentile(x.reshape(-1, 4, 4), 5, axis=0))
    with pytest.raises(ValueError, match="no pressure above their resting level"):
        touch_levels(np.zeros((2, 3, 2, 2)))
    held = 100.0 + rng.normal(0, 1.0, (6, 10, 4, 4))
    held[:, :, 1:3, 1:3] += 50.0  # pressed in every frame: the data cannot tell its rest
    with pytest.raises(ValueError, match="no pressure above their resting level"):
        touch_levels(held)


def test_score_margins():
    scores = np.array([[2.0, 0.5, 1.0], [0.0, 3.0, 3.0], [np.nan, 0, 0]])
    assert score_margins(scores, np.array([0, 1, 0])).tolist() == [1.0, 0.0, -math.inf]
    assert score_margins(scores[:1], np.array([-1])).tolist() == [-math.inf]
    assert checkpoints_for(100) == (12, 25, 38, 50, 62, 75, 88) and checkpoints_for(1) == ()


def test_calibration_keeps_early_errors_at_the_stated_rate():
    rng = np.random.default_rng(3)
    n, k = 400, 4
    # margins grow with time into the touch; wrong labels have small margins
    correct = rng.random((n, k)) < np.array([0.6, 0.75, 0.85, 0.9])
    margins = np.where(
        correct, rng.gamma(2.0, 1.0, (n, k)) * np.arange(1, k + 1), rng.gamma(1.0, 0.4, (n, k))
    )
    rule = calibrate_early_rule(margins, correct, (2, 4, 6, 8), target_error=0.05, how="synthetic")
    assert rule.active and rule.touches == n and rule.decided > n // 2
    first = first_decisions(margins, rule.threshold)
    decided = first >= 0
    errors = (~correct[np.flatnonzero(decided), first[decided]]).sum()
    assert (errors + 1) / (decided.sum() + 1) <= 0.05 and rule.error == pytest.approx(errors / decided.sum())
    # a lower threshold would break the bound: the rule decides as early as the bound allows
    lower = margins[np.isfinite(margins) & (margins > 0) & (margins < rule.threshold)]
    if len(lower):
        first = first_decisions(margins, lower.max())
        d = first >= 0
        assert ((~correct[np.flatnonzero(d), first[d]]).sum() + 1) / (d.sum() + 1) > 0.05
    back = EarlyRule.from_metadata(rule.to_metadata())
    assert back == rule and "calibrated to 5% errors" in back.describe()


def test_calibration_on_a_hopeless_model_never_decides_early():
    rng = np.random.default_rng(4)
    margins = rng.random((30, 3))
    rule = calibrate_early_rule(margins, rng.random((30, 3)) < 0.5, (1, 2, 3))
    assert not rule.active and math.isinf(rule.threshold) and "no early decisions" in rule.describe()
    assert EarlyRule.from_metadata(rule.to_metadata()).threshold == math.inf
    with pytest.raises(ValueError, match="early_decision metadata"):
        EarlyRule.from_metadata("not json")
    with pytest.raises(ValueError, match="shape"):
        calibrate_early_rule(margins, margins > 0, (1, 2))
