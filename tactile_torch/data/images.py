"""Tactile-image explorations: a seeded synthetic generator and the ``.npz`` loader/saver.

The generator simulates the study's setting (method 1): a fingertip presses on a textured
surface lying on a pressure-mapping array and moves over it for 10 s at 10 frames/s. Per exploration:

1. **Surface**: one of :data:`OBJECTS`, embossed sheets and household objects of the four classes
   (dots, dashes, horizontal lines, grid) that differ in pitch, element size, orientation and relief,
   placed with a random shift and a small random rotation. Its height map ``h`` (mm) is rendered on a
   fine grid (4 x 4 points per sensel).
2. **Finger**: an elliptic paraboloid (radii 7-11 mm, 1.4 times longer along the finger, random
   finger angle) pressed to a depth ``d(t)`` that varies (a random mean force, a slow oscillation,
   noise, touch-down and lift-off ramps) and moved along a smooth random path (about 5-20 mm/s).
3. **Contact pressure**: ``p ∝ max(0, d(t) + h - relief - q(x - c(t)))^1.5`` (``q`` the paraboloid):
   a light press touches only the tops of the raised elements, a firm one also the base.
4. **Sensor**: the pressure is averaged over each sensel of a coarse grid (default 24 x 24 sensels of
   1.33 mm), multiplied by a per-sensel gain (±5 %), plus Gaussian noise (1.5 counts), quantised to
   8 bits (saturation 255) and zeroed below a noise threshold of 3 counts.
5. **Display**: the sensel map is upsampled bilinearly to ``frame_size`` pixels (like a pressure-mapping
   display), white where the interpolated pressure is below 4 counts, a jet colour map above.

The classes are not trivially separable: coarse sensels blur fine textures, a firm press fills the
grooves, long dashes look like lines, a rectangular grid with one wide pitch looks like lines inside a
fingertip-sized contact, and the path covers a random part of the surface. ``docs/image.md`` gives the
accuracy simple classifiers reach on the method-1 features of this set.

The knobs that decide how hard the set is are arguments of :func:`make_explorations`: the sensel pitch
(``sensel_pitch_mm``), the fingertip's size (``contact_mm``), the texture's spatial scale
(``texture_scale``), the share of look-alike objects (``near_duplicates``, :data:`NEAR_DUPLICATES`)
and the sensor noise (``noise_counts``). Their defaults give the set above; conclusions drawn on it
should be checked at other settings (``tactile_torch.studies.claims`` does).

The ``.npz`` format (docs/formats.md): ``frames`` uint8 ``(N, T, H, W, 3)`` RGB, ``labels`` int64 ``(N,)``,
``class_names`` str ``(C,)``, optional ``groups`` int64 ``(N,)``; raw pressure maps ``(N, T, H, W)``
float are accepted in place of ``frames`` and rendered with :func:`render_pressure`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from ..validation import RandomState, check_finite, check_positive, check_tensor, numpy_rng, torch_generator

CLASS_NAMES = ("dots", "dashes", "horizontal_lines", "grid")
"""The four texture classes of the study, in label order."""

SENSEL_PITCH_MM = 4.0 / 3.0
"""Distance between sensel centres (mm)."""
FRAME_RATE_HZ = 10.0
"""Frames per second of the simulated recordings (the study: 10)."""
SATURATION = 255.0
"""Sensor reading that maps to the top of the colour map (8-bit ADC)."""
NOISE_THRESHOLD = 3.0
"""Sensel readings below this many counts are set to 0 (the sensor software's noise threshold)."""
DISPLAY_FLOOR = 4.0
"""Interpolated readings below this many counts are shown white."""
_OVERSAMPLE = 4  # fine-grid points per sensel side: the pressure is integrated over each sensel


@dataclass(frozen=True)
class SurfaceObject:
    """A textured object: the elements' layout and size (mm) and the relief height (mm).

    ``size_mm`` is the diameter of a dot or the width of a dash or line; ``length_mm`` the length of a
    dash; ``pitch_mm`` the distance between rows (lines, dashes) or lattice points (dots);
    ``pitch2_mm`` the distance between dashes along a row or between the second family of grid lines;
    ``stagger`` offsets every other row by half a period (hexagonal dots, brick-like dashes);
    ``orientation_deg`` rotates the pattern (0: rows horizontal).
    """

    name: str
    pattern: str
    pitch_mm: float
    size_mm: float
    relief_mm: float
    orientation_deg: float = 0.0
    pitch2_mm: float | None = None
    length_mm: float = 0.0
    stagger: bool = False


OBJECTS: tuple[SurfaceObject, ...] = (
    SurfaceObject("embossed sheet (dots)", "dots", 7.0, 3.5, 0.6),
    SurfaceObject("LEGO baseplate", "dots", 8.0, 4.8, 1.7),
    SurfaceObject("rubber shower mat", "dots", 10.0, 6.0, 2.5, 15.0, stagger=True),
    SurfaceObject("bubble wrap", "dots", 11.0, 9.0, 3.0, 0.0, stagger=True),
    SurfaceObject("embossed sheet (dashes)", "dashes", 7.0, 3.0, 0.6, 0.0, 11.0, 7.0, stagger=True),
    SurfaceObject("anti-slip stair tread", "dashes", 9.0, 3.5, 1.5, 0.0, 18.0, 14.0),
    SurfaceObject("rubber door mat", "dashes", 8.0, 4.0, 2.0, 0.0, 15.0, 10.0, stagger=True),
    SurfaceObject("toy tyre tread", "dashes", 10.0, 4.0, 2.0, 10.0, 12.0, 6.0),
    SurfaceObject("embossed sheet (lines)", "horizontal_lines", 7.0, 3.0, 0.6),
    SurfaceObject("ribbed rubber mat", "horizontal_lines", 6.0, 3.0, 1.5, -8.0),
    SurfaceObject("corrugated plastic sheet", "horizontal_lines", 5.0, 2.5, 1.0, 5.0),
    SurfaceObject("bamboo placemat", "horizontal_lines", 9.0, 7.0, 1.0),
    SurfaceObject("embossed sheet (grid)", "grid", 8.0, 2.5, 0.6),
    SurfaceObject("oven cooling rack", "grid", 7.0, 2.5, 3.0, 0.0, 16.0),
    SurfaceObject("silicone baking mat", "grid", 10.0, 4.0, 2.0, 20.0),
    SurfaceObject("plastic canvas mesh", "grid", 5.0, 2.0, 1.0),
)
"""The simulated objects: four per class, an embossed sheet and three household objects each."""

NEAR_DUPLICATES: tuple[SurfaceObject, ...] = (
    SurfaceObject("beaded rows", "dots", 8.0, 3.5, 0.6, 0.0, 4.0),
    SurfaceObject("long-dash sheet", "dashes", 7.0, 3.0, 0.6, 0.0, 12.0, 11.0),
    SurfaceObject("fine ribbed sheet", "horizontal_lines", 4.0, 2.0, 0.6),
    SurfaceObject("wide grid", "grid", 7.0, 3.0, 0.6, 0.0, 30.0),
)
"""One look-alike object per class, close to another class inside a fingertip-sized contact: touching
beads in rows and dashes with 1 mm gaps (both look like lines), lines at 4 mm (three sensels: the
texture blurs away), a grid whose second family of lines is 30 mm apart (lines, mostly)."""

DEFAULT_CONTACT_MM = (6.0, 9.0)
"""Range of the fingertip pad's semi-axis along the finger (mm); the pad is 1.3 times narrower across."""
DEFAULT_NOISE_COUNTS = 1.5
"""Standard deviation of the sensor noise (counts)."""


@dataclass
class ImageExplorations:
    """A set of tactile-image explorations.

    Attributes
    ----------
    frames : tensor of shape (N, T, 3, H, W), uint8
        RGB frames as a pressure-mapping display shows them (white: no pressure).
    labels : tensor of shape (N,), int64
    class_names : tuple of str
    groups : tensor of shape (N,), int64, or None
        Grouping for grouped splits; for the synthetic set, the index of the object in
        :data:`OBJECTS`.
    pressure : tensor of shape (N, T, S, S), float32, or None
        The sensel readings (0-255 counts) behind the frames, when known.
    frame_rate_hz : float or None
        Frames per second, when known (the generator's :data:`FRAME_RATE_HZ`; a file's ``frame_rate_hz``).
    """

    frames: torch.Tensor
    labels: torch.Tensor
    class_names: tuple[str, ...]
    groups: torch.Tensor | None = None
    pressure: torch.Tensor | None = None
    frame_rate_hz: float | None = None

    def __len__(self) -> int:
        return int(self.labels.shape[0])


def jet(x: torch.Tensor) -> torch.Tensor:
    """Return the jet colour (dark blue → cyan → yellow → dark red) of values in [0, 1]: (...) → (..., 3)."""
    x = x.clamp(0.0, 1.0).unsqueeze(-1)
    centres = torch.tensor([3.0, 2.0, 1.0], dtype=x.dtype)  # R, G, B
    return (1.5 - (4.0 * x - centres).abs()).clamp(0.0, 1.0)


def render_pressure(
    pressure: torch.Tensor,
    frame_size: int | tuple[int, int] | None = None,
    *,
    saturation: float | None = None,
) -> torch.Tensor:
    """Return display frames of pressure maps: jet colours where there is pressure, white elsewhere.

    The maps are upsampled bilinearly (``align_corners=False``) to ``frame_size`` and shown white
    where the interpolated value is below :data:`DISPLAY_FLOOR` counts on the ``saturation`` scale.

    Parameters
    ----------
    pressure : tensor of shape (N, T, h, w), float, >= 0
    frame_size : int or (H, W), optional
        Display size; default: the maps' own size.
    saturation : float, optional
        Reading shown at the top of the colour map. Default: :data:`SATURATION` (255 counts), or 1 if
        no value exceeds 1 (maps given as fractions of saturation).

    Returns
    -------
    tensor of shape (N, T, 3, H, W), uint8

    Examples
    --------
    >>> render_pressure(torch.zeros(1, 2, 4, 4), 8).shape
    torch.Size([1, 2, 3, 8, 8])
    """
    check_tensor(pressure, "pressure")
    if pressure.ndim != 4:
        raise ValueError(f"pressure must have shape (N, T, h, w), got {tuple(pressure.shape)}")
    pressure = pressure.float()
    check_finite(pressure, "pressure")
    if saturation is None:
        saturation = SATURATION if pressure.numel() == 0 or float(pressure.max()) > 1.0 else 1.0
    check_positive(saturation, "saturation")
    size = (frame_size, frame_size) if isinstance(frame_size, int) else frame_size
    n, t, h, w = pressure.shape
    scaled = pressure.reshape(n * t, 1, h, w) / saturation
    if size is not None and tuple(size) != (h, w):
        scaled = F.interpolate(scaled, size=tuple(size), mode="bilinear", align_corners=False)
    scaled = scaled.reshape(n, t, *scaled.shape[-2:])
    white = scaled < DISPLAY_FLOOR / SATURATION
    x = scaled.clamp(0.0, 1.0)
    # jet(), one channel at a time in place: the same float operations in the same order (so the same
    # bytes), without the (..., 3) intermediates that made this the generator's slowest step.
    frames = torch.empty((n, t, 3, *x.shape[-2:]), dtype=torch.uint8)
    channel = torch.empty_like(x)
    for c, centre in enumerate((3.0, 2.0, 1.0)):  # R, G, B as in jet()
        torch.mul(x, 4.0, out=channel)
        channel.sub_(centre).abs_().neg_().add_(1.5).clamp_(0.0, 1.0)  # 1.5 - |4x - centre|
        channel.masked_fill_(white, 1.0).mul_(255.0).round_()
        frames[:, :, c] = channel
    return frames


# ------------------------------------------------------------------------------------ height maps
def _edge(inside: torch.Tensor, shoulder: float = 0.3) -> torch.Tensor:
    """Height fraction from the signed distance inside an element (mm): a soft 0.3 mm shoulder."""
    return (inside / shoulder + 0.5).clamp(0.0, 1.0)


def _centred(x: torch.Tensor, period: float) -> torch.Tensor:
    """Offset from the nearest multiple of ``period`` (in [-period/2, period/2))."""
    return torch.remainder(x + period / 2, period) - period / 2


def _height(obj: SurfaceObject, u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Height fraction (0-1) of ``obj`` at pattern coordinates ``(u, v)`` in mm (u along rows)."""
    p, half = obj.pitch_mm, obj.size_mm / 2
    if obj.pattern == "horizontal_lines":
        return _edge(half - _centred(v, p).abs())
    if obj.pattern == "grid":
        p2 = obj.pitch2_mm or p
        return torch.maximum(_edge(half - _centred(v, p).abs()), _edge(half - _centred(u, p2).abs()))
    period = obj.pitch2_mm or p
    rows = [(0.0, 0.0)]
    if obj.stagger:  # every other row shifted by half a period: two lattices with twice the row pitch
        rows = [(0.0, 0.0), (period / 2, p)]
    distance = None
    for du, dv in rows:
        a = _centred(u - du, period)
        b = _centred(v - dv, 2 * p if obj.stagger else p)
        if obj.pattern == "dashes":  # a stadium: a segment of length (length - width) thickened
            a = (a.abs() - (obj.length_mm - obj.size_mm) / 2).clamp(min=0.0)
        d = torch.sqrt(a * a + b * b)
        distance = d if distance is None else torch.minimum(distance, d)
    return _edge(half - distance)


def _smooth_noise(rng: np.random.Generator, n: int, t: np.ndarray, periods: tuple[float, float], k: int = 3):
    """Sum of ``k`` random sinusoids per row (unit total amplitude): (n, len(t))."""
    period = rng.uniform(*periods, size=(n, k, 1))
    phase = rng.uniform(0, 2 * np.pi, size=(n, k, 1))
    amp = rng.dirichlet(np.ones(k), size=n)[..., None]
    return (amp * np.sin(2 * np.pi * t / period + phase)).sum(1)


def make_explorations(
    n_per_class: int = 60,
    *,
    n_frames: int = 100,
    frame_size: int = 96,
    sensels: int = 24,
    objects: tuple[SurfaceObject, ...] = OBJECTS,
    random_state: RandomState = None,
    keep_pressure: bool = False,
    sensel_pitch_mm: float = SENSEL_PITCH_MM,
    contact_mm: tuple[float, float] = DEFAULT_CONTACT_MM,
    texture_scale: float = 1.0,
    near_duplicates: float = 0.0,
    noise_counts: float = DEFAULT_NOISE_COUNTS,
) -> ImageExplorations:
    """Return ``n_per_class`` simulated explorations of each class (objects drawn evenly within a class).

    See the module docstring for the model. Deterministic for a given ``random_state``; with the
    default knobs (the last five arguments) the result is the same as before the knobs existed.

    Parameters
    ----------
    n_per_class : int >= 1
    n_frames : int >= 1
        Frames per exploration at 10 frames/s (the study: 100, i.e. 10 s).
    frame_size : int >= sensels
        Side of the displayed frames in pixels.
    sensels : int >= 4
        Sensels per side of the sensor (pitch ``sensel_pitch_mm``).
    objects : tuple of SurfaceObject
        The objects to simulate; their ``pattern`` must be one of :data:`CLASS_NAMES`.
    random_state : int, numpy.random.Generator, torch.Generator or None
    keep_pressure : bool
        Also return the sensel readings (``pressure``).
    sensel_pitch_mm : float > 0
        Distance between sensel centres (default :data:`SENSEL_PITCH_MM`): a larger pitch is a coarser
        sensor over a larger area (``sensels`` stays the count per side).
    contact_mm : (float, float)
        Range of the fingertip pad's semi-axis (mm), drawn per exploration: a larger pad covers more
        texture periods per frame.
    texture_scale : float > 0
        Multiplies every object's pitches and element sizes (not the relief): below 1 the textures
        get finer than the sensels can resolve.
    near_duplicates : float in [0, 1]
        Share of each class's explorations made on that class's look-alike object
        (:data:`NEAR_DUPLICATES`, appended to ``objects``) instead of ``objects``.
    noise_counts : float >= 0
        Standard deviation of the sensor noise in counts (default 1.5).

    Returns
    -------
    ImageExplorations
        ``frames`` (N, T, 3, frame_size, frame_size) uint8 with N = 4 * n_per_class, in class order;
        ``groups`` holds each exploration's index in ``objects`` (followed by :data:`NEAR_DUPLICATES`
        when ``near_duplicates > 0``).

    Examples
    --------
    >>> data = make_explorations(1, n_frames=5, frame_size=48, random_state=0)
    >>> data.frames.shape, data.labels.tolist()
    (torch.Size([4, 5, 3, 48, 48]), [0, 1, 2, 3])
    """
    for value, name in ((n_per_class, "n_per_class"), (n_frames, "n_frames"), (frame_size, "frame_size")):
        check_positive(value, name, integer=True)
    check_positive(sensels, "sensels", integer=True)
    if sensels < 4 or frame_size < sensels:
        raise ValueError(f"need 4 <= sensels <= frame_size, got sensels={sensels}, frame_size={frame_size}")
    unknown = sorted({o.pattern for o in objects} - set(CLASS_NAMES))
    if unknown:
        raise ValueError(f"objects must have patterns among {CLASS_NAMES}, got {unknown}")
    check_positive(sensel_pitch_mm, "sensel_pitch_mm")
    check_positive(texture_scale, "texture_scale")
    check_positive(noise_counts, "noise_counts", strict=False)
    if len(contact_mm) != 2 or not 0.0 < float(contact_mm[0]) <= float(contact_mm[1]) < math.inf:
        raise ValueError(f"contact_mm must be a range (low, high) with 0 < low <= high, got {contact_mm}")
    if not 0.0 <= float(near_duplicates) <= 1.0:
        raise ValueError(f"near_duplicates must be a share in [0, 1], got {near_duplicates}")
    rng = numpy_rng(random_state)
    per_class = {c: [i for i, o in enumerate(objects) if o.pattern == c] for c in CLASS_NAMES}
    missing = [c for c, idx in per_class.items() if not idx]
    if missing:
        raise ValueError(f"objects must include every class, missing {missing}")
    labels = np.repeat(np.arange(len(CLASS_NAMES)), n_per_class)
    n_alike = round(float(near_duplicates) * n_per_class)
    if n_alike:
        objects = (*objects, *NEAR_DUPLICATES)
    alike = {o.pattern: len(objects) - len(NEAR_DUPLICATES) + k for k, o in enumerate(NEAR_DUPLICATES)}
    groups = np.concatenate(
        [
            np.concatenate(
                [np.resize(rng.permutation(per_class[c]), n_per_class - n_alike), np.full(n_alike, alike[c])]
            ).astype(np.int64)
            for c in CLASS_NAMES
        ]
    )  # objects evenly (and in random order) within each class, then the look-alikes
    if texture_scale != 1.0:
        objects = tuple(_scaled(o, float(texture_scale)) for o in objects)
    gen = torch_generator(rng)
    frames, pressure = [], []
    batch = max(1, (1 << 22) // (n_frames * (sensels * _OVERSAMPLE) ** 2))
    sensor = _Sensor(
        float(sensel_pitch_mm), (float(contact_mm[0]), float(contact_mm[1])), float(noise_counts)
    )
    for start in range(0, len(labels), batch):
        chunk = groups[start : start + batch]
        p = _simulate_pressure([objects[i] for i in chunk], n_frames, sensels, rng, gen, sensor)
        frames.append(render_pressure(p, frame_size))
        if keep_pressure:
            pressure.append(p)
    return ImageExplorations(
        frames=torch.cat(frames),
        labels=torch.as_tensor(labels, dtype=torch.int64),
        class_names=CLASS_NAMES,
        groups=torch.as_tensor(groups, dtype=torch.int64),
        pressure=torch.cat(pressure) if keep_pressure else None,
        frame_rate_hz=FRAME_RATE_HZ,
    )


@dataclass(frozen=True)
class _Sensor:
    """The knobs of :func:`make_explorations` that act inside the simulation."""

    pitch_mm: float = SENSEL_PITCH_MM
    contact_mm: tuple[float, float] = DEFAULT_CONTACT_MM
    noise_counts: float = DEFAULT_NOISE_COUNTS


def _scaled(obj: SurfaceObject, factor: float) -> SurfaceObject:
    """``obj`` with its pitches and element sizes multiplied by ``factor`` (relief unchanged)."""
    return replace(
        obj,
        pitch_mm=obj.pitch_mm * factor,
        size_mm=obj.size_mm * factor,
        length_mm=obj.length_mm * factor,
        pitch2_mm=None if obj.pitch2_mm is None else obj.pitch2_mm * factor,
    )


def _simulate_pressure(
    objs: list[SurfaceObject],
    n_frames: int,
    sensels: int,
    rng: np.random.Generator,
    gen: torch.Generator,
    sensor: _Sensor = _Sensor(),
) -> torch.Tensor:
    """Sensel readings (n, T, S, S) in counts for one explorations per object in ``objs``."""
    n = len(objs)
    fine = sensels * _OVERSAMPLE
    extent = sensels * sensor.pitch_mm
    axis = (torch.arange(fine, dtype=torch.float32) + 0.5) * (extent / fine)  # mm, fine-grid centres
    y, x = torch.meshgrid(axis, axis, indexing="ij")

    # Surface, fixed on the sensor for the whole exploration: random shift and a small rotation.
    angle = np.deg2rad([o.orientation_deg for o in objs] + rng.uniform(-3, 3, n))
    shift = rng.uniform(0, 50, size=(n, 2))
    heights = []
    for obj, a, (su, sv) in zip(objs, angle, shift, strict=True):
        u = x * math.cos(a) + y * math.sin(a) + su
        v = -x * math.sin(a) + y * math.cos(a) + sv
        heights.append(_height(obj, u, v) * obj.relief_mm)
    height = torch.stack(heights)[:, None]  # (n, 1, G, G)
    relief = torch.tensor([o.relief_mm for o in objs], dtype=torch.float32).view(n, 1, 1, 1)

    # Finger: depth over time (mean force, oscillation, noise, touch-down and lift-off ramps).
    t = np.arange(n_frames) / FRAME_RATE_HZ
    duration = max(t[-1], 1e-9)
    depth = relief.view(n, 1).numpy() * rng.uniform(0.3, 0.8, (n, 1))
    depth = depth * (
        1 + 0.35 * _smooth_noise(rng, n, t, (2.0, 8.0)) + 0.05 * rng.standard_normal((n, n_frames))
    )
    touch = rng.uniform(0.0, 0.12, (n, 1)) * duration
    lift = duration * (1.0 - rng.uniform(0.0, 0.12, (n, 1)))
    ramp = np.clip(np.minimum(t - touch, lift - t) / 0.4, 0.0, 1.0)
    depth = np.clip(depth, 0.0, None) * ramp
    # Path: a smooth wander around a random centre, amplitude about a third of the sensor.
    centre = rng.uniform(0.35, 0.65, (n, 2, 1)) * extent
    amplitude = rng.uniform(0.15, 0.35, (n, 2, 1)) * extent
    wander = np.stack([_smooth_noise(rng, n, t, (3.0, 12.0)), _smooth_noise(rng, n, t, (3.0, 12.0))], 1)
    path = centre + amplitude * wander / np.maximum(np.abs(wander).max(-1, keepdims=True), 1e-9)
    semi_axis = rng.uniform(*sensor.contact_mm, (n, 1))  # mm along the finger; 1.3 times shorter across
    finger = rng.uniform(0, np.pi, (n, 1))

    def frames_tensor(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(a, dtype=torch.float32).view(n, -1, 1, 1)

    cx, cy = frames_tensor(path[:, 0]), frames_tensor(path[:, 1])
    cos_f, sin_f = frames_tensor(np.cos(finger)), frames_tensor(np.sin(finger))
    a = frames_tensor(semi_axis)
    # (n, T, G, G) arrays, updated in place: the same float operations in the same order as the formulas
    # in the comments (so the same bytes), with a third of the memory traffic.
    dx, dy = x - cx, y - cy
    along = dx * cos_f
    along.add_(dy * sin_f)  # along = (x - cx) cos + (y - cy) sin
    across = dx.neg_().mul_(sin_f)
    across.add_(dy.mul_(cos_f))  # across = -(x - cx) sin + (y - cy) cos
    del dx, dy
    rho2 = along.div_(a).pow_(2)
    rho2.add_(across.mul_(1.3).div_(a).pow_(2))  # rho2 = (along / a)^2 + (1.3 across / a)^2
    del across
    gap = rho2.mul_(rho2)  # mm: a flat pad, 1 mm above the surface at the rim of its ellipse
    overlap = (
        (frames_tensor(depth) + height).sub_(relief).sub_(gap).clamp_(min=0.0)
    )  # depth + h - relief - gap
    del gap, rho2
    stiffness = torch.as_tensor(rng.uniform(90.0, 160.0, n), dtype=torch.float32).view(n, 1, 1, 1)
    root = overlap.sqrt()
    contact = overlap.mul_(stiffness).mul_(
        root
    )  # counts; Hertz-like p ∝ overlap^1.5 (stiffness overlap sqrt)

    # Sensor: area average per sensel, gain, noise, 8-bit quantisation, noise threshold.
    readings = F.avg_pool2d(contact.reshape(-1, 1, fine, fine), _OVERSAMPLE).reshape(
        n, n_frames, sensels, sensels
    )
    gain = 1.0 + 0.05 * torch.randn(n, 1, sensels, sensels, generator=gen)
    readings = readings * gain + sensor.noise_counts * torch.randn(readings.shape, generator=gen)
    readings = torch.round(readings).clamp(0.0, SATURATION)
    return torch.where(readings < NOISE_THRESHOLD, 0.0, readings)


# ------------------------------------------------------------------------------------------ .npz io
def save_explorations(path: str | Path, data: ImageExplorations) -> Path:
    """Write ``data`` to ``path`` in the image ``.npz`` format (frames channels-last); return the path.

    See :func:`tactile_torch.robot.files.formats.write_explorations` (``.npz`` is appended when missing, as
    :func:`numpy.savez` does).
    """
    from ..robot.files.formats import ExplorationArrays, write_explorations

    arrays = ExplorationArrays(
        frames=data.frames.permute(0, 1, 3, 4, 2).contiguous().numpy(),
        pressure=None,
        labels=data.labels.numpy().astype(np.int64),
        class_names=tuple(data.class_names),
        groups=None if data.groups is None else data.groups.numpy().astype(np.int64),
        frame_rate_hz=data.frame_rate_hz,
    )
    return write_explorations(path, arrays)


def load_explorations(path: str | Path, *, frame_size: int | None = None) -> ImageExplorations:
    """Read an image-exploration ``.npz`` (see the module docstring) into tensors.

    ``frames`` uint8 ``(N, T, H, W, 3)`` become ``(N, T, 3, H, W)``; raw pressure maps ``(N, T, H, W)``
    (float) are rendered with :func:`render_pressure` (to ``frame_size`` if given) and kept in
    ``pressure``. Raises ``ValueError`` naming the file and the key for a missing key or a wrong
    shape or dtype (:func:`tactile_torch.robot.files.formats.read_explorations`).
    """
    from ..robot.files.formats import read_explorations

    return explorations_from_arrays(read_explorations(path), frame_size=frame_size)


def explorations_from_arrays(arrays, *, frame_size: int | None = None) -> ImageExplorations:
    """Return :class:`ImageExplorations` (tensors, channels first) of a file's validated arrays.

    ``arrays`` is a :class:`tactile_torch.robot.files.formats.ExplorationArrays`; pressure maps are rendered
    with :func:`render_pressure` (to ``frame_size`` if given).
    """
    pressure = None
    if arrays.frames is not None:
        frames = torch.from_numpy(arrays.frames).permute(0, 1, 4, 2, 3).contiguous()
    else:
        pressure = torch.from_numpy(np.ascontiguousarray(arrays.pressure, dtype=np.float32))
        frames = render_pressure(pressure, frame_size)
    return ImageExplorations(
        frames=frames,
        labels=torch.from_numpy(arrays.labels.astype(np.int64)),
        class_names=tuple(arrays.class_names),
        groups=None if arrays.groups is None else torch.from_numpy(arrays.groups.astype(np.int64)),
        pressure=pressure,
        frame_rate_hz=getattr(arrays, "frame_rate_hz", None),
    )


__all__ = [
    "CLASS_NAMES",
    "NEAR_DUPLICATES",
    "OBJECTS",
    "ImageExplorations",
    "SurfaceObject",
    "explorations_from_arrays",
    "jet",
    "load_explorations",
    "make_explorations",
    "render_pressure",
    "save_explorations",
]
