"""The DDS rows of the stream benchmark: the same stream fed over a ROS 2 topic, and the transport's floor.

:func:`dds_rows` measures one bundle on frames published by another process
(:mod:`bench.ros2_probe`) as ``std_msgs/msg/Float32MultiArray`` over Cyclone DDS, on the loopback only
and a DDS domain of its own, the stream in this process (``Ros2Source`` -> ``LiveStream``, a JSON line
per result to ``/dev/null``, each decision published back as ``std_msgs/msg/String``):

- ``frames/s``: the publisher writes as fast as its writer takes the messages, lossless on both sides
  (``--qos lossless``: reliable, keep all up to 1000 queued, so the writer waits for a slower reader and
  no frame is lost: ``frames lost`` says so); frames/s is what the stream sustained: frames read / time
  from the first touch's first frame to the last touch's result;
- ``touch-end latency``: paced at 200 frames/s, from taking the frame that ended a touch off the DDS
  reader to its JSON line printed (the serial rows' definition), median and 99th percentile; and to
  its decision published on the decision topic (written to the DDS writer);
- ``round trip``: on the publisher's clock, from writing the frame that ended a touch to the decision
  arriving back on the decision topic: two DDS hops, the stream's stages and the model.

:func:`echo_row` is the floor of the transport alone: the same publisher, paced, and in this process a
DDS echo that answers each frame at once (decode, ``{"i": n}`` published back), no stages, no model.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import time

import numpy as np

PACED_HZ = 200.0


def _domain() -> int:
    from tests.ros2_helpers import free_domain_id

    return free_domain_id()


def _publisher(
    values: np.ndarray, domain: int, rate: float, tmp: str, qos: str = "sensor"
) -> subprocess.Popen:
    path = os.path.join(tmp, f"frames-{domain}.npy")
    np.save(path, values.astype(np.float32))
    argv = [sys.executable, "-m", "bench.ros2_probe", "publish", "--domain-id", str(domain), "--values", path]
    env = {k: v for k, v in os.environ.items() if k not in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID")}
    argv += ["--rate", str(rate), "--qos", qos]
    return subprocess.Popen(argv, stdout=subprocess.PIPE, text=True, env=env)


def _probe_result(publisher: subprocess.Popen) -> dict:
    out, _ = publisher.communicate(timeout=120)
    return json.loads(out.strip().splitlines()[-1])


def _stream(bundle: str, frames: np.ndarray, rate: float, tmp: str, qos: str = "sensor") -> dict:
    """Stream ``frames`` published at ``rate`` (0: as fast as possible) over DDS with ``qos`` on both sides."""
    from tactile_torch.robot.ros2.dds import DdsOptions, DdsTypes
    from tactile_torch.robot.ros2.message_types import FLOAT_ARRAY_TYPE, message_types
    from tactile_torch.robot.ros2.messages import TopicFields
    from tactile_torch.robot.ros2.publish import DecisionPublisher
    from tactile_torch.robot.ros2.source import Ros2Source
    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.robot.stream.live import LiveOptions, LiveStream, item_spec
    from tactile_torch.robot.stream.output import result_json
    from tactile_torch.robot.stream.port_lines import StreamDisconnected, StreamTimeout

    pipe = OnnxPipeline(bundle)
    domain = _domain()
    source = Ros2Source(
        "/bench/frames",
        item_spec(pipe),
        fields=TopicFields(FLOAT_ARRAY_TYPE),
        dds=DdsOptions(domain_id=domain, config="loopback", qos=qos),
        silence_s=1.0,
        idle_timeout_s=3.0,
        start_timeout_s=60.0,
    )
    decisions = DecisionPublisher(source.node, "/bench/replies", DdsTypes(message_types()), result_json)
    live = LiveStream(pipe, source, LiveOptions())
    live.warm_up()
    publisher = _publisher(frames, domain, rate, tmp, qos)
    latencies, published, first, last, counts = [], [], None, None, {"touch": 0, "early": 0}
    with open(os.devnull, "w") as sink, contextlib.suppress(StreamTimeout, StreamDisconnected):
        for result in live:  # ends when the publisher leaves
            print(result_json(result), file=sink, flush=True)
            printed = time.monotonic()
            decisions(result)
            now = time.monotonic()
            first = first or result.segment.started_at
            counts[result.kind] += 1
            if result.kind == "touch":
                latencies.append((printed - result.segment.ended_at) * 1e3)
                published.append((now - result.segment.ended_at) * 1e3)
                last = now
    probe = _probe_result(publisher)
    source.close()
    read = source.counts.items
    trips = [ms for _, ms in probe["replies"]]
    return {
        "frames": read,
        "lost": len(frames) - read,
        "frames_per_s": read / (last - first) if first is not None and last is not None else float("nan"),
        "touches": counts["touch"],
        "early": counts["early"],
        "latency_median_ms": float(np.median(latencies)) if latencies else float("nan"),
        "latency_p99_ms": float(np.percentile(latencies, 99)) if latencies else float("nan"),
        "published_median_ms": float(np.median(published)) if published else float("nan"),
        "trip_median_ms": float(np.median(trips)) if trips else float("nan"),
        "trip_p99_ms": float(np.percentile(trips, 99)) if trips else float("nan"),
        "publisher_frames_per_s": probe["written"] / probe["seconds"],
    }


def dds_rows(
    bundle: str, model: str, side: int, frames: np.ndarray, paced: np.ndarray, tmp: str
) -> list[dict]:
    """One row: ``bundle`` streamed over DDS (frames/s on ``frames``, latencies on ``paced`` at 200 Hz)."""
    # as fast as possible, lossless (reliable, keep all: the publisher waits for the stream; frames/s is
    # what the stream sustained)
    fast = _stream(bundle, frames, 0.0, tmp, qos="lossless")
    slow = _stream(bundle, paced, PACED_HZ, tmp)
    return [
        {
            "array": f"{side}x{side}",
            "model": model,
            "path": "ROS 2 (Cyclone DDS, loopback)",
            "frames/s (1 thread)": round(fast["frames_per_s"]),
            "frames lost": fast["lost"],
            "touches (early)": f"{fast['touches']} ({fast['early']})",
            "touch-end latency median ms": round(slow["latency_median_ms"], 3),
            "p99 ms": round(slow["latency_p99_ms"], 3),
            "to published median ms": round(slow["published_median_ms"], 3),
            "round trip median ms": round(slow["trip_median_ms"], 3),
            "round trip p99 ms": round(slow["trip_p99_ms"], 3),
            "publisher frames/s": round(fast["publisher_frames_per_s"]),
        }
    ]


def echo_row(side: int, paced: np.ndarray, tmp: str) -> dict:
    """The floor: frames paced at 200 Hz over DDS, each answered at once by a DDS echo in this process."""
    from tactile_torch.robot.ros2.dds import DdsNode, DdsOptions, DdsTypes
    from tactile_torch.robot.ros2.message_types import FLOAT_ARRAY_TYPE, STRING_TYPE, message_types
    from tactile_torch.robot.ros2.reader import TopicReader

    store = message_types()
    types = DdsTypes(store)
    domain = _domain()
    with DdsNode(DdsOptions(domain_id=domain, config="loopback")) as node:
        frames = TopicReader(node, "/bench/frames", FLOAT_ARRAY_TYPE, types)
        writer = node.writer("/bench/replies", STRING_TYPE, types, profile="reliable")
        publisher = _publisher(paced, domain, PACED_HZ, tmp)
        answered, last = 0, time.monotonic() + 60.0
        while answered < len(paced) and time.monotonic() < last:
            for received in frames.take(0.05):
                store.deserialize_cdr(received.cdr, FLOAT_ARRAY_TYPE)  # a reader decodes what it takes
                cdr = store.serialize_cdr(
                    store.types[STRING_TYPE](data=json.dumps({"i": answered})), STRING_TYPE
                )
                writer.write(types.sample(STRING_TYPE, cdr))
                answered += 1
                last = time.monotonic() + 5.0
        probe = _probe_result(publisher)
    trips = [ms for _, ms in probe["replies"]]
    return {
        "array": f"{side}x{side}",
        "model": "none: DDS echo (the transport's floor)",
        "path": "ROS 2 (Cyclone DDS, loopback)",
        "frames lost": len(paced) - answered,
        "round trip median ms": round(float(np.median(trips)), 3),
        "round trip p99 ms": round(float(np.percentile(trips, 99)), 3),
    }


HAND_SENSORS = ("thumb", "index", "middle", "ring", "palm")
HAND_HZ = 1000.0


def hand_row(
    bundle: str, model: str, x: np.ndarray, tmp: str, *, seconds: float, rate: float = HAND_HZ, on_event=None
) -> dict:
    """A hand: ``TactileState`` messages of 5 sensors of ``x``'s array, at ``rate`` (0: a flood), read with every
    sensor cut into touches of its own (``sensor="all"``) and decided by one bundle, in this process."""
    from bench.bench_stream_frames import T
    from tactile_torch.robot.ros2.dds import DdsOptions
    from tactile_torch.robot.ros2.message_types import TACTILE_STATE_TYPE
    from tactile_torch.robot.ros2.messages import TopicFields
    from tactile_torch.robot.ros2.source import Ros2Source
    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.robot.stream.live import LiveOptions, LiveStream, item_spec
    from tactile_torch.robot.stream.output import result_json
    from tactile_torch.robot.stream.port_lines import StreamDisconnected, StreamTimeout

    n = int(seconds * (rate or HAND_HZ))
    side = x.shape[-1]
    slow = 5  # an exploration of T frames held 5 times longer: a touch of 0.2 s at 1 kHz
    rest = np.zeros((slow * T // 2, side, side), np.float32)
    hand = np.zeros((n, len(HAND_SENSORS), side, side), np.float32)
    touches = [np.concatenate([np.repeat(x[i % len(x)], slow, axis=0), rest]) for i in range(len(x))]
    for k in range(len(HAND_SENSORS)):  # each sensor's touches, shifted: they start and end at other times
        part = np.concatenate([touches[(i + k) % len(x)] for i in range(n // len(touches[0]) + 2)])
        hand[:, k] = np.roll(part, k * 37, axis=0)[:n]
    values = os.path.join(tmp, f"hand-{side}.npy")
    np.save(values, hand)
    pipe = OnnxPipeline(bundle)
    domain = _domain()
    source = Ros2Source(
        "/bench/hand",
        item_spec(pipe),
        fields=TopicFields(TACTILE_STATE_TYPE, sensor="all"),
        dds=DdsOptions(domain_id=domain, config="loopback"),
        silence_s=1.0,
        idle_timeout_s=3.0,
        start_timeout_s=60.0,
        on_event=on_event,
    )
    live = LiveStream(pipe, source, LiveOptions(), on_event=on_event)
    live.warm_up()
    env = {k: v for k, v in os.environ.items() if k not in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID")}
    argv = [
        sys.executable,
        "-m",
        "tests.ros2_publisher",
        "--domain-id",
        str(domain),
        "--topic",
        "/bench/hand",
    ]
    argv += ["--type", TACTILE_STATE_TYPE, "--values", values, "--rate", str(rate or HAND_HZ)]
    argv += ["--sensors", ",".join(HAND_SENSORS), *(["--fast"] if not rate else [])]
    publisher = subprocess.Popen(argv, stdout=subprocess.PIPE, text=True, env=env)
    decisions, first, last = 0, None, None
    cpu0 = time.process_time()
    with open(os.devnull, "w") as sink, contextlib.suppress(StreamTimeout, StreamDisconnected):
        for result in live:
            print(result_json(result), file=sink, flush=True)
            first = first or result.segment.started_at
            decisions += result.kind == "touch"
            last = time.monotonic()
    cpu = time.process_time() - cpu0
    publisher.communicate(timeout=120)
    source.close()
    read = source.counts.items
    return {
        "array": f"{len(HAND_SENSORS)} x {side}x{side} (TactileState)",
        "model": model,
        "path": f"ROS 2 hand, {'a flood' if not rate else f'{rate:g} Hz'}",
        "frames/s (1 thread)": round(read / (last - first))
        if first is not None and last is not None
        else None,
        "frames lost": len(hand) * len(HAND_SENSORS) - read,
        "frames known lost": live.lost,
        "touches (early)": f"{decisions} ({live.early})",
        "frames per CPU-s": round(read / cpu) if cpu > 0 else None,
    }


NOTES = [
    "ROS 2 rows: the frames are published by another process (python -m bench.ros2_probe) as "
    "std_msgs/msg/Float32MultiArray over Cyclone DDS (loopback only, a DDS domain of their own; "
    "frames/s: a flood (the publisher's rate in its column), lossless (reliable, keep all: the publisher waits for "
    "the stream, nothing is lost; at --qos sensor a flood loses what the stream cannot take, counted), and "
    "frames/s is what the stream sustained; the latency rows: best effort at 200 frames/s); "
    "the stream runs in the benchmark's process (Ros2Source -> LiveStream), publishes each decision back as "
    "std_msgs/msg/String JSON, and the publisher times each round trip on its own clock: from writing the frame "
    "that ended a touch to the decision's arrival. The echo row answers every frame at once, no stages, no "
    "model: the transport's floor.",
]


HAND_NOTE = (
    f"Hand rows: TactileState messages of {len(HAND_SENSORS)} sensors ({', '.join(HAND_SENSORS)}) of the array, "
    f"published by another process (python -m tests.ros2_publisher --sensors ...) at {HAND_HZ:g} Hz (paced), or as "
    "fast as it writes (a flood), best effort; the stream reads every sensor (sensor='all': one sequencer and "
    "touch segmenter per sensor, one bundle) in this process; frames/s counts every sensor's frames (5 per "
    "message); frames lost = sent - read, which the stream counted itself (frames known lost: DDS's statuses)."
)

__all__ = ["HAND_NOTE", "NOTES", "PACED_HZ", "dds_rows", "echo_row", "hand_row"]


def main() -> None:
    """``python -m bench.ros2_rows``: the serial and DDS paths side by side, on template bundles, one run.

    Without the trade-off study (minutes): synthetic explorations of a 16 x 16 and a 4 x 4 array (T = 20
    frames), a class-mean template bundle (``tests.stream_helpers.template_bundle``: a linear classical
    model with touch levels and a calibrated early rule, frame rate 100 Hz in its metadata), 12 touches
    as fast as possible and 20 paced at 200 frames/s, through the serial path (a pty, the stream-frames
    benchmark's own function) and through DDS; then the DDS echo.
    """
    import tempfile

    from bench.bench_stream_frames import T, _explorations, _recording
    from bench.bench_stream_frames import _stream as serial_stream
    from tests.stream_helpers import template_bundle

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for side in (16, 4):
            x, y, _, names = _explorations(side, quick=True)
            bundle = str(
                template_bundle(os.path.join(tmp, f"t{side}.onnx"), x, y, names, frame_rate_hz=100.0)
            )
            frames, paced = _recording(x, 12), _recording(x, 20)
            fast = serial_stream(bundle, frames, paced=False)
            slow = serial_stream(bundle, paced, paced=True)
            rows.append(
                {
                    "array": f"{side}x{side}",
                    "model": "class-mean templates",
                    "path": "serial (pty)",
                    "frames/s (1 thread)": round(fast["frames_per_s"]),
                    "frames lost": fast["lost"],
                    "touches (early)": f"{fast['touches']} ({fast['early']})",
                    "touch-end latency median ms": round(slow["latency_median_ms"], 3),
                    "p99 ms": round(slow["latency_p99_ms"], 3),
                }
            )
            rows += dds_rows(bundle, "class-mean templates", side, frames, paced, tmp)
            rows.append(echo_row(side, paced, tmp))
    keys = list(dict.fromkeys(k for row in rows for k in row))
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for row in rows:
        print("| " + " | ".join(str(row.get(k, "")) for k in keys) + " |")
    print(f"\n{T} frames per touch; " + " ".join(NOTES))


if __name__ == "__main__":
    main()
