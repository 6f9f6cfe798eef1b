"""Frames through the live stream's stages (tactile_torch.robot.stream.source, .serial_source,
.stream_segments, .live): frame lines over files and a pseudo-terminal, garbage and out-of-range
frames, touches cut through pauses, and the same touches live and offline. Torch-free: the bundle is
tests.stream_helpers.frame_bundle."""

import io
import json
import math
import threading

import numpy as np
import pytest
import serial

from tactile_torch.robot.runtime import OnnxPipeline
from tactile_torch.robot.stream.live import LiveOptions, LiveStream, item_spec, touch_setup
from tactile_torch.robot.stream.output import result_json, result_record
from tactile_torch.robot.stream.port_lines import StreamTimeout
from tactile_torch.robot.stream.segments import Segments, SlidingWindows
from tactile_torch.robot.stream.serial_source import SerialSource, parse_values
from tactile_torch.robot.stream.source import REJECTED, ArraySource, Break, ItemSpec, Reading
from tactile_torch.robot.stream.touch_segments import TouchSegmenter
from tactile_torch.robot.stream.touches import TouchLevels
from tactile_torch.robot.stream.wire import format_frame, simulate_frames
from tests.stream_helpers import PtySensor, frame_bundle

LEVELS = TouchLevels(onset=4.0, release=2.0, min_frames=2, source="test")


@pytest.fixture
def bundle(tmp_path):
    """A 4 x 4 pressure bundle of T = 4 frames: class "top" for pressure on the top half, "bottom" below."""
    weights = np.zeros((4, 4, 2), np.float32)
    weights[:2, :, 0] = weights[2:, :, 1] = 1.0
    meta = {
        "frame_rate_hz": 100.0,
        "value_range": [-10.0, 300.0],
        "touch_levels": LEVELS.to_metadata(),
        "early_decision": {"threshold": 20.0, "checkpoints": [1, 2, 3], "target_error": 0.05},
    }
    path = frame_bundle(
        tmp_path / "grasp.onnx", weights, n_frames=4, class_names=["top", "bottom"], metadata=meta
    )
    return OnnxPipeline(path)


def _touches(n_rest=5):
    """Frames with three touches (top 7 frames, bottom 6 frames, top 3 frames) between resting frames."""
    parts, labels = [], []
    rng = np.random.default_rng(0)
    for half, length in (("top", 7), ("bottom", 6), ("top", 3)):
        parts.append(rng.uniform(0, 0.1, (n_rest, 4, 4)))
        labels += [-1] * n_rest
        touch = rng.uniform(0, 0.1, (length, 4, 4))
        rows = slice(0, 2) if half == "top" else slice(2, 4)
        touch[:, rows] += np.linspace(2, 8, length)[:, None, None]  # a pressure that builds up
        parts.append(touch)
        labels += [0 if half == "top" else 1] * length
    parts.append(rng.uniform(0, 0.1, (n_rest, 4, 4)))
    return np.round(np.concatenate(parts).astype(np.float32), 3), np.array(labels + [-1] * n_rest)


def test_parse_values_takes_exactly_the_frame_or_t_and_the_frame():
    assert parse_values(b"1,2,3,4\r\n", 4)[0] is None
    t, values = parse_values(b"0.25,1,2,3,4", 4)
    assert t == 0.25 and values.tolist() == [1, 2, 3, 4]
    for bad in (b"1,2,3", b"1,2,3,4,5,6", b"1,2,x,4", b"1,nan,3,4", b"\xff\xfe,1,2,3", b""):
        assert parse_values(bad, 4) is None


def test_frame_lines_with_garbage_and_out_of_range_values(bundle):
    spec = item_spec(bundle)
    assert (spec.kind, spec.shape, spec.low, spec.high, spec.rate_hz) == (
        "frame",
        (4, 4),
        -10.0,
        300.0,
        100.0,
    )
    frames = np.arange(5 * 16, dtype=np.float32).reshape(5, 4, 4)
    lines = [format_frame(f, i / 100) for i, f in enumerate(frames)]
    lines.insert(2, b"1,2,3\n")  # a line cut short: garbage, not a frame
    lines.insert(4, format_frame(np.full((4, 4), 1e30), 0.015))  # a corrupted value: rejected
    source = SerialSource(io.BytesIO(b"".join(lines)), spec)
    out = list(source.readings())
    readings = [r for r in out if isinstance(r, Reading)]
    assert [r.t for r in readings] == pytest.approx([0, 0.01, 0.02, 0.03, 0.04])
    assert np.array_equal(np.stack([r.values for r in readings]), frames)
    assert [b.kind for b in out if isinstance(b, Break)] == [REJECTED]
    counts = source.counts
    assert (counts.items, counts.skipped, counts.rejected) == (5, 1, 1)


def test_touches_live_over_a_pty_equal_the_touches_offline(bundle):
    frames, _ = _touches()
    t = np.arange(len(frames)) / 100.0
    offline = [result_record(r) for r in LiveStream(bundle, ArraySource(frames, item_spec(bundle), t=t))]
    expected = [r for r in offline if r["event"] == "touch"]
    sensor = PtySensor()
    try:
        port = serial.serial_for_url(sensor.path, timeout=0.05)
        source = SerialSource(port, item_spec(bundle), idle_timeout_s=2.0, silence_s=0.5)
        live = LiveStream(bundle, source, LiveOptions(max_results=3))
        writer = threading.Thread(
            target=simulate_frames, args=(sensor, frames), kwargs={"t": t, "timestamps": True}, daemon=True
        )
        writer.start()
        got = [result_record(r) for r in live]
        writer.join()
    finally:
        sensor.close()
    touches = [r for r in got if r["event"] == "touch"]
    assert [(r["start"], r["frames"], r["name"]) for r in touches] == [
        (5, 7, "top"),
        (17, 6, "bottom"),
        (28, 3, "top"),
    ]
    keys = ("start", "frames", "frames_used", "label", "ended_by", "flags")
    assert [[r[k] for k in keys] for r in touches] == [[r[k] for k in keys] for r in expected]
    assert np.allclose([r["scores"] for r in touches], [r["scores"] for r in expected], atol=1e-5)
    # the rule decided every touch early, at the first checkpoint whose margin reached 20: 2 frames in
    # (the mean of pressures 2 and 3 on 8 taxels gives 20), the same live and offline
    early = [(r["touch"], r["frames"], r["name"]) for r in got if r["event"] == "early"]
    assert early == [(0, 2, "top"), (1, 2, "bottom"), (2, 2, "top")]
    assert early == [(r["touch"], r["frames"], r["name"]) for r in offline if r["event"] == "early"]
    assert all(r["decision"]["early"] and r["decision"]["frames"] == 2 for r in touches)
    assert touches[0]["decision"]["after_s"] == pytest.approx(0.01) and "stretched" in touches[2]["flags"]
    assert live.summary().startswith(
        "32 frames read, 3 touches (3 decided early, 0 partial withheld, 0 contacts too short)"
    )


class _Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


class _ScriptedPort:
    """Reads return the script: bytes, or a float = that many seconds of silence (then silence forever)."""

    def __init__(self, script, clock):
        self.script, self.clock = list(script), clock

    def read(self, size):
        item = self.script.pop(0) if self.script else 1.0
        if isinstance(item, float):
            self.clock.now += item
            return b""
        return item


def test_a_pause_splits_a_touch_and_says_so(bundle):
    spec = item_spec(bundle)
    press = np.zeros((10, 4, 4), np.float32)
    press[:, :2] = 5.0
    press[9] = 0.0  # released at the end
    clock = _Clock()
    script = [format_frame(f) for f in press[:6]] + [0.7] + [format_frame(f) for f in press[6:]]
    events = []
    source = SerialSource(
        _ScriptedPort(script, clock),
        spec,
        idle_timeout_s=3.0,
        silence_s=0.5,
        clock=clock,
        on_event=events.append,
    )
    results = []
    with pytest.raises(StreamTimeout):
        for r in LiveStream(bundle, source, LiveOptions(early=False)):
            results.append(result_record(r))
    # one contact, split by the sensor's pause: two touches, the first cut by the silence, the second
    # flagged as the rest of a contact; never one touch of 9 frames
    assert [(r["start"], r["frames"], r["ended_by"], r["flags"]) for r in results] == [
        (0, 6, "silence", ["cut"]),
        (6, 3, "release", ["after_cut", "stretched"]),
    ]
    assert [e.kind for e in events] == ["silence", "resumed", "silence"]


def test_the_touch_in_progress_is_reported_when_the_input_ends(bundle):
    press = np.zeros((6, 4, 4), np.float32)
    press[2:] = 5.0
    live = LiveStream(bundle, ArraySource(press, item_spec(bundle)), LiveOptions(early=False))
    assert list(live) == []
    assert [(r.segment.frames, r.segment.ended_by, r.flags) for r in live.finish()] == [
        (4, "end of input", ("cut",))
    ]


def test_a_gap_in_t_ends_a_touch_offline_and_live_alike(bundle):
    press = np.zeros((12, 4, 4), np.float32)
    press[2:10, 2:] = 6.0
    t = np.arange(12) / 100.0
    t[6:] += 0.2  # 20 frames lost in the middle of the touch
    live = LiveStream(bundle, ArraySource(press, item_spec(bundle), t=t), LiveOptions(early=False))
    touches = [result_record(r) for r in live]
    assert [(r["start"], r["frames"], r["ended_by"], r["flags"]) for r in touches] == [
        (2, 4, "gap", ["cut"]),
        (6, 4, "release", ["after_cut"]),
    ]
    assert live.sequencer.gaps == 1 and live.sequencer.lost == 20


def test_sliding_windows_of_frames_for_continuous_exploration(bundle):
    frames = np.random.default_rng(1).uniform(0, 5, (11, 4, 4)).astype(np.float32)
    source = ArraySource(frames, item_spec(bundle), t=np.arange(11) / 100.0)
    windows = list(Segments(source, SlidingWindows(source.spec, 4, 2)))
    assert [w.end_sample for w in windows] == [4, 6, 8, 10]
    assert all(np.array_equal(w.data[0], frames[w.end_sample - 4 : w.end_sample]) for w in windows)
    live = LiveStream(bundle, ArraySource(frames, source.spec), LiveOptions(segment="windows", step=4))
    records = [json.loads(result_json(r)) for r in live]
    assert [r["sample"] for r in records] == [4, 8] and {r["event"] for r in records} == {"window"}


def test_a_bundle_without_levels_needs_an_onset(tmp_path, bundle):
    levels, rule = touch_setup(bundle, LiveOptions(onset=8.0))
    assert (levels.onset, levels.release) == (8.0, 4.0) and rule.threshold == 20.0
    bare = OnnxPipeline(frame_bundle(tmp_path / "bare.onnx", np.ones((4, 4, 2), np.float32)))
    with pytest.raises(ValueError, match="records no touch levels"):
        touch_setup(bare)
    assert touch_setup(bare, LiveOptions(onset=3.0))[0].onset == 3.0
    with pytest.raises(ValueError, match="touches are cut from frames"):
        TouchSegmenter(ItemSpec("sample", (3,)), LEVELS, 4)
    with pytest.raises(ValueError, match="segment must be one of"):
        LiveOptions(segment="grasps")
    assert math.isinf(item_spec(bare).high)


def test_memory_of_a_touch_stream_does_not_grow(bundle):
    """Bounded memory: the first and last T frames of a touch whatever its length, nothing per touch kept."""
    import tracemalloc

    rng = np.random.default_rng(5)
    press = np.where(np.arange(2000)[:, None, None] % 40 < 30, 5.0, 0.0) * np.ones((1, 4, 4))
    frames = (press + rng.uniform(0, 0.1, press.shape)).astype(np.float32)
    press[:, :2] = 5.0
    long_touch = np.concatenate([np.zeros((2, 4, 4)), press, np.zeros((2, 4, 4))]).astype(np.float32)

    def peak(values):
        tracemalloc.start()
        live = LiveStream(bundle, ArraySource(values, item_spec(bundle)), LiveOptions(early=False))
        n = sum(1 for _ in live)
        size = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return n, size

    n_short, short = peak(frames[:200])
    n_long, long = peak(frames)
    assert (n_short, n_long) == (5, 50)  # 10x the touches ...
    assert long < short + 64 * 1024  # ... not 10x the memory
    one, single = peak(long_touch)  # one touch of 2000 frames
    assert one == 1 and single < short + 64 * 1024
