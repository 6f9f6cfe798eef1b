"""ROS 2 over Cyclone DDS (tactile_torch.robot.ros2.dds and .publish): the DDS types are ROS 2's on the
wire, byte for byte; a real publisher process (``simulate-sensor --ros2-topic``) reaches a subscriber
on the loopback only (every RTPS message either participant sent went to 127.0.0.1, read from Cyclone
DDS's own trace); the configuration, names and errors. Needs the optional extra ``ros2``."""

from __future__ import annotations

import json
import subprocess
import time

import numpy as np
import pytest

from tactile_torch.cli import BAD_INPUT_EXIT, main
from tactile_torch.robot.ros2.dds import (
    DdsNode,
    DdsOptions,
    DdsTypes,
    check_domain_id,
    dds_topic_name,
    dds_type_name,
    default_domain_id,
    loopback_config,
    resolve_config,
    ros_type_of,
)
from tactile_torch.robot.ros2.message_types import (
    FLOAT_ARRAY_TYPE,
    IMAGE_TYPE,
    IMU_TYPE,
    STRING_TYPE,
    TACTILE_STATE_TYPE,
    message_types,
)
from tactile_torch.robot.ros2.messages import MessageEncoder, TopicFields
from tactile_torch.robot.ros2.reader import RELIABILITY_POLICY, TopicReader
from tests.ros2_helpers import cli, free_domain_id, ros2_env, selected_interfaces, sent_to, traced_loopback

pytest.importorskip(
    "cyclonedds", reason="the optional extra 'ros2' (cyclonedds) is not installed: pip install -e '.[ros2]'"
)


def _recordings(path, n=200, rate_hz=800.0):
    """Write two synthetic triaxial recordings in g (numpy only: the robot's CI job runs these tests)."""
    rng = np.random.default_rng(0)
    signals = (rng.normal(0, 0.3, (2, n, 3)) + np.array([0.0, 0.0, 1.0])).astype(np.float32)
    np.savez(
        path,
        signals=signals,
        labels=np.array([0, 1]),
        class_names=np.array(["cork", "felt"]),
        rate_hz=rate_hz,
    )
    return signals, rate_hz


def _as_idl(struct, message, types: DdsTypes):
    """The Cyclone IDL struct instance holding the same values as a rosbags message (test-only converter)."""
    values = {}
    for name, _ in types.store.fielddefs[message.__msgtype__][1]:
        value = getattr(message, name)
        if hasattr(value, "__msgtype__"):
            value = _as_idl(types.struct(value.__msgtype__), value, types)
        elif isinstance(value, list) and value and hasattr(value[0], "__msgtype__"):
            value = [_as_idl(types.struct(v.__msgtype__), v, types) for v in value]
        elif isinstance(value, np.ndarray):
            value = value.tolist()
        values[name] = value
    return struct(**values)


@pytest.mark.parametrize(
    ("fields", "frame", "kwargs"),
    [
        (TopicFields(IMU_TYPE), np.array([0.5, -1.0, 1.0]), {}),
        (TopicFields(FLOAT_ARRAY_TYPE), np.arange(6.0).reshape(2, 3), {}),
        (TopicFields(IMAGE_TYPE), np.arange(6.0).reshape(2, 3) * 1000, {"encoding": "mono16"}),
        (TopicFields(TACTILE_STATE_TYPE, sensor="tip"), np.arange(12.0), {}),
    ],
    ids=["imu", "float32multiarray", "image", "tactilestate"],
)
def test_dds_types_serialize_as_ros2_messages_byte_for_byte(fields, frame, kwargs):
    # The DDS type built from the definition, serialized by Cyclone DDS itself, gives the bytes rosbags
    # gives for the same message (what rosbag2 stores and a ROS 2 node sends): the types are ROS 2's.
    store = message_types()
    types = DdsTypes(store)
    cdr = MessageEncoder(fields, store, **kwargs).encode(frame, 1_700_000_000_123_456_789)
    struct = types.struct(fields.msgtype)
    idl = _as_idl(struct, store.deserialize_cdr(cdr, fields.msgtype), types)
    assert idl.serialize() == cdr
    assert struct.__idl_typename__.replace(".", "::") == dds_type_name(fields.msgtype)


def test_the_decision_string_is_what_a_ros2_talker_sends():
    # A ROS 2 talker's std_msgs/String "Hello World: 1" on rt/chatter, as a DDS router recorded it:
    # 00 01 00 00 | length 15 | the text and its NUL | padding (eProsima DDS Router docs, Echo Participant)
    talker = bytes.fromhex("000100000f00000048656c6c6f20576f726c643a20310000")
    store = message_types()
    message = store.types[STRING_TYPE](data="Hello World: 1")
    cdr = store.serialize_cdr(message, STRING_TYPE)
    assert bytes(cdr) == talker[: len(cdr)] and talker[len(cdr) :] == b"\x00"  # Cyclone pads to 4 bytes
    assert DdsTypes(store).topic_type(STRING_TYPE).__idl_typename__ == "std_msgs.msg.dds_.String_"
    assert (
        dds_topic_name("/chatter") == "rt/chatter"
        and ros_type_of("std_msgs::msg::dds_::String_") == STRING_TYPE
    )


def test_a_publisher_process_reaches_the_stream_on_the_loopback_only(tmp_path):
    # simulate-sensor publishes a recording as sensor_msgs/Imu; this process streams it (the type found
    # from the publisher) through a vibration bundle: every sample arrives, m/s^2 back to g, stamped at
    # the recording's rate, and the windows and their scores are those of the same samples offline.
    # Both participants trace every RTPS message they send: all went to 127.0.0.1, over the loopback alone.
    from tactile_torch.robot.ros2.source import Ros2Source
    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.robot.stream.live import LiveStream, item_spec
    from tactile_torch.robot.stream.output import result_record
    from tactile_torch.robot.stream.port_lines import StreamDisconnected
    from tactile_torch.robot.stream.source import ArraySource
    from tests.stream_helpers import energy_bundle

    signals, rate_hz = _recordings(tmp_path / "rec.npz")
    pipe = OnnxPipeline(energy_bundle(tmp_path / "energy.onnx", window=64, step=32))
    offline = [result_record(r) for r in LiveStream(pipe, ArraySource(signals[1], item_spec(pipe)))]
    domain = free_domain_id()
    pub_config = traced_loopback(tmp_path / "pub.xml")
    sub_config = traced_loopback(tmp_path / "sub.xml")
    publisher = subprocess.Popen(
        cli(
            "simulate-sensor", "--ros2-topic", "/imu", "--data", str(tmp_path / "rec.npz"), "--recording", "1",
            "--domain-id", str(domain), "--dds-config", str(pub_config), "--wait-subscriber", "30",
        ),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=ros2_env(),
    )  # fmt: skip
    values, stamps, live = [], [], []
    source = Ros2Source(
        "/imu", item_spec(pipe), dds=DdsOptions(domain_id=domain, config=str(sub_config)), start_timeout_s=30
    )
    try:
        readings = source.readings

        def recorded():  # the readings, kept on their way to the stream
            for item in readings():
                if hasattr(item, "values"):
                    values.append(item.values)
                    stamps.append(item.t)
                yield item

        source.readings = recorded
        with pytest.raises(StreamDisconnected, match=r"/imu: the publisher left after 200 samples"):
            for result in LiveStream(pipe, source):
                live.append(result_record(result))
        out, err = publisher.communicate(timeout=30)
    finally:
        source.close()
        publisher.kill()
    assert publisher.returncode == 0 and f"{len(signals[1])} messages published" in out, err
    assert source.msgtype == IMU_TYPE
    np.testing.assert_allclose(np.array(values), signals[1], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(np.diff(stamps), 1 / rate_hz, atol=1e-6)  # header stamps at the rate
    assert [r["sample"] for r in live] == [r["sample"] for r in offline] and len(live) == 5
    assert [r["label"] for r in live] == [r["label"] for r in offline]
    np.testing.assert_allclose([r["scores"] for r in live], [r["scores"] for r in offline], rtol=1e-5)
    for config in (pub_config, sub_config):
        trace = config.with_suffix(".log")
        destinations = sent_to(trace)
        assert len(destinations) > 10 and set(destinations) == {"127.0.0.1"}, trace.read_text()[-2000:]
        assert selected_interfaces(trace).split()[0] == "lo" and "eth" not in selected_interfaces(trace)
        assert "Domain/General/AllowMulticast/#text: false" in trace.read_text()


def test_a_lossless_reader_names_a_best_effort_publisher_it_cannot_match():
    # ROS 2's sensor-data publishers are best effort: a reliable (lossless) reader never matches them, and
    # DDS says which policy refused it
    types = DdsTypes(message_types())
    with DdsNode(DdsOptions(domain_id=free_domain_id(), config="loopback", qos="lossless")) as node:
        lossless = TopicReader(node, "/tactile", FLOAT_ARRAY_TYPE, types)
        best_effort = TopicReader(node, "/tactile", FLOAT_ARRAY_TYPE, types, profile="sensor")
        # (a writer is deleted when dropped: keep it)
        writer = node.writer("/tactile", FLOAT_ARRAY_TYPE, types, profile="sensor")
        deadline = time.monotonic() + 10
        while (refused := lossless.incompatible()) is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert refused == RELIABILITY_POLICY and lossless.publishers() == 0
        assert lossless.incompatible() is None  # said once
        while not best_effort.publishers() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert best_effort.publishers() == 1 and best_effort.incompatible() is None and writer is not None


def test_decisions_are_published_as_std_msgs_string_json():
    # what `ros2 topic echo /hand/tactile/decision` shows: std_msgs/msg/String whose data is the JSON line
    from tactile_torch.robot.ros2.publish import DecisionPublisher, decision_topic

    store = message_types()
    types = DdsTypes(store)
    topic = decision_topic("/hand/tactile")
    assert topic == "/hand/tactile/decision"
    with DdsNode(DdsOptions(domain_id=free_domain_id(), config="loopback")) as node:
        echo = TopicReader(node, topic, STRING_TYPE, types, profile="lossless")
        publisher = DecisionPublisher(
            node, topic, types, to_json=lambda r: json.dumps({"event": "touch", "label": r})
        )
        deadline = time.monotonic() + 10
        while not publisher.subscribers() and time.monotonic() < deadline:
            time.sleep(0.02)
        publisher(1)
        publisher(0)
        got = []
        while len(got) < 2 and time.monotonic() < deadline:
            got += [store.deserialize_cdr(m.cdr, STRING_TYPE).data for m in echo.take(0.1)]
    assert [json.loads(g)["label"] for g in got] == [1, 0]
    assert publisher.summary_note() == "2 decisions published on /hand/tactile/decision"


def test_configuration_names_and_errors(tmp_path, monkeypatch, capsys):
    # the trace check above sees any destination (a line as Cyclone DDS writes it, another address)
    fake = tmp_path / "fake.log"
    fake.write_text("1.0 [7]  tev: ddsi_xpack_send 96: 0x1:20 0x2:76 [ udp/192.0.2.9:7410@1 ]\n")
    assert sent_to(fake) == ["192.0.2.9"]
    xml = loopback_config()
    for part in (
        '<NetworkInterface name="lo"/>',
        "<AllowMulticast>false</AllowMulticast>",
        '<Peer address="127.0.0.1"/>',
    ):
        assert part in xml
    monkeypatch.delenv("CYCLONEDDS_URI", raising=False)
    assert resolve_config(None) == (xml, "loopback only (127.0.0.1, multicast off)")
    assert resolve_config(None, environ={"CYCLONEDDS_URI": "file:///etc/robot.xml"}) == (
        "file:///etc/robot.xml",
        "CYCLONEDDS_URI",
    )
    (tmp_path / "robot.xml").write_text(xml)
    assert resolve_config(str(tmp_path / "robot.xml")) == (xml, str(tmp_path / "robot.xml"))
    with pytest.raises(FileNotFoundError, match=r"nope\.xml: no such Cyclone DDS configuration file"):
        resolve_config(str(tmp_path / "nope.xml"))
    assert default_domain_id({"ROS_DOMAIN_ID": "42"}) == 42 and default_domain_id({}) == 0
    with pytest.raises(ValueError, match=r"ROS_DOMAIN_ID must be a domain id in 0\.\.232, got 'x'"):
        default_domain_id({"ROS_DOMAIN_ID": "x"})
    with pytest.raises(ValueError, match=r"domain_id must be an int in 0\.\.232, got 233"):
        check_domain_id(233)
    with pytest.raises(
        ValueError, match=r"topic must be an absolute ROS 2 topic name such as /hand/tactile, got 'imu'"
    ):
        dds_topic_name("imu")
    assert ros_type_of("Imu") is None
    # the command line: one line, status 2
    assert main(["simulate-sensor", "--ros2-topic", "/imu", "--domain-id", "300"]) == BAD_INPUT_EXIT
    assert "--domain-id must be an int in 0..232, got 300" in capsys.readouterr().err
    assert main(["simulate-sensor", "--ros2-topic", "/imu", "--pty"]) == BAD_INPUT_EXIT
    assert "give one of --port PORT, --pty or --ros2-topic TOPIC" in capsys.readouterr().err
    _recordings(tmp_path / "rec.npz")
    argv = [
        "simulate-sensor",
        "--ros2-topic",
        "/x",
        "--data",
        str(tmp_path / "rec.npz"),
        "--ros2-type",
        IMAGE_TYPE,
    ]
    assert main(argv) == BAD_INPUT_EXIT
    assert (
        "--ros2-type sensor_msgs/msg/Image cannot carry the accelerometer samples of --data"
        in capsys.readouterr().err
    )


def test_without_cyclonedds_dds_commands_say_which_extra(monkeypatch, capsys):
    import sys

    monkeypatch.setitem(sys.modules, "cyclonedds", None)  # as without the extra
    assert main(["simulate-sensor", "--ros2-topic", "/imu", "--seconds", "0.1"]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert (
        err
        == "tactile-torch simulate-sensor: --ros2-topic needs the optional extra 'ros2' (the cyclonedds package), which is not installed: pip install 'tactile-torch[ros2]'\n"
    )
