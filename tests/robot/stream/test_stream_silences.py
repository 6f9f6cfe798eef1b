"""Silences judged by the sensor's clock, cut touches marked partial, and a serial line of several arrays.

Issue 41, points 4 and 6 on a serial line (pseudo-terminal): a sensor whose lines arrive late (its
writer starved of CPU) but whose ``t`` runs on without a step cuts no touch; one that really pauses
(``t`` steps over the pause) does, and the cut touch's decision is withheld unless the bundle's early
rule is sure of it (``on_partial="decide"`` gives it anyway); a line carrying the frames of several
arrays (``all_sensors``) gives each array touches of its own. Torch-free.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import serial

from tactile_torch.robot.runtime import OnnxPipeline
from tactile_torch.robot.stream.early_decision import EarlyRule
from tactile_torch.robot.stream.live import LiveOptions, LiveStream, item_spec
from tactile_torch.robot.stream.output import result_record
from tactile_torch.robot.stream.serial_source import SerialSource
from tactile_torch.robot.stream.source import ArraySource
from tactile_torch.robot.stream.touch_output import touch_text
from tactile_torch.robot.stream.touches import TouchLevels
from tactile_torch.robot.stream.wire import format_frame
from tests.stream_helpers import PtySensor, frame_bundle

RATE = 50.0


def _bundle(tmp_path, *, rule=None):
    weights = np.zeros((4, 4, 2), np.float32)
    weights[:2, :, 0] = weights[2:, :, 1] = 1.0
    meta = {
        "frame_rate_hz": RATE,
        "touch_levels": TouchLevels(onset=20.0, release=10.0, min_frames=2).to_metadata(),
    }
    if rule is not None:
        meta["early_decision"] = rule.to_metadata()
    return OnnxPipeline(
        frame_bundle(tmp_path / "b.onnx", weights, n_frames=8, class_names=["top", "bottom"], metadata=meta)
    )


def _frames(n=40, touch=(5, 35)):
    frames = np.zeros((n, 4, 4), np.float32)
    frames[touch[0] : touch[1], :2] = 5.0
    return frames


def _live(pipe, parts, *, options=None, all_sensors=False):
    """Play ``parts`` (``(lines, seconds to wait after)``) into a pty; return every result's record."""
    sensor = PtySensor()
    try:
        port = serial.serial_for_url(sensor.path, timeout=0.05)
        source = SerialSource(
            port, item_spec(pipe), idle_timeout_s=1.0, silence_s=0.3, all_sensors=all_sensors
        )
        live = LiveStream(pipe, source, options or LiveOptions())

        def play():
            for lines, wait in parts:
                sensor.write(b"".join(lines))
                time.sleep(wait)

        writer = threading.Thread(target=play)
        writer.start()
        results = []
        try:
            results.extend(live)
        except TimeoutError:
            results += live.finish("timeout")
        records = [result_record(r) for r in results]
        live.raw = results
        writer.join()
    finally:
        sensor.close()
    return records, live


def _lines(frames, t):
    return [format_frame(f, float(ti)) for f, ti in zip(frames, t, strict=True)]


def test_lines_that_arrive_late_with_t_on_schedule_cut_no_touch(tmp_path):
    pipe = _bundle(tmp_path)
    frames, t = _frames(), np.arange(40) / RATE
    records, live = _live(pipe, [(_lines(frames[:15], t[:15]), 0.6), (_lines(frames[15:], t[15:]), 0.0)])
    touches = [r for r in records if r["event"] == "touch"]
    assert [(r["frames"], r["ended_by"], r["partial"]) for r in touches] == [(30, "release", False)]
    assert live.sequencer.gaps == 0


@pytest.mark.parametrize("on_partial", ["withhold", "decide"])
def test_a_real_pause_cuts_the_touch_and_its_part_is_withheld_unless_asked(tmp_path, on_partial):
    pipe = _bundle(tmp_path)
    frames, t = _frames(), np.arange(40) / RATE
    t[15:] += 0.6  # the sensor's clock runs on through its pause
    records, live = _live(
        pipe,
        [(_lines(frames[:15], t[:15]), 0.6), (_lines(frames[15:], t[15:]), 0.0)],
        options=LiveOptions(on_partial=on_partial),
    )
    first, second = [r for r in records if r["event"] == "touch"]
    assert (first["frames"], first["ended_by"], second["frames"]) == (10, "silence", 20)
    assert first["partial"] and second["partial"] and "after_cut" in second["flags"]
    if on_partial == "withhold":  # the bundle has no calibrated rule: neither part is decided
        assert first["decision"] is None and second["decision"] is None
        assert "withheld (partial: a touch cut by silence" in touch_text(live.raw[0])
        assert first["withheld"].startswith("partial: a touch cut by silence after 10 frames")
        assert second["withheld"].startswith("partial: the rest of a contact cut before it")
    else:
        assert first["decision"]["name"] == "top" and first["withheld"] is None


def test_a_cut_touch_the_early_rule_is_sure_of_is_decided(tmp_path):
    pipe = _bundle(tmp_path, rule=EarlyRule(threshold=1.0, checkpoints=(2, 4)))
    frames, t = _frames(), np.arange(40) / RATE
    t[15:] += 0.6
    records, _ = _live(pipe, [(_lines(frames[:15], t[:15]), 0.6), (_lines(frames[15:], t[15:]), 0.0)])
    first = next(r for r in records if r["event"] == "touch")
    # decided early, before the cut: what the robot was told stands
    assert first["decision"]["early"] and first["partial"]


def test_a_line_of_several_arrays_gives_each_its_own_touches(tmp_path):
    pipe = _bundle(tmp_path)
    n = 60
    frames = np.zeros((n, 2, 4, 4), np.float32)
    frames[5:25, 0, :2] = 5.0  # array 0 touched at the top
    frames[15:50, 1, 2:] = 5.0  # array 1 at the bottom, overlapping in time
    t = np.arange(n) / RATE
    lines = [format_frame(f.reshape(2, -1).reshape(-1), float(ti)) for f, ti in zip(frames, t, strict=True)]
    records, live = _live(pipe, [(lines, 0.0)], all_sensors=True)
    assert live.sensors == ("0", "1")
    got = {s: [(r["start"], r["frames"], r["name"]) for r in records if r["sensor"] == s] for s in ("0", "1")}
    for k, name in enumerate(("0", "1")):
        alone = LiveStream(pipe, ArraySource(frames[:, k], item_spec(pipe), t=t))
        expected = [(r.segment.start_item, r.segment.frames, r.name) for r in [*alone, *alone.finish()]]
        assert got[name] == expected, name
    assert got == {"0": [(5, 20, "top")], "1": [(15, 35, "bottom")]}
