"""Per-window results of a stream: classification by a bundle, the vote over the last windows, JSON and
text lines."""

import io
import json
import math

import numpy as np
import pytest

from tactile_torch.robot.runtime import OnnxPipeline
from tactile_torch.robot.stream.live import LiveOptions, LiveStream, item_spec
from tactile_torch.robot.stream.output import WindowVote, classify_windows, result_json, result_text
from tactile_torch.robot.stream.segments import Window
from tactile_torch.robot.stream.serial_source import SerialSource
from tactile_torch.robot.stream.wire import format_sample
from tests.stream_helpers import axis_recording, energy_bundle, expected_axis


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    return OnnxPipeline(energy_bundle(tmp_path_factory.mktemp("energy") / "energy.onnx", window=16))


def _window(data=None, *, index=0, gaps=0, flags=(), read_at=0.0):
    data = np.zeros((1, 3, 16), np.float32) if data is None else data
    return Window(
        data=data, index=index, end_sample=16 * (index + 1), read_at=read_at, gaps=gaps, flags=flags
    )


def test_results_carry_the_bundle_label_and_a_latency(bundle):
    rec, _ = axis_recording("xzy", 32)
    stream = b"".join(format_sample(s) for s in rec)
    source = SerialSource(io.BytesIO(stream), item_spec(bundle))
    results = list(LiveStream(bundle, source, LiveOptions(step=16)))
    assert [r.name for r in results] == [expected_axis(r.window.data[0]) for r in results]
    assert [r.name for r in results] == list("xxzzyy")
    for r in results:
        np.testing.assert_allclose(
            r.scores, (r.window.data[0].astype(np.float64) ** 2).mean(axis=1), rtol=1e-5
        )
        assert r.latency_ms >= 0 and r.vote is None and r.flags == ()


def test_a_window_with_non_finite_scores_gets_no_label(bundle):
    data = np.ones((1, 3, 16), np.float32)
    data[0, 1, 3] = 1e30  # the square overflows float32: inf scores, as in a trained bundle's features
    results = list(classify_windows([_window(data, flags=("skipped",))], bundle, range_g=math.inf))
    (r,) = results
    assert r.label is None and r.name is None and r.scores is None
    assert r.flags == ("skipped", "non_finite_scores")
    record = json.loads(result_json(r))
    assert (
        record["label"] is None
        and record["score"] is None
        and record["flags"] == ["skipped", "non_finite_scores"]
    )
    assert "no label: scores not finite" in result_text(r) and "inf" not in result_text(r)


def test_a_window_beyond_the_range_or_constant_is_unknown_with_its_reason(bundle):
    beyond = np.ones((1, 3, 16), np.float32)
    beyond[0, 1, 3] = 20.0
    flat = np.zeros((1, 3, 16), np.float32)
    ok = np.ones((1, 3, 16), np.float32) * np.linspace(-1, 1, 16, dtype=np.float32)
    windows = [_window(d, index=i) for i, d in enumerate((beyond, flat, ok))]
    vote = WindowVote(3, class_names=bundle.class_names)
    r = list(classify_windows(windows, bundle, vote=vote))
    assert [x.label for x in r[:2]] == [-1, -1] and [x.name for x in r[:2]] == ["unknown", "unknown"]
    assert r[0].reason == "a sample of 20 g, beyond the sensor's range ±5 g" and r[0].flags == ("unknown",)
    assert r[1].reason.startswith("no vibration: every axis is constant")
    assert r[0].vote is None and r[2].vote.windows == 1  # unknown windows do not vote
    record = json.loads(result_json(r[0]))
    assert record["label"] == -1 and record["name"] == "unknown" and record["score"] is None
    assert record["reason"] == r[0].reason and record["flags"] == ["unknown"]
    assert "unknown" in result_text(r[0]) and "beyond the sensor's range" in result_text(r[0])
    assert r[2].label >= 0 and r[2].reason is None and json.loads(result_json(r[2]))["reason"] is None


def test_majority_vote_ties_go_to_the_most_recent_label():
    vote = WindowVote(3, class_names=["a", "b", "c"])
    scores = np.zeros(3)
    got = [vote.update(label, scores) for label in [0, 1, 1, 2, 0]]
    # windows: [0] [0 1] [0 1 1] [1 1 2] [1 2 0]
    assert [(v.name, round(v.support, 3), v.windows) for v in got] == [
        ("a", 1.0, 1),
        ("b", 0.5, 2),
        ("b", 0.667, 3),
        ("b", 0.667, 3),
        ("a", 0.333, 3),
    ]


def test_mean_vote_is_the_argmax_of_the_mean_scores():
    vote = WindowVote(2, "mean", class_names=["a", "b"])
    assert vote.update(0, np.array([1.0, 0.0])).label == 0
    v = vote.update(1, np.array([0.0, 3.0]))
    assert (v.label, v.support, v.windows) == (1, 1.5, 2)
    v = vote.update(0, np.array([0.5, 0.4]))  # window 1 drops out: mean of [0, 3] and [0.5, 0.4]
    assert (v.label, v.support) == (1, pytest.approx(1.7))


def test_the_vote_is_cleared_at_a_gap_and_skips_unlabelled_windows(bundle):
    x = np.zeros((1, 3, 16), np.float32)
    x[0, 0] = np.linspace(0.5, 1.5, 16)  # not constant: a constant window is unknown
    y = np.zeros((1, 3, 16), np.float32)
    y[0, 1] = np.linspace(0.5, 1.5, 16)
    bad = x.copy()
    bad[0, 2, 0] = 1e30
    windows = [_window(x, index=0), _window(x, index=1), _window(bad, index=2), _window(y, index=3, gaps=1)]
    results = list(classify_windows(windows, bundle, vote=WindowVote(5, class_names=bundle.class_names)))
    assert [(r.vote.name, r.vote.windows) if r.vote else None for r in results] == [
        ("x", 1),
        ("x", 2),
        None,  # no label, no vote
        ("y", 1),  # the gap cleared the two x windows
    ]


def test_json_lines_are_strict_json_with_every_field(bundle):
    rec, _ = axis_recording("y", 40)
    t = np.arange(40) / 800.0
    stream = b"".join(format_sample(s, ti) for s, ti in zip(rec, t, strict=True))
    source = SerialSource(io.BytesIO(b"junk\n" + stream), item_spec(bundle))
    lines = [result_json(r) for r in LiveStream(bundle, source, LiveOptions(step=8, vote=2))]
    records = [
        json.loads(line, parse_constant=lambda c: pytest.fail(f"not strict JSON: {c}")) for line in lines
    ]
    assert len(records) == 4 and all("\n" not in line for line in lines)
    first = records[0]
    assert set(first) == {
        "event", "window", "time", "sample", "t_start", "t_end", "rate_hz", "label", "name", "score", "scores",
        "latency_ms", "skipped", "rejected", "gaps", "lost", "flags", "reason", "vote", "sensor",
    }  # fmt: skip
    assert (first["window"], first["sample"], first["name"], first["skipped"]) == (0, 16, "y", 1)
    assert first["event"] == "window"
    assert first["t_start"] == 0.0 and first["t_end"] == pytest.approx(15 / 800.0)
    assert first["score"] == max(first["scores"]) and first["rate_hz"] == pytest.approx(800.0)
    assert first["vote"] == {"label": 1, "name": "y", "support": 1.0, "windows": 1}
    assert records[1]["skipped"] == 0 and records[3]["vote"]["windows"] == 2
    assert math.isfinite(first["time"]) and first["latency_ms"] >= 0


def test_text_lines_name_the_class_and_what_happened_on_the_line(bundle):
    x = np.zeros((1, 3, 16), np.float32)
    x[0, 0] = np.resize([0.5, -0.5], 16)  # mean square 0.25; not constant
    window = Window(data=x, index=7, end_sample=400, read_at=0.0, skipped=2, gaps=1, flags=("skipped",))
    (r,) = classify_windows([window], bundle, vote=WindowVote(3, class_names="xyz"))
    line = result_text(r)
    assert line.split()[:5] == ["7", "400", "x", "score", "+0.250"]
    assert line.endswith("vote x (1.00 of 1)  2 skipped, 1 gap(s)  [skipped]")


@pytest.mark.parametrize(
    ("args", "match"),
    [((0,), "n must be an int >= 1, got 0"), ((3, "median"), "method must be one of")],
)
def test_vote_bad_arguments(args, match):
    with pytest.raises(ValueError, match=match):
        WindowVote(*args)
