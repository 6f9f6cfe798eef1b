"""The continuity of a stream's time stamps: items lost, stamps off schedule, ``t`` going back, another rate.

:class:`Sequencer` is the second stage of a live stream (:mod:`tactile_torch.robot.stream.source`):
it reads the sensor's ``t`` of each reading and says where continuity broke (no window or touch may
span that point) and how many items the sensor's clock says are missing. One rule for every source,
built so that no stamp can crash the stream or make up a loss:

- a step of one period (within :data:`~tactile_torch.robot.files.sample_times.GAP_TOLERANCE`) goes on at
  once (the common case costs one subtraction and two comparisons);
- a step off the period holds the reading until the next one says what it was: **a stamp off
  schedule** (the next reading is back on the schedule: the stamp is corrected to its due time,
  counted in :attr:`Sequencer.corrected`, and nothing is cut: ``1e308``, ``inf``, NaN, a frame 0.1 s
  off, a stamp going back alone), **the first step of another rate** (the next step is the same:
  up to :data:`RATE_RUN` readings are held, then the rate is adopted without a cut: 100 Hz data for
  an 800 Hz bundle, milliseconds read as seconds), or **a discontinuity** (cut there);
- **losses are counted once the stream steps regularly again** (:data:`SETTLED` steps of one
  period), as the items its ``t`` says are missing across the whole disturbance: stamps of any value
  inside it count nothing, and a jump of more than :data:`MAX_PERIODS` periods is a clock jump, not
  a count. With :attr:`Sequencer.origin` (the reading clock when a live source opened), a count is
  also bounded by what the sensor can have sent since: ``(read_at - origin) * rate * 1.05 + 2``
  items in all.

numpy-free, pure Python: it runs on every reading.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from ..files.sample_times import (  # one rule for files and the live stream, one wording
    GAP_TOLERANCE,
    RATE_TOLERANCE,
    describe_duration,
    describe_gap,
)
from .port_lines import StreamEvent
from .source import RECONNECT, EventEmitter, Reading

RATE_RUN = 16
"""Equal off-period steps in a row after which they are the sensor's own rate, adopted for the checks."""
SAME_STEP = 0.1
"""Steps within this share of each other are the same step (one rate)."""
SETTLED = 2
"""Steps of one period in a row that settle a disturbance: the items it lost are counted then."""
MAX_PERIODS = 1e12
"""A jump of ``t`` by more periods than this is a clock jump (a reset, a corrupted stamp), never a count."""


class Sequencer:
    """Check the continuity of the sensor's ``t`` (see the module notes for the rule).

    Parameters
    ----------
    rate_hz : float, optional
        The expected rate; without it only ``t`` going back breaks continuity, and nothing is counted lost.
    item : str
        What an item is called in messages (``"sample"``, ``"frame"``).
    name : str
        What the stream reads (port, topic, file), for messages: times are said as durations and
        positions since the stream's first ``t`` (``a 0.4 s gap 12.3 s into /dev/ttyUSB0``,
        :func:`~tactile_torch.robot.files.sample_times.describe_gap`), never as epoch times.
    on_event, clock
        Events ``"gap"`` and ``"stamp"`` (rate-limited) and ``"rate"`` (once).

    Attributes
    ----------
    gaps : int
        Cuts that ended a window or touch in progress (counted by
        :class:`~tactile_torch.robot.stream.segments.Segments`, with the breaks that did).
    lost : int
        Items the sensor's ``t`` says are missing.
    corrected : int
        Stamps off schedule, taken at their due time.
    origin : float or None
        The reading clock when a live source opened (``None``: no bound from the clock, as for a file).
    """

    def __init__(
        self,
        rate_hz: float | None = None,
        *,
        item: str = "sample",
        name: str = "the stream",
        on_event: Callable[[StreamEvent], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.rate_hz = rate_hz
        self.item, self.name = item, name
        self._first_t: float | None = None  # the stream's first t: where positions are counted from
        self.gaps = self.lost = self.corrected = 0
        self.origin: float | None = None
        self._period = None if rate_hz is None else 1.0 / rate_hz
        self._prev_t: float | None = None
        self._count = 0  # readings passed on
        self._held: list[Reading] = []
        self._run = False  # the held readings step alike: another rate?
        self._suspect: Reading | None = None  # a reading off a run's step, held for one more
        self._settled = 0  # one-period steps in a row since the last disturbance
        self._open: tuple | None = (
            None  # a disturbance: t and count before it, the first t after, across a reconnection
        )
        self._breaks = 0  # cuts inside the open disturbance
        self._last_at: float | None = None
        self._reconnected_at = -1  # readings passed when the last reconnection happened
        self._events = EventEmitter(on_event, clock)
        self._window()

    def _window(self) -> None:
        p = self._period
        self._lo = None if p is None else (1.0 - GAP_TOLERANCE) * p
        self._hi = None if p is None else (1.0 + GAP_TOLERANCE) * p

    @property
    def period(self) -> float | None:
        """The period the steps are judged by (the bundle's, or the data's own once adopted), seconds."""
        return self._period

    def _into(self, t: float) -> str:
        """``"12.3 s into /dev/ttyUSB0"``: where ``t`` lies in the stream, as people read it."""
        first = self._first_t if self._first_t is not None else t
        return f"{describe_duration(t - first)} into {self.name}"

    def note(self, kind: str, message: str) -> None:
        """Say something about the stream's continuity (rate-limited, as gaps are)."""
        self._events.emit(kind, message, repeated=True)

    def push(self, reading: Reading) -> tuple[tuple[bool, Reading], ...] | None:
        """Judge one reading; ``None``: pass it on as it is; else the ``(cut, reading)`` pairs to pass on, in order.

        ``cut`` True: continuity broke before that reading (no window or touch may span it).
        """
        t, prev = reading.t, self._prev_t
        if t is not None and prev is not None and not self._held and self._lo is not None:
            if self._lo <= t - prev <= self._hi:
                self._prev_t = t
                self._count += 1
                if self._open is not None:
                    self._settled += 1
                    self._settle(reading.read_at)
                return None
        out: list = []
        self._judge(reading, out)
        return tuple(out)

    def reset(self, kind: str | None = None) -> tuple[tuple[bool, Reading], ...]:
        """A break (``kind``) or the end (``None``): return the held readings to pass on first.

        ``t`` is forgotten, except across a reconnection, whose next step counts what was lost meanwhile.
        """
        out: list = []
        self._release(out)
        if self._open is not None:
            self._close(self._last_at, settled=self._settled > 0)
        if kind == RECONNECT:
            self._reconnected_at = self._count
        else:
            self._prev_t, self._open = None, None
        return tuple(out)

    # -- passing on ------------------------------------------------------------------------------------
    def _pass(self, reading: Reading, out: list, cut: bool = False) -> None:
        out.append((cut, reading))
        self._count += 1
        self._last_at = reading.read_at
        if reading.t is not None:
            self._prev_t = reading.t
            if self._first_t is None:
                self._first_t = reading.t

    def _regular(self, reading: Reading, out: list) -> None:
        self._pass(reading, out)
        self._settled += 1
        if self._open is not None:
            self._settle(reading.read_at)

    def _release(self, out: list) -> None:
        """Pass on what is held without a verdict: a cut before each step that is not a period."""
        held, self._held, self._run = self._held, [], False
        if self._suspect is not None:
            held.append(self._suspect)
            self._suspect = None
        for r in held:
            d = r.t - self._prev_t if self._prev_t is not None else None
            if d is None or self._lo <= d <= self._hi:
                self._regular(r, out)
            elif 0 < d < self._lo:  # faster than the period: nothing lost
                self._pass(r, out)
            else:
                self._disturb(self._prev_t, r)
                self._pass(r, out, cut=True)

    # -- judging ---------------------------------------------------------------------------------------
    def _judge(self, reading: Reading, out: list) -> None:
        t = reading.t
        if t is None:  # an item without a stamp passes unchecked
            self._release(out)
            out.append((False, reading))
            self._count += 1
            return
        if not math.isfinite(t):
            self._release(out)
            self._correct(reading, out, f"a time stamp that is no number ({t})")
            return
        prev, period = self._prev_t, self._period
        if prev is None:
            self._pass(reading, out)
            return
        if period is None:  # no rate to judge steps by: only t going back breaks continuity, said at once
            if t <= prev:
                self.note(
                    "gap",
                    f"{self._into(prev)}, t went back by {describe_duration(prev - t)}: a spliced recording or a "
                    "sensor reset",
                )
            self._pass(reading, out, cut=t <= prev)
            return
        held = self._held
        if not held:
            if self._lo <= t - prev <= self._hi:
                self._regular(reading, out)
            else:
                held.append(reading)
            return
        if self._run:
            self._extend_run(reading, out)
            return
        h = held[0]
        d1, d2 = h.t - prev, t - h.t
        if abs(t - prev - 2 * period) <= GAP_TOLERANCE * period:  # back on schedule: h's stamp was wrong
            self._held = []
            self._correct(
                h,
                out,
                f"a time stamp {describe_duration(h.t - prev - period)} off schedule",
                due=prev + period,
            )
            self._judge(reading, out)
        elif d1 > 0 and abs(d2 - d1) <= SAME_STEP * d1:  # a second step like the first: another rate?
            held.append(reading)
            self._run = True
        else:  # continuity broke before h
            self._held = []
            self._disturb(prev, h)
            self._pass(h, out, cut=True)
            self._judge(reading, out)

    def _extend_run(self, reading: Reading, out: list) -> None:
        held = self._held
        step = held[1].t - held[0].t
        last, suspect = held[-1], self._suspect
        self._suspect = None
        if suspect is None:
            if abs(reading.t - last.t - step) <= SAME_STEP * step:
                held.append(reading)
                if len(held) >= RATE_RUN:
                    self._adopt(out)
            else:
                self._suspect = (
                    reading  # off the run's step: the next reading says whether its stamp was wrong
                )
            return
        if abs(reading.t - last.t - 2 * step) <= SAME_STEP * step:  # back on the run's schedule
            self.corrected += 1
            due = last.t + step
            self._events.emit(
                "stamp",
                f"a time stamp {describe_duration(suspect.t - due)} off schedule; taken at its due time, "
                f"{self._into(due)}",
                repeated=True,
            )
            held += [suspect._replace(t=due), reading]
            if len(held) >= RATE_RUN:
                self._adopt(out)
            return
        self._release(out)  # the run ended before it was a rate: each of its steps is judged as it is
        self._judge(suspect, out)
        self._judge(reading, out)

    def _adopt(self, out: list) -> None:
        held, self._held, self._run = self._held, [], False
        step = (held[-1].t - held[0].t) / (len(held) - 1)
        expected = self._period
        hint = ""
        for factor, unit in ((1e3, "milliseconds"), (1e6, "microseconds"), (1e-3, "seconds")):
            if abs(step / expected / factor - 1) <= RATE_TOLERANCE:
                hint = f" (t reads like {unit}: declare the unit of t)"
        self._events.emit(
            "rate",
            f"t advances {step * 1e3:.4g} ms per {self.item} ({1 / step:.4g} Hz), not {expected * 1e3:.4g} ms "
            f"({1 / expected:.4g} Hz){hint}: gaps are now judged at {1 / step:.4g} Hz; results are flagged 'rate'",
        )
        self._period = step
        self._window()
        self._open = None  # what looked like a disturbance was the new rate
        first, prev = held[0], self._prev_t
        cut = prev is not None and not 0 < first.t - prev <= (1 + GAP_TOLERANCE) * step
        if cut:
            self._disturb(prev, first)
        self._pass(first, out, cut=cut)
        for r in held[1:]:
            self._pass(r, out)
        self._settled = len(held) - 1

    def _correct(self, reading: Reading, out: list, what: str, due: float | None = None) -> None:
        if due is None and self._prev_t is not None and self._period is not None:
            due = self._prev_t + self._period
        self.corrected += 1
        taken = "taken without a stamp" if due is None else f"taken at its due time, {self._into(due)}"
        self._events.emit("stamp", f"{what}; {taken}", repeated=True)
        if due is None:
            out.append((False, reading._replace(t=None)))
            self._count += 1
        else:
            self._regular(reading._replace(t=due), out)

    # -- losses ----------------------------------------------------------------------------------------
    def _disturb(self, prev: float, reading: Reading) -> None:
        """Continuity broke between ``prev`` and ``reading``: the losses are counted when it settles."""
        self._settled = 0
        self._breaks += 1
        if self._open is None:
            self._breaks = 1
            self._open = (prev, self._count, reading.t, self._count == self._reconnected_at)
        elif self._breaks == RATE_RUN:
            self._events.emit(
                "gap",
                f"t has not stepped regularly for {RATE_RUN} {self.item}s since {self._into(self._open[0])} (for "
                f"{describe_duration(reading.t - self._open[0])}): no window or touch can be cut; is t the sensor's "
                "clock, in the unit declared?",
            )

    def _settle(self, at: float) -> None:
        if self._settled >= SETTLED:
            self._close(at)

    def _close(self, at: float | None, *, settled: bool = True) -> None:
        before, count_before, after, across = self._open
        self._open = None
        t, count = self._prev_t, self._count
        if self._breaks > 1:
            span = f"{self._breaks} gaps in t over {describe_duration(t - before)} from {self._into(before)}"
        elif after >= before:
            first = self._first_t if self._first_t is not None else before
            span = describe_gap(after - before, before - first, self.name)
        else:
            span = f"{self._into(before)}, t went back by {describe_duration(before - after)}"
        what = f"{span}: "
        periods = (t - before) / self._period if self._period else math.nan
        if not settled:  # the stream broke or ended before t stepped regularly again: nothing to count by
            what += (
                f"t did not step regularly again before the stream broke, no count of {self.item}s missing"
            )
        elif not abs(periods) <= MAX_PERIODS:
            what += f"a clock jump (a sensor reset?), not a count of {self.item}s missing"
        else:
            missing = round(periods) - (count - count_before)
            if missing > 0:
                bounded = self._bound(missing, at)
                self.lost += bounded
                what += f"{bounded} {self.item}(s) missing"
                if bounded < missing:
                    what += (
                        f" (t says {missing}, more than the sensor can have sent since the stream started)"
                    )
            elif after < before:
                what += "a spliced recording or a sensor reset"
            else:
                what += f"time stamps off schedule, no {self.item} missing"
        if across:
            what += " across the reconnection"
        self._events.emit("gap", what, repeated=True)

    def _bound(self, missing: int, now: float | None) -> int:
        if self.origin is None or now is None:
            return missing
        rate = max(1.0 / self._period, self.rate_hz or 0.0)
        allowed = math.floor((now - self.origin) * rate * (1 + RATE_TOLERANCE)) + 2 - self._count - self.lost
        return max(0, min(missing, allowed))


__all__ = ["MAX_PERIODS", "RATE_RUN", "SAME_STEP", "SETTLED", "Sequencer"]
