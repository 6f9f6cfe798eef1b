"""Signals no surface gives (zeros, constants, noise, tones, a still sensor): the one generator of them.

:func:`out_of_distribution_signals` draws the windows the "unknown" rule of an exported classifier
(:mod:`tactile_torch.ood`) is measured on (``tests/export/test_model_graph.py``,
``export/measure_unknown.py``, the numbers of ``docs/export.md``). NumPy only.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..validation import check_count, check_positive, numpy_rng

OUT_OF_DISTRIBUTION_KINDS = (
    "zeros",
    "constant",
    "constant 1 g",
    "white noise 4.9 g",
    "white noise sd 0.01 g",
    "white noise sd 0.1 g",
    "white noise sd 1 g",
    "pure tone",
    "square wave",
    "still sensor",
)
"""Signals of :func:`out_of_distribution_signals`, in the order they are drawn."""
STILL_NOISE_G = 0.0047
"""A still sensor's noise (standard deviation, g): 1.2 LSB of the ADXL345's 3.9 mg, as the bundled generator's."""
STILL_STEP_G = 0.0039
"""A still sensor's resolution (g): its readings are multiples of it."""


def out_of_distribution_signals(
    n: int,
    window: int,
    rate_hz: float,
    random_state: object = None,
    *,
    kinds: Sequence[str] | None = None,
) -> dict[str, np.ndarray]:
    """Return ``n`` vibration windows ``(n, 3, window)`` float32 of each signal no surface gives, by kind.

    The kinds (:data:`OUT_OF_DISTRIBUTION_KINDS`): ``"zeros"``; ``"constant"`` (each axis constant,
    uniform in [-4, 4] g) and ``"constant 1 g"`` (0, 0, 1 g: a sensor at rest), as a stuck sensor
    gives; white noise uniform in ±4.9 g, and Gaussian of sd 0.01, 0.1 and 1 g (the last clipped to
    ±5 g); a ``"pure tone"`` and a ``"square wave"`` of one frequency per window, uniform in
    [5, rate_hz / 2.2] Hz, an amplitude uniform in [0.05, 4] g and a phase per axis; a ``"still
    sensor"``: gravity (1 g) tilted by an angle uniform in [0, 30] degrees from z towards x, plus
    Gaussian noise of :data:`STILL_NOISE_G` per axis, rounded to the resolution :data:`STILL_STEP_G`
    (a sensor at rest: not constant, yet no surface's vibration). The tones' frequencies, phases and
    amplitudes are drawn first, then each selected kind in the order above; a kind left out draws
    nothing, so a kind's windows depend only on the seed and the kinds before it.

    Parameters
    ----------
    n : int
        Windows of each kind (>= 1).
    window : int
        Samples per window (>= 1).
    rate_hz : float
        Sample rate in Hz (> 0): sets the tones' time axis and top frequency.
    random_state : int, numpy or torch generator, or None
        Source of randomness; a ``numpy.random.Generator`` is drawn from as is.
    kinds : sequence of str, optional
        The kinds to return, in the order given (default: all of :data:`OUT_OF_DISTRIBUTION_KINDS`).

    Examples
    --------
    >>> signals = out_of_distribution_signals(2, 8, 100.0, random_state=0, kinds=["zeros", "pure tone"])
    >>> {kind: x.shape for kind, x in signals.items()}
    {'zeros': (2, 3, 8), 'pure tone': (2, 3, 8)}
    """
    n = check_count(n, "n", 1)
    window = check_count(window, "window", 1)
    check_positive(rate_hz, "rate_hz")
    selected = OUT_OF_DISTRIBUTION_KINDS if kinds is None else tuple(kinds)
    unknown = [kind for kind in selected if kind not in OUT_OF_DISTRIBUTION_KINDS]
    if unknown or not selected:
        raise ValueError(
            f"kinds must be a non-empty list of {list(OUT_OF_DISTRIBUTION_KINDS)}, got {kinds!r}"
        )
    rng = numpy_rng(random_state)
    t = np.arange(window) / rate_hz
    freq = rng.uniform(5, rate_hz / 2.2, (n, 1, 1))
    phase = rng.uniform(0, 2 * np.pi, (n, 3, 1))
    amp = rng.uniform(0.05, 4, (n, 1, 1))
    shape = (n, 3, window)
    draw = {
        "zeros": lambda: np.zeros(shape),
        "constant": lambda: np.zeros(shape) + rng.uniform(-4, 4, (n, 3, 1)),
        "constant 1 g": lambda: np.zeros(shape) + np.array([0.0, 0.0, 1.0])[:, None],
        "white noise 4.9 g": lambda: rng.uniform(-4.9, 4.9, shape),
        "white noise sd 0.01 g": lambda: rng.normal(0, 0.01, shape),
        "white noise sd 0.1 g": lambda: rng.normal(0, 0.1, shape),
        "white noise sd 1 g": lambda: rng.normal(0, 1.0, shape).clip(-5, 5),
        "pure tone": lambda: amp * np.sin(2 * np.pi * freq * t + phase),
        "square wave": lambda: amp * np.sign(np.sin(2 * np.pi * freq * t + phase)),
        "still sensor": lambda: _still(rng, shape),
    }
    wanted = set(selected)
    signals = {kind: draw[kind]().astype(np.float32) for kind in OUT_OF_DISTRIBUTION_KINDS if kind in wanted}
    return {kind: signals[kind] for kind in selected}


def _still(rng: np.random.Generator, shape: tuple[int, int, int]) -> np.ndarray:
    """Windows of a sensor at rest: tilted gravity, small noise, the sensor's resolution."""
    tilt = np.deg2rad(rng.uniform(0.0, 30.0, (shape[0], 1)))
    gravity = np.concatenate([np.sin(tilt), np.zeros_like(tilt), np.cos(tilt)], axis=1)[:, :, None]
    return np.round((gravity + rng.normal(0.0, STILL_NOISE_G, shape)) / STILL_STEP_G) * STILL_STEP_G


__all__ = [
    "OUT_OF_DISTRIBUTION_KINDS",
    "STILL_NOISE_G",
    "STILL_STEP_G",
    "out_of_distribution_signals",
]
