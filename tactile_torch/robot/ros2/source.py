"""The ROS 2 source of a live stream: a topic's messages over Cyclone DDS, decoded into samples or frames.

:class:`Ros2Source` is the :class:`~tactile_torch.robot.stream.source.Source` of ``tactile-torch stream
--ros2-topic``: it subscribes to the topic (its type given, or found from the first publisher), decodes
each message with :class:`~tactile_torch.robot.ros2.messages.MessageDecoder` (the decoder the bag reader
uses) and handles the publisher the way the serial source handles its port:

==============================================  ==================================================
the publisher                                   the stream
==============================================  ==================================================
appears late (or not at all)                    waits, ``waiting`` events, :class:`StreamTimeout`
                                                after the start timeout; one that matched but
                                                whose messages do not arrive is said so
pauses (matched, but sends nothing)             a ``silence`` event after ``silence_s``; the touch
                                                in progress ends when the sensor's clock agrees;
                                                ``resumed`` when messages come back;
                                                :class:`StreamTimeout` after the idle timeout (not
                                                before its DDS lease has ended: a killed publisher
                                                is seen to leave only then)
leaves (its writer or process ends; a killed    ``disconnected`` when DDS says so:
process is seen when its DDS lease ends, 10 s   :class:`StreamDisconnected`, or with ``reconnect``
by Cyclone DDS's default)                       a wait for a publisher, for the idle timeout from
                                                then
comes back, or another starts (even before      ``reconnected`` at its first message (a new DDS
the old one's lease ended)                      writer), a break, counted in ``reconnects``
sends faster than the stream takes it           the messages its queue had no room for (best
                                                effort), or lost on the way, are counted in
                                                ``lost`` (DDS's sample-rejected and sample-lost
                                                statuses) and said; the touch there is cut
offers a QoS or a type the reader cannot match  one event naming the publisher's QoS or type
                                                and the option that reads it
sends a message that does not give an item      skipped and counted, a ``skipped`` event with the
(another size, an unknown image encoding, a     reason (five a second at most); one larger than
missing sensor)                                 :data:`MIN_MESSAGE_BOUND` or 16 times an item's
                                                values at 8 bytes each is not decoded
sends values outside the item's range           rejected, a ``range`` event and a break
==============================================  ==================================================

An item's time ``t`` is the message's ``header.stamp``, from which the stream sees lost messages (a
step of more than 1.5 periods); a message without a header (``Float32MultiArray``), or whose stamp is
zero (a driver that does not stamp), has no ``t``, as a serial line without one. Every message also
carries when its publisher wrote it (DDS's source timestamp, ``Reading.sent_at``): without ``t`` it is
the clock that silences and durations are judged by (never losses: a publisher that stalls would look
like lost frames; DDS's own counts say those). With ``fields.sensor`` ``"all"``, every sensor of a
``TactileState`` is read, one reading per sensor and message (:attr:`Ros2Source.sensors`).
``cyclonedds`` and ``rosbags`` (the extra ``ros2``) are imported when a :class:`Ros2Source` is made (it
joins the DDS domain then; :meth:`Ros2Source.close` leaves it).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence

from ..files.sample_times import describe_duration
from ..stream.port_lines import StreamDisconnected, StreamEvent, StreamTimeout
from ..stream.source import (
    LOST,
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
from .dds import DEFAULT_LEASE_S, DdsNode, DdsOptions, DdsTypes, ros_type_of
from .message_types import IMU_TYPE, MessageDefinition, message_types
from .messages import ALL_SENSORS, MessageDecoder, MessageError, TopicFields
from .reader import RELIABILITY_POLICY, TYPE_POLICIES, TopicReader, discover_type

_POLL_S = 0.05  # longest wait for a message before the silence, timeout and publisher checks run
MIN_MESSAGE_BOUND = 64 * 1024
"""A message larger than ``max(MIN_MESSAGE_BOUND, 16 * 8 * values per item)`` bytes is skipped undecoded."""


def message_bound(spec: ItemSpec) -> int:
    """Return the largest message (bytes) a source of items ``spec`` decodes; larger ones are skipped, and said."""
    return max(MIN_MESSAGE_BOUND, 16 * 8 * spec.size)


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
        Items, messages skipped, items rejected, reconnections (publishers that came back), items lost
        (DDS's counts).
    msgtype : str or None
        The topic's message type once known.
    node : DdsNode
        The DDS participant (an output hook may publish with it, e.g. the decisions).
    sensors : list of str
        With ``fields.sensor`` ``"all"``: the sensors' names, in the order they first appeared
        (a reading's ``sensor`` indexes it); empty otherwise.
    opened_at : float or None
        The clock when the reader joined the topic (what the sequencer bounds losses by).
    """

    def __init__(  # noqa: PLR0913
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
        self.sensors: list[str] = []
        self.opened_at: float | None = None
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
        clock = self._clock
        started = clock()
        if self.msgtype is None:  # a ROS 2 tool finds the type from the publisher
            self.msgtype = self._wait(
                started,
                "publisher",
                lambda: discover_type(node, self.name, timeout_s=min(_POLL_S, self.start_timeout_s)),
            )
        decoder = self._decoder(self.msgtype)
        reader = TopicReader(node, self.name, self.msgtype, DdsTypes(decoder.store))
        self.opened_at = clock()
        if self.on_open is not None:
            self.on_open(self.name)
        yield from _Reading(self, node, reader, decoder).run()


class _Reading:
    """One run of :meth:`Ros2Source.readings`: the messages, the publishers that come and go, the losses."""

    def __init__(
        self, source: Ros2Source, node: DdsNode, reader: TopicReader, decoder: MessageDecoder
    ) -> None:
        self.source, self.node, self.reader, self.decoder = source, node, reader, decoder
        spec = source.spec
        self.counts, self.emit, self.clock = source.counts, source._events.emit, source._clock
        self.shape, self.size, self.sample = tuple(spec.shape), spec.size, spec.kind == SAMPLE
        self.frame_shape = self.shape[:2]
        self.bound = message_bound(spec)
        self.all = decoder.fields.sensor == ALL_SENSORS
        self.sensor_index: dict[str, int] = {}
        self.refused: set[str] = set()  # sensors whose frames do not fit the bundle (said once)
        self.last_item = self.first_item = source.opened_at  # time counts from when the reader is there
        self.silent = self.had_publisher = self.said_quiet = False
        self.matched_at: float | None = None  # when a publisher matched while nothing was read yet
        self.fresh = False  # readings since the last break: a break with none is no news to the segmenter
        self.gone_at: float | None = None  # when DDS said the publisher left
        self.writer: int | None = None  # the publication whose messages are being read
        self.leases: dict[int, float] = {}
        self.left: set[int] = set()  # writers whose departure was said
        self.interleaved = False

    # -- the loop ----------------------------------------------------------------------------------
    def run(self) -> Iterator[Reading | Break]:
        source, reader = self.source, self.reader
        while True:
            batch = reader.take(_POLL_S)
            now = self.clock()
            before = self.counts.items
            for received in batch:
                yield from self._message(received, now)
            yield from self._losses(now)
            if (
                self.counts.items > before
            ):  # messages that gave no item (skipped) do not keep the stream alive
                continue
            yield from self._publishers(now)
            waited = now - (self.last_item if self.gone_at is None else max(self.last_item, self.gone_at))
            self._timeouts(waited)
            if waited >= source.silence_s and not self.silent and self.gone_at is None:
                self.silent = True
                yield from self._silence(waited)

    def _message(self, received, now: float) -> Iterator[Reading | Break]:
        source, counts, emit = self.source, self.counts, self.emit
        if received.publisher != self.writer:
            yield from self._writer(received.publisher, now)
        try:
            if len(received.cdr) > self.bound:  # bounded: a huge message is not decoded
                raise MessageError(
                    f"a message of {len(received.cdr)} bytes, more than the {self.bound} read at most"
                )
            if self.all:
                stamp, channels = self.decoder.decode_sensors(received.cdr)
            else:
                stamp, values, own_shape = self.decoder.decode(received.cdr)
                if len(values) != self.size or (
                    own_shape is not None and own_shape != self.frame_shape and not self.sample
                ):
                    got = f"{own_shape[0]} x {own_shape[1]}" if own_shape else f"{len(values)} values"
                    raise MessageError(
                        f"a message of {got}, not the {' x '.join(map(str, self.shape))} the bundle takes"
                    )
                channels = [(None, values)]
        except MessageError as err:
            counts.skipped += 1
            emit("skipped", f"{source.name}: {err}; skipped", repeated=True)
            return
        t = stamp * 1e-9 if stamp else None
        sent = received.source_ns * 1e-9
        if self.silent or not counts.items:
            waited = now - self.last_item
            self.first_item = now if not counts.items else self.first_item
            if self.silent and counts.items:
                emit("resumed", f"{source.item}s again after {describe_duration(waited)} of silence")
            elif waited >= source.silence_s:
                emit("first", f"first {source.item} after {waited:.1f} s")
            self.silent = False
        self.last_item = now
        for name, values in channels:
            index = 0 if name is None else self._sensor(name, len(values))
            if index is None:
                continue
            if source.spec.checks_range and not source.spec.in_range(values):
                counts.rejected += 1
                emit(
                    "range",
                    f"a {source.item}{'' if name is None else f' of sensor {name!r}'} out of the sensor's range "
                    f"{source.spec.describe_range()} was rejected: {source.spec.describe_item(values)}",
                    repeated=True,
                )
                yield Break(REJECTED, now, None if name is None else index)
                continue
            counts.items += 1
            self.fresh = True
            yield Reading(
                tuple(values.tolist()) if self.sample else values.reshape(self.shape), t, now, sent, index
            )

    def _sensor(self, name: str, size: int) -> int | None:
        """The index of a sensor of a hand (a new one is added), ``None`` when its frames do not fit the bundle."""
        index = self.sensor_index.get(name)
        if index is not None:
            return index
        if size != self.size:
            if name not in self.refused:
                self.refused.add(name)
                self.emit(
                    "skipped",
                    f"{self.source.name}: sensor {name!r} has {size} values, not the "
                    f"{' x '.join(map(str, self.shape))} the bundle takes: not read",
                )
            return None
        index = self.sensor_index[name] = len(self.source.sensors)
        self.source.sensors.append(name)
        return index

    def _writer(self, handle: int, now: float) -> Iterator[Break]:
        """The first message of another DDS writer: a publisher back (or a new one), at its first message."""
        previous, self.writer = self.writer, handle
        if previous is None:
            return
        away = self.gone_at is not None or now - self.last_item >= self.source.silence_s
        if not away:  # two publishers at once: their messages interleave (said once)
            if not self.interleaved:
                self.interleaved = True
                self.emit(
                    "publishers",
                    f"{self.source.name}: messages of more than one publisher interleave: they are read as one sensor",
                )
            return
        self.counts.reconnects += 1
        gone = self.gone_at if self.gone_at is not None else self.last_item
        still = previous in self.reader.matched()
        self.emit(
            "reconnected",
            f"a publisher of {self.source.name} is back after {now - gone:.1f} s (a new DDS writer"
            + (
                "; the one before has not left yet: it stopped without leaving, DDS will say at its lease's end)"
                if still
                else ")"
            ),
        )
        self.gone_at = None
        self.fresh = False
        yield Break(RECONNECT, now)  # another connection: nothing spans it

    def _losses(self, now: float) -> Iterator[Break]:
        rejected, lost = self.reader.losses()
        if not rejected and not lost:
            return
        per = max(1, len(self.source.sensors))  # a hand's message holds a frame of every sensor
        self.counts.lost += (rejected + lost) * per
        why = []
        if rejected:
            why.append(
                f"{rejected} found the reader's queue of {self.reader.depth} full (the stream did not keep up)"
            )
        if lost:
            why.append(f"{lost} lost on the way (DDS)")
        each = f" (a frame of each of {per} sensors)" if per > 1 else ""
        what = f"{rejected + lost} messages{each}" if per > 1 else f"{rejected + lost} {self.source.item}s"
        self.emit("lost", f"{self.source.name}: {what} lost: {'; '.join(why)}", repeated=True)
        if self.fresh:  # the touch or window in progress lacks them
            self.fresh = False
            yield Break(LOST, now)

    # -- publishers --------------------------------------------------------------------------------
    def _publishers(self, now: float) -> Iterator[Break]:
        source, reader = self.source, self.reader
        policy = reader.incompatible()
        if policy is not None:
            self._refused(policy)
        matched = reader.matched()
        for publication in self.node.publishers(source.name):
            self.leases[publication.handle] = publication.lease_s
        if matched:
            self.had_publisher = True
            if not self.counts.items and not self.counts.skipped and not self.said_quiet:
                self.matched_at = self.matched_at or now
                if now - self.matched_at >= source.silence_s:
                    self.said_quiet = True
                    self.emit("quiet", self._quiet(now - self.matched_at))
            if self.writer is not None and self.writer not in matched and self.writer not in self.left:
                self.left.add(
                    self.writer
                )  # another publisher remains: this one's departure is news, not an end
                self.emit("disconnected", f"{source.name}: the publisher of the {source.item}s before left")
            return
        if not self.had_publisher or self.gone_at is not None:
            return
        self.left.add(self.writer)
        lease = self.leases.get(self.writer, DEFAULT_LEASE_S)
        how = (
            f" (it stopped {now - self.last_item:.1f} s ago: DDS says so when its lease of {lease:g} s ends)"
            if now - self.last_item >= lease * 0.9
            else ""
        )
        if not self.counts.items and not self.counts.skipped and not self.said_quiet:
            how += f"; {self._quiet(now - (self.matched_at or now))}"
        if not source.reconnect:
            raise StreamDisconnected(
                f"{source.name}: the publisher left after {self.counts.items} {source.item}s{how}"
            )
        self.gone_at = now
        self.emit(
            "disconnected",
            f"{source.name}: the publisher left after {self.counts.items} {source.item}s{how}; waiting for it to "
            f"come back ({_giving_up(source.idle_timeout_s)})",
        )
        self.silent = True  # the departure ends the segment: no touch spans it
        if self.fresh:
            self.fresh = False
            yield Break(RECONNECT, now)

    def _refused(self, policy: int) -> None:
        """Say why DDS refused a publisher: its message type, or its QoS."""
        source = self.source
        theirs = sorted(
            {
                t
                for p in self.node.publishers(source.name)
                if (t := ros_type_of(p.type_name)) != source.msgtype and t
            }
        )
        if policy in TYPE_POLICIES or theirs:
            other = theirs[0] if theirs else "another type"
            read = f"msgtype='{theirs[0]}'" if theirs else "its type as msgtype="
            self.emit(
                "type",
                f"{source.name} is published as {other}, not {source.msgtype}: read it with {read}, or leave "
                "msgtype= out to take the publisher's type",
            )
        elif policy == RELIABILITY_POLICY:
            self.emit(
                "qos",
                f"a publisher of {source.name} is best effort, which a {source.dds.qos} reader cannot match: read it "
                "with qos='sensor' (best effort)",
            )
        else:
            self.emit(
                "qos",
                f"a publisher of {source.name} offers a QoS this reader cannot match (DDS policy {policy})",
            )

    def _timeouts(self, waited: float) -> None:
        source, counts = self.source, self.counts
        if self.gone_at is not None:
            if waited >= source.idle_timeout_s:
                raise StreamDisconnected(
                    f"{source.name}: gave up waiting for a publisher, {waited:.1f} s after the last one left "
                    f"(idle timeout {source.idle_timeout_s:g} s)"
                )
            return
        limit = source.idle_timeout_s if counts.items else source.start_timeout_s
        lease = ""
        if source.reconnect and counts.items and self.reader.publishers():
            # a publisher that was killed is still matched until its DDS lease ends: wait for DDS to say
            # it left (then for it to come back), rather than give up while it is matched
            own = self.leases.get(self.writer, DEFAULT_LEASE_S)
            if own + 1.0 > limit:
                limit, lease = own + 1.0, f", or the publisher's DDS lease of {own:g} s"
        if waited < limit:
            return
        what = (
            f"no valid {source.item}"
            if counts.skipped
            else "no data"
            if not counts.items
            else f"no {source.item}"
        )
        raise StreamTimeout(
            f"{source.name}: {what} for {waited:.1f} s (timeout {source.idle_timeout_s if counts.items else limit:g} s"
            f"{lease}); {counts.items} {source.item}s read, {counts.skipped} messages skipped"
        )

    def _silence(self, waited: float) -> Iterator[Break]:
        source, counts = self.source, self.counts
        limit = source.idle_timeout_s if counts.items else source.start_timeout_s
        if counts.items:
            self.emit(
                "silence",
                f"no {source.item} for {describe_duration(waited)} after {counts.items} {source.item}s, "
                f"{describe_duration(self.last_item - self.first_item)} into the stream; waiting ({_giving_up(limit)})",
            )
            if self.fresh:
                self.fresh = False
                yield Break(SILENCE, self.clock())
        elif not self.had_publisher:
            self.emit(
                "waiting",
                f"no matching publisher yet on {source.name} (domain {source.domain_id}) after {waited:.1f} s "
                f"({_giving_up(limit)})",
            )

    def _quiet(self, waited: float) -> str:
        source = self.source
        lost = (
            "at qos 'sensor' a message larger than the receiving socket's buffer is lost whole, unsaid by DDS: "
            "qos='lossless' delivers it"
            if source.dds.qos == "sensor"
            else "or larger than DDS can deliver"
        )
        return (
            f"a publisher of {source.name} matched, but no message of it arrived in {waited:.1f} s: it sends "
            f"none, or they do not get through ({lost})"
        )


__all__ = ["MIN_MESSAGE_BOUND", "Ros2Source", "message_bound"]
