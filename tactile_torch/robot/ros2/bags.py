"""ROS 2 bags (rosbag2, sqlite3 or MCAP storage) as recordings, read with the pure-Python ``rosbags``.

``rosbags`` is the optional extra ``ros`` (``pip install 'tactile-torch[ros]'``); nothing else in
tactile-torch needs it, and the robot runtime never does. A topic is read through the one decoder of
live topics and bags, :class:`tactile_torch.robot.ros2.messages.MessageDecoder`, so a bag gives
``predict`` the numbers that ``stream --ros2-topic`` reads from the same messages live:

==================================  ============================================================
``sensor_msgs/msg/Imu``             ``linear_acceleration`` (m/s^2 by the message's definition)
                                    divided by 9.80665 → a triaxial recording in g; time from
                                    each message's ``header.stamp``
``std_msgs/msg/Float32MultiArray``  one pressure map per message, ``H x W`` taxels (``shape=``,
                                    else the array's ``layout.dim`` sizes); time from the bag's
                                    receive stamps (the message has no header)
``sensor_msgs/msg/Image``           one map per message (``32FC1``, ``mono16``, ``mono8``), its
                                    ``height x width``; time from ``header.stamp``
``tactile_msgs/msg/TactileState``   one map per message from the channel ``sensor=`` (the only
                                    one by default), ``shape=`` taxels; time from ``header.stamp``
any message                         the numbers at ``field=`` (a dotted path): maps of
                                    ``shape=`` taxels; its type from ``msg_defs=`` (``.msg`` text)
                                    or the bag's own definitions; time from ``header.stamp`` when
                                    it has one, else the receive stamps
==================================  ============================================================

Messages with a header whose stamps are all zero (a driver that does not stamp) are timed by the
bag's receive stamps instead. One bag and topic is one recording. A bag is its directory (with
``metadata.yaml``) or one of its storage files (``.db3``, ``.mcap``). Reads are bounded: at most
``max_messages`` messages (:data:`MAX_BAG_MESSAGES` by default) and :data:`MAX_BAG_BYTES` bytes of
message data per topic; beyond either the bag is refused in one line, before the data is held in
memory.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..files.sample_times import TimeBase, rate_hz, time_base
from .message_types import (
    IMU_TYPE,
    ROS_EXTRA,
    STANDARD_TYPES,
    MessageDefinition,
    MissingExtraError,
    has_type,
    import_extra,
    message_types,
    rosbags_module,
)
from .messages import MessageDecoder, TopicFields

PathLike = str | os.PathLike

READABLE_TYPES = STANDARD_TYPES
"""Topic types read without ``field=``."""
BAG_SUFFIXES = (".db3", ".mcap")
MAX_BAG_MESSAGES = 10_000_000
"""Messages read from one topic at most (about 3.5 hours of a 800 Hz IMU)."""
MAX_BAG_BYTES = 1 << 30
"""Bytes of serialized messages read from one topic at most (1 GiB)."""


@dataclass
class BagTopic:
    """The messages of one topic of one bag.

    Attributes
    ----------
    path : Path
    topic : str
    msgtype : str
    stamps_s : ndarray (n,) float64, seconds from the first message
    values : ndarray, float32
        ``(n, 3)`` accelerations in g (IMU), or ``(n, H, W)`` pressure maps.
    kind : str
        ``"imu"`` or ``"frame"`` (:attr:`TopicFields.kind <tactile_torch.robot.ros2.messages.TopicFields.kind>`).
    rate_hz : float
        From the stamps: the slope of the stamps against the message index between gaps
        (:func:`tactile_torch.robot.files.sample_times.time_base`).
    timing : TimeBase, optional
        What the stamps say, in nanoseconds: the gaps (``timing.gaps``, no window spans one) and
        the irregularity; the readers of several bags warn once for all (``describe_timing``).
    """

    path: Path
    topic: str
    msgtype: str
    stamps_s: np.ndarray
    values: np.ndarray
    rate_hz: float
    timing: TimeBase | None = None
    kind: str = "imu"

    @property
    def name(self) -> str:
        """How messages name this recording: ``<bag>:<topic>``."""
        return f"{self.path}:{self.topic}"


def is_bag(path: PathLike) -> bool:
    """Return whether ``path`` is a rosbag2 directory (``metadata.yaml``) or storage file (``.db3``, ``.mcap``)."""
    path = Path(path)
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix.lower() in BAG_SUFFIXES


def _rosbags():
    rosbags_module("reading ROS 2 bags")
    return import_extra("rosbags.rosbag2", ROS_EXTRA, "reading ROS 2 bags").Reader


def _describe(topics: dict[str, str]) -> str:
    return ", ".join(f"{t} ({m})" for t, m in sorted(topics.items())) or "no topic"


def _pick_topic(path: Path, topics: dict[str, str], topic: str | None, field: str | None) -> str:
    readable = {t: m for t, m in topics.items() if m in READABLE_TYPES}
    if topic is None:
        if len(readable) == 1 and field is None:
            return next(iter(readable))
        what = "several readable topics" if readable else "no IMU or pressure-array topic"
        if field is not None:
            what = f"field={field!r} given"
        raise ValueError(f"{path}: {what}; name one with topic=, the bag has {_describe(topics)}")
    if topic not in topics:
        raise ValueError(f"{path}: no topic {topic!r}; the bag has {_describe(topics)}")
    if topics[topic] not in READABLE_TYPES and field is None:
        raise ValueError(
            f"{path}: topic {topic} holds {topics[topic]}, expected {IMU_TYPE} (accelerations), one of "
            f"{', '.join(READABLE_TYPES[1:])} (pressure maps), or the numbers at field= of any message"
        )
    return topic


def _bag_definitions(connection) -> list[MessageDefinition]:
    """The message definition a bag stores with a connection (rosbag2 >= Iron, MCAP), if any."""
    msgdef = getattr(connection, "msgdef", None)
    text = getattr(msgdef, "data", "") or ""
    if not text.strip() or "msg" not in str(getattr(msgdef, "format", "msg")).lower():
        return []
    return [MessageDefinition(text, connection.msgtype, f"the bag's definition of {connection.msgtype}")]


def _types_for(path: Path, topic: str, msgtype: str, connection, msg_defs: Sequence[MessageDefinition]):
    store = message_types(msg_defs, topic_type=msgtype)
    if has_type(store, msgtype):
        return store
    try:
        stored = message_types([*msg_defs, *_bag_definitions(connection)], topic_type=msgtype)
    except ValueError:
        stored = store
    if has_type(stored, msgtype):
        return stored
    raise ValueError(
        f"{path}:{topic}: no definition of {msgtype} in the bag or among the standard ROS 2 messages: give its "
        ".msg text with msg_defs="
    )


def _map_shape(path: Path, topic: str, given, shape: tuple[int, int] | None, size: int, i: int):
    if shape is not None and given is not None and tuple(given) != tuple(shape):
        raise ValueError(
            f"{path}:{topic}: message {i} is a {given[0]} x {given[1]} map, not the {shape[0]} x {shape[1]} of the shape"
        )
    if shape is None:
        if given is None:
            raise ValueError(
                f"{path}:{topic}: message {i} has {size} values and no two-dimensional shape; give the map's "
                "shape with shape=(H, W)"
            )
        shape = given
    if shape[0] * shape[1] != size:
        raise ValueError(
            f"{path}:{topic}: message {i} has {size} values, not the {shape[0]} x {shape[1]} of the shape"
        )
    return shape


def read_bag(  # noqa: PLR0915
    path: PathLike,
    topic: str | None = None,
    *,
    shape: tuple[int, int] | None = None,
    field: str | None = None,
    sensor: str | None = None,
    msg_defs: Sequence[MessageDefinition] = (),
    max_messages: int = MAX_BAG_MESSAGES,
) -> BagTopic:
    """Read one topic of a ROS 2 bag; return its samples in g (IMU) or its pressure maps.

    Parameters
    ----------
    path : path
        The bag's directory, or one ``.db3``/``.mcap`` storage file.
    topic : str, optional
        Default: the bag's only IMU or pressure-array topic.
    shape : (H, W), optional
        Pressure maps: the taxel grid (default: the message's own, an image's or a two-dimensional
        layout's; needed for TactileState and other flat arrays).
    field : str, optional
        The dotted path of the field holding the numbers (any message type; see
        :class:`~tactile_torch.robot.ros2.messages.TopicFields`).
    sensor : str, optional
        TactileState topics: the sensor (channel) to read; default the only one.
    msg_defs : sequence of MessageDefinition
        Definitions of message types that are neither standard nor stored in the bag.
    max_messages : int
        Refuse a topic with more messages (bounded read).

    Returns
    -------
    BagTopic

    Raises
    ------
    MissingExtraError
        Without ``rosbags`` (the ``ros`` extra).
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        One line naming the bag: not a bag, no such topic, a topic of another type, fewer than 2
        messages, more than ``max_messages`` messages or :data:`MAX_BAG_BYTES` bytes, maps that do
        not match ``shape``, a message that does not give the values (an image encoding other than
        32FC1/mono16/mono8, a missing sensor or field), stamps that do not increase, non-finite values.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such bag")
    Reader = _rosbags()
    from rosbags.rosbag2 import ReaderError

    try:
        reader = Reader(path)
        reader.open()
    except (ReaderError, KeyError, ValueError, OSError) as err:
        raise ValueError(f"{path}: not a readable ROS 2 bag ({' '.join(str(err).split())})") from None
    try:
        topics = {c.topic: c.msgtype for c in reader.connections}
        topic = _pick_topic(path, topics, topic, field)
        connections = [c for c in reader.connections if c.topic == topic]
        msgtype = topics[topic]
        fields = TopicFields(msgtype, field, sensor)
        try:
            decoder = MessageDecoder(fields, _types_for(path, topic, msgtype, connections[0], msg_defs))
        except ValueError as err:
            if str(err).startswith(str(path)):
                raise
            raise ValueError(f"{path}:{topic}: {err}") from None
        declared = sum(c.msgcount for c in connections)
        if declared > max_messages:
            raise ValueError(
                f"{path}:{topic}: {declared} messages, more than the {max_messages} read at most "
                "(max_messages=)"
            )
        stamps, received, values, n_bytes = [], [], [], 0
        for i, (_, at, raw) in enumerate(reader.messages(connections=connections)):
            n_bytes += len(raw)
            if i >= max_messages or n_bytes > MAX_BAG_BYTES:
                limit = f"{max_messages} messages" if i >= max_messages else f"{MAX_BAG_BYTES} bytes"
                raise ValueError(f"{path}:{topic}: more than the {limit} read at most (max_messages=)")
            try:
                reading = decoder.decode(raw)
            except ValueError as err:
                raise ValueError(f"{path}:{topic}: message {i}: {err}") from None
            if fields.kind == "frame":
                shape = _map_shape(path, topic, reading.shape, shape, len(reading.values), i)
                values.append(reading.values.reshape(shape))
            elif len(reading.values) != 3:
                raise ValueError(f"{path}:{topic}: message {i} has {len(reading.values)} values, not x, y, z")
            else:
                values.append(reading.values)
            stamps.append(reading.stamp_ns)
            received.append(at)
    except ValueError:
        raise
    except Exception as err:  # a corrupt storage file, a message that does not deserialize
        raise ValueError(f"{path}:{topic}: unreadable message ({type(err).__name__}: {err})") from None
    finally:
        reader.close()
    if len(values) < 2:
        raise ValueError(f"{path}:{topic}: {len(values)} message(s), at least 2 are needed for a recording")
    if stamps[0] is None or not any(stamps):  # no header, or a driver that leaves it unstamped
        stamps = received
    ns = np.asarray(stamps, dtype=np.int64)
    dt = np.diff(ns)
    if (dt <= 0).any():
        raise ValueError(
            f"{path}:{topic}: time stamps must strictly increase, message {int(np.argmax(dt <= 0)) + 1} does not"
        )
    array = np.stack(values).astype(np.float32)
    timing = time_base((ns - ns[0]).astype(np.float64), resolution=1.0)
    rate = rate_hz(timing.period * 1e-9, timing.period_error)
    return BagTopic(path, topic, msgtype, (ns - ns[0]) * 1e-9, array, rate, timing=timing, kind=fields.kind)


def read_bag_topic(path, options=None) -> BagTopic:
    """Read the topic of the bag ``path`` that ``options`` name (a :class:`~tactile_torch.robot.files.data_sources.DataOptions`:
    ``topic``, ``shape``, ``field``, ``sensor``, ``msg_defs``, ``max_messages``; ``None``: the defaults)."""
    return read_bag(
        path,
        getattr(options, "topic", None),
        shape=getattr(options, "shape", None),
        field=getattr(options, "field", None),
        sensor=getattr(options, "sensor", None),
        msg_defs=getattr(options, "msg_defs", ()),
        max_messages=getattr(options, "max_messages", MAX_BAG_MESSAGES),
    )


__all__ = [
    "IMU_TYPE",
    "MAX_BAG_BYTES",
    "MAX_BAG_MESSAGES",
    "READABLE_TYPES",
    "BagTopic",
    "MissingExtraError",
    "is_bag",
    "read_bag",
    "read_bag_topic",
]
