"""Read one ROS 2 topic over DDS: its messages as they arrive, what DDS says was lost, who publishes it.

:class:`TopicReader` is the data reader under :class:`~tactile_torch.robot.ros2.source.Ros2Source` (and the
tests' and benchmark's listeners): it takes every queued message at once (so that those the queue had no
room for come after all it returns), reads DDS's sample-rejected and sample-lost statuses, the matched
publications and the QoS policy that refused one; :func:`discover_type` finds a topic's type from its
publishers, as ``ros2 topic echo`` does. ``cyclonedds`` (the extra ``ros2``) is imported inside.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from .dds import CdrSample, DdsNode, DdsTypes, instance_handle, qos, ros_type_of


@dataclass(frozen=True)
class Received:
    """One message taken from a topic.

    Attributes
    ----------
    cdr : bytes
        The message's CDR bytes, with their 4-byte encapsulation header (decode them with
        :meth:`tactile_torch.robot.ros2.messages.MessageDecoder.decode`).
    source_ns : int
        When the publisher wrote it (its clock, Unix nanoseconds).
    publisher : int
        The handle of the writer that sent it.
    """

    cdr: bytes
    source_ns: int
    publisher: int


class TopicReader:
    """Read one ROS 2 topic of a :class:`DdsNode`: the messages as they arrive, what was lost, who publishes them.

    Parameters
    ----------
    node : DdsNode
    topic : str
        The ROS 2 topic, e.g. ``/hand/tactile``.
    msgtype : str
        Its message type (:func:`discover_type` finds it from a publisher).
    types : DdsTypes
    profile : {"sensor", "lossless"}, optional
        The reader's QoS (default: the node's; :func:`qos`).
    """

    def __init__(
        self, node: DdsNode, topic: str, msgtype: str, types: DdsTypes, *, profile: str | None = None
    ) -> None:
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState, WaitSet
        from cyclonedds.sub import DataReader

        self.topic = topic
        self.msgtype = msgtype
        self.depth = int(node.options.depth)
        self.reader = DataReader(
            node.participant,
            node.topic(topic, msgtype, types),
            qos=qos(profile or node.options.qos, self.depth),
        )
        self._waitset = WaitSet(node.participant)
        self._condition = ReadCondition(self.reader, SampleState.Any | ViewState.Any | InstanceState.Any)
        self._waitset.attach(self._condition)
        self._incompatible = self._rejected = self._lost = 0
        self.reliable = (profile or node.options.qos) != "sensor"
        node._entities.insert(0, self.reader)

    def take(self, timeout_s: float) -> list[Received]:
        """Return every message queued (in the order they arrived), waiting up to ``timeout_s`` for the first.

        Everything queued is taken at once, so that messages the queue had no room for (:meth:`losses`)
        come after all those returned.
        """
        from cyclonedds.util import duration

        samples = self.reader.take(self.depth)
        if not samples and timeout_s > 0:
            self._waitset.wait(duration(seconds=timeout_s))
            samples = self.reader.take(self.depth)
        return [
            Received(s.cdr, s.sample_info.source_timestamp, instance_handle(s.sample_info.publication_handle))
            for s in samples
            if isinstance(s, CdrSample)  # not the notices of a writer that left (no data)
        ]

    def losses(self) -> tuple[int, int]:
        """Return the messages lost since the last call: ``(rejected, lost)``.

        ``rejected``: the queue was full when they arrived (the stream did not keep up); a best-effort
        message refused so is gone, a reliable one is sent again (not counted). ``lost``: DDS saw them
        go missing on the way (best effort: a gap in the writer's sequence; reliable: a publisher whose
        history no longer held them).
        """
        rejected = 0 if self.reliable else int(self.reader.get_sample_rejected_status().total_count)
        lost = int(self.reader.get_sample_lost_status().total_count)
        new = (rejected - self._rejected, lost - self._lost)
        self._rejected, self._lost = rejected, lost
        return new

    def publishers(self) -> int:
        """Return how many publishers of the topic are matched now."""
        return int(self.reader.get_subscription_matched_status().current_count)

    def matched(self) -> list[int]:
        """Return the handles of the publications matched now (:attr:`Received.publisher` of their messages)."""
        return [instance_handle(h) for h in self.reader.get_matched_publications()]

    def incompatible(self) -> int | None:
        """Return the id of the QoS policy that refused a publisher since the last call, ``None`` if none did.

        :data:`RELIABILITY_POLICY` (a best-effort publisher for a lossless reader), :data:`TYPE_POLICIES`
        (a publisher of another message type on the topic), or another DDS policy id.
        """
        status = self.reader.get_requested_incompatible_qos_status()
        total = int(status.total_count)
        new, self._incompatible = total > self._incompatible, total
        return int(status.last_policy_id) if new else None


RELIABILITY_POLICY = 11
"""DDS's id of the reliability QoS policy (a best-effort publisher refused by a reliable reader)."""
TYPE_POLICIES = (23, 24)
"""DDS's ids of the data-representation and type-consistency policies: a publisher of another type."""


def discover_type(
    node: DdsNode,
    topic: str,
    *,
    timeout_s: float,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> str | None:
    """Return the ROS 2 message type of the first publication of ``topic`` seen within ``timeout_s``, else ``None``.

    Raises ``ValueError`` when the topic's publications are not ROS 2 messages or disagree.
    """
    deadline = clock() + timeout_s
    while True:
        names = node.publications(topic)
        if names:
            types = {ros_type_of(n) for n in names}
            if None in types or len(types) > 1:
                raise ValueError(
                    f"the publishers of {topic} offer the DDS types {', '.join(names)}, not one ROS 2 message type"
                )
            return types.pop()
        if clock() >= deadline:
            return None
        sleep(0.05)


__all__ = ["RELIABILITY_POLICY", "TYPE_POLICIES", "Received", "TopicReader", "discover_type"]
