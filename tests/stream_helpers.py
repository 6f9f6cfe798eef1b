"""Test helpers for the serial stream: a simulated sensor on a pseudo-terminal, and a tiny bundle.

:class:`PtySensor` is the sensor's end of a pty pair: the stream opens :attr:`PtySensor.path` (the
slave) with pyserial exactly as it would open ``/dev/ttyUSB0``, and the test writes protocol lines to
the master, pauses, or closes it (what a writer closing the port or an unplugged adapter looks like
to the reader: ``EIO``). ``link=`` puts the path behind a symlink that :meth:`PtySensor.replug`
points to a new pty, as udev's ``/dev/serial/by-id/...`` links do when an adapter is plugged again.

:func:`energy_bundle` writes a vibration bundle whose scores are the mean square of each axis over
the window (classes ``"x"``, ``"y"``, ``"z"``): the label of every window is known in advance, and a
sample of 1e30 overflows the scores to inf, as it overflows the features of a trained bundle.
"""

from __future__ import annotations

import array
import fcntl
import json
import os
import termios
import time
import tty
from pathlib import Path

import numpy as np

from tactile_torch.robot.integrity import seal
from tactile_torch.robot.stream.wire import format_sample


class PtySensor:
    """The writing end of a pseudo-terminal; :attr:`path` is the port the stream opens."""

    def __init__(self, link: Path | None = None) -> None:
        self.link = link
        self._open_pty()

    def _open_pty(self) -> None:
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo or line editing before pyserial configures the port
        self.tty = os.ttyname(self._slave)
        if self.link is not None:
            tmp = self.link.with_suffix(".new")
            tmp.unlink(missing_ok=True)
            tmp.symlink_to(self.tty)
            tmp.replace(self.link)

    @property
    def path(self) -> str:
        return str(self.link) if self.link is not None else self.tty

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            view = view[os.write(self.master, view) :]

    def write_samples(self, samples: np.ndarray, t: np.ndarray | None = None) -> None:
        """Write samples ``(n, 3)`` as ``x,y,z`` lines, or ``t,x,y,z`` with ``t`` ``(n,)`` in seconds."""
        lines = [format_sample(s, None if t is None else float(t[i])) for i, s in enumerate(samples)]
        self.write(b"".join(lines))

    def unread(self) -> int:
        """Return the bytes written but not yet read by the stream."""
        buf = array.array("i", [0])
        fcntl.ioctl(self._slave, termios.FIONREAD, buf)
        return buf[0]

    def drain(self, timeout: float = 20.0) -> None:
        """Wait until the stream has read everything written (a closing pty drops unread input)."""
        # written bytes reach the reader's queue through the kernel's flip buffer: wait for the queue
        # to stay empty a while, not just to be empty once
        deadline, empty_since = time.monotonic() + timeout, None
        while (now := time.monotonic()) < deadline:
            empty_since = (empty_since or now) if not self.unread() else None
            if empty_since is not None and now - empty_since >= 0.05:
                return
            time.sleep(0.01)
        raise TimeoutError(f"the stream did not read {self.unread()} bytes within {timeout} s")

    def close(self) -> None:
        """Close both ends: the reader's next read fails as on an unplugged adapter."""
        for fd in (self.master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        self.master = self._slave = -1

    def replug(self) -> None:
        """Close this pty and point :attr:`link` at a new one (the adapter plugged in again)."""
        self.close()
        self._open_pty()


def axis_recording(axes: str, n_each: int, *, random_state: int = 0) -> tuple[np.ndarray, list[str]]:
    """Return ``(n_each * len(axes), 3)`` samples in g where, in turn, one axis dominates; and the axes.

    Values stay within ±4 g (inside the ADXL345's ±5 g), quantised to the sensor's 3.9 mg steps.
    """
    rng = np.random.default_rng(random_state)
    parts = []
    for axis in axes:
        part = rng.normal(0.0, 0.05, size=(n_each, 3))
        part[:, "xyz".index(axis)] = rng.normal(0.0, 1.0, size=n_each)
        parts.append(part)
    rec = np.clip(np.concatenate(parts), -4.0, 4.0)
    return np.round(rec / 0.0039) * 0.0039, list(axes)


def expected_axis(window: np.ndarray) -> str:
    """Return the axis with the largest mean square in a window ``(3, W)``: the bundle's label."""
    return "xyz"[int(np.argmax((window.astype(np.float32) ** 2).mean(axis=1)))]


def _varint(n: int) -> bytes:
    out = bytearray()
    n &= (1 << 64) - 1  # negative int64 as protobuf writes it
    while True:
        byte, n = n & 0x7F, n >> 7
        out.append(byte | (0x80 if n else 0))
        if not n:
            return bytes(out)


def _field(number: int, value: int | str | bytes) -> bytes:
    """One protobuf field: an int (varint) or a string/bytes/message (length-delimited)."""
    if isinstance(value, int):
        return _varint(number << 3) + _varint(value)
    data = value.encode() if isinstance(value, str) else value
    return _varint(number << 3 | 2) + _varint(len(data)) + data


def _tensor_info(name: str, elem_type: int, dims: list[int | str]) -> bytes:
    shape = b"".join(_field(1, _field(2 if isinstance(d, str) else 1, d)) for d in dims)
    tensor = _field(1, elem_type) + _field(2, shape)  # TypeProto.Tensor
    return _field(1, name) + _field(2, _field(1, tensor))  # ValueInfoProto


def _node(op: str, inputs: list[str], outputs: list[str], **attributes: int | list[int]) -> bytes:
    body = b"".join(_field(1, i) for i in inputs) + b"".join(_field(2, o) for o in outputs) + _field(4, op)
    for name, value in attributes.items():
        if isinstance(value, list):  # AttributeProto: INTS (type 7) in field 8, else INT (type 2) in 3
            attr = _field(1, name) + b"".join(_field(8, v) for v in value) + _field(20, 7)
        else:
            attr = _field(1, name) + _field(3, value) + _field(20, 2)
        body += _field(5, attr)
    return body


def energy_bundle(
    path: Path,
    *,
    window: int = 64,
    rate_hz: float = 800.0,
    step: int | None = None,
    drop: tuple[str, ...] = (),
    metadata: dict[str, str] | None = None,
    sealed: bool = True,
) -> Path:
    """Write a vibration bundle: scores = per-axis mean square over the window times a weight of ones
    (an initializer, as a trained bundle's weights), label = their argmax.

    ``drop`` leaves metadata keys out (e.g. ``("window_size",)`` for a bundle that is not a vibration one);
    ``metadata`` replaces or adds keys (e.g. a header that lies about the window); ``sealed=False``
    writes no digest, as the exporters did before tactile-torch 0.1 wrote one.

    The ONNX protobuf is encoded here by hand (a dozen fields of ``onnx.proto``), so that the stream
    and runtime tests run on the robot install, which has onnxruntime but not the ``onnx`` package.
    """
    float_, int64 = 1, 7  # TensorProto.DataType
    weight = _field(1, 3) + _field(2, float_) + _field(8, "weight") + _field(9, np.ones(3, "<f4").tobytes())
    graph = (
        _field(1, _node("Mul", ["raw", "raw"], ["square"]))
        + _field(1, _node("ReduceMean", ["square"], ["energy"], axes=[2], keepdims=0))
        + _field(1, _node("Mul", ["energy", "weight"], ["scores"]))
        + _field(1, _node("ArgMax", ["scores"], ["labels"], axis=1, keepdims=0))
        + _field(2, "energy")
        + _field(5, weight)  # GraphProto.initializer: TensorProto dims, data_type, name, raw_data
        + _field(11, _tensor_info("raw", float_, ["B", 3, window]))
        + _field(12, _tensor_info("labels", int64, ["B"]))
        + _field(12, _tensor_info("scores", float_, ["B", 3]))
    )
    meta = {
        "tactile_torch.pipeline": "vibration-energy",
        "tactile_torch.version": "test",
        "input_shape": json.dumps([None, 3, window]),
        "input_layout": "B,3,W",
        "class_names": json.dumps(["x", "y", "z"]),
        "window_size": str(window),
        "step": str(step or window),
        "sample_rate_hz": str(float(rate_hz)),
        **(metadata or {}),
    }
    model = (
        _field(1, 8)  # ir_version
        + _field(2, "tactile-torch tests")  # producer_name
        + _field(7, graph)
        + _field(8, _field(1, "") + _field(2, 13))  # opset_import: the default domain, opset 13
        + b"".join(_field(14, _field(1, k) + _field(2, v)) for k, v in meta.items() if k not in drop)
    )
    Path(path).write_bytes(seal(model) if sealed else model)
    return path


def _initializer(name: str, array: np.ndarray) -> bytes:
    """One TensorProto (dims, data_type, name, raw_data) of a float32 or int64 array."""
    array = np.ascontiguousarray(array)
    data_type = {np.dtype(np.float32): 1, np.dtype(np.int64): 7}[array.dtype]
    dims = b"".join(_field(1, int(d)) for d in array.shape)
    return (
        dims
        + _field(2, data_type)
        + _field(8, name)
        + _field(9, array.astype(array.dtype.newbyteorder("<")).tobytes())
    )


def frame_bundle(
    path: Path,
    weights: np.ndarray,
    *,
    n_frames: int = 4,
    class_names: list[str] | None = None,
    metadata: dict[str, object] | None = None,
) -> Path:
    """Write a pressure-map bundle ``(B, T, H, W)``: scores = the mean frame times ``weights`` ``(H, W, C)``.

    A linear classifier of the mean frame over the ``T`` frames (``weights`` may be class-mean
    templates fitted with numpy: a real, if simple, trained model), label = the argmax of the scores.
    ``metadata`` adds keys (``frame_rate_hz``, ``touch_levels`` ... JSON-encoded when not strings).
    Encoded by hand, like :func:`energy_bundle`, so that the robot tests need no ``onnx`` package.
    """
    h, w, c = weights.shape
    float_, int64 = 1, 7
    graph = (
        _field(1, _node("ReduceMean", ["raw"], ["mean"], axes=[1], keepdims=0))
        + _field(1, _node("Flatten", ["mean"], ["flat"], axis=1))
        + _field(1, _node("MatMul", ["flat", "weights"], ["scores"]))
        + _field(1, _node("ArgMax", ["scores"], ["labels"], axis=1, keepdims=0))
        + _field(2, "mean-frame")
        + _field(5, _initializer("weights", weights.reshape(h * w, c).astype(np.float32)))
        + _field(11, _tensor_info("raw", float_, ["B", n_frames, h, w]))
        + _field(12, _tensor_info("labels", int64, ["B"]))
        + _field(12, _tensor_info("scores", float_, ["B", c]))
    )
    meta = {
        "tactile_torch.pipeline": "pressure-mean-frame",
        "tactile_torch.version": "test",
        "input_shape": json.dumps([None, n_frames, h, w]),
        "input_layout": "B,T,H,W",
        "class_names": json.dumps(class_names or [f"class {i}" for i in range(c)]),
        **{k: v if isinstance(v, str) else json.dumps(v) for k, v in (metadata or {}).items()},
    }
    model = (
        _field(1, 8)
        + _field(2, "tactile-torch tests")
        + _field(7, graph)
        + _field(8, _field(1, "") + _field(2, 13))
        + b"".join(_field(14, _field(1, k) + _field(2, v)) for k, v in meta.items())
    )
    Path(path).write_bytes(seal(model))
    return path


def template_bundle(
    path: Path,
    explorations: np.ndarray,
    labels: np.ndarray,
    class_names: list[str],
    *,
    frame_rate_hz: float,
    contact: str = "raises",
) -> Path:
    """Train and write a :func:`frame_bundle` on pressure-map explorations ``(N, T, H, W)``, numpy only.

    The classifier scores the mean frame against each class's centred mean frame (a linear template
    classifier). The bundle records what the exporters record: the frame rate, the value range, the touch
    levels of the training explorations, and an early-decision rule calibrated on held-out explorations
    (two folds: templates fitted on one half score the other at the rule's checkpoints, prefixes brought
    to T by :func:`tactile_torch.robot.stream.touches.fit_frames`).
    """
    from tactile_torch.robot.stream.early_decision import calibrate_early_rule, checkpoints_for, score_margins
    from tactile_torch.robot.stream.touches import fit_frames, frame_metadata

    x = np.asarray(explorations, dtype=np.float64)
    y = np.asarray(labels)
    n, t = x.shape[:2]
    c = len(class_names)

    def fit(rows):
        means = np.stack([x[rows][y[rows] == k].mean(axis=(0, 1)) for k in range(c)])  # (C, H, W)
        return np.moveaxis(means - means.mean(axis=0), 0, -1)  # (H, W, C)

    checkpoints = checkpoints_for(t)
    margins, correct = np.full((n, len(checkpoints)), -np.inf), np.zeros((n, len(checkpoints)), bool)
    half = np.arange(n) % 2 == 0
    for train in (half, ~half):
        weights = fit(np.flatnonzero(train)).reshape(-1, c)
        for j, k in enumerate(checkpoints):
            prefix = np.stack([fit_frames(e[:k], t) for e in x[~train]]).mean(axis=1)
            scores = prefix.reshape(len(prefix), -1) @ weights
            pred = scores.argmax(axis=1)
            margins[~train, j] = score_margins(scores, pred)
            correct[~train, j] = pred == y[~train]
    rule = calibrate_early_rule(margins, correct, checkpoints, how=f"{n} held-out explorations (two folds)")
    meta, note = frame_metadata(x, frame_rate_hz=frame_rate_hz, contact=contact)
    assert note is None, note
    meta["early_decision"] = rule.to_metadata()
    return frame_bundle(
        path, fit(np.arange(n)).astype(np.float32), n_frames=t, class_names=class_names, metadata=meta
    )


_BUNDLES: dict[tuple, Path] = {}


class SerialWindows:
    """The windows a vibration stream cuts from a serial source: the one stream assembly on a tiny bundle.

    For the tests of the serial side (faults, gaps, reconnections): a :class:`SerialSource` on ``port``
    through :class:`~tactile_torch.robot.stream.live.LiveStream` with an :func:`energy_bundle` of
    ``window_size`` samples at ``rate_hz`` (``None``: a bundle that states no rate); iterating gives each
    result's :class:`~tactile_torch.robot.stream.segments.Window`. ``range_g``: the accepted range
    (default: the bundle's, 5 g); ``source``: :class:`SerialSource`'s other arguments.
    """

    def __init__(
        self, port, *, window_size, step=None, rate_hz=800.0, range_g=None, max_windows=None, **source
    ) -> None:
        import tempfile

        from tactile_torch.robot.runtime import OnnxPipeline
        from tactile_torch.robot.stream.live import LiveOptions, LiveStream, item_spec
        from tactile_torch.robot.stream.serial_source import SerialSource

        key = (int(window_size), rate_hz)
        if key not in _BUNDLES:
            path = Path(tempfile.mkdtemp(prefix="serial-windows-")) / "energy.onnx"
            drop = ("sample_rate_hz",) if rate_hz is None else ()
            _BUNDLES[key] = energy_bundle(path, window=int(window_size), rate_hz=rate_hz or 800.0, drop=drop)
        self.pipe = OnnxPipeline(_BUNDLES[key])
        self.source = SerialSource(port, item_spec(self.pipe, range_g=range_g), **source)
        options = LiveOptions(step=window_size if step is None else step, max_results=max_windows)
        self.live = LiveStream(
            self.pipe,
            self.source,
            options,
            on_event=source.get("on_event"),
            clock=source.get("clock", time.monotonic),
        )

    def __iter__(self):
        for result in self.live:
            yield result.window

    samples = property(lambda self: self.source.counts.items)
    skipped = property(lambda self: self.source.counts.skipped)
    rejected = property(lambda self: self.source.counts.rejected)
    reconnects = property(lambda self: self.source.counts.reconnects)
    format_switches = property(lambda self: self.source.counts.format_switches)
    gaps = property(lambda self: self.live.sequencer.gaps)
    lost = property(lambda self: self.live.lost)
    windows = property(lambda self: self.live.segmenter.windows)
    sequencer = property(lambda self: self.live.sequencer)
