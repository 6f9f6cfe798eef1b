"""A seeded simulator of the study's stylus: an accelerometer dragged over surfaces.

:func:`make_vibration_recordings` simulates the stylus of the study (an ADXL345 accelerometer on a
probe dragged at 58.9 cm/s over surfaces on a turntable, 800 Hz, 3.9 mg resolution, ±5 g): each
surface has its own roughness spectrum, hardness (soft surfaces damp high frequencies), texture
period, sparse or regular impacts, stick-slip, and every recording slow wear drift, gravity on the
z axis, sensor noise, quantisation and clipping. A few surfaces are deliberately alike
(:data:`SURFACES`, ``alike_of``). :func:`make_vibration_dataset` returns windows ready for the
features. Everything is a function of ``random_state`` only.

Examples
--------
>>> rec = make_vibration_recordings(n_surfaces=4, duration_s=2.0, random_state=0)
>>> rec.signals[0].shape, rec.rate_hz, rec.class_names[:2]
((1600, 3), 800.0, ('glass', 'aluminium'))
>>> make_vibration_dataset(n_surfaces=3, windows_per_surface=5, window_size=200, random_state=0).windows.shape
torch.Size([15, 3, 200])
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING

import numpy as np

from ..exceptions import InputTypeError
from ..validation import check_positive, numpy_rng
from .vibration import QUANTUM_G, RANGE_G, SAMPLE_RATE_HZ, VibrationRecordings, VibrationWindows

if TYPE_CHECKING:  # the generator itself is torch-free: simulate-sensor plays it on the robot
    from ..validation import RandomState

SPEED_M_S = 0.589  # turntable speed under the stylus, 58.9 cm/s


# ----------------------------------------------------------------------------------------------
# Synthetic surfaces
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Surface:
    """Parameters of one synthetic surface (before the per-seed jitter of :func:`make_vibration_recordings`).

    Attributes
    ----------
    name : str
    rms_g : float
        RMS of the roughness vibration on the normal (z) axis, after the probe and hardness filters.
    corner_hz : float
        Corner of the roughness spectrum, ``PSD ~ 1 / (1 + (f / corner)^(2 slope))``; a fine grain
        (``v / grain size``) gives a high corner.
    slope : float
        Roll-off exponent above the corner.
    hardness : float
        In [0, 1]; the contact low-passes the vibration at ``30 * (400/30)^hardness`` Hz (fourth
        order), so soft surfaces (felt, foam) lose their high frequencies.
    texture_mm : float
        Spatial period of a regular texture (weave, grain, corrugation), 0 for none; it sounds at
        ``speed / period`` Hz with harmonics, frequency-modulated by the turntable's speed wobble.
    texture : float
        Amplitude of the texture tone relative to ``rms_g``.
    impacts_hz : float
        Rate of sparse random impacts (grains, pores), Poisson.
    bump_mm : float
        Spacing of regular impacts (tile joints, perforations), 0 for none.
    impact_g : float
        Median peak of one impact's response (log-normal spread).
    slip_hz, slip_g : float
        Stick-slip: mean rate of the slip events (gamma-distributed intervals) and their peak on the
        tangential (x) axis, plus the sawtooth of the stick phases.
    tangential, lateral : float
        Roughness gain of the x (along the motion) and y axes relative to z.
    alike_of : str
        Name of the surface this one is deliberately close to (shares its random jitter), or "".
    """

    name: str
    rms_g: float
    corner_hz: float
    slope: float
    hardness: float
    texture_mm: float = 0.0
    texture: float = 0.0
    impacts_hz: float = 0.0
    bump_mm: float = 0.0
    impact_g: float = 0.0
    slip_hz: float = 0.0
    slip_g: float = 0.0
    tangential: float = 0.6
    lateral: float = 0.35
    alike_of: str = ""


# Named after common test surfaces; the numbers are invented to give each a plausible character
# (not fitted to measurements). Five pairs are deliberately alike (alike_of).
SURFACES: tuple[Surface, ...] = (
    Surface("glass", 0.03, 400, 1.0, 1.00),
    Surface("aluminium", 0.045, 250, 1.0, 1.00),
    Surface("steel", 0.055, 300, 1.0, 1.00, alike_of="aluminium"),
    Surface("sandpaper-p120", 0.4, 380, 0.6, 1.00, impacts_hz=25, impact_g=0.9, tangential=0.8, lateral=0.5),
    Surface(
        "sandpaper-p150",
        0.34,
        395,
        0.6,
        1.00,
        impacts_hz=21,
        impact_g=0.78,
        tangential=0.8,
        lateral=0.5,
        alike_of="sandpaper-p120",
    ),
    Surface("cork", 0.12, 90, 1.2, 0.45, impacts_hz=4, impact_g=0.4, tangential=0.7, lateral=0.4),
    Surface("carpet", 0.18, 40, 1.8, 0.12, texture_mm=3.0, texture=0.3, tangential=0.9, lateral=0.6),
    Surface("rubber", 0.06, 120, 1.0, 0.35, slip_hz=35, slip_g=0.7, tangential=1.2, lateral=0.3),
    Surface("corrugated-cardboard", 0.09, 100, 1.2, 0.45, texture_mm=5.0, texture=1.5),
    Surface("paper", 0.07, 180, 1.0, 0.60),
    Surface("cardstock", 0.085, 165, 1.0, 0.66, alike_of="paper"),
    Surface("ceramic-tiles", 0.05, 250, 1.0, 1.00, bump_mm=20.0, impact_g=1.5, tangential=0.5, lateral=0.3),
    Surface("perforated-metal", 0.06, 300, 1.0, 1.00, bump_mm=5.0, impact_g=0.7),
    Surface("brick", 0.45, 150, 0.9, 0.90, impacts_hz=10, impact_g=1.2, tangential=0.7, lateral=0.5),
    Surface(
        "concrete",
        0.35,
        175,
        0.9,
        0.92,
        impacts_hz=15,
        impact_g=0.95,
        tangential=0.7,
        lateral=0.5,
        alike_of="brick",
    ),
    Surface("felt", 0.08, 50, 1.5, 0.10, tangential=0.8, lateral=0.5),
    Surface("velvet", 0.068, 58, 1.5, 0.14, tangential=0.8, lateral=0.5, alike_of="felt"),
    Surface("denim", 0.09, 150, 1.0, 0.30, texture_mm=1.6, texture=0.8),
    Surface("leather", 0.08, 80, 1.2, 0.35, texture_mm=2.5, texture=0.2, slip_hz=18, slip_g=0.08),
    Surface("foam", 0.07, 30, 2.0, 0.05, slip_hz=12, slip_g=0.15, tangential=0.9, lateral=0.6),
    Surface(
        "silicone-mat",
        0.05,
        100,
        1.0,
        0.25,
        texture_mm=8.0,
        texture=0.4,
        slip_hz=22,
        slip_g=0.45,
        tangential=1.1,
    ),
    Surface("polished-wood", 0.06, 150, 1.0, 0.80, texture_mm=6.0, texture=0.6),
    Surface("rough-wood", 0.18, 120, 1.0, 0.75, texture_mm=4.0, texture=0.5, impacts_hz=3, impact_g=0.5),
    Surface("mdf", 0.07, 220, 1.0, 0.70),
    Surface("abs-plastic", 0.04, 250, 1.0, 0.85, slip_hz=60, slip_g=0.06),
    Surface("vinyl", 0.05, 220, 1.0, 0.65, slip_hz=45, slip_g=0.12, tangential=0.8),
    Surface("wire-mesh", 0.07, 200, 1.0, 0.95, bump_mm=2.0, impact_g=0.3),
    Surface("sandpaper-p60", 0.7, 350, 0.6, 1.00, impacts_hz=40, impact_g=1.8, tangential=0.8, lateral=0.5),
)

_PROBE_RESONANCE_HZ = 220.0  # first bending mode of the stylus
_PROBE_DAMPING = 0.12
_TILT_DEG = 12.0  # the probe leans forward: gravity shows mostly on z, a little on x
_NOISE_LSB = 1.2  # sensor noise, RMS in LSB
_JITTER = 0.08  # log-normal spread of every surface parameter from one seed to another
_SESSION_JITTER = 0.04  # and from one session (re-mounting) to the next
_WEAR = (-0.04, 0.01)  # range of the linear gain drift over one recording


def surface_table(n_surfaces: int = 28) -> list[Surface]:
    """The surfaces of a data set of ``n_surfaces``: :data:`SURFACES` in order, cycled (``name-2`` ...) beyond 28."""
    check_positive(n_surfaces, "n_surfaces", integer=True)
    table = []
    for i in range(n_surfaces):
        base = SURFACES[i % len(SURFACES)]
        lap = i // len(SURFACES)
        table.append(base if lap == 0 else replace(base, name=f"{base.name}-{lap + 1}", alike_of=""))
    return table


def make_vibration_recordings(
    n_surfaces: int = 28,
    *,
    duration_s: float = 60.0,
    n_sessions: int = 1,
    rate_hz: float = SAMPLE_RATE_HZ,
    surfaces: Sequence[Surface] | None = None,
    random_state: RandomState = None,
    noise_lsb: float = _NOISE_LSB,
    session_jitter: float = _SESSION_JITTER,
    alike_distance: float = 1.0,
    wear: tuple[float, float] = _WEAR,
) -> VibrationRecordings:
    """Simulate stylus recordings of ``n_surfaces`` surfaces, ``n_sessions`` recordings each.

    Per recording, in g at ``rate_hz`` (float32, ``(n, 3)``, ``n = round(duration_s * rate_hz)``):

    1. roughness: Gaussian noise with the surface's spectrum, normalised to its RMS, per axis with
       its tangential and lateral gains;
    2. texture tone at ``speed / period`` and two harmonics, with the turntable's 1 % speed wobble;
    3. impacts: Poisson (``impacts_hz``) or regular (every ``bump_mm``), each exciting the probe's
       damped resonance (220 Hz), mostly on z;
    4. stick-slip: quasi-periodic slips (gamma intervals, CV 0.25) on x with a stick-phase sawtooth;
    5. everything filtered by the probe resonance and the surface's hardness low-pass;
    6. slow wear drift: the vibration's gain moves linearly by U(-4 %, +1 %) over the recording and
       wanders by 1 % (0.2 Hz noise);
    7. gravity (1 g, probe tilted 12° ± 1°, mostly z), sensor noise of 1.2 LSB, quantisation to
       3.9 mg and clipping to ±1282 LSB (±4.9998 g).

    Surface parameters are those of :func:`surface_table`, each multiplied by a log-normal jitter of
    8 % drawn per seed (alike surfaces share their partner's jitter, so they stay alike) and by 4 %
    per session.

    The knobs that decide how hard the set is (``noise_lsb``, ``session_jitter``, ``alike_distance``,
    ``wear``) default to the values above; with the defaults the result is the same as before they
    existed.

    Parameters
    ----------
    n_surfaces : int
        Number of surfaces (classes); the first 28 are :data:`SURFACES`. Ignored if ``surfaces``.
    duration_s : float
        Length of every recording.
    n_sessions : int
        Recordings per surface (``session`` is ``"<surface>/<k>"``).
    rate_hz : float
        Sample rate (the sensor's bandwidth is half of it).
    surfaces : sequence of Surface, optional
        Your own surfaces instead of :func:`surface_table` (``alike_of`` names one of them).
    random_state : int, numpy or torch Generator, or None
    noise_lsb : float >= 0
        Sensor noise, RMS in LSB of 3.9 mg (default 1.2).
    session_jitter : float >= 0
        Log-normal spread of every surface parameter from one session to the next (default 0.04):
        larger values make recordings of one surface on different days less alike.
    alike_distance : float >= 0
        How far each ``alike_of`` surface lies from its partner, as a share of the tabulated
        difference: 1 as in :data:`SURFACES`, 0 identical (near-duplicate surfaces), 2 twice as far.
    wear : (float, float)
        Range of the linear gain drift over a recording (default ``(-0.04, 0.01)``: -4 % ... +1 %).

    Returns
    -------
    VibrationRecordings
        ``n_surfaces * n_sessions`` recordings, surface-major, labels ``0 .. n_surfaces - 1``.

    Notes
    -----
    Each recording is generated from its own random stream (derived from ``random_state``, the
    surface index and the session), so a surface's signal does not depend on how many surfaces are
    generated, and memory stays at one recording at a time. About 0.05 s per minute of recording.
    """
    table = surface_table(n_surfaces) if surfaces is None else list(surfaces)
    if not table or not all(isinstance(s, Surface) for s in table):
        raise InputTypeError(f"surfaces must be a non-empty sequence of Surface, got {surfaces!r}")
    check_positive(n_sessions, "n_sessions", integer=True)
    check_positive(duration_s, "duration_s")
    check_positive(rate_hz, "rate_hz")
    check_positive(noise_lsb, "noise_lsb", strict=False)
    check_positive(session_jitter, "session_jitter", strict=False)
    check_positive(alike_distance, "alike_distance", strict=False)
    if len(wear) != 2 or not -1.0 < float(wear[0]) <= float(wear[1]) < math.inf:
        raise ValueError(f"wear must be a range (low, high) with -1 < low <= high, got {wear}")
    n = round(duration_s * rate_hz)
    if n < 2:
        raise ValueError(f"duration_s * rate_hz must give at least 2 samples, got {n}")
    seed = int(numpy_rng(random_state).integers(2**63))
    index = {s.name: i for i, s in enumerate(table)}
    sensor = _Stylus(float(noise_lsb), (float(wear[0]), float(wear[1])))
    signals, labels, sessions = [], [], []
    for i, surface in enumerate(table):
        family = index.get(surface.alike_of, i)
        jitter = np.random.default_rng([seed, family, 0]).lognormal(0.0, _JITTER, size=8)
        if family != i and alike_distance != 1.0:
            surface = _toward(table[family], surface, float(alike_distance))
        for k in range(n_sessions):
            rng = np.random.default_rng([seed, i, k + 1])
            spread = rng.lognormal(0.0, session_jitter, size=8)
            signals.append(_simulate(surface, jitter * spread, n, float(rate_hz), rng, sensor))
            labels.append(i)
            sessions.append(f"{surface.name}/{k}")
    return VibrationRecordings(
        signals=signals,
        labels=np.array(labels),
        class_names=tuple(s.name for s in table),
        rate_hz=float(rate_hz),
        session=np.array(sessions),
    )


@dataclass(frozen=True)
class _Stylus:
    """The knobs of :func:`make_vibration_recordings` that act inside the simulation."""

    noise_lsb: float = _NOISE_LSB
    wear: tuple[float, float] = _WEAR


_NUMERIC_FIELDS = tuple(f.name for f in fields(Surface) if f.type == "float")


def _toward(partner: Surface, surface: Surface, distance: float) -> Surface:
    """``surface`` moved to ``partner + distance * (surface - partner)`` in every numeric parameter."""
    moved = {
        name: max(0.0, getattr(partner, name) + distance * (getattr(surface, name) - getattr(partner, name)))
        for name in _NUMERIC_FIELDS
    }
    return replace(surface, **moved)


def _lowpass_noise(
    rng: np.random.Generator, shape: tuple[int, ...], n: int, rate: float, cutoff_hz: float
) -> np.ndarray:
    """Unit-variance Gaussian noise band-limited to ``cutoff_hz`` (brick-wall in frequency), ``shape + (n,)``."""
    freqs = np.fft.rfftfreq(n, 1.0 / rate)
    spec = (rng.standard_normal(shape + freqs.shape) + 1j * rng.standard_normal(shape + freqs.shape)) * (
        (freqs > 0) & (freqs <= cutoff_hz)
    )
    x = np.fft.irfft(spec, n)
    return x / np.maximum(x.std(axis=-1, keepdims=True), 1e-12)


def _add_stick_slip(
    smooth: np.ndarray,
    impulses: np.ndarray,
    slip_hz: float,
    slip_g: float,
    rate: float,
    rng: np.random.Generator,
) -> None:
    """Add stick-slip to ``smooth`` and ``impulses`` ``(3, n)`` in place (stage 4 of :func:`_simulate`)."""
    n = smooth.shape[1]
    intervals = rng.gamma(16.0, 1.0 / (16.0 * slip_hz), size=int(2 * slip_hz * n / rate) + 4)
    slips = np.round(np.cumsum(intervals) * rate).astype(np.int64)
    slips = slips[slips < n]
    amp = slip_g * rng.lognormal(0.0, 0.2, size=slips.size)
    np.add.at(impulses, (0, slips), -amp)
    np.add.at(impulses, (2, slips), 0.3 * amp)
    if slips.size:
        last = np.concatenate([[0], slips])
        which = np.searchsorted(slips, np.arange(n), side="right")
        nxt = np.concatenate([slips, [n]])
        ramp = (np.arange(n) - last[which]) / np.maximum(nxt[which] - last[which], 1) - 0.5
        smooth[0] += 0.4 * slip_g * ramp


def _simulate(
    surface: Surface,
    jitter: np.ndarray,
    n: int,
    rate: float,
    rng: np.random.Generator,
    sensor: _Stylus = _Stylus(),
) -> np.ndarray:
    """One recording ``(n, 3)`` float32 in g of ``surface`` with parameters scaled by ``jitter`` (8,)."""
    rms, corner, hardness_hz, texture_mm, impact_g, slip_hz, slip_g, event_rate = (
        surface.rms_g * jitter[0],
        surface.corner_hz * jitter[1],
        30.0 * (400.0 / 30.0) ** surface.hardness * jitter[2],
        surface.texture_mm * jitter[3],
        surface.impact_g * jitter[4],
        surface.slip_hz * jitter[5],
        surface.slip_g * jitter[6],
        jitter[7],
    )
    t = np.arange(n) / rate
    freqs = np.fft.rfftfreq(n, 1.0 / rate)
    nyquist = rate / 2
    ratio = freqs / _PROBE_RESONANCE_HZ
    probe = 1.0 / (1.0 - ratio**2 + 2j * _PROBE_DAMPING * ratio)
    contact = 1.0 / np.sqrt(1.0 + (freqs / hardness_hz) ** 4)
    transfer = probe * contact  # (nf,)
    gains = np.array([surface.tangential, surface.lateral, 1.0])[:, None]

    # 1. roughness, shaped in frequency and normalised to its RMS per axis
    shape = np.sqrt(1.0 / (1.0 + (freqs / corner) ** (2 * surface.slope))) * (freqs > 0)
    spec = (
        (rng.standard_normal((3, freqs.size)) + 1j * rng.standard_normal((3, freqs.size))) * shape * transfer
    )
    rough = np.fft.irfft(spec, n)
    rough *= rms * gains / np.maximum(rough.std(axis=-1, keepdims=True), 1e-12)

    # time-domain excitations, filtered below: smooth ones and unit impulses
    smooth = np.zeros((3, n))
    impulses = np.zeros((3, n))
    speed = SPEED_M_S * (1.0 + 0.01 * np.sin(2 * np.pi * t / 1.07 + rng.uniform(0, 2 * np.pi)))
    speed *= 1.0 + 0.003 * _lowpass_noise(rng, (), n, rate, 0.5)
    distance_mm = np.cumsum(speed) / rate * 1000.0

    # 2. texture tone and harmonics below the sensor's Nyquist frequency
    if texture_mm > 0 and surface.texture > 0:
        phase = 2 * np.pi * distance_mm / texture_mm
        base_hz = SPEED_M_S * 1000.0 / texture_mm
        tone = np.zeros(n)
        for h, level in ((1, 1.0), (2, 0.5), (3, 0.25)):  # three harmonics
            if h * base_hz < 0.95 * nyquist:
                tone += level * np.cos(h * phase + rng.uniform(0, 2 * np.pi))
        smooth += np.array([0.5, 0.2, 1.0])[:, None] * (surface.texture * rms * tone)

    # 3. impacts: sparse (Poisson) and regular (bumps every bump_mm, 3 % spacing jitter)
    times = []
    if surface.impacts_hz > 0:
        count = rng.poisson(surface.impacts_hz * event_rate * n / rate)
        times.append(rng.integers(0, n, size=count))
    if surface.bump_mm > 0:
        bumps = distance_mm / (surface.bump_mm * event_rate) + 0.03 * _lowpass_noise(rng, (), n, rate, 2.0)
        times.append(np.flatnonzero(np.diff(np.floor(bumps)) > 0) + 1)
    if times:
        at = np.concatenate(times)
        amp = impact_g * rng.lognormal(0.0, 0.4 if surface.impacts_hz > 0 else 0.2, size=at.size)
        direction = np.stack([rng.normal(0.3, 0.2, at.size), rng.normal(0.0, 0.2, at.size), np.ones(at.size)])
        np.add.at(impulses, (slice(None), at), direction * amp)

    # 4. stick-slip: slips on x (and a little z) at gamma-distributed intervals, sawtooth in between
    if slip_hz > 0 and slip_g > 0:
        _add_stick_slip(smooth, impulses, slip_hz, slip_g, rate, rng)

    # 5. through the probe and the contact; impulses scaled so one impact peaks at its amplitude
    response = np.fft.irfft(transfer, n)
    peak = np.abs(response).max()
    excited = np.fft.rfft(smooth) * transfer + np.fft.rfft(impulses) * (transfer / peak)
    excited[:, 0] = 0.0  # a stylus that stays on the surface has no mean acceleration
    vib = rough + np.fft.irfft(excited, n)

    # 6. wear drift and slow wander of the gain
    drift = 1.0 + rng.uniform(*sensor.wear) * t / t[-1] + 0.01 * _lowpass_noise(rng, (), n, rate, 0.2)
    vib *= drift

    # 7. gravity, sensor noise, quantisation, clipping
    tilt = np.deg2rad(_TILT_DEG + rng.normal(0.0, 1.0))
    vib += np.array([np.sin(tilt), 0.0, np.cos(tilt)])[:, None]
    vib += rng.normal(0.0, sensor.noise_lsb * QUANTUM_G, size=vib.shape)
    top = math.floor(RANGE_G / QUANTUM_G)
    codes = np.clip(np.rint(vib / QUANTUM_G), -top, top)
    return (codes * QUANTUM_G).T.astype(np.float32)


def make_vibration_dataset(
    n_surfaces: int = 28,
    *,
    windows_per_surface: int = 100,
    window_size: int = 800,
    n_sessions: int = 1,
    random_state: RandomState = None,
) -> VibrationWindows:
    """Simulate recordings (:func:`make_vibration_recordings`) and cut them into windows.

    Each surface gets ``windows_per_surface`` consecutive non-overlapping windows of ``window_size``
    samples at 800 Hz, spread over its ``n_sessions`` recordings (just long enough).

    Returns
    -------
    VibrationWindows
        ``windows`` ``(n_surfaces * windows_per_surface, 3, window_size)`` float32 in g, surface-major
        and in time order, ``labels``, ``recording``, ``position`` (odd/even split: ``position % 2``).

    Examples
    --------
    >>> ds = make_vibration_dataset(n_surfaces=2, windows_per_surface=4, window_size=400, random_state=1)
    >>> ds.windows.shape, ds.labels.tolist()
    (torch.Size([8, 3, 400]), [0, 0, 0, 0, 1, 1, 1, 1])
    """
    check_positive(windows_per_surface, "windows_per_surface", integer=True)
    check_positive(window_size, "window_size", integer=True)
    check_positive(n_sessions, "n_sessions", integer=True)
    if windows_per_surface % n_sessions:
        raise ValueError(
            f"windows_per_surface must be a multiple of n_sessions={n_sessions}, got {windows_per_surface}"
        )
    per_session = windows_per_surface // n_sessions
    rec = make_vibration_recordings(
        n_surfaces,
        duration_s=per_session * window_size / SAMPLE_RATE_HZ,
        n_sessions=n_sessions,
        random_state=random_state,
    )
    return rec.windows(window_size)


__all__ = [
    "SPEED_M_S",
    "SURFACES",
    "Surface",
    "make_vibration_dataset",
    "make_vibration_recordings",
    "surface_table",
]
