"""Frames through the live stream: how many frames per second one stream sustains, and touch-end latency.

For a 16 x 16 and a 4 x 4 taxel array (synthetic pressure maps of the frame generator, 40 frames per
touch at 200 frames/s, rest between touches), with the classical model the trade-off study recommends on them
(``run_tradeoff(quick=True)`` over the classical candidates, refitted on all the data and deployed with
its touch levels and calibrated early rule) and with the temporal taxel CNN (``TaxelCNNClassifier``,
5 epochs, exported with the same touch levels; no early rule: it has no held-out folds here):

- ``frames/s``: frames written into a pseudo-terminal as fast as the reader takes them, read by one
  stream in this process (``SerialSource`` -> ``LiveStream``: parsing, continuity, touches, the
  bundle at every touch's end and early-decision checkpoint, a JSON line per result written to
  ``/dev/null``), onnxruntime on one thread; against the loop a user would write with pyserial
  (``readline()``, ``np.array(line.split(','))``, windows of the bundle's frames, ``predict`` each), in
  the same run, as a ratio;
- ``touch-end latency``: at real-time pacing (200 frames/s), from reading the frame that ended a touch
  (the first below the release level) to its JSON line printed, median and 99th percentile.

The DDS path (the same bundles and frames over a ROS 2 topic through Cyclone DDS, and the DDS echo that
is the transport's floor) adds its rows from :mod:`bench.ros2_rows` when the extra ``ros2`` is installed.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
import threading
import time

import numpy as np

TITLE = "Frames live: frames per second one stream sustains, and touch-end latency (16x16 and 4x4 arrays)"

T = 40  # frames per touch (the explorations' length): 0.2 s at the paced rate
PACED_HZ = 200.0


def _explorations(side: int, quick: bool):
    from tactile_torch.data.images import make_explorations

    data = make_explorations(
        3 if quick else 8,
        n_frames=T,
        frame_size=max(16, side),
        sensels=side,
        keep_pressure=True,
        random_state=4,
    )
    return data.pressure.numpy(), data.labels.numpy(), data.groups.numpy(), list(data.class_names)


def _classical(x, y, groups, names, tmp: str) -> tuple[str, str]:
    """Deploy the trade-off study's recommended classical candidate; return ``(bundle, name)``."""
    from tactile_torch.tradeoff import run_tradeoff
    from tactile_torch.tradeoff.inputs import TradeoffData

    data = TradeoffData(
        "pressure", tuple(names), "synthetic", raw=x, labels=y, groups=groups, rate_hz=PACED_HZ
    )
    out = os.path.join(tmp, f"tradeoff-{x.shape[-1]}")
    result = run_tradeoff(
        data,
        out_dir=out,
        quick=True,
        progress=False,
        log=lambda *_: None,
        classifiers=["lda", "hmsvm", "ncm"],
    )
    name = result.recommended
    if name is None:  # no candidate beat the baseline on this small set: deploy the most accurate one
        name = max((r for r in result.rows if r["accuracy"] is not None), key=lambda r: r["accuracy"])["name"]
        result = run_tradeoff(
            data, out_dir=out, quick=True, progress=False, log=lambda *_: None, classifiers=["lda", "hmsvm", "ncm"],
            deploy=name,
        )  # fmt: skip
        return result.deployed[0]["onnx"], f"{name} (most accurate; none recommended)"
    return os.path.join(out, "recommended.onnx"), name


def _cnn(x, y, names, tmp: str) -> str:
    from tactile_torch.export import export_classifier
    from tactile_torch.neural.estimators import TaxelCNNClassifier
    from tactile_torch.robot.stream.touches import frame_metadata

    clf = TaxelCNNClassifier(max_epochs=5, progress=False, random_state=0).fit(x, y)
    meta, _ = frame_metadata(x, frame_rate_hz=PACED_HZ)
    path = os.path.join(tmp, f"cnn-{x.shape[-1]}.onnx")
    export_classifier(clf, path, x[:2].astype(np.float32), class_names=names, metadata=meta)
    return path


def _recording(x: np.ndarray, n_touches: int) -> np.ndarray:
    """``n_touches`` explorations in turn, each followed by T / 2 resting frames (zeros)."""
    rest = np.zeros((T // 2, *x.shape[2:]), np.float32)
    parts = []
    for i in range(n_touches):
        parts += [x[i % len(x)].astype(np.float32), rest]
    return np.concatenate(parts)


def _stream(bundle: str, frames: np.ndarray, *, paced: bool) -> dict:
    """Run one stream on a pty fed ``frames``; return frames/s and the touch-end latencies."""
    import serial

    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.robot.stream.live import LiveOptions, LiveStream, item_spec
    from tactile_torch.robot.stream.output import result_json
    from tactile_torch.robot.stream.port_lines import StreamTimeout
    from tactile_torch.robot.stream.serial_source import SerialSource
    from tactile_torch.robot.stream.wire import simulate_frames
    from tests.stream_helpers import PtySensor

    pipe = OnnxPipeline(bundle)
    sensor = PtySensor()
    latencies, counts = [], {"touch": 0, "early": 0}
    with open(os.devnull, "w") as sink:
        try:
            port = serial.serial_for_url(sensor.path, timeout=0.05)
            source = SerialSource(port, item_spec(pipe), idle_timeout_s=2.0, silence_s=1.0)
            live = LiveStream(pipe, source, LiveOptions())
            live.warm_up()
            writer = threading.Thread(
                target=simulate_frames,
                args=(sensor, frames),
                kwargs={"rate_hz": PACED_HZ, "realtime": paced, "timestamps": True},
            )
            first = last = None
            writer.start()
            with contextlib.suppress(
                StreamTimeout
            ):  # the stream ends on its idle timeout after the last frame
                for result in live:
                    print(result_json(result), file=sink, flush=True)
                    now = time.monotonic()
                    first = first or result.segment.started_at
                    counts[result.kind] += 1
                    if result.kind == "touch":
                        latencies.append((now - result.segment.ended_at) * 1e3)
                        last = now
            writer.join()
        finally:
            sensor.close()
    read = source.counts.items
    seconds = last - first if first is not None else float("nan")
    return {
        "frames": read,
        "lost": len(frames) - read,
        "frames_per_s": read / seconds,
        "touches": counts["touch"],
        "early": counts["early"],
        "latency_median_ms": float(np.median(latencies)) if latencies else float("nan"),
        "latency_p99_ms": float(np.percentile(latencies, 99)) if latencies else float("nan"),
    }


def _cpu(bundle: str, frames: np.ndarray) -> dict:
    """CPU time (not wall time: robust to a shared machine) of the whole stream on the frames' lines, and
    of one touch decision: frames per CPU-second through ``SerialSource`` -> ``LiveStream`` from an
    in-memory port, and the median CPU milliseconds of ``classify`` on one touch's input."""
    import io

    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.robot.stream.live import LiveOptions, LiveStream, item_spec
    from tactile_torch.robot.stream.output import result_json
    from tactile_torch.robot.stream.serial_source import SerialSource
    from tactile_torch.robot.stream.wire import format_frame

    pipe = OnnxPipeline(bundle)
    lines = b"".join(format_frame(f, i / PACED_HZ) for i, f in enumerate(frames))
    live = LiveStream(pipe, SerialSource(io.BytesIO(lines), item_spec(pipe)), LiveOptions())
    live.warm_up()
    start = time.process_time()
    for result in live:
        result_json(result)
    cpu = time.process_time() - start
    touch = np.ascontiguousarray(frames[:T][None], dtype=np.float32)
    times = []
    for _ in range(30):
        t0 = time.process_time()
        pipe.classify(touch)
        times.append(time.process_time() - t0)
    return {"frames_per_cpu_s": len(frames) / cpu, "decision_cpu_ms": 1e3 * float(np.median(times))}


def _readline_loop(bundle: str, frames: np.ndarray) -> float:
    """Frames/s of the loop a user would write: pyserial readline, split, windows of T frames, predict."""
    import serial

    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.robot.stream.wire import simulate_frames
    from tests.stream_helpers import PtySensor

    pipe = OnnxPipeline(bundle)
    shape = frames.shape[1:]
    sensor = PtySensor()
    try:
        port = serial.serial_for_url(sensor.path, timeout=1.0)
        writer = threading.Thread(target=simulate_frames, args=(sensor, frames), kwargs={"realtime": False})
        writer.start()
        window, n, start = [], 0, None
        while n < len(frames):
            line = port.readline()
            if not line:
                break
            start = start or time.perf_counter()
            window.append(np.array(line.split(b","), dtype=np.float32).reshape(shape))
            n += 1
            if len(window) == T:
                pipe.predict(np.stack(window)[None])
                window = []
        seconds = time.perf_counter() - start
        writer.join()
    finally:
        sensor.close()
    return n / seconds


def _dds_available() -> bool:
    """Whether the ROS 2 extra is installed (the DDS rows need cyclonedds and rosbags)."""
    import importlib.util

    return all(importlib.util.find_spec(m) is not None for m in ("cyclonedds", "rosbags"))


def run(quick: bool) -> dict:
    rows, notes = [], []
    n_touches = 12 if quick else 60
    dds = _dds_available()
    with tempfile.TemporaryDirectory() as tmp:
        for side in (16, 4):
            x, y, groups, names = _explorations(side, quick)
            classical, name = _classical(x, y, groups, names, tmp)
            cnn = _cnn(x, y, names, tmp)
            frames = _recording(x, n_touches)
            paced = _recording(x, 6 if quick else 20)
            reference = _readline_loop(classical, frames)
            for model, bundle in ((f"classical: {name}", classical), ("CNN: temporal taxel CNN", cnn)):
                fast = _stream(bundle, frames, paced=False)
                slow = _stream(bundle, paced, paced=True)
                cpu = _cpu(bundle, frames)
                row = {
                    "array": f"{side}x{side}",
                    "model": model,
                    "path": "serial (pty)",
                    "frames/s (1 thread)": round(fast["frames_per_s"]),
                    "frames lost": fast["lost"],
                    "touches (early)": f"{fast['touches']} ({fast['early']})",
                    "touch-end latency median ms": round(slow["latency_median_ms"], 3),
                    "p99 ms": round(slow["latency_p99_ms"], 3),
                    "frames per CPU-s": round(cpu["frames_per_cpu_s"]),
                    "decision CPU ms": round(cpu["decision_cpu_ms"], 3),
                }
                if bundle == classical:
                    row["readline loop frames/s"] = round(reference)
                    row["ratio"] = round(fast["frames_per_s"] / reference, 2)
                rows.append(row)
                if dds:  # the same bundle and frames over a ROS 2 topic (bench/ros2_rows.py)
                    from bench.ros2_rows import dds_rows

                    rows += dds_rows(bundle, model, side, frames, paced, tmp)
            if dds:
                from bench.ros2_rows import echo_row, hand_row

                rows.append(echo_row(side, paced, tmp))
                if side == 16:  # a hand: 5 arrays of 16 x 16 at 1 kHz, one process (issue 41)
                    for model, bundle in (
                        (f"classical: {name}", classical),
                        ("CNN: temporal taxel CNN", cnn),
                    ):
                        rows.append(hand_row(bundle, model, x, tmp, seconds=3.0 if quick else 10.0))
                        rows.append(hand_row(bundle, model, x, tmp, seconds=2.0 if quick else 5.0, rate=0.0))
    notes += [
        "Machine shared with other developers' jobs (2 cores): rates and latencies carry their load; compare "
        "within a run.",
        f"Workload: {n_touches} touches of {T} frames, each followed by {T // 2} resting frames, written into a "
        "pty as fast as the reader takes them ('t,' and the H*W values per line); frames/s = frames read / time "
        "from the first touch's first frame to the last touch's result.",
        f"Latency: paced at {PACED_HZ:g} frames/s; from reading the frame that ended a touch (the first below "
        "the release level) to its JSON line printed (the touch's own last frame comes one frame period, "
        f"{1e3 / PACED_HZ:g} ms here, before it).",
        "Goals (issue 31): >= 1000 frames/s for 16x16 with a classical model; < 5 ms median touch-end latency "
        "with a classical model.",
        "frames per CPU-s: the same frames' lines from an in-memory port through the same stream, divided by "
        "the process's CPU time (time.process_time), which a shared machine does not inflate: the rate one "
        "thread sustains on a core of its own. decision CPU ms: CPU time of one touch's classification "
        "(OnnxPipeline.classify on T frames), median of 30.",
        "Readline loop: pyserial readline(), np.array(line.split(',')), one predict per T frames (no touches, no "
        "fault handling): what a user would write; same pty, same bundle, same process.",
    ]
    if dds:
        from bench.ros2_rows import HAND_NOTE, NOTES

        notes += [*NOTES, HAND_NOTE]
    else:
        notes.append("No ROS 2 rows: the extra ros2 (cyclonedds, rosbags) is not installed.")
    return {"rows": rows, "notes": notes}


if __name__ == "__main__":
    print(json.dumps(run(quick=True), indent=1))
