"""ROS 2 messages as values (tactile_torch.robot.ros2.messages): the one decoder of bags and live topics,
checked on messages written by rosbags' own serializer (byte for byte what rosbag2 stores and ROS 2
publishes), every encoding and layout, a robot's own .msg definition, and every documented error.
Needs the optional extra ``ros`` (rosbags)."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.robot.ros2.message_types import (
    FLOAT_ARRAY_TYPE,
    IMAGE_TYPE,
    IMU_TYPE,
    MAX_MSG_DEF_BYTES,
    TACTILE_STATE_TYPE,
    MessageDefinition,
    message_types,
    read_message_definition,
    ros_type_name,
)
from tactile_torch.robot.ros2.messages import MessageDecoder, MessageEncoder, MessageError, TopicFields

pytest.importorskip(
    "rosbags", reason="the optional extra 'ros' (rosbags) is not installed: pip install -e '.[ros]'"
)

TIP_MSG = """\
# my_hand/msg/Fingertip: a fingertip's taxels with a header
std_msgs/Header header
Pad pad
uint16[] raw
"""
PAD_MSG = "float32[12] taxels\nstring name\n"
G = 9.80665


@pytest.fixture(scope="module")
def store():
    return message_types(
        [MessageDefinition(PAD_MSG, "my_hand/msg/Pad"), MessageDefinition(TIP_MSG, "my_hand/msg/Fingertip")]
    )


def _header(t, sec, nanosec):
    return t["std_msgs/msg/Header"](
        stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id="f"
    )


def _image(t, data: bytes, h, w, encoding, step, bigendian=0):
    return t[IMAGE_TYPE](
        header=_header(t, 3, 250),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=bigendian,
        step=step,
        data=np.frombuffer(data, dtype=np.uint8),
    )


def test_imu_gives_one_sample_in_g_with_the_header_stamp(store):
    t = store.types
    v = t["geometry_msgs/msg/Vector3"]
    msg = t[IMU_TYPE](
        header=_header(t, 12, 5),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=v(x=0.0, y=0.0, z=0.0),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=v(x=G, y=-2 * G, z=0.5),
        linear_acceleration_covariance=np.zeros(9),
    )
    reading = MessageDecoder(TopicFields(IMU_TYPE), store).decode(store.serialize_cdr(msg, IMU_TYPE))
    assert reading.stamp_ns == 12_000_000_005 and reading.shape is None
    np.testing.assert_allclose(reading.values, [1.0, -2.0, 0.5 / G], rtol=1e-7)
    assert reading.values.dtype == np.float32


@pytest.mark.parametrize(
    ("encoding", "dtype", "bigendian"),
    [
        ("32FC1", "<f4", 0),
        ("32FC1", ">f4", 1),
        ("mono16", "<u2", 0),
        ("mono16", ">u2", 1),
        ("mono8", "u1", 0),
    ],
)
def test_images_give_frames_in_their_encoding_rows_step_bytes_apart(store, encoding, dtype, bigendian):
    t = store.types
    frame = (np.arange(12).reshape(3, 4) * 7 + 1).astype(dtype)
    row = 4 * frame.itemsize
    padded = b"".join(frame[i].tobytes() + b"\xee" * 3 for i in range(3))  # step = row + 3 padding bytes
    msg = _image(t, padded, 3, 4, encoding, row + 3, bigendian)
    reading = MessageDecoder(TopicFields(IMAGE_TYPE), store).decode(store.serialize_cdr(msg, IMAGE_TYPE))
    assert reading.shape == (3, 4) and reading.stamp_ns == 3_000_000_250
    np.testing.assert_array_equal(reading.values, frame.astype(np.float32).reshape(-1))


def test_float32_multiarray_gives_its_layout_shape_and_no_stamp(store):
    t = store.types
    dim = t["std_msgs/msg/MultiArrayDimension"]
    msg = t[FLOAT_ARRAY_TYPE](
        layout=t["std_msgs/msg/MultiArrayLayout"](
            dim=[dim(label="h", size=2, stride=6), dim(label="w", size=3, stride=3)], data_offset=0
        ),
        data=np.arange(6, dtype=np.float32),
    )
    reading = MessageDecoder(TopicFields(FLOAT_ARRAY_TYPE), store).decode(
        store.serialize_cdr(msg, FLOAT_ARRAY_TYPE)
    )
    assert reading.stamp_ns is None and reading.shape == (2, 3)
    np.testing.assert_array_equal(reading.values, np.arange(6))


def _tactile_state(store, channels):
    t = store.types
    sensors = [
        t["sensor_msgs/msg/ChannelFloat32"](name=n, values=np.asarray(v, np.float32)) for n, v in channels
    ]
    msg = t[TACTILE_STATE_TYPE](header=_header(t, 1, 0), sensors=sensors)
    return store.serialize_cdr(msg, TACTILE_STATE_TYPE)


def test_tactile_state_gives_the_named_sensor(store):
    cdr = _tactile_state(store, [("thumb", [1, 2, 3]), ("index", [4, 5, 6, 7])])
    reading = MessageDecoder(TopicFields(TACTILE_STATE_TYPE, sensor="index"), store).decode(cdr)
    np.testing.assert_array_equal(reading.values, [4, 5, 6, 7])
    with pytest.raises(MessageError, match=r"a TactileState of 2 sensors \('thumb', 'index'\): choose one"):
        MessageDecoder(TopicFields(TACTILE_STATE_TYPE), store).decode(cdr)
    with pytest.raises(MessageError, match=r"without the sensor 'ring'; its sensors: 'thumb', 'index'"):
        MessageDecoder(TopicFields(TACTILE_STATE_TYPE, sensor="ring"), store).decode(cdr)
    one = _tactile_state(store, [("palm", [9, 8])])
    np.testing.assert_array_equal(
        MessageDecoder(TopicFields(TACTILE_STATE_TYPE), store).decode(one).values, [9, 8]
    )


def test_a_robots_own_message_is_read_at_the_field_path(store):
    t = store.types
    pad = t["my_hand/msg/Pad"](taxels=np.arange(12, dtype=np.float32) / 4, name="tip")
    msg = t["my_hand/msg/Fingertip"](header=_header(t, 0, 42), pad=pad, raw=np.array([7, 65535], np.uint16))
    cdr = store.serialize_cdr(msg, "my_hand/msg/Fingertip")
    nested = MessageDecoder(TopicFields("my_hand/msg/Fingertip", field="pad.taxels"), store).decode(cdr)
    np.testing.assert_array_equal(nested.values, np.arange(12) / 4)
    assert nested.stamp_ns == 42
    raw = MessageDecoder(TopicFields("my_hand/msg/Fingertip", field="raw"), store).decode(cdr)
    np.testing.assert_array_equal(raw.values, [7, 65535])


@pytest.mark.parametrize(
    ("fields", "kwargs", "values"),
    [
        (TopicFields(IMU_TYPE), {}, np.array([0.125, -1.5, 1.0])),
        (TopicFields(FLOAT_ARRAY_TYPE), {}, np.arange(12.0).reshape(3, 4) / 3),
        (TopicFields(IMAGE_TYPE), {"encoding": "32FC1"}, np.arange(12.0).reshape(3, 4) / 7),
        (TopicFields(IMAGE_TYPE), {"encoding": "mono16"}, np.arange(12.0).reshape(3, 4) * 5000),
        (TopicFields(IMAGE_TYPE), {"encoding": "mono8"}, np.arange(12.0).reshape(3, 4) * 20),
        (TopicFields(TACTILE_STATE_TYPE, sensor="tip"), {}, np.arange(12.0) - 6),
        (TopicFields("my_hand/msg/Fingertip", field="pad.taxels"), {}, np.arange(12.0) / 8),
    ],
    ids=["imu", "float32multiarray", "32FC1", "mono16", "mono8", "tactilestate", "custom"],
)
def test_encoder_and_decoder_are_inverse(store, fields, kwargs, values):
    cdr = MessageEncoder(fields, store, **kwargs).encode(values, 7_000_000_009)
    reading = MessageDecoder(fields, store).decode(cdr)
    np.testing.assert_array_equal(reading.values, values.astype(np.float32).reshape(-1))
    stamped = fields.msgtype != FLOAT_ARRAY_TYPE
    assert reading.stamp_ns == (7_000_000_009 if stamped else None)
    assert store.deserialize_cdr(cdr, fields.msgtype) is not None  # rosbags reads what we write


def test_message_definitions_are_named_by_their_path_or_explicitly(tmp_path):
    pkg = tmp_path / "my_hand" / "msg"
    pkg.mkdir(parents=True)
    (pkg / "Pad.msg").write_text(PAD_MSG)
    assert read_message_definition(pkg / "Pad.msg").name == "my_hand/msg/Pad"
    (tmp_path / "pad.txt").write_text(PAD_MSG)
    assert read_message_definition(f"other/Pad={tmp_path / 'pad.txt'}").name == "other/msg/Pad"
    unnamed = read_message_definition(tmp_path / "pad.txt")
    assert unnamed.name is None
    store = message_types([unnamed], topic_type="robot_msgs/msg/Pad")  # named by the topic's type
    assert "robot_msgs/msg/Pad" in store.fielddefs
    assert ros_type_name("sensor_msgs/Image") == "sensor_msgs/msg/Image"


def test_documented_errors(store, tmp_path):
    with pytest.raises(
        ValueError, match=r"no definition of the message type my_hand/msg/Nope: give its \.msg text"
    ):
        MessageDecoder(TopicFields("my_hand/msg/Nope", field="x"), store)
    with pytest.raises(ValueError, match=r"my_hand/msg/Fingertip is not one of the standard types .* field="):
        MessageDecoder(TopicFields("my_hand/msg/Fingertip"), store)
    with pytest.raises(
        ValueError,
        match=r"my_hand/msg/Pad has no field 'values' \(field='pad.values'\); its fields: taxels, name",
    ):
        MessageDecoder(TopicFields("my_hand/msg/Fingertip", field="pad.values"), store)
    with pytest.raises(ValueError, match=r"sensor= names a sensor of tactile_msgs/msg/TactileState"):
        MessageDecoder(TopicFields(IMAGE_TYPE, sensor="tip"), store)
    with pytest.raises(ValueError, match=r"does not say which type it defines: name it pkg/msg/Name=FILE"):
        message_types([MessageDefinition(PAD_MSG, None, "pad.txt")])
    with pytest.raises(
        ValueError, match=r"bad\.msg line 1: not a field of a message definition \(TYPE NAME\): 'float32\[ x'"
    ):
        message_types([MessageDefinition("float32[ x\n", "a/msg/B", "bad.msg")])
    with pytest.raises(
        ValueError, match=r"^bad\.msg: not a message definition rosbags can read for a/msg/B \(\w+\)$"
    ):
        message_types([MessageDefinition("float32 x 1 2 3\n", "a/msg/B", "bad.msg")])
    with pytest.raises(ValueError, match=r"a message type must be named pkg/msg/Name"):
        ros_type_name("Imu")
    big = tmp_path / "big.msg"
    big.write_text("# " + "x" * MAX_MSG_DEF_BYTES)
    with pytest.raises(ValueError, match=r"big\.msg: \d+ bytes, more than the 65536"):
        read_message_definition(big)
    with pytest.raises(FileNotFoundError, match=r"nothing\.msg: no such message definition"):
        read_message_definition(tmp_path / "nothing.msg")
    t = store.types
    rgb = _image(t, bytes(36), 3, 4, "rgb8", 12)
    with pytest.raises(
        MessageError, match=r"an Image of encoding 'rgb8'; frames are read from 32FC1, mono16, mono8"
    ):
        MessageDecoder(TopicFields(IMAGE_TYPE), store).decode(store.serialize_cdr(rgb, IMAGE_TYPE))
    short = _image(t, bytes(10), 3, 4, "mono8", 4)
    with pytest.raises(MessageError, match=r"an Image of 3 x 4 mono8 with step 4 holds 10 bytes"):
        MessageDecoder(TopicFields(IMAGE_TYPE), store).decode(store.serialize_cdr(short, IMAGE_TYPE))
    nan = _tactile_state(store, [("tip", [1.0, np.nan])])
    with pytest.raises(MessageError, match=r"a tactile_msgs/msg/TactileState message holds NaN/inf values"):
        MessageDecoder(TopicFields(TACTILE_STATE_TYPE), store).decode(nan)
    with pytest.raises(MessageError, match=r"a message that does not decode as sensor_msgs/msg/Image"):
        MessageDecoder(TopicFields(IMAGE_TYPE), store).decode(b"\x00\x01\x00\x00\x01")
    with pytest.raises(
        ValueError, match=r"a mono8 Image holds whole numbers in 0\.\.255, got values in 0\.\.300"
    ):
        MessageEncoder(TopicFields(IMAGE_TYPE), store, encoding="mono8").encode(np.array([[0.0, 300.0]]))
    with pytest.raises(
        ValueError, match=r"encoding must be one of \('32FC1', 'mono16', 'mono8'\), got 'bgr8'"
    ):
        MessageEncoder(TopicFields(IMAGE_TYPE), store, encoding="bgr8")
