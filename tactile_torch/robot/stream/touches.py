"""Touches: contacts cut from a stream of taxel frames, and the frames a bundle takes from one.

A robot hand classifies a contact, not a fixed window. A **touch** starts at the first frame whose
activity (the total, or the peak, pressure above the resting level) reaches the onset level, and ends
before the first frame whose activity falls below the release level (lower: hysteresis, so that noise
around one level does not chop a contact into pieces); a touch shorter than ``min_frames`` is not one
(a knock, a noise spike). The levels (:class:`TouchLevels`) come from the bundle's training data by
default (:func:`touch_levels`, recorded in the bundle's metadata by the exporters) and can be given.

A bundle trained on explorations of a fixed number ``T`` of frames gets a touch's frames brought to
``T`` by :func:`fit_frames`, the function the training side selected its frames with (the last ``T``
frames of a grasp: the object held); a touch (or the start of one, for an early decision) shorter than
``T`` is stretched to ``T`` frames by repeating frames evenly.

One segmentation for the live stream and for ``predict``: :class:`TouchTracker` is the state machine
both run (:class:`tactile_torch.robot.stream.touch_segments.TouchSegmenter`). numpy only.

Examples
--------
>>> levels = TouchLevels(onset=10.0, release=5.0, min_frames=2)
>>> tracker = TouchTracker(levels)
>>> [tracker.update(a) for a in (0, 12, 8, 6, 4, 0)]
[0, 1, 0, 0, 2, 0]
>>> fit_frames(np.arange(5), 3), fit_frames(np.arange(2), 4)
(array([2, 3, 4]), array([0, 0, 1, 1]))
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

SIGNALS = ("total", "peak")
"""What a frame's activity is: the sum (``total``) or the largest (``peak``) pressure above rest over its taxels."""
CONTACT = ("raises", "lowers", "auto")
"""How contact changes a raw pressure reading: it raises it (force arrays), lowers it (iCub's skin), or
found from the data (``auto``)."""
RESTING_PERCENTILE = 5.0
"""Resting level of a taxel: this percentile of its readings (in the contact direction) over the training frames."""
ONSET_SHARE = 0.25
"""Default onset level: this share of the peak activity of a weak training touch (:data:`WEAK_TOUCH_QUANTILE`)."""
RELEASE_SHARE = 0.125
"""Default release level: this share of the same peak (half the onset: the hysteresis)."""
WEAK_TOUCH_QUANTILE = 0.1
"""The training explorations' peak activities are summarised by this quantile: a touch as light as the
lightest tenth of the training touches still starts (a median would miss the light ones)."""
DEAD_BAND = 3.0
"""Pressure counts towards a frame's activity above ``rest + DEAD_BAND * noise`` (noise of one reading)."""
NOISE_CONTACT = 10.0
"""A light training touch must peak above this many noise standard deviations of one reading, else the
training frames show no contact (e.g. a taxel pressed in every frame, whose contact is taken for its rest)."""
MAX_LEVEL_EXPLORATIONS = 64
"""Training explorations (evenly spaced) whose frames set the default levels: enough for a median."""
MIN_TOUCH_S = 0.1
"""Default shortest touch in seconds (at least 2 frames)."""
GRAY = (0.2989, 0.5870, 0.1140)
"""Grayscale weights of RGB frames (the image pipeline's): pressure of an RGB pixel is ``1 - gray``."""
_MIN_SKEW = 0.1

NONE, START, END, SHORT = 0, 1, 2, 3
"""What :meth:`TouchTracker.update` says about a frame: nothing new, a touch starts at it, the touch
ended before it, a contact ended before it that was too short to be a touch."""


def contact_sign(values: np.ndarray, contact: str = "raises") -> tuple[float, float]:
    """Return ``(sign, skewness)``: +1 if contact raises the readings, -1 if it lowers them.

    ``contact="auto"`` decides from the skewness of the readings around each taxel's median (a tail of
    high readings: contact raises them), towards contact as the rarer state; ``ValueError`` when the
    skewness is below 0.1 in size. ``values``: readings ``(..., H, W)``.
    """
    if contact not in CONTACT:
        raise ValueError(f"contact must be one of {CONTACT}, got {contact!r}")
    flat = np.asarray(values, dtype=np.float64).reshape(-1, *np.shape(values)[-2:])
    dev = flat - np.median(flat, axis=0)
    spread = dev.std()
    skewness = float((dev**3).mean() / spread**3) if spread > 0 else 0.0
    if contact == "auto":
        if abs(skewness) < _MIN_SKEW:
            raise ValueError(
                "contact: the readings do not show whether contact raises or lowers them "
                f"(skewness {skewness:.2f}); set contact='raises' or contact='lowers'"
            )
        return (1.0 if skewness > 0 else -1.0), skewness
    return (1.0 if contact == "raises" else -1.0), skewness


def resting_level(signed: np.ndarray) -> np.ndarray:
    """Return each taxel's resting level ``(H, W)``: the :data:`RESTING_PERCENTILE` of ``signed`` ``(..., H, W)``.

    ``signed`` are readings times the contact sign, so that contact raises them.
    """
    flat = np.asarray(signed, dtype=np.float64).reshape(-1, *np.shape(signed)[-2:])
    return np.percentile(flat, RESTING_PERCENTILE, axis=0)


def reading_noise(explorations: np.ndarray) -> float:
    """Return the noise standard deviation of one reading, from frame-to-frame differences.

    Differences cancel the slowly changing contact; their median absolute value measures the noise
    (Gaussian: ``sigma = 1.4826 * MAD / sqrt(2)``). ``explorations``: ``(N, T, H, W)``; 0 when ``T < 2``.
    """
    x = np.asarray(explorations, dtype=np.float64)
    if x.ndim < 2 or x.shape[1] < 2:
        return 0.0
    return float(1.4826 * np.median(np.abs(np.diff(x, axis=1))) / np.sqrt(2.0))


def fit_frames(frames: np.ndarray, n_frames: int) -> np.ndarray:
    """Return ``n_frames`` frames of a touch ``(k, ...)``: its last ``n_frames``, or all of it stretched.

    ``k >= n_frames``: the last ``n_frames`` frames (a view), as the training side selected the
    frames of a grasp (:func:`tactile_torch.data.grasps.load_drimus_grasps`, ``load_icub_grasps``: the
    object held). ``k < n_frames``: frame ``i`` of the result is ``frames[floor(i * k / n_frames)]``
    (each frame repeated about ``n_frames / k`` times), so that features of the touch's time series
    (the OR-fusion of its edges, its total variation and threshold crossings, its moments) are those
    of its own frames.

    Raises ``ValueError`` for an empty touch or ``n_frames < 1``.
    """
    k = len(frames)
    if n_frames < 1 or k < 1:
        raise ValueError(f"fit_frames needs at least one frame and n_frames >= 1, got {k} and {n_frames}")
    if k >= n_frames:
        return frames[k - n_frames :]
    return frames[(np.arange(n_frames) * k) // n_frames]


def fit_explorations(explorations: np.ndarray, n_frames: int | None) -> tuple[np.ndarray, str | None]:
    """Return explorations ``(N, T', ...)`` brought to ``n_frames`` by :func:`fit_frames`, and a one-line note.

    Unchanged (note ``None``) when they already have ``n_frames`` frames or ``n_frames`` is ``None``.
    """
    have = explorations.shape[1]
    if n_frames is None or have == n_frames:
        return explorations, None
    fitted = np.ascontiguousarray(np.stack([fit_frames(x, n_frames) for x in explorations]))
    how = (
        f"their last {n_frames}"
        if have > n_frames
        else f"each frame repeated about {n_frames / have:.2g} times"
    )
    return fitted, (
        f"explorations of {have} frames brought to the {n_frames} this bundle takes ({how}: "
        "tactile_torch.robot.stream.touches.fit_frames, as training selected them)"
    )


@dataclass(frozen=True, eq=False)
class TouchLevels:
    """How a touch is cut from frames: activity signal, onset and release levels, shortest touch.

    Attributes
    ----------
    onset, release : float
        A touch starts at a frame whose activity is ``>= onset`` and ends before one whose activity
        is ``< release`` (``release <= onset``).
    min_frames : int
        Shorter contacts are not touches (counted, reported, not classified).
    signal : {"total", "peak"}
        Activity of a frame: the sum or the largest of its taxels' pressure above rest.
    sign : float
        +1: contact raises a reading; -1: it lowers it (iCub).
    rest : float or ndarray of shape (H, W)
        Resting level of each taxel, in ``sign * reading`` units.
    floor : float
        Pressure above ``rest`` counts only beyond this (a few noise standard deviations).
    rgb : bool
        Frames are RGB ``(H, W, 3)`` 0-255: pressure is ``1 - gray / 255`` (white: no pressure).
    source : str
        Where the levels come from, in words (the training data, or given).
    """

    onset: float
    release: float
    min_frames: int = 2
    signal: str = "total"
    sign: float = 1.0
    rest: float | np.ndarray = 0.0
    floor: float = 0.0
    rgb: bool = False
    source: str = "given"
    _rest: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.signal not in SIGNALS:
            raise ValueError(f"touch signal must be one of {SIGNALS}, got {self.signal!r}")
        for name in ("onset", "release"):
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float | np.number)
                or not math.isfinite(value)
            ):
                raise ValueError(f"{name} must be a finite number, got {value!r}")
        if not self.release <= self.onset:
            raise ValueError(
                f"release must be at most onset (hysteresis), got release {self.release:g} > onset {self.onset:g}"
            )
        if (
            isinstance(self.min_frames, bool)
            or not isinstance(self.min_frames, int | np.integer)
            or self.min_frames < 1
        ):
            raise ValueError(f"min_frames must be an int >= 1, got {self.min_frames!r}")
        object.__setattr__(self, "_rest", np.asarray(self.rest, dtype=np.float32) + np.float32(self.floor))

    def pressure(self, frame: np.ndarray) -> np.ndarray:
        """Return the pressure above rest (and floor) of a frame ``(H, W)`` (or ``(H, W, 3)`` RGB), >= 0."""
        if self.rgb:
            gray = frame[..., 0] * GRAY[0] + frame[..., 1] * GRAY[1] + frame[..., 2] * GRAY[2]
            above = (1.0 - gray / 255.0) - self._rest
        elif self.sign == 1.0:
            above = frame - self._rest
        else:
            above = -frame - self._rest
        return np.maximum(above, 0.0)

    def activity(self, frame: np.ndarray) -> float:
        """Return a frame's activity: the total (or peak) pressure above rest."""
        p = self.pressure(frame)
        return float(p.sum() if self.signal == "total" else p.max())

    def with_overrides(
        self,
        *,
        onset: float | None = None,
        release: float | None = None,
        min_frames: int | None = None,
        signal: str | None = None,
    ) -> TouchLevels:
        """Return these levels with some replaced (``release`` defaults to half a new ``onset``)."""
        if onset is not None and release is None:
            release = onset / 2.0
        changed = any(v is not None for v in (onset, release, min_frames, signal))
        return TouchLevels(
            onset=float(self.onset if onset is None else onset),
            release=float(self.release if release is None else release),
            min_frames=int(self.min_frames if min_frames is None else min_frames),
            signal=self.signal if signal is None else signal,
            sign=self.sign,
            rest=self.rest,
            floor=self.floor,
            rgb=self.rgb,
            source=self.source + (", with levels given" if changed else ""),
        )

    def to_metadata(self) -> dict:
        """Return the levels as a JSON-able dict (the bundle metadata :data:`~tactile_torch.robot.contract.TOUCH_LEVELS_KEY`)."""
        rest = np.asarray(self.rest, dtype=np.float64)
        return {
            "signal": self.signal,
            "onset": float(self.onset),
            "release": float(self.release),
            "min_frames": int(self.min_frames),
            "sign": float(self.sign),
            "rest": float(rest) if rest.ndim == 0 else [[round(float(v), 6) for v in row] for row in rest],
            "floor": float(self.floor),
            "rgb": bool(self.rgb),
            "source": self.source,
        }

    @classmethod
    def from_metadata(cls, value: str | dict, shape: tuple[int, ...] | None = None) -> TouchLevels:
        """Return the levels a bundle records (JSON text or dict); ``ValueError`` naming what is wrong.

        ``shape``: the frame shape ``(H, W)`` a per-taxel ``rest`` must have.
        """
        try:
            d = json.loads(value) if isinstance(value, str) else dict(value)
            rest = np.asarray(d.get("rest", 0.0), dtype=np.float64)
            levels = cls(
                onset=float(d["onset"]),
                release=float(d["release"]),
                min_frames=int(d.get("min_frames", 2)),
                signal=str(d.get("signal", "total")),
                sign=float(d.get("sign", 1.0)),
                rest=float(rest) if rest.ndim == 0 else rest,
                floor=float(d.get("floor", 0.0)),
                rgb=bool(d.get("rgb", False)),
                source=str(d.get("source", "the bundle")),
            )
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as err:
            raise ValueError(
                f"touch_levels metadata must be the JSON of touch levels, got {str(value)[:80]!r}: {err}"
            ) from None
        if shape is not None and rest.ndim and rest.shape != tuple(shape[:2]):
            raise ValueError(
                f"touch_levels metadata: rest must have shape {tuple(shape[:2])}, got {rest.shape}"
            )
        if levels.sign not in (1.0, -1.0):
            raise ValueError(f"touch_levels metadata: sign must be 1 or -1, got {levels.sign:g}")
        return levels


def touch_levels(
    explorations: np.ndarray,
    *,
    frame_rate_hz: float | None = None,
    contact: str = "raises",
    sign: float | None = None,
    rest: np.ndarray | None = None,
    rgb: bool = False,
    signal: str = "total",
) -> TouchLevels:
    """Return the default touch levels of a bundle from its training explorations.

    Each training exploration holds a contact (a grasp's held frames, a finger's exploration), so its
    largest frame activity is that touch's strength; the lightest touches matter most, so the onset is
    :data:`ONSET_SHARE` of the :data:`WEAK_TOUCH_QUANTILE` quantile of those peaks, the release
    :data:`RELEASE_SHARE` of it. The resting levels must show in the data: every taxel at rest
    in some of the frames (a moving contact; at least 5 % of them), or readings whose rest is
    already subtracted (as the grasp loaders of :mod:`tactile_torch.data.grasps` give them); a taxel
    pressed in every training frame would take its contact for its rest. Pressure is measured above each taxel's resting level (given,
    e.g. a fitted :class:`~tactile_torch.features.transformers.PressureImageFeatures`' ``resting_``;
    else :func:`resting_level`) plus :data:`DEAD_BAND` noise standard deviations (:func:`reading_noise`).
    The shortest touch is :data:`MIN_TOUCH_S` at ``frame_rate_hz`` (2 frames at least, and when the
    rate is unknown).

    Parameters
    ----------
    explorations : ndarray
        Pressure maps ``(N, T, H, W)`` (any counts) or RGB frames ``(N, T, 3, H, W)`` / ``(N, T, H, W, 3)``
        uint8 (``rgb=True``).
    frame_rate_hz : float, optional
    contact : {"raises", "lowers", "auto"}
        Pressure maps: how contact changes a reading (:func:`contact_sign`), unless ``sign`` is given.
    sign : float, optional
    rest : ndarray of shape (H, W), optional
    rgb : bool
    signal : {"total", "peak"}

    Raises
    ------
    ValueError
        When the training frames show no activity at all (every frame at rest).
    """
    x = np.asarray(explorations)
    if rgb and x.ndim == 5 and x.shape[2] == 3 and x.shape[-1] != 3:
        x = np.moveaxis(x, 2, -1)  # (N, T, H, W, 3), as the stream's RGB frames
    if x.ndim != (5 if rgb else 4) or not len(x):
        raise ValueError(
            f"explorations must have shape (N, T, H, W){' x 3 (RGB)' if rgb else ''}, got {x.shape}"
        )
    # a bounded sample of the explorations: RGB display frames are large (100 frames of 96 x 96 x 3 each)
    sample = x[np.unique(np.linspace(0, len(x) - 1, min(len(x), MAX_LEVEL_EXPLORATIONS)).round().astype(int))]
    few = sample[np.unique(np.linspace(0, len(sample) - 1, min(len(sample), 8)).round().astype(int))]
    if rgb:
        sign_, rest_ = 1.0, 0.0
        noise = reading_noise(
            np.stack(
                [1.0 - (e[..., 0] * GRAY[0] + e[..., 1] * GRAY[1] + e[..., 2] * GRAY[2]) / 255.0 for e in few]
            )
        )
    else:
        sign_ = float(sign) if sign is not None else contact_sign(x, contact)[0]
        rest_ = resting_level(sign_ * x) if rest is None else np.asarray(rest, dtype=np.float64)
        noise = reading_noise(few)
    base = TouchLevels(1.0, 0.0, 2, signal, sign_, rest_, DEAD_BAND * noise, rgb)
    peaks = np.array([max(base.activity(f.astype(np.float32)) for f in e) for e in sample])
    contact_level = float(np.quantile(peaks, WEAK_TOUCH_QUANTILE))
    if (
        not contact_level > NOISE_CONTACT * noise
    ):  # within a few readings' noise of rest: no contact to speak of
        raise ValueError(
            "explorations: the training frames show no pressure above their resting level (a light training "
            f"touch peaks at {contact_level:g}), so no touch level can be set from them; give the levels "
            "(onset=, release=)"
        )
    rate = "" if frame_rate_hz is None else f" at {frame_rate_hz:g} frames/s"
    min_frames = 2 if frame_rate_hz is None else max(2, math.ceil(MIN_TOUCH_S * frame_rate_hz - 1e-9))
    return TouchLevels(
        onset=ONSET_SHARE * contact_level,
        release=RELEASE_SHARE * contact_level,
        min_frames=min_frames,
        signal=signal,
        sign=sign_,
        rest=rest_,
        floor=DEAD_BAND * noise,
        rgb=rgb,
        source=f"training data: {ONSET_SHARE:g} and {RELEASE_SHARE:g} of the peak {signal} pressure of a light "
        f"training touch ({contact_level:.4g}, the {WEAK_TOUCH_QUANTILE:.0%} quantile of {len(peaks)}), shortest "
        f"touch {min_frames} frames{rate}",
    )


def frame_metadata(
    explorations: np.ndarray,
    *,
    frame_rate_hz: float | None,
    rgb: bool = False,
    contact: str = "raises",
    sign: float | None = None,
    rest: np.ndarray | None = None,
    levels: TouchLevels | None = None,
) -> tuple[dict, str | None]:
    """Return the metadata a frame bundle records for the live stream, and a note when the levels could not be set.

    Keys (:mod:`tactile_torch.robot.contract`): ``frame_rate_hz``; ``value_range`` for pressure maps
    (the training values' range widened by its own width on each side: a corrupted value, or data in
    other units, lies outside; RGB frames are 0-255 by their type); ``touch_levels``
    (:func:`touch_levels`, or ``levels`` when the training touches were cut at those: a hand's recordings,
    :mod:`tactile_torch.robot.stream.recorded_touches`), unless the training frames do not allow them (then
    the note says why and the stream needs ``--onset``).
    """
    from ..contract import FRAME_RATE_KEY, TOUCH_LEVELS_KEY, VALUE_RANGE_KEY

    meta: dict = {}
    if frame_rate_hz is not None:
        meta[FRAME_RATE_KEY] = float(frame_rate_hz)
    x = np.asarray(explorations)
    if not rgb:
        lo, hi = float(x.min()), float(x.max())
        span = max(hi - lo, abs(hi), 1.0)
        meta[VALUE_RANGE_KEY] = [lo - span, hi + span]
    try:
        if levels is None:
            levels = touch_levels(
                x, frame_rate_hz=frame_rate_hz, contact=contact, sign=sign, rest=rest, rgb=rgb
            )
    except ValueError as err:
        return meta, f"no touch levels in the bundle ({err}); stream needs --onset"
    meta[TOUCH_LEVELS_KEY] = levels.to_metadata()
    return meta, None


class TouchTracker:
    """The touch state machine: feed it each frame's activity, it says where touches start and end.

    :meth:`update` returns :data:`START` at the first frame of a touch, :data:`END` at the first frame
    after a touch (the frame is not part of it), :data:`SHORT` there instead when the contact lasted
    fewer than ``min_frames`` frames, :data:`NONE` otherwise. :meth:`cut` ends a touch in progress
    at a break (a silence, a gap in ``t``): the next frame at or above the onset starts a new touch.

    Attributes
    ----------
    touching : bool
    frames : int
        Frames of the touch in progress (0 when not touching).
    """

    def __init__(self, levels: TouchLevels) -> None:
        self.levels = levels
        self._onset, self._release, self._min = levels.onset, levels.release, levels.min_frames
        self.touching = False
        self.frames = 0

    def update(self, activity: float) -> int:
        """Take one frame's activity; return :data:`NONE`, :data:`START`, :data:`END` or :data:`SHORT`."""
        if self.touching:
            if activity < self._release:
                n, self.touching, self.frames = self.frames, False, 0
                return END if n >= self._min else SHORT
            self.frames += 1
            return NONE
        if activity >= self._onset:
            self.touching, self.frames = True, 1
            return START
        return NONE

    def cut(self) -> int:
        """End the touch in progress at a break; return :data:`END`, :data:`SHORT`, or :data:`NONE` (none)."""
        if not self.touching:
            return NONE
        n, self.touching, self.frames = self.frames, False, 0
        return END if n >= self._min else SHORT


__all__ = [
    "CONTACT",
    "DEAD_BAND",
    "END",
    "GRAY",
    "MAX_LEVEL_EXPLORATIONS",
    "MIN_TOUCH_S",
    "NOISE_CONTACT",
    "NONE",
    "ONSET_SHARE",
    "RELEASE_SHARE",
    "RESTING_PERCENTILE",
    "SHORT",
    "SIGNALS",
    "START",
    "WEAK_TOUCH_QUANTILE",
    "TouchLevels",
    "TouchTracker",
    "contact_sign",
    "fit_explorations",
    "fit_frames",
    "frame_metadata",
    "reading_noise",
    "resting_level",
    "touch_levels",
]
