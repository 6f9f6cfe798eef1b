"""ROS 2 messages as sensor values: one decoder for bags and live topics, and its inverse.

The messages' types come from one place, the type store of
:func:`tactile_torch.robot.ros2.message_types.message_types` (rosbags' standard messages, TactileState, a robot's
own ``.msg`` text). The bag reader (:mod:`tactile_torch.robot.ros2.bags`) and the live DDS source
(:mod:`tactile_torch.robot.ros2.source`) decode a message's CDR bytes with that store and turn it into
values with one :class:`MessageDecoder`, so that ``predict`` on a bag and ``stream --ros2-topic`` read
the same numbers; :class:`MessageEncoder` writes them (``simulate-sensor --ros2-topic``, tests' bags).

What a message gives (:class:`TopicFields` says which field, and which sensor):

=====================================  ==================================================================
``sensor_msgs/msg/Imu``                ``linear_acceleration`` (m/s^2 by the message's definition) divided
                                       by 9.80665: one sample ``(3,)`` in g; time: ``header.stamp``
``std_msgs/msg/Float32MultiArray``     ``data``: one frame (``layout.dim`` gives its shape when it has two
                                       dimensions); no time in the message
``sensor_msgs/msg/Image``              one frame ``(height, width)`` from ``data``, encodings ``32FC1``,
                                       ``mono16``, ``mono8`` (values as numbers: 0-255 for mono8, 0-65535
                                       for mono16), rows ``step`` bytes apart, ``is_bigendian`` honoured;
                                       time: ``header.stamp``
``tactile_msgs/msg/TactileState``      the ``values`` of the ``sensors`` channel named ``sensor`` (the
                                       only one by default): one frame; time: ``header.stamp``
any message (``.msg`` text)            the numbers at ``field`` (a dotted path, e.g. ``hand.taxels``):
                                       one frame, or one sample of 3 values in g; time:
                                       ``header.stamp`` when the message has one
=====================================  ==================================================================

``rosbags`` is the optional extra ``ros``; this module uses it through the type store it is given.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ...validation import saturate_float32
from ..files.csv_logs import STANDARD_GRAVITY
from .message_types import (
    FLOAT_ARRAY_TYPE,
    IMAGE_TYPE,
    IMU_TYPE,
    NUMPY_DTYPES,
    STANDARD_TYPES,
    TACTILE_STATE_TYPE,
    check_field_path,
    default_message,
    has_header,
    has_type,
)

IMAGE_ENCODINGS = {"32FC1": np.dtype(np.float32), "mono16": np.dtype(np.uint16), "mono8": np.dtype(np.uint8)}
"""``sensor_msgs/msg/Image`` encodings read as frames, and the numbers each pixel holds."""


ALL_SENSORS = "all"
""":attr:`TopicFields.sensor` that reads every sensor of a ``TactileState`` (a hand: one stream per sensor)."""


class MessageError(ValueError):
    """A message that does not give the values asked for (a field missing, a frame of another size)."""


@dataclass(frozen=True)
class TopicFields:
    """Which values a topic's messages give.

    Attributes
    ----------
    msgtype : str
        The message type, ``pkg/msg/Name``.
    field : str or None
        A dotted path to the field holding the numbers (needed for any type but
        :data:`STANDARD_TYPES`; it overrides their default field).
    sensor : str or None
        ``TactileState``: the name of the sensor (channel) to read; ``None``: the only one;
        :data:`ALL_SENSORS` (``"all"``): every one (:meth:`MessageDecoder.decode_sensors`).
    """

    msgtype: str
    field: str | None = None
    sensor: str | None = None

    @property
    def kind(self) -> str:
        """``"imu"`` for IMU messages (one sample per message), ``"frame"`` for the others."""
        return "imu" if self.msgtype == IMU_TYPE and self.field is None else "frame"

    def describe(self) -> str:
        """How the values are read, for messages: ``tactile_msgs/msg/TactileState, sensor 'tip'``."""
        what = self.msgtype
        if self.field:
            what += f", field {self.field}"
        if self.sensor:
            what += f", sensor {self.sensor!r}"
        return what


class MessageValues(NamedTuple):
    """The values of one message.

    Attributes
    ----------
    stamp_ns : int or None
        ``header.stamp`` in nanoseconds; ``None`` when the message has no header.
    values : ndarray, float32
        ``(3,)`` in g for an IMU message; a frame's numbers, flat and row-major, otherwise.
    shape : (int, int) or None
        The frame's own shape when the message gives one (an image, a two-dimensional layout).
    """

    stamp_ns: int | None
    values: np.ndarray
    shape: tuple[int, int] | None = None


class MessageDecoder:
    """Turn a topic's messages (CDR bytes or decoded) into :class:`MessageValues` tuples.

    Parameters
    ----------
    fields : TopicFields
        The type, and the field or sensor to read.
    store : rosbags type store
        From :func:`message_types`; it must know ``fields.msgtype``.

    Raises :class:`MessageError` (a ``ValueError``) for a message that does not give the values:
    a field that is missing or holds no numbers, an image encoding not in :data:`IMAGE_ENCODINGS`, a
    sensor that is not in the message, non-finite values.
    """

    def __init__(self, fields: TopicFields, store) -> None:
        if not has_type(store, fields.msgtype):
            raise ValueError(
                f"no definition of the message type {fields.msgtype}: give its .msg text with msg_defs=; "
                f"known here are the standard ROS 2 messages and {TACTILE_STATE_TYPE}"
            )
        if fields.msgtype not in STANDARD_TYPES and not fields.field:
            raise ValueError(
                f"{fields.msgtype} is not one of the standard types ({', '.join(STANDARD_TYPES)}): name the "
                "field that holds the numbers with field=, a dotted path such as taxels.values"
            )
        if fields.field:
            check_field_path(store, fields.msgtype, fields.field)
        if fields.sensor is not None and fields.msgtype != TACTILE_STATE_TYPE:
            raise ValueError(
                f"sensor= names a sensor of {TACTILE_STATE_TYPE} messages, not of {fields.msgtype}"
            )
        if fields.sensor == ALL_SENSORS and fields.field:
            raise ValueError(
                f"sensor='{ALL_SENSORS}' reads every sensor of a {TACTILE_STATE_TYPE}: give no field="
            )
        self.fields = fields
        self.store = store
        self._path = fields.field.split(".") if fields.field else None
        self._stamped = has_header(store, fields.msgtype)

    def _message(self, cdr: bytes | memoryview):
        try:
            return self.store.deserialize_cdr(cdr, self.fields.msgtype)
        except Exception as err:  # rosbags raises assorted errors on bytes that do not decode
            raise MessageError(
                f"a message that does not decode as {self.fields.msgtype} ({type(err).__name__})"
            ) from None

    def decode(self, cdr: bytes | memoryview) -> MessageValues:
        """Return the :class:`MessageValues` of one message's CDR bytes (with their 4-byte header)."""
        return self.values(self._message(cdr))

    def decode_sensors(self, cdr: bytes | memoryview) -> tuple[int | None, list[tuple[str, np.ndarray]]]:
        """Return ``(stamp_ns, [(sensor name, values), ...])`` of every sensor of a ``TactileState`` message.

        The values of each sensor as :meth:`decode` gives one (float, flat, in the message's order); a
        sensor whose values are not finite is left out (the message is not refused for one bad sensor).
        """
        message = self._message(cdr)
        channels = []
        for channel in message.sensors:
            values = np.asarray(channel.values, dtype=np.float64).reshape(-1)
            if np.isfinite(values).all():
                channels.append((str(channel.name), saturate_float32(values)))
        s = message.header.stamp
        return int(s.sec) * 1_000_000_000 + int(s.nanosec), channels

    def values(self, message) -> MessageValues:
        """Return the :class:`MessageValues` of one decoded message."""
        msgtype, shape = self.fields.msgtype, None
        if self._path is not None:
            values = _numbers(_follow(message, self._path), self.fields.field)
        elif msgtype == IMU_TYPE:
            a = message.linear_acceleration
            values = np.array((a.x, a.y, a.z), dtype=np.float64) / STANDARD_GRAVITY
        elif msgtype == FLOAT_ARRAY_TYPE:
            values = np.asarray(message.data, dtype=np.float32)
            dims = message.layout.dim
            shape = (int(dims[0].size), int(dims[1].size)) if len(dims) == 2 else None
        elif msgtype == IMAGE_TYPE:
            values = _image(message)
            shape = (int(message.height), int(message.width))
        else:
            values = _channel(message.sensors, self.fields.sensor)
        values = np.asarray(values, dtype=np.float64).reshape(-1)
        if not np.isfinite(values).all():
            raise MessageError(f"a {msgtype} message holds NaN/inf values")
        values = saturate_float32(values)  # 1e308 reads as beyond the sensor's range, not as inf
        stamp = None
        if self._stamped:
            s = message.header.stamp
            stamp = int(s.sec) * 1_000_000_000 + int(s.nanosec)
        return MessageValues(stamp, values, shape)


class MessageEncoder:
    """Turn values into the CDR bytes of a topic's messages: the inverse of :class:`MessageDecoder`.

    What ``simulate-sensor --ros2-topic`` publishes, and how the tests write bags: IMU samples in g
    become ``linear_acceleration`` in m/s^2 (orientation and angular velocity marked as not given,
    covariance element 0 set to -1, as ``sensor_msgs/msg/Imu`` prescribes); a frame ``(H, W)``
    becomes a ``Float32MultiArray`` (layout ``height``, ``width``), an ``Image`` of ``encoding``, the
    one sensor ``sensor`` (default ``"tactile"``) of a ``TactileState``, or the numbers at
    ``fields.field`` of any other message, whose other fields keep their zero values. Messages with a
    header get ``stamp_ns`` and ``frame_id``.

    Parameters
    ----------
    fields : TopicFields
    store : rosbags type store
    encoding : {"32FC1", "mono16", "mono8"}
        Images only. ``mono16`` and ``mono8`` take whole numbers in their range.
    frame_id : str
        The headers' ``frame_id``.
    """

    def __init__(self, fields: TopicFields, store, *, encoding: str = "32FC1", frame_id: str = "") -> None:
        MessageDecoder(fields, store)  # the same checks: a known type, a field path that exists
        if encoding not in IMAGE_ENCODINGS:
            raise ValueError(f"encoding must be one of {tuple(IMAGE_ENCODINGS)}, got {encoding!r}")
        self.fields = fields
        self.store = store
        self.encoding = encoding
        self.frame_id = str(frame_id)
        self._path = fields.field.split(".") if fields.field else None

    def encode(self, values: np.ndarray, stamp_ns: int = 0) -> bytes:
        """Return the CDR bytes (with their header) of one message holding ``values`` and stamped ``stamp_ns``."""
        msgtype, t = self.fields.msgtype, self.store.types
        values = np.asarray(values)
        message = default_message(self.store, msgtype)
        if self._path is not None:
            _assign(self.store, message, msgtype, self._path, values)
        elif msgtype == IMU_TYPE:
            a = np.asarray(values, dtype=np.float64).reshape(3) * STANDARD_GRAVITY
            message.linear_acceleration = t["geometry_msgs/msg/Vector3"](x=a[0], y=a[1], z=a[2])
            message.orientation.w = 1.0
            message.orientation_covariance[0] = -1.0  # no orientation estimate (sensor_msgs/msg/Imu)
            message.angular_velocity_covariance[0] = -1.0  # no angular velocity
        elif msgtype == FLOAT_ARRAY_TYPE:
            h, w = values.shape if values.ndim == 2 else (len(values.reshape(-1)), 1)
            dim = t["std_msgs/msg/MultiArrayDimension"]
            message.layout.dim = [
                dim(label="height", size=h, stride=h * w),
                dim(label="width", size=w, stride=w),
            ]
            message.data = values.astype(np.float32).reshape(-1)
        elif msgtype == IMAGE_TYPE:
            if values.ndim != 2:
                raise ValueError(f"an Image holds a frame (H, W), got values of shape {values.shape}")
            dtype = IMAGE_ENCODINGS[self.encoding]
            if dtype.kind == "u" and (
                (values != np.round(values)).any() or values.min() < 0 or values.max() > np.iinfo(dtype).max
            ):
                raise ValueError(
                    f"a {self.encoding} Image holds whole numbers in 0..{np.iinfo(dtype).max}, got values in "
                    f"{values.min():g}..{values.max():g}"
                )
            pixels = values.astype(dtype.newbyteorder("<"))
            message.height, message.width = values.shape
            message.encoding, message.is_bigendian = self.encoding, 0
            message.step = values.shape[1] * dtype.itemsize
            message.data = np.frombuffer(pixels.tobytes(), dtype=np.uint8)
        else:
            channel = t["sensor_msgs/msg/ChannelFloat32"]
            message.sensors = [
                channel(name=self.fields.sensor or "tactile", values=values.astype(np.float32).reshape(-1))
            ]
        if has_header(self.store, msgtype):
            message.header.stamp.sec, message.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
            message.header.frame_id = self.frame_id
        return bytes(self.store.serialize_cdr(message, msgtype))


def encode_sensors(
    store, channels: list[tuple[str, np.ndarray]], stamp_ns: int = 0, *, frame_id: str = ""
) -> bytes:
    """Return the CDR bytes of one ``TactileState`` holding several sensors' frames: ``[(name, frame), ...]``.

    What a hand's driver publishes, and what the tests and the benchmark play to ``stream --sensor all``.
    """
    t = store.types
    message = default_message(store, TACTILE_STATE_TYPE)
    channel = t["sensor_msgs/msg/ChannelFloat32"]
    message.sensors = [
        channel(name=str(name), values=np.asarray(frame, dtype=np.float32).reshape(-1))
        for name, frame in channels
    ]
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
    message.header.frame_id = frame_id
    return bytes(store.serialize_cdr(message, TACTILE_STATE_TYPE))


def _assign(store, message, msgtype: str, path: list[str], values: np.ndarray) -> None:
    from rosbags.typesys.base import Nodetype

    for part in path[:-1]:
        msgtype = dict(store.fielddefs[msgtype][1])[part][1]
        message = getattr(message, part)
    kind, arg = dict(store.fielddefs[msgtype][1])[path[-1]]
    if (
        kind not in (Nodetype.ARRAY, Nodetype.SEQUENCE)
        or arg[0][0] != Nodetype.BASE
        or arg[0][1][0] == "string"
    ):
        raise ValueError(f"{msgtype}.{path[-1]} is not an array of numbers, so it cannot hold a frame")
    flat = values.reshape(-1).astype(NUMPY_DTYPES[arg[0][1][0]])
    if kind == Nodetype.ARRAY and len(flat) != arg[1]:
        raise ValueError(f"{msgtype}.{path[-1]} holds {arg[1]} numbers, got {len(flat)}")
    setattr(message, path[-1], flat)


def _follow(message, path: list[str]):
    value = message
    for part in path:
        value = getattr(value, part)
    return value


def _numbers(value, field: str) -> np.ndarray:
    if isinstance(value, (bytes, bytearray, memoryview)):
        return np.frombuffer(value, dtype=np.uint8)
    array = np.asarray(value)
    if array.dtype.kind not in "biuf":
        raise MessageError(f"the field {field} holds {type(value).__name__} values, not numbers")
    return array


def _image(message) -> np.ndarray:
    encoding = str(message.encoding)
    dtype = IMAGE_ENCODINGS.get(encoding)
    if dtype is None:
        raise MessageError(
            f"an Image of encoding {encoding!r}; frames are read from {', '.join(IMAGE_ENCODINGS)} images"
        )
    h, w, step = int(message.height), int(message.width), int(message.step)
    data = (
        np.frombuffer(message.data, dtype=np.uint8)
        if not isinstance(message.data, np.ndarray)
        else message.data
    )
    row = w * dtype.itemsize
    if step < row or len(data) < h * step or h == 0 or w == 0:
        raise MessageError(
            f"an Image of {h} x {w} {encoding} with step {step} holds {len(data)} bytes, not the {h} x {max(step, row)} needed"
        )
    rows = np.ascontiguousarray(np.asarray(data, dtype=np.uint8)[: h * step].reshape(h, step)[:, :row])
    return rows.view(dtype.newbyteorder(">" if message.is_bigendian else "<")).reshape(h, w)


def _channel(sensors, name: str | None) -> np.ndarray:
    names = [str(s.name) for s in sensors]
    if name is None:
        if len(sensors) != 1:
            raise MessageError(
                f"a TactileState of {len(sensors)} sensors ({', '.join(map(repr, names)) or 'none'}): choose one "
                f"with sensor=NAME, or read every one with sensor={ALL_SENSORS}"
            )
        return sensors[0].values
    try:
        return sensors[names.index(name)].values
    except ValueError:
        raise MessageError(
            f"a TactileState without the sensor {name!r}; its sensors: {', '.join(map(repr, names)) or 'none'}"
        ) from None


__all__ = [
    "ALL_SENSORS",
    "IMAGE_ENCODINGS",
    "MessageDecoder",
    "MessageEncoder",
    "MessageError",
    "MessageValues",
    "TopicFields",
    "encode_sensors",
]
