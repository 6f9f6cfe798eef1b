"""The ROS 2 source of a live stream: a topic's messages over Cyclone DDS, decoded into samples or frames.

:class:`Ros2Source` is the :class:`~tactile_torch.robot.stream.source.Source` of ``tactile-torch stream
--ros2-topic``: it subscribes to the topic (its type given, or found from the first publisher), decodes
each message with :class:`~tactile_torch.robot.ros2.messages.MessageDecoder` (the decoder the bag reader
uses) and handles the publisher the way the serial source handles its port:

==============================================  ==================================================
the publisher                                   the stream
==============================================  ==================================================
appears late (or not at all)                    waits, ``waiting`` events, :class:`StreamTimeout`
                                                after the start timeout
pauses (matched, but sends nothing)             a ``silence`` event and a break after
                                                ``silence_s``; ``resumed`` when messages come back;
                                                :class:`StreamTimeout` after the idle timeout
leaves (its writer or process ends; a killed    ``disconnected``: :class:`StreamDisconnected`, or
process is seen when its DDS lease ends, 10 s   with ``reconnect`` a wait for a publisher until the
by Cyclone DDS's default)                       idle timeout, ``reconnected`` and a break when one
                                                matches again
offers a QoS the reader cannot match (best      one ``qos`` event naming the fix
effort for ``qos="reliable"``)
sends a message that does not give an item      skipped and counted, a ``skipped`` event with the
(another size, an unknown image encoding, a     reason (five a second at most); one larger than
missing sensor)                                 :data:`MIN_MESSAGE_BOUND` or 16 times an item's values
                                                at 8 bytes each is not even decoded
sends values outside the item's range           rejected, a ``range`` event and a break
==============================================  ==================================================

An item's time ``t`` is the message's ``header.stamp``, from which the stream sees lost messages (a
step of more than 1.5 periods); a message without a header (``Float32MultiArray``), or whose stamp is
zero (a driver that does not stamp), has no ``t``, as a serial line without one: the publisher's write
time is no sensor clock (a publisher that stalls would look like lost frames), so only silences break
such a stream.
``cyclonedds`` and ``rosbags`` (the extra ``ros2``) are imported when a :class:`Ros2Source` is made (it
joins the DDS domain then; :meth:`Ros2Source.close` leaves it).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence

from ..stream.port_lines import StreamDisconnected, StreamEvent, StreamTimeout
from ..stream.source import (
    RECONNECT,
    REJECTED,
    SAMPLE,
    SILENCE,
    Break,
    EventEmitter,
    ItemSpec,
    Reading,
    SourceCounts,
)
from .dds import DdsNode, DdsOptions, DdsTypes, TopicReader, discover_type
from .message_types import IMU_TYPE, MessageDefinition, message_types
from .messages import MessageDecoder, MessageError, TopicFields

_POLL_S = 0.05  # longest wait for a message before the silence, timeout and publisher checks run
MIN_MESSAGE_BOUND = 64 * 1024
"""A message larger than ``max(MIN_MESSAGE_BOUND, 16 * 8 * values per item)`` bytes is skipped undecoded."""


def _giving_up(limit: float) -> str:
    return "no time limit" if math.isinf(limit) else f"giving up after {limit:g} s"


class Ros2Source:
    """Samples or frames from a ROS 2 topic over DDS (a :class:`~tactile_torch.robot.stream.source.Source`).

    Parameters
    ----------
    topic : str
        The ROS 2 topic, e.g. ``/hand/tactile``.
    spec : ItemSpec
        What an item is (a sample ``(3,)`` in g, a frame ``(H, W)``) and its accepted range.
    fields : TopicFields, optional
        The message type and the field or sensor to read; ``msgtype`` ``None`` (or no ``fields``)
        takes the type of the first publisher.
    msg_defs : sequence of MessageDefinition
        ``.msg`` text of a robot's own message types.
    dds : DdsOptions, optional
        Domain, configuration (loopback by default), QoS.
    silence_s, idle_timeout_s, start_timeout_s, reconnect, on_event, on_open, clock
        As :class:`~tactile_torch.robot.stream.serial_source.SerialSource`; ``idle_timeout_s`` ``None``
        means never (a topic has no end of input).
    node : DdsNode, optional
        A participant to use (and not close); default: one made from ``dds`` now, which
        :meth:`close` deletes.

    Attributes
    ----------
    counts : SourceCounts
        Items, messages skipped, items rejected, reconnections (publishers that came back).
    msgtype : str or None
        The topic's message type once known.
    node : DdsNode
        The DDS participant (an output hook may publish with it, e.g. the decisions).
    """

    def __init__(
        self,
        topic: str,
        spec: ItemSpec,
        *,
        fields: TopicFields | None = None,
        msg_defs: Sequence[MessageDefinition] = (),
        dds: DdsOptions | None = None,
        silence_s: float = 0.5,
        idle_timeout_s: float | None = None,
        start_timeout_s: float | None = None,
        reconnect: bool = False,
        on_event: Callable[[StreamEvent], None] | None = None,
        on_open: Callable[[str], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
        node: DdsNode | None = None,
    ) -> None:
        from .dds import dds_topic_name

        dds_topic_name(topic)  # refuse a name that is no ROS 2 topic before anything starts
        self.name = topic
        self.spec = spec
        self.fields = fields
        self.msgtype = fields.msgtype if fields is not None and fields.msgtype else None
        self.msg_defs = tuple(msg_defs)
        self.dds = dds or DdsOptions()
        self.silence_s = float(silence_s)
        self.idle_timeout_s = math.inf if idle_timeout_s is None else float(idle_timeout_s)
        self.start_timeout_s = self.idle_timeout_s if start_timeout_s is None else float(start_timeout_s)
        self.reconnect = bool(reconnect)
        self.on_open = on_open
        self.counts = SourceCounts()
        self.item = spec.kind
        self._events = EventEmitter(on_event, clock)
        self._clock = clock
        self._owns_node = node is None
        self.node = DdsNode(self.dds) if node is None else node
        self.domain_id, self.config_description = self.node.domain_id, self.node.config_description

    def close(self) -> None:
        """Leave the DDS domain (delete the participant), if this source made it."""
        if self._owns_node:
            self.node.close()

    # -- set-up ---------------------------------------------------------------------------------

    def _decoder(self, msgtype: str) -> MessageDecoder:
        fields = self.fields or TopicFields(msgtype)
        fields = TopicFields(msgtype, fields.field, fields.sensor)
        if (fields.kind == "imu") != (self.spec.kind == SAMPLE) and fields.field is None:
            what = "accelerometer samples" if self.spec.kind == SAMPLE else "frames"
            raise ValueError(
                f"{self.name} carries {msgtype}, but the bundle takes {what}: give a topic of "
                + (
                    f"{IMU_TYPE}"
                    if self.spec.kind == SAMPLE
                    else "frames (Float32MultiArray, Image, TactileState)"
                )
                + ", or the field that holds them with field="
            )
        self.fields = fields
        return MessageDecoder(fields, message_types(self.msg_defs, topic_type=msgtype))

    def _wait(self, started: float, what: str, ready: Callable[[], object]):
        """Poll ``ready()`` until it is truthy; report waiting and time out as the serial port does."""
        warned = False
        while True:
            value = ready()
            if value:
                return value
            waited = self._clock() - started
            if waited >= self.start_timeout_s:
                raise StreamTimeout(
                    f"{self.name}: no {what} for {waited:.1f} s (timeout {self.start_timeout_s:g} s); 0 "
                    f"{self.item}s read"
                )
            if waited >= self.silence_s and not warned:
                warned = True
                self._events.emit(
                    "waiting",
                    f"no {what} yet on {self.name} (domain {self.domain_id}) after {waited:.1f} s "
                    f"({_giving_up(self.start_timeout_s)})",
                )

    # -- reading --------------------------------------------------------------------------------

    def readings(self) -> Iterator[Reading | Break]:
        """Yield a :class:`Reading` per accepted message and a :class:`Break` where continuity is lost."""
        yield from self._read(self.node)

    def _read(self, node: DdsNode) -> Iterator[Reading | Break]:
        clock, spec, counts, emit = self._clock, self.spec, self.counts, self._events.emit
        started = clock()
        if self.msgtype is None:  # a ROS 2 tool finds the type from the publisher
            self.msgtype = self._wait(
                started,
                "publisher",
                lambda: discover_type(node, self.name, timeout_s=min(_POLL_S, self.start_timeout_s)),
            )
        decoder = self._decoder(self.msgtype)
        reader = TopicReader(node, self.name, self.msgtype, DdsTypes(decoder.store))
        if self.on_open is not None:
            self.on_open(self.name)
        shape, size, sample = tuple(spec.shape), spec.size, spec.kind == SAMPLE
        bound = max(MIN_MESSAGE_BOUND, 16 * 8 * size)
        frame_shape = shape[:2]
        check, in_range = spec.checks_range, spec.in_range
        last_item = clock()  # time counts from when the reader is there, as from a port's opening
        silent = had_publisher = False
        fresh = False  # readings since the last break: a break with none is no news to the segmenter
        gone_at: float | None = None
        while True:
            batch = reader.take(_POLL_S)
            now = clock()
            for received in batch:
                try:
                    if len(received.cdr) > bound:  # bounded: a huge message is not decoded
                        raise MessageError(
                            f"a message of {len(received.cdr)} bytes, more than the {bound} read at most"
                        )
                    stamp, values, own_shape = decoder.decode(received.cdr)
                    if len(values) != size or (
                        own_shape is not None and own_shape != frame_shape and not sample
                    ):
                        got = f"{own_shape[0]} x {own_shape[1]}" if own_shape else f"{len(values)} values"
                        raise MessageError(
                            f"a message of {got}, not the {' x '.join(map(str, shape))} the bundle takes"
                        )
                except MessageError as err:
                    counts.skipped += 1
                    emit("skipped", f"{self.name}: {err}; skipped", repeated=True)
                    continue
                t = stamp * 1e-9 if stamp else None
                if check and not in_range(values):
                    counts.rejected += 1
                    emit(
                        "range",
                        f"a {self.item} out of the sensor's range {spec.describe_range()} was rejected: "
                        f"{spec.describe_item(values)}",
                        repeated=True,
                    )
                    fresh = False
                    yield Break(REJECTED, now)
                    continue
                if silent or not counts.items:
                    waited = now - last_item
                    if silent and counts.items:
                        emit("resumed", f"{self.item}s again after {waited:.1f} s of silence")
                    elif waited >= self.silence_s:
                        emit("first", f"first {self.item} after {waited:.1f} s")
                    silent = False
                last_item = now
                counts.items += 1
                fresh = True
                yield Reading(tuple(values.tolist()) if sample else values.reshape(shape), t, now)
            if batch:
                continue
            publishers = reader.publishers()
            if reader.incompatible_qos():
                emit(
                    "qos",
                    f"a publisher of {self.name} offers a QoS this reader cannot match (a best-effort publisher, "
                    f"and a {self.dds.qos} reader?): read it with the sensor QoS (best effort)",
                )
            if publishers:
                if gone_at is not None:  # a publisher is back: what follows is another connection
                    counts.reconnects += 1
                    emit("reconnected", f"a publisher of {self.name} is back after {now - gone_at:.1f} s")
                    gone_at = None
                    if fresh:
                        fresh = False
                        yield Break(RECONNECT, now)
                had_publisher = True
            elif had_publisher and gone_at is None:
                if not self.reconnect:
                    raise StreamDisconnected(
                        f"{self.name}: the publisher left after {counts.items} {self.item}s"
                    )
                gone_at = now
                emit(
                    "disconnected",
                    f"{self.name}: the publisher left after {counts.items} {self.item}s; waiting for it to come back "
                    f"({_giving_up(self.idle_timeout_s)})",
                )
                silent = True  # the departure ends the segment: no touch spans it
                if fresh:
                    fresh = False
                    yield Break(RECONNECT, now)
            waited = now - last_item
            limit = self.idle_timeout_s if counts.items else self.start_timeout_s
            if waited >= limit:
                if gone_at is not None:
                    raise StreamDisconnected(
                        f"{self.name}: gave up waiting for a publisher, {waited:.1f} s without a {self.item} "
                        f"(idle timeout {limit:g} s)"
                    )
                what = (
                    f"no valid {self.item}"
                    if counts.skipped
                    else "no data"
                    if not counts.items
                    else f"no {self.item}"
                )
                raise StreamTimeout(
                    f"{self.name}: {what} for {waited:.1f} s (timeout {limit:g} s); {counts.items} {self.item}s "
                    f"read, {counts.skipped} messages skipped"
                )
            if waited >= self.silence_s and not silent and gone_at is None:
                silent = True
                if counts.items:
                    emit(
                        "silence",
                        f"no {self.item} for {waited:.1f} s after {counts.items} {self.item}s; waiting "
                        f"({_giving_up(limit)})",
                    )
                    if fresh:
                        fresh = False
                        yield Break(SILENCE, now)
                elif not had_publisher:
                    emit(
                        "waiting",
                        f"no matching publisher yet on {self.name} (domain {self.domain_id}) after {waited:.1f} s "
                        f"({_giving_up(limit)})",
                    )


__all__ = ["MIN_MESSAGE_BOUND", "Ros2Source"]
