"""tactile_torch.robot.files.sample_times: the rate and the gaps of real loggers' time stamps (issue 34)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_torch.robot.files.sample_times import (
    GAP_TOLERANCE,
    describe_timing,
    rate_hz,
    stamp_resolution,
    time_base,
)
from tactile_torch.robot.files.sample_times import GAP_TOLERANCE as STREAM_GAP_TOLERANCE


def test_the_stream_and_the_files_share_one_gap_rule():
    assert STREAM_GAP_TOLERANCE is GAP_TOLERANCE


@pytest.mark.parametrize(
    ("decimals", "resolution"),
    [(1, 0.1), (0, 1.0)],  # epoch ms rounded to 0.1 ms (steps 1.2 / 1.3), and to 1 ms (steps 1 / 2)
)
def test_rounded_epoch_milliseconds_give_800_hz_no_gap_no_warning(decimals, resolution):
    t = np.round(1_700_000_000_000.0 + np.arange(32_000) * 1.25 + 0.03, decimals)
    steps = np.unique(np.round(np.diff(t), 6))
    assert 1 / np.median(np.diff(t)) * 1e3 != pytest.approx(800, rel=0.01)  # the median's answer is wrong
    base = time_base(t, resolution=resolution)
    assert rate_hz(base.period * 1e-3, base.period_error) == 800.0, steps
    assert base.gaps.size == 0 and base.irregular == 0.0
    assert describe_timing([("log.csv", base, 1e-3)]) == []


def test_a_gap_is_found_and_does_not_bias_the_rate():
    t = np.round(np.arange(4_000) * 1.25, 1)
    t[2_500:] += 1_000.0  # the logger paused for 1 s
    base = time_base(t, resolution=0.1)
    assert base.gaps.tolist() == [2_500] and base.longest_gap == pytest.approx(1_001.2)
    assert rate_hz(base.period * 1e-3, base.period_error) == 800.0
    (line,) = describe_timing([("a.csv", base, 1e-3), ("b.csv", time_base(t[:2_000], resolution=0.1), 1e-3)])
    assert line == (
        "1 gap(s) in the time stamps of 1 of 2 file(s) (steps longer than 1.5 sample periods; the longest, "
        "a 1 s gap 3.12 s into a.csv): no window spans a gap"
    )


def test_epoch_stamps_give_a_gap_people_can_read():
    t = np.round(1_762_430_000_000.0 + np.arange(16_000) * 1.25, 1)  # epoch milliseconds, 800 Hz
    t[9_840:] += 400.0  # 0.4 s lost 12.3 s into the log
    base = time_base(t, resolution=0.1)
    (line,) = describe_timing([("day2/felt.csv", base, 1e-3)])
    assert "the longest, a 0.401 s gap 12.3 s into day2/felt.csv" in line
    assert "e+09" not in line and "e+12" not in line


def test_one_lost_sample_is_a_gap_and_jitter_is_irregular_not_a_gap():
    t = np.arange(1_000) * 1.25
    lost = np.delete(t, 500)  # one sample missing: a step of 2 periods
    assert time_base(lost, resolution=0.001).gaps.tolist() == [500]
    jitter = t + np.random.default_rng(0).uniform(-0.1, 0.1, t.size)  # +-8 % of a period, no gap
    base = time_base(jitter)
    assert base.gaps.size == 0 and 0.05 < base.irregular < 0.17
    (line,) = describe_timing([("j.csv", base, 1e-3)])
    assert line.startswith("time steps vary by up to ") and "in 1 of 1 file(s) (the most in j.csv)" in line


def test_a_stated_period_judges_gaps_against_itself():
    t = np.arange(100) * 2.0  # steps of 2 ms read against a stated 800 Hz: every step a gap
    assert time_base(t, period=1.25).gaps.size == 99
    assert time_base(t, period=2.0).gaps.size == 0


def test_stamp_resolution_is_the_last_digit_written():
    assert stamp_resolution(np.array(["1700000000001.3", "1700000000002.5"])) == pytest.approx(0.1)
    assert stamp_resolution(np.array(["0", "0.00125", "5e-3"])) == pytest.approx(1e-5)
    assert stamp_resolution(np.array(["12", "14"])) == 1.0


@settings(max_examples=25, deadline=None)
@given(
    rate=st.floats(20, 50_000),
    n=st.integers(50, 3_000),
    decimals=st.integers(1, 4),
    offset=st.floats(0, 1e6),
)
def test_rounded_stamps_give_the_rate_within_the_rounding(rate, n, decimals, offset):
    period = 1e3 / rate  # ms
    resolution = 10.0**-decimals
    t = np.round(offset + np.arange(n) * period, decimals)
    if (np.diff(t) <= 0).any():  # rounding coarser than the period: not a log a reader accepts
        return
    base = time_base(t, resolution=resolution)
    assert base.gaps.size == 0
    # the least-squares slope is off by at most the rounding over the span (end points off by half a digit)
    assert abs(base.period - period) <= 2 * resolution / (n - 1) + 1e-9 * period
