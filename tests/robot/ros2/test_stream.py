"""``tactile-torch stream --ros2-topic``: a live ROS 2 topic over Cyclone DDS, end to end.

Every test starts real processes: a publisher (``tests/ros2_publisher.py``, a DDS participant of its
own) and the stream command, on a DDS domain of their own (``tests.ros2_helpers.free_domain_id``) and
the loopback-only configuration. They check what the robot gets: the touches and decisions equal the
same stages run offline on the same frames (:class:`~tactile_torch.robot.stream.source.ArraySource`,
what ``predict`` runs), every decision is printed and published on the decision topic, nothing is
lost or repeated, on synthetic frames and on real grasps (iCub fingertips, the Schunk hand's arrays)
replayed at their recorded rate; a publisher that starts late, pauses, leaves and comes back is
handled like a serial port that does the same. Torch-free (the bundles are numpy templates written
by ``tests.stream_helpers.frame_bundle``). Needs the optional extra ``ros2``."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest

from tactile_torch.cli import main
from tactile_torch.robot.ros2.dds import DdsOptions
from tactile_torch.robot.ros2.messages import TopicFields
from tactile_torch.robot.ros2.source import Ros2Source
from tactile_torch.robot.runtime import OnnxPipeline
from tactile_torch.robot.stream.early_decision import EarlyRule
from tactile_torch.robot.stream.live import LiveStream, item_spec
from tactile_torch.robot.stream.output import result_record
from tactile_torch.robot.stream.port_lines import StreamDisconnected, StreamTimeout
from tactile_torch.robot.stream.source import ArraySource
from tactile_torch.robot.stream.touches import TouchLevels, touch_levels
from tests.ros2_helpers import (
    DecisionListener,
    cli,
    free_domain_id,
    ros2_env,
    start_publisher,
    write_frame_bag,
)
from tests.stream_helpers import frame_bundle

pytest.importorskip(
    "cyclonedds", reason="the optional extra 'ros2' (cyclonedds) is not installed: pip install -e '.[ros2]'"
)
pytest.importorskip("rosbags", reason="the optional extra 'ros2' (rosbags) is not installed")

TOUCH_KEYS = ("touch", "start", "frames", "frames_used", "label", "name", "ended_by", "flags")


# -- the data: synthetic touches, and real grasps ---------------------------------------------------


def _synthetic():
    """Frames of a 4 x 4 array at 100 Hz: three touches (top, bottom, top) between resting frames."""
    rng = np.random.default_rng(0)
    parts = []
    for rows, length in ((slice(0, 2), 7), (slice(2, 4), 6), (slice(0, 2), 4)):
        parts.append(rng.uniform(0, 0.1, (5, 4, 4)))
        touch = rng.uniform(0, 0.1, (length, 4, 4))
        touch[:, rows] += np.linspace(2, 8, length)[:, None, None]
        parts.append(touch)
    parts.append(rng.uniform(0, 0.1, (5, 4, 4)))
    frames = np.round(np.concatenate(parts), 3).astype(np.float32)
    weights = np.zeros((4, 4, 2), np.float32)
    weights[:2, :, 0] = weights[2:, :, 1] = 1.0
    levels = TouchLevels(onset=4.0, release=2.0, min_frames=2, source="test")
    return frames, 100.0, weights, ["top", "bottom"], levels, 4


def _drimus(root):
    """Two grasps (two objects) on the Schunk hand's third distal array (13 x 6), at their ~15 Hz.

    The array the objects touch in every grasp; each grasp is replayed from 3 frames before its
    contact to 9 frames into it, followed by 3 of its first (resting) frames (1.6 s of frames). The model: templates of
    the held frames above rest (numpy); the levels from the held frames above the resting level of the
    grasps' first phase (:func:`touch_levels`), as a user with such recordings would set them.
    """
    from tactile_torch.robot.stream.touches import resting_level

    array, names = "ts6_f3_distal", ["BALL_RUBBER", "ORANGE_FRESH"]
    grasps = {n: [] for n in names}
    for f in sorted((root / "grasps_npz").glob("*.npz")):
        with np.load(f) as z:
            if str(z["class_name"]) in grasps:
                grasps[str(z["class_name"])].append((z[array].astype(np.float32), z["phase"]))
    rest = resting_level(np.concatenate([g[p == 1] for n in names for g, p in grasps[n]]))
    held = {n: np.stack([g[p >= 3][:60] for g, p in grasps[n]]) for n in names}
    levels = touch_levels(np.concatenate(list(held.values())), frame_rate_hz=15.0, rest=rest)
    weights = np.stack([held[n].mean((0, 1)) for n in names], axis=-1)
    weights = (weights - weights.mean(-1, keepdims=True)) / 1000.0  # centred templates: nearest mean
    parts = []
    for n in names:
        g = grasps[n][0][0]
        onset = int(np.argmax([levels.activity(f) >= levels.onset for f in g]))
        parts += [g[onset - 3 : onset + 9], g[:3]]
    return np.concatenate(parts), 15.0, weights.astype(np.float32), names, levels, 6


def _icub(root):
    """Three iCub grasps (three objects) between open-hand slices (the ``none`` class), played at 20 Hz.

    Each grasp's last 8 slices (the object held) between two open-hand slices: 32 slices, 1.6 s.

    5 fingertips x 12 taxels per slice, raw 0-255 readings (contact lowers them). The data set gives no
    rate: 20 Hz is assumed. Rest: the open hand's median reading per taxel; levels set between the
    open hand's activity and the grasps'.
    """

    def read(path):
        lines = [line.split() for line in path.read_text().splitlines()[1:] if line.strip()]
        return np.array([lines[i + 2 : i + 7] for i in range(0, len(lines), 7)], dtype=np.float32)

    data = root / "iCubGraspDataset"
    names = ["empty_coke", "med_coke", "med_vitamin_water"]
    open_hand = read(data / "none_1.txt")
    grasps = [read(data / f"{n}_1.txt") for n in names]
    levels = TouchLevels(
        onset=150.0, release=100.0, sign=-1.0, rest=-np.median(open_hand, axis=0), source="test"
    )
    weights = np.stack([255.0 - g[-4:].mean(0) for g in grasps], axis=-1)
    weights = (weights - weights.mean(-1, keepdims=True)) / 1000.0  # centred templates: nearest mean
    parts = [open_hand[:2]]
    for g in grasps:
        parts += [g[-8:], open_hand[2:4]]
    return np.concatenate(parts), 20.0, weights.astype(np.float32), names, levels, 4


def _bundle(tmp_path, weights, names, levels, n_frames, rate):
    """A pressure bundle of ``n_frames`` frames with the touch levels and an early rule that always fires."""
    path = tmp_path / "grasp.onnx"
    checkpoints = tuple(c for c in (2, 3) if c < n_frames) or (1,)
    meta = {
        "frame_rate_hz": rate,
        "touch_levels": levels.to_metadata(),
        "early_decision": EarlyRule(threshold=0.0, checkpoints=checkpoints).to_metadata(),  # always early
    }
    return OnnxPipeline(
        frame_bundle(path, weights, n_frames=n_frames, class_names=list(names), metadata=meta)
    )


# -- running the processes --------------------------------------------------------------------------


def _start_stream(pipe, topic, domain, *extra):
    argv = cli(
        "stream",
        "--model",
        str(pipe.path),
        "--ros2-topic",
        topic,
        "--domain-id",
        str(domain),
        "--json",
        *extra,
    )
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ros2_env())


def _finish(*processes, timeout=60):
    outs = []
    for p in processes:
        try:
            outs.append(p.communicate(timeout=timeout))
        finally:
            p.kill()
        p.stdout_text = outs[-1][0]
    return outs


def _offline(pipe, frames, rate):
    t = np.arange(len(frames)) / rate
    live = LiveStream(pipe, ArraySource(frames, item_spec(pipe), t=t))
    return [result_record(r) for r in live] + [result_record(r) for r in live.finish()]


def _assert_same_touches(got, expected):
    """The touches (and early decisions) of ``got`` are those of ``expected``: same cut, labels, scores to 1e-5."""
    touches = [r for r in got if r["event"] == "touch"]
    assert [[r[k] for k in TOUCH_KEYS] for r in touches] == [
        [r[k] for k in TOUCH_KEYS] for r in expected if r["event"] == "touch"
    ]
    np.testing.assert_allclose(
        [r["scores"] for r in touches], [r["scores"] for r in expected if r["event"] == "touch"], atol=1e-5
    )
    early = [(r["touch"], r["frames"], r["label"]) for r in got if r["event"] == "early"]
    assert early == [(r["touch"], r["frames"], r["label"]) for r in expected if r["event"] == "early"]
    decided = [(d["label"], d["early"], d["frames"]) for d in (r["decision"] for r in touches)]
    assert decided == [
        (d["label"], d["early"], d["frames"])
        for d in (r["decision"] for r in expected if r["event"] == "touch")
    ]  # what the robot was told for each touch, and how far into it


# -- the tests --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("source", "msgtype", "encoding", "sensor"),
    [
        ("synthetic", "tactile_msgs/msg/TactileState", "32FC1", "index"),
        ("drimus_sdh_tactile", "tactile_msgs/msg/TactileState", "32FC1", "f3_distal"),
        ("icub_grasp", "sensor_msgs/msg/Image", "mono8", None),
    ],
)
def test_touches_over_dds_equal_predict_offline_and_every_decision_is_published(
    tmp_path, shared_data, capsys, source, msgtype, encoding, sensor
):
    frames, rate, weights, names, levels, n_frames = (
        _synthetic()
        if source == "synthetic"
        else (_drimus if source.startswith("drimus") else _icub)(shared_data(source))
    )
    pipe = _bundle(tmp_path, weights, names, levels, n_frames, rate)
    # offline: predict on a bag of the same messages (the touches it cuts are the stream's stages run
    # on the bag's frames: ArraySource, checked equal to them here too)
    t = np.arange(len(frames)) / rate
    bag = write_frame_bag(
        tmp_path / "grasps", TopicFields(msgtype, sensor=sensor), frames, encoding=encoding,
        stamps_ns=[10**9 + round(v * 1e9) for v in t],
    )  # fmt: skip
    assert (
        main(
            [
                "predict",
                "--model",
                str(pipe.path),
                "--data",
                str(bag),
                "--json",
                *(("--sensor", sensor) if sensor else ()),
            ]
        )
        == 0
    )
    predicted = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    expected = _offline(pipe, frames, rate)
    _assert_same_touches(predicted, [r for r in expected if r["event"] == "touch"])
    n_touches = len(predicted)
    assert n_touches >= 2 and sum(r["event"] == "early" for r in expected) >= 1  # the replay tests something
    extra = ("--encoding", encoding) + (("--sensor", sensor) if sensor else ())
    # the publisher pauses 0.7 s in the middle of the last touch (the stream's silence is 0.5 s)
    last = predicted[-1]
    cut = last["start"] + last["frames"] // 2
    extra += ("--plan", f"0:{cut},pause=0.7,{cut}:{len(frames)}")
    sensor = ("--sensor", sensor) if sensor else ()
    domain, topic = free_domain_id(), "/hand/tactile"
    listener = DecisionListener(f"{topic}/decision", domain)  # subscribed before the stream starts
    try:
        # Both start at once: the publisher waits for the stream's reader, which the stream creates
        # after its decision writer, so the listener has the writer before the first decision.
        stream = _start_stream(pipe, topic, domain, *sensor)
        publisher = start_publisher(tmp_path, frames, rate, topic, domain, msgtype, *extra)
        (out, err), (pub_out, _) = _finish(stream, publisher)
        decisions = listener.wait_for(len(out.splitlines()), timeout_s=10)
    finally:
        listener.close()
    # without --reconnect the stream ends when the publisher leaves, as at a serial port that fails
    assert stream.returncode == 4 and f"done {len(frames)}" in pub_out, err
    assert f"{topic}: the publisher left after {len(frames)} frames" in err
    got = [json.loads(line) for line in out.splitlines()]
    touches = [r for r in got if r["event"] == "touch"]
    # every touch before the pause: the touch, label, scores and early decision predict and the offline
    # stages give
    before = [r for r in got if r["touch"] < n_touches - 1]
    _assert_same_touches(before, [r for r in expected if r["touch"] < n_touches - 1])
    _assert_same_touches(touches[:-2], predicted[:-1])
    # the paused touch: reported as two, cut by the silence, never one merged touch
    first, second = touches[-2:]
    assert (first["start"], first["ended_by"], second["start"]) == (last["start"], "silence", cut)
    assert "cut" in first["flags"] and "after_cut" in second["flags"]
    assert first["frames"] + second["frames"] == last["frames"]
    assert decisions == got  # every decision printed was published, in order, and nothing else
    header = next(line for line in err.splitlines() if "reading ROS 2 topic" in line)
    assert f"reading ROS 2 topic {topic} ({msgtype}" in header and "loopback only" in header
    assert f"decisions published on {topic}/decision (std_msgs/msg/String, JSON)" in header
    # nothing lost or repeated: every frame read once, in order (header stamps: no step but the pause)
    summary = err.strip().splitlines()[-1]
    assert summary.startswith(f"{len(frames)} frames read, {n_touches + 1} touches"), summary
    assert " 1 gaps (0 frames known lost)" in summary and " 0 messages skipped" in summary, summary
    assert f"{len(got)} decisions published on {topic}/decision" in summary


def _run_in_process(pipe, source, publisher):
    """Run the stream's stages in this process on ``source`` until it raises; return (records, error, live)."""
    live = LiveStream(pipe, source)
    records, error = [], None
    try:
        for result in live:
            records.append(result_record(result))
    except (StreamTimeout, StreamDisconnected) as err:
        error = err
    records += [result_record(r) for r in live.finish()]
    source.close()
    _finish(publisher)
    return records, error, live


def test_a_publisher_that_starts_late_pauses_leaves_and_comes_back(tmp_path):
    # A touch split by the publisher's pause is reported as two (cut, then the rest of a contact), never
    # merged; the publisher leaving is a disconnection: with reconnect the stream waits for it, says
    # when it is back, and counts a reconnection; the touch it interrupted is cut, not merged either.
    # The stream runs in this process (the command's own run is the test above), the publisher in its own.
    frames, rate, weights, names, levels, n_frames = _synthetic()
    pipe = _bundle(tmp_path, weights, names, levels, n_frames, rate)
    domain, topic, events = free_domain_id(), "/hand/tactile", []
    opened = []
    source = Ros2Source(
        topic,
        item_spec(pipe),
        fields=TopicFields("tactile_msgs/msg/TactileState"),
        dds=DdsOptions(domain_id=domain, config="loopback"),
        silence_s=0.3,
        idle_timeout_s=1.5,
        start_timeout_s=30.0,
        reconnect=True,
        on_event=lambda e: events.append((time.monotonic(), e.kind, e.message)),
        on_open=opened.append,
    )
    # touch 1 is frames 5-11: a pause after frame 8; touch 2 (17-22): a departure after frame 19. The
    # publisher starts 0.6 s after the stream: late.
    plan = "0:9,pause=0.45,9:20,leave=0.45,20:37"
    publisher = start_publisher(
        tmp_path,
        frames,
        rate,
        topic,
        domain,
        "tactile_msgs/msg/TactileState",
        "--plan",
        plan,
        "--delay",
        "0.6",
    )
    records, error, live = _run_in_process(pipe, source, publisher)
    assert "done 37" in publisher.stdout_text
    assert isinstance(error, StreamDisconnected) and "gave up waiting for a publisher" in str(error)
    touches = [r for r in records if r["event"] == "touch"]
    assert [(r["start"], r["frames"], r["ended_by"], r["flags"]) for r in touches] == [
        (5, 4, "silence", ["cut"]),
        (9, 3, "release", ["after_cut", "stretched"]),
        (17, 3, "reconnect", ["cut", "stretched"]),
        (20, 3, "release", ["after_cut", "stretched"]),
        (28, 4, "release", []),
    ], records
    kinds = [k for _, k, _ in events]
    assert kinds == [
        "waiting",
        "first",
        "silence",
        "resumed",
        "disconnected",
        "reconnected",
        "resumed",
        "disconnected",
    ]
    messages = [m for _, _, m in events]
    assert messages[0].startswith("no matching publisher yet on /hand/tactile") and opened == [topic]
    assert "the publisher left after 20 frames; waiting for it to come back" in messages[4]
    assert messages[5].startswith("a publisher of /hand/tactile is back after")
    assert live.summary().startswith("37 frames read, 5 touches") and source.counts.reconnects == 1


def test_the_ros2_commands_of_docs_stream_run_as_written(tmp_path):
    # docs/stream.md, "ROS 2 topics": its bash block, as written, in a directory holding the two files it
    # names, with ROS_DOMAIN_ID set to a domain of this test's own (and no CYCLONEDDS_URI: loopback)
    from pathlib import Path

    from tactile_torch.robot.files.frame_recordings import FrameRecording, write_frame_recording

    page = (Path(__file__).resolve().parents[3] / "docs" / "stream.md").read_text(encoding="utf-8")
    section = page.split("## ROS 2 topics", 1)[1].split("\n## ", 1)[0]
    blocks = [b.split("```", 1)[0] for b in section.split("```bash\n")[1:]]
    assert len(blocks) == 1 and "--ros2-topic /hand/tactile" in blocks[0]
    frames, rate, weights, names, levels, n_frames = _synthetic()
    _bundle(tmp_path, weights, names, levels, n_frames, rate)  # grasp.onnx
    write_frame_recording(tmp_path / "grasp.npz", FrameRecording(frames, np.arange(len(frames)) / rate))
    env = ros2_env(ROS_DOMAIN_ID=str(free_domain_id()))
    env["PATH"] = f"{Path(sys.executable).parent}:{env.get('PATH', '')}"  # tactile-torch of this interpreter
    run = subprocess.run(
        ["bash", "-e", "-c", blocks[0]], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 0, run.stderr
    shown = [json.loads(line) for line in run.stdout.splitlines() if line.startswith("{")]
    touches = [json.loads(line) for line in (tmp_path / "touches.jsonl").read_text().splitlines()]
    assert len(shown) == 2 and shown == touches[:2] and sum(r["event"] == "touch" for r in touches) == 3
    assert (
        "loopback only (127.0.0.1, multicast off)" in run.stderr
        and f"{len(touches)} decisions published" in run.stderr
    )


def test_messages_that_give_no_frame_are_skipped_and_said(tmp_path):
    # a message of another size, without the sensor, too large to decode: skipped, counted and said;
    # a frame out of range: rejected and a break, as on a serial line. One participant, local delivery.
    from tactile_torch.robot.ros2.dds import DdsNode, DdsTypes
    from tactile_torch.robot.ros2.message_types import TACTILE_STATE_TYPE, message_types
    from tactile_torch.robot.ros2.messages import MessageEncoder
    from tactile_torch.robot.stream.source import Break, ItemSpec, Reading

    store = message_types()
    types = DdsTypes(store)
    tip, palm = (MessageEncoder(TopicFields(TACTILE_STATE_TYPE, sensor=s), store) for s in ("tip", "palm"))
    messages = [
        tip.encode(np.ones(16), 1),
        tip.encode(np.ones(12), 2),  # another array
        palm.encode(np.ones(16), 3),  # another sensor
        tip.encode(np.ones(20_000), 4),  # 80 kB: not decoded
        tip.encode(np.full(16, 1e6), 5),  # beyond the range
        tip.encode(np.full(16, 2.0), 6),
    ]
    events = []
    with DdsNode(DdsOptions(domain_id=free_domain_id(), config="loopback")) as node:
        writer = node.writer("/t", TACTILE_STATE_TYPE, types)
        source = Ros2Source(
            "/t",
            ItemSpec("frame", (4, 4), -10.0, 300.0, 100.0),
            fields=TopicFields(TACTILE_STATE_TYPE, sensor="tip"),
            node=node,
            silence_s=0.2,
            idle_timeout_s=0.5,
            start_timeout_s=10.0,
            on_event=events.append,
            on_open=lambda name: [writer.write(types.sample(TACTILE_STATE_TYPE, m)) for m in messages],
        )
        got = []
        with pytest.raises(
            StreamTimeout,
            match=r"/t: no valid frame for 0\.\d s \(timeout 0\.5 s\); 2 frames read, 3 messages skipped",
        ):
            for item in source.readings():
                got.append(item)
    assert [type(g).__name__ for g in got] == ["Reading", "Break", "Reading", "Break"]
    assert [g.kind for g in got if isinstance(g, Break)] == ["rejected", "silence"]
    assert [float(g.values[0, 0]) for g in got if isinstance(g, Reading)] == [1.0, 2.0]
    assert got[0].t == pytest.approx(1e-9)  # the header stamp
    counts = source.counts
    assert (counts.items, counts.skipped, counts.rejected) == (2, 3, 1)
    said = [e.message for e in events if e.kind == "skipped"]
    assert "a message of 12 values, not the 4 x 4 the bundle takes" in said[0]
    assert "a TactileState without the sensor 'tip'; its sensors: 'palm'" in said[1]
    assert "a message of 8" in said[2] and "bytes, more than the 65536 read at most" in said[2]
