"""Publish on ROS 2 topics over DDS: a recording as a sensor would (``simulate-sensor``), and the stream's decisions.

:func:`publish_recording` writes samples or frames as messages of a topic at their recorded rate (what
``tactile-torch simulate-sensor --ros2-topic`` does, and what the tests replay real grasps with);
:class:`DecisionPublisher` is the output hook of ``tactile-torch stream --ros2-topic`` that publishes
each decision.

The decision topic's type is ``std_msgs/msg/String`` holding the JSON object the stream prints with
``--json`` (one line, strict JSON): every ROS 2 installation has ``std_msgs``, so ``ros2 topic echo``
shows it and any node reads it without a custom package, and the JSON carries everything a decision
has (label, name, score and scores, the touch's start and duration, the frames used, latency, flags,
whether it was an early decision), which no standard message type holds (``diagnostic_msgs`` has
strings only, ``vision_msgs`` is not part of a base installation). A consumer parses ``data`` with any
JSON parser, exactly as it parses the stream's stdout.

Runs on the robot: numpy, ``cyclonedds`` and ``rosbags`` (the extra ``ros2``), imported inside functions.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from .dds import DECISION_DEPTH, DdsNode, DdsTypes
from .message_types import STRING_TYPE
from .messages import MessageEncoder

SETTLE_S = 0.25
"""Seconds a publisher waits after it matched a subscriber before it writes: the subscriber matches the
publisher on its own side a moment later, and a best-effort message written before that is lost."""


def decision_topic(topic: str) -> str:
    """Return the default topic of the decisions about ``topic``: ``<topic>/decision``.

    >>> decision_topic("/hand/tactile")
    '/hand/tactile/decision'
    """
    return topic.rstrip("/") + "/decision"


class DecisionPublisher:
    """Publish each result of a stream as ``std_msgs/msg/String`` JSON on a ROS 2 topic (an output hook).

    Parameters
    ----------
    node : DdsNode
    topic : str
        The decision topic, e.g. ``/hand/tactile/decision``.
    types : DdsTypes
    to_json : callable
        One result -> its JSON line (``result_json`` of the stream).

    The writer is reliable and volatile and keeps the last :data:`~tactile_torch.robot.ros2.dds.DECISION_DEPTH`
    decisions for subscribers that acknowledge late; a best-effort subscriber (``ros2 topic echo``'s
    default for a sensor topic) matches it too.
    """

    def __init__(self, node: DdsNode, topic: str, types: DdsTypes, to_json: Callable[[object], str]) -> None:
        self.topic = topic
        self._types = types
        self._writer = node.writer(topic, STRING_TYPE, types, profile="reliable", depth=DECISION_DEPTH)
        self._to_json = to_json
        self.published = 0

    def publish(self, text: str) -> None:
        """Publish one string."""
        message = self._types.store.types[STRING_TYPE](data=text)
        cdr = self._types.store.serialize_cdr(message, STRING_TYPE)
        self._writer.write(self._types.sample(STRING_TYPE, cdr))
        self.published += 1

    def __call__(self, result) -> None:
        self.publish(self._to_json(result))

    def summary_note(self) -> str:
        """What the stream's summary line adds: how many decisions were published where."""
        return f"{self.published} decisions published on {self.topic}"

    def subscribers(self) -> int:
        """Return how many subscribers of the decision topic are matched now."""
        return int(self._writer.get_publication_matched_status().current_count)


def wait_for_subscriber(
    writer,
    timeout_s: float,
    *,
    settle_s: float = SETTLE_S,
    sleep=time.sleep,
    clock: Callable[[], float] = time.monotonic,
) -> bool:
    """Wait until ``writer`` has matched a subscriber (then :data:`SETTLE_S` more); return whether one came."""
    deadline = clock() + timeout_s
    while writer.get_publication_matched_status().current_count == 0:
        if clock() >= deadline:
            return False
        sleep(0.01)
    sleep(settle_s)
    return True


def linger(
    writer, profile: str, *, timeout_s: float = 5.0, sleep: Callable[[float], None] = time.sleep
) -> None:
    """Let the last messages reach the subscribers before ``writer`` (or its participant) is deleted.

    A subscriber that learns that a writer left before its last messages arrived drops them (they
    travel on another socket than the discovery notice): a reliable writer waits until its
    subscribers acknowledged everything (up to ``timeout_s``), a best-effort one waits
    :data:`SETTLE_S`.
    """
    if profile != "sensor":
        from cyclonedds.util import duration

        writer.wait_for_acks(duration(seconds=timeout_s))
    else:
        sleep(SETTLE_S)


def publish_recording(
    writer,
    types: DdsTypes,
    encoder: MessageEncoder,
    values: np.ndarray,
    *,
    rate_hz: float,
    t: np.ndarray | None = None,
    start: int = 0,
    stop: int | None = None,
    realtime: bool = True,
    stamp0_ns: int | None = None,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Write ``values[start:stop]`` as messages of ``writer``'s topic; return how many were written.

    Parameters
    ----------
    writer : DataWriter
        From :meth:`DdsNode.writer`, of the type ``encoder`` writes.
    types : DdsTypes
    encoder : MessageEncoder
    values : ndarray
        ``(n, 3)`` samples in g (IMU) or ``(n, H, W)`` frames.
    rate_hz : float
        Item ``i`` is stamped ``stamp0_ns + i / rate_hz`` (whatever ``start`` is, so that a recording
        published in parts keeps one clock) and, with ``realtime``, written at that pace.
    t : ndarray of shape (n,), optional
        Each item's time in seconds (a recording's own clock, irregular steps kept): stamps
        ``stamp0_ns + (t[i] - t[0])`` and pace instead of ``i / rate_hz``.
    realtime : bool
        Pace the messages at ``rate_hz`` (on an absolute schedule, so that delays do not add up);
        ``False``: as fast as the writer takes them.
    stamp0_ns : int, optional
        The stamp of item 0 (default: now, Unix time).
    """
    if not rate_hz > 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz!r}")
    stop = len(values) if stop is None else min(int(stop), len(values))
    stamp0 = time.time_ns() if stamp0_ns is None else int(stamp0_ns)
    msgtype = encoder.fields.msgtype
    offsets = np.arange(len(values)) / rate_hz if t is None else np.asarray(t, dtype=np.float64) - float(t[0])
    began = clock()
    for i in range(start, stop):
        if realtime:
            wait = began + (offsets[i] - offsets[start]) - clock()
            if wait > 0:
                sleep(wait)
        cdr = encoder.encode(values[i], stamp0 + round(offsets[i] * 1e9))
        writer.write(types.sample(msgtype, cdr))
    return max(stop - start, 0)


__all__ = [
    "SETTLE_S",
    "DecisionPublisher",
    "decision_topic",
    "linger",
    "publish_recording",
    "wait_for_subscriber",
]
