"""ROS 2 bags (sqlite3 and MCAP storage) written with rosbags' own writer and read back as recordings:
IMU topics in g with header stamps, pressure-array topics as explorations, bad bags in one line (train
on bags with ``--data bag --topic``: tests/cli/test_training_inputs.py). Needs the optional extra
``ros`` (rosbags); torch-free, as on the robot."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.cli import BAD_INPUT_EXIT, main
from tactile_torch.robot.files.data_sources import DataOptions, read_source
from tactile_torch.robot.ros2.bags import read_bag
from tests.robot_data import surface_recordings
from tests.ros2_helpers import write_frame_bag
from tests.stream_helpers import energy_bundle

pytest.importorskip(
    "rosbags", reason="the optional extra 'ros' (rosbags) is not installed: pip install -e '.[ros]'"
)

G = 9.80665


@pytest.fixture(scope="module")
def rec():
    return surface_recordings(4, 4.0)


def _typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def write_imu_bag(path, signal_g, rate, *, storage="sqlite3", topic="/imu", start_s=1_700_000_000):
    """A rosbag2 of sensor_msgs/msg/Imu messages (m/s^2) written with rosbags' writer."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = _typestore()
    t = ts.types
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        conn = writer.add_connection(topic, "sensor_msgs/msg/Imu", typestore=ts)
        other = writer.add_connection("/status", "std_msgs/msg/String", typestore=ts)
        zero = t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        for i, a in enumerate(np.asarray(signal_g, dtype=np.float64) * G):
            ns = start_s * 10**9 + round(1e9 * i / rate)
            header = t["std_msgs/msg/Header"](
                stamp=t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9), frame_id="imu"
            )
            msg = t["sensor_msgs/msg/Imu"](
                header=header,
                orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=zero,
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=t["geometry_msgs/msg/Vector3"](x=a[0], y=a[1], z=a[2]),
                linear_acceleration_covariance=np.zeros(9),
            )
            writer.write(conn, ns + 5000, ts.serialize_cdr(msg, "sensor_msgs/msg/Imu"))
        writer.write(
            other,
            start_s * 10**9,
            ts.serialize_cdr(t["std_msgs/msg/String"](data="ok"), "std_msgs/msg/String"),
        )
    return path


def write_pressure_bag(path, maps, *, storage="mcap", topic="/pressure", layout=True):
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = _typestore()
    t = ts.types
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    dims = [
        t["std_msgs/msg/MultiArrayDimension"](label=k, size=n, stride=0)
        for k, n in zip("hw", maps.shape[1:], strict=True)
    ]
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        conn = writer.add_connection(topic, "std_msgs/msg/Float32MultiArray", typestore=ts)
        for i, m in enumerate(maps):
            msg = t["std_msgs/msg/Float32MultiArray"](
                layout=t["std_msgs/msg/MultiArrayLayout"](dim=dims if layout else [], data_offset=0),
                data=m.astype(np.float32).ravel(),
            )
            writer.write(conn, 10**9 + i * 10**8, ts.serialize_cdr(msg, "std_msgs/msg/Float32MultiArray"))
    return path


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_imu_bags_read_back_in_g_with_header_stamps(tmp_path, rec, storage):
    signal = rec.signals[1][:800]
    bag = write_imu_bag(tmp_path / "felt_2", signal, 800.0, storage=storage)
    topic = read_bag(bag)  # the only Imu topic is found (the /status strings are left alone)
    assert topic.topic == "/imu" and topic.rate_hz == 800.0 and topic.values.shape == (800, 3)
    np.testing.assert_allclose(topic.values, signal, atol=1e-6)
    np.testing.assert_allclose(topic.stamps_s[:3], [0, 1 / 800, 2 / 800], atol=1e-9)
    storage_file = next(p for p in bag.iterdir() if p.suffix in (".db3", ".mcap"))
    np.testing.assert_array_equal(read_bag(storage_file, "/imu").values, topic.values)
    data = read_source([bag], DataOptions(topic="/imu"))
    assert data.class_names == ("felt",) and data.session.tolist() == ["2"]


def test_pressure_bags_become_explorations(tmp_path):
    rng = np.random.default_rng(0)
    maps = [rng.uniform(0, 1, (n, 4, 5)).astype(np.float32) for n in (25, 30)]
    bags = [
        write_pressure_bag(tmp_path / "dots_1", maps[0]),
        write_pressure_bag(tmp_path / "grid_1", maps[1], storage="sqlite3", layout=False),
    ]
    with pytest.raises(
        ValueError, match=r"grid_1:/pressure: message 0 has 20 values and no two-dimensional shape"
    ):
        read_source(bags)
    data = read_source(bags, DataOptions(shape=(4, 5), frames=10))
    assert data.kind == "image" and data.frames is None and data.pressure.shape == (5, 10, 4, 5)
    assert data.labels.tolist() == [0, 0, 1, 1, 1] and data.groups.tolist() == [0, 0, 1, 1, 1]
    np.testing.assert_array_equal(data.pressure[3], maps[1][10:20])
    with pytest.raises(ValueError, match=r"not the 2 x 5 of the shape"):
        read_source(bags[:1], DataOptions(shape=(2, 5)))


def test_bad_bags_get_one_line(tmp_path, rec):
    bag = write_imu_bag(tmp_path / "run", rec.signals[0][:100], 800.0)
    with pytest.raises(
        ValueError, match=r"run: no topic '/imu/data'; the bag has /imu \(sensor_msgs/msg/Imu\), /status"
    ):
        read_bag(bag, "/imu/data")
    with pytest.raises(
        ValueError, match=r"run: topic /status holds std_msgs/msg/String, expected sensor_msgs/msg/Imu"
    ):
        read_bag(bag, "/status")
    with pytest.raises(ValueError, match=r"run:/imu: 100 messages, more than the 50 read at most"):
        read_bag(bag, max_messages=50)
    empty = write_imu_bag(tmp_path / "empty", np.zeros((0, 3)), 800.0, storage="mcap")
    with pytest.raises(ValueError, match=r"empty:/imu: 0 message\(s\), at least 2 are needed"):
        read_bag(empty)
    (tmp_path / "junk.mcap").write_bytes(b"not a bag at all")
    with pytest.raises(ValueError, match=r"junk\.mcap: not a readable ROS 2 bag|junk\.mcap:None: unreadable"):
        read_bag(tmp_path / "junk.mcap")
    with pytest.raises(FileNotFoundError, match=r"nothing\.mcap: no such bag"):
        read_bag(tmp_path / "nothing.mcap")


def test_predict_reads_bags_by_topic_without_torch(tmp_path, rec, capsys):
    bag = write_imu_bag(tmp_path / "z_1", rec.signals[0][:640], 800.0, storage="mcap")
    model = str(energy_bundle(tmp_path / "m.onnx"))  # labels the axis of most energy: z (gravity)
    assert main(["predict", "--model", model, "--data", str(bag), "--topic", "/imu"]) == 0
    assert "overall accuracy 1.0000" in capsys.readouterr().out
    assert main(["predict", "--model", model, "--data", str(bag), "--topic", "/nope"]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no topic '/nope'; the bag has /imu (sensor_msgs/msg/Imu)" in err


@pytest.mark.parametrize(
    ("msgtype", "encoding", "sensor"),
    [
        ("sensor_msgs/msg/Image", "mono8", None),
        ("sensor_msgs/msg/Image", "mono16", None),
        ("sensor_msgs/msg/Image", "32FC1", None),
        ("tactile_msgs/msg/TactileState", "32FC1", "tip"),
    ],
)
def test_image_and_tactile_state_bags_become_maps_timed_by_their_headers(tmp_path, msgtype, encoding, sensor):
    from tactile_torch.robot.ros2.messages import TopicFields

    rng = np.random.default_rng(1)
    maps = rng.integers(0, 256, (12, 4, 5)).astype(np.float32)
    fields = TopicFields(msgtype, sensor=sensor)
    bag = write_frame_bag(tmp_path / "duck_1", fields, maps, encoding=encoding, storage="sqlite3")
    shape = None if msgtype.endswith("Image") else (4, 5)
    topic = read_bag(bag, sensor=sensor, shape=shape)
    assert (
        topic.kind == "frame"
        and topic.values.shape == (12, 4, 5)
        and topic.rate_hz == pytest.approx(1 / 0.066)
    )
    np.testing.assert_array_equal(topic.values, maps)
    if msgtype.endswith("TactileState"):
        with pytest.raises(
            ValueError, match=r"duck_1:/tactile: message 0 has 20 values and no two-dimensional shape"
        ):
            read_bag(bag)
    data = read_source([bag], DataOptions(shape=shape, sensor=sensor, frames=6))
    assert data.kind == "image" and data.pressure.shape == (2, 6, 4, 5) and data.class_names == ("duck",)


def test_unstamped_headers_fall_back_to_the_bags_receive_stamps(tmp_path):
    from tactile_torch.robot.ros2.messages import TopicFields

    maps = np.arange(5 * 6, dtype=np.float32).reshape(5, 2, 3)
    bag = write_frame_bag(tmp_path / "b", TopicFields("sensor_msgs/msg/Image"), maps, stamps_ns=[0] * 5)
    assert read_bag(bag).rate_hz == pytest.approx(100.0)  # receive stamps 10 ms apart


def test_a_robots_own_message_is_read_from_the_bags_definition_or_a_msg_file(tmp_path):
    from tactile_torch.robot.ros2.message_types import MessageDefinition, message_types
    from tactile_torch.robot.ros2.messages import TopicFields

    text = "std_msgs/Header header\nfloat32[] taxels\nuint8 finger\n"
    own = MessageDefinition(text, "my_hand/msg/Taxels")
    maps = np.arange(8 * 6, dtype=np.float32).reshape(8, 2, 3)
    fields = TopicFields("my_hand/msg/Taxels", field="taxels")
    bag = write_frame_bag(tmp_path / "mcap_bag", fields, maps, store=message_types([own]))
    np.testing.assert_array_equal(read_bag(bag, "/tactile", field="taxels", shape=(2, 3)).values, maps)
    with pytest.raises(ValueError, match=r"field='taxels' given; name one with topic="):
        read_bag(bag, field="taxels", shape=(2, 3))
    with pytest.raises(
        ValueError, match=r"topic /tactile holds my_hand/msg/Taxels, expected .* or the numbers at field="
    ):
        read_bag(bag, "/tactile")
    with pytest.raises(ValueError, match=r"my_hand/msg/Taxels has no field 'values'"):
        read_bag(bag, "/tactile", field="values", shape=(2, 3))
    # the same topic with the definition given as a .msg file (a bag that does not store it)
    read = read_bag(bag, "/tactile", field="taxels", shape=(2, 3), msg_defs=[own])
    np.testing.assert_array_equal(read.values, maps)


def test_a_bag_of_pressure_maps_is_a_frame_recording_predict_cuts_touches_from(tmp_path, capsys):
    """simulate-sensor and predict read a bag of pressure maps as one frame recording (its stamps as t)."""
    import json

    from tactile_torch.robot.files.frame_recordings import read_frame_recording
    from tactile_torch.robot.stream.touches import TouchLevels
    from tests.stream_helpers import frame_bundle

    maps = np.zeros((20, 4, 5), np.float32)
    maps[3:9, :2] = 5.0  # two touches: top rows, then bottom rows
    maps[12:17, 2:] = 5.0
    bag = write_pressure_bag(tmp_path / "dots_1", maps)
    rec = read_frame_recording(bag)
    assert rec.frames.shape == (20, 4, 5) and rec.class_names == ("dots",) and rec.labels.tolist() == [0] * 20
    np.testing.assert_allclose(rec.t[:3], [0.0, 0.1, 0.2], atol=1e-9)
    weights = np.zeros((4, 5, 2), np.float32)
    weights[:2, :, 0] = weights[2:, :, 1] = 1.0
    levels = TouchLevels(onset=5.0, release=2.0).to_metadata()
    bundle = frame_bundle(tmp_path / "b.onnx", weights, n_frames=4, metadata={"touch_levels": levels})
    assert main(["predict", "--model", str(bundle), "--data", str(bag), "--json"]) == 0
    touches = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(r["start"], r["frames"], r["label"]) for r in touches] == [(3, 6, 0), (12, 5, 1)]
