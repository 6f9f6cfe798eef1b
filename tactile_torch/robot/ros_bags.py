"""ROS 2 bags (rosbag2, sqlite3 or MCAP storage) as recordings, read with the pure-Python ``rosbags``.

``rosbags`` is the optional extra ``ros`` (``pip install 'tactile-torch[ros]'``); nothing else in
tactile-torch needs it, and the robot runtime never does. Two kinds of topic are read:

==================================  ============================================================
``sensor_msgs/msg/Imu``             ``linear_acceleration`` (m/s^2 by the message's definition)
                                    divided by 9.80665 → a triaxial recording in g; time from
                                    each message's ``header.stamp``
``std_msgs/msg/Float32MultiArray``  one pressure map per message, ``H x W`` taxels (``shape=``,
                                    else the array's ``layout.dim`` sizes); time from the bag's
                                    receive stamps (the message has no header)
==================================  ============================================================

One bag and topic is one recording. A bag is its directory (with ``metadata.yaml``) or one of its
storage files (``.db3``, ``.mcap``). Reads are bounded: at most ``max_messages`` messages
(:data:`MAX_BAG_MESSAGES` by default) and :data:`MAX_BAG_BYTES` bytes of message data per topic;
beyond either the bag is refused in one line, before the data is held in memory.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .checks import saturate_float32
from .csv_logs import STANDARD_GRAVITY
from .sample_times import TimeBase, rate_hz, time_base

PathLike = str | os.PathLike

IMU_TYPE = "sensor_msgs/msg/Imu"
PRESSURE_TYPE = "std_msgs/msg/Float32MultiArray"
READABLE_TYPES = (IMU_TYPE, PRESSURE_TYPE)
BAG_SUFFIXES = (".db3", ".mcap")
MAX_BAG_MESSAGES = 10_000_000
"""Messages read from one topic at most (about 3.5 hours of a 800 Hz IMU)."""
MAX_BAG_BYTES = 1 << 30
"""Bytes of serialized messages read from one topic at most (1 GiB)."""
ROS_EXTRA = "ros"


class MissingExtraError(ImportError, ValueError):
    """An optional extra is not installed (an ``ImportError``; a ``ValueError`` so the CLI prints one line)."""


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
    rate_hz : float
        From the stamps: the slope of the stamps against the message index between gaps
        (:func:`tactile_torch.robot.sample_times.time_base`).
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
    try:
        from rosbags.rosbag2 import Reader
        from rosbags.typesys import Stores, get_typestore
    except ImportError as err:
        raise MissingExtraError(
            f"reading ROS 2 bags needs the optional extra {ROS_EXTRA!r} (the rosbags package), which is "
            f"not installed: pip install 'tactile-torch[{ROS_EXTRA}]'",
            name="rosbags",
        ) from err
    return Reader, get_typestore(Stores.ROS2_HUMBLE)


def _describe(topics: dict[str, str]) -> str:
    return ", ".join(f"{t} ({m})" for t, m in sorted(topics.items())) or "no topic"


def _pick_topic(path: Path, topics: dict[str, str], topic: str | None) -> str:
    readable = {t: m for t, m in topics.items() if m in READABLE_TYPES}
    if topic is None:
        if len(readable) == 1:
            return next(iter(readable))
        what = "several readable topics" if readable else "no IMU or pressure-array topic"
        raise ValueError(f"{path}: {what}; name one with topic=, the bag has {_describe(topics)}")
    if topic not in topics:
        raise ValueError(f"{path}: no topic {topic!r}; the bag has {_describe(topics)}")
    if topics[topic] not in READABLE_TYPES:
        raise ValueError(
            f"{path}: topic {topic} holds {topics[topic]}, expected {IMU_TYPE} (accelerations) or "
            f"{PRESSURE_TYPE} (pressure maps, with shape=(H, W))"
        )
    return topic


def _map_shape(path: Path, topic: str, message, shape: tuple[int, int] | None, i: int) -> tuple[int, int]:
    size = len(message.data)
    if shape is None:
        dims = [int(d.size) for d in message.layout.dim]
        if len(dims) != 2:
            raise ValueError(
                f"{path}:{topic}: message {i} has {size} values and a layout of {len(dims)} dimension(s); "
                "give the map's shape with shape=(H, W)"
            )
        shape = (dims[0], dims[1])
    if shape[0] * shape[1] != size:
        raise ValueError(
            f"{path}:{topic}: message {i} has {size} values, not the {shape[0]} x {shape[1]} of the shape"
        )
    return shape


def read_bag(
    path: PathLike,
    topic: str | None = None,
    *,
    shape: tuple[int, int] | None = None,
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
        Pressure maps: the taxel grid (default: the message layout's two dimensions).
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
        not match ``shape``, stamps that do not increase, non-finite values.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such bag")
    Reader, typestore = _rosbags()
    from rosbags.rosbag2 import ReaderError

    try:
        reader = Reader(path)
        reader.open()
    except (ReaderError, KeyError, ValueError, OSError) as err:
        raise ValueError(f"{path}: not a readable ROS 2 bag ({' '.join(str(err).split())})") from None
    try:
        topics = {c.topic: c.msgtype for c in reader.connections}
        topic = _pick_topic(path, topics, topic)
        connections = [c for c in reader.connections if c.topic == topic]
        msgtype = topics[topic]
        declared = sum(c.msgcount for c in connections)
        if declared > max_messages:
            raise ValueError(
                f"{path}:{topic}: {declared} messages, more than the {max_messages} read at most "
                "(max_messages=)"
            )
        stamps, values, n_bytes = [], [], 0
        for i, (_, received, raw) in enumerate(reader.messages(connections=connections)):
            n_bytes += len(raw)
            if i >= max_messages or n_bytes > MAX_BAG_BYTES:
                limit = f"{max_messages} messages" if i >= max_messages else f"{MAX_BAG_BYTES} bytes"
                raise ValueError(f"{path}:{topic}: more than the {limit} read at most (max_messages=)")
            message = typestore.deserialize_cdr(raw, msgtype)
            if msgtype == IMU_TYPE:
                a = message.linear_acceleration
                stamps.append(message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec)
                values.append((a.x, a.y, a.z))
            else:
                shape = _map_shape(path, topic, message, shape, i)
                stamps.append(received)
                values.append(np.asarray(message.data, dtype=np.float32).reshape(shape))
    except ValueError:
        raise
    except Exception as err:  # a corrupt storage file, a message that does not deserialize
        raise ValueError(f"{path}:{topic}: unreadable message ({type(err).__name__}: {err})") from None
    finally:
        reader.close()
    if len(values) < 2:
        raise ValueError(f"{path}:{topic}: {len(values)} message(s), at least 2 are needed for a recording")
    ns = np.asarray(stamps, dtype=np.int64)
    dt = np.diff(ns)
    if (dt <= 0).any():
        raise ValueError(
            f"{path}:{topic}: time stamps must strictly increase, message {int(np.argmax(dt <= 0)) + 1} does not"
        )
    if msgtype == IMU_TYPE:
        array = np.asarray(values, dtype=np.float64) / STANDARD_GRAVITY
    else:
        array = np.stack(values)
    if not np.isfinite(array).all():
        bad = int(np.argwhere(~np.isfinite(array.reshape(len(array), -1)))[0][0])
        raise ValueError(f"{path}:{topic}: message {bad} holds NaN/inf values")
    timing = time_base((ns - ns[0]).astype(np.float64), resolution=1.0)
    rate = rate_hz(timing.period * 1e-9, timing.period_error)
    values = saturate_float32(array) if msgtype == IMU_TYPE else array.astype(np.float32)
    return BagTopic(path, topic, msgtype, (ns - ns[0]) * 1e-9, values, rate, timing)


__all__ = [
    "IMU_TYPE",
    "MAX_BAG_BYTES",
    "MAX_BAG_MESSAGES",
    "PRESSURE_TYPE",
    "BagTopic",
    "MissingExtraError",
    "is_bag",
    "read_bag",
]
