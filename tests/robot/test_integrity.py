"""Bundle digests (tactile_torch.robot.integrity): every exporter seals, every load checks, no onnx needed.

Runs on the robot install: the bundle is the hand-encoded energy bundle of ``tests.stream_helpers``
(the exporters' own bundles are checked where they are tested: tests/export/test_model_graph.py,
tests/neural/, tests/tradeoff/, tests/test_clustering.py)."""

import hashlib
import re
import warnings

import numpy as np
import pytest

from tactile_torch.cli import BAD_INPUT_EXIT, main
from tactile_torch.robot.contract import DIGEST_KEY
from tactile_torch.robot.integrity import (
    NotProtobufError,
    UnsealedBundleWarning,
    check_digest,
    seal,
    seal_bundle,
)
from tactile_torch.robot.runtime import OnnxPipeline
from tests.stream_helpers import energy_bundle

WINDOWS = np.linspace(-1, 1, 2 * 3 * 16, dtype=np.float32).reshape(2, 3, 16) ** 3


@pytest.fixture
def bundle(tmp_path):
    return energy_bundle(tmp_path / "energy.onnx", window=16)


def _flip(data: bytes, byte: int, bit: int = 0) -> bytes:
    changed = bytearray(data)
    changed[byte] ^= 1 << bit
    return bytes(changed)


def test_a_sealed_bundle_loads_and_its_digest_covers_all_but_itself(bundle):
    data = bundle.read_bytes()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning for a sealed bundle
        pipe = OnnxPipeline(bundle)
    assert (
        pipe.sealed
        and pipe.predict(WINDOWS).tolist() == np.argmax((WINDOWS**2).mean(axis=2), axis=1).tolist()
    )
    # the digest is the SHA-256 of the file without its own property (the last field seal() writes)
    value = pipe.metadata[DIGEST_KEY]
    entry = data.rindex(DIGEST_KEY.encode()) - 4  # tag, entry length, key tag, key length
    assert value == "sha256:" + hashlib.sha256(data[:entry]).hexdigest()
    assert data[entry + 2 :].endswith(value.encode())
    assert seal(data) == data  # sealing again replaces the digest by the same one


def test_every_single_bit_flip_is_refused(bundle):
    """A bit flipped anywhere (the graph, the weights, the metadata, the digest and its key): refused."""
    data = bundle.read_bytes()
    accepted = []
    for byte in range(len(data)):
        for bit in range(8):
            try:
                check_digest(_flip(data, byte, bit), "b.onnx")
            except ValueError:
                continue
            accepted.append((byte, bit))
    assert accepted == [], f"{len(accepted)} of {8 * len(data)} flips accepted"


@pytest.mark.parametrize(
    ("where", "match"),
    [
        (lambda d: d.index(np.ones(3, "<f4").tobytes()) + 5, "digest does not match its content"),  # a weight
        (lambda d: d.index(b"ReduceMean") + 3, "digest does not match its content"),  # the graph
        (lambda d: d.index(b'["x", "y", "z"]') + 2, "digest does not match its content"),  # class names
        (lambda d: len(d) - 1, "digest does not match its content"),  # the digest's value
        (lambda d: d.index(DIGEST_KEY.encode()) + 3, r"digest entry \(tactile_torch.sha256\) is damaged"),
    ],
    ids=["weights", "graph", "metadata", "digest", "digest key"],
)
def test_a_flipped_bit_is_one_line_and_status_2(bundle, tmp_path, capsys, where, match):
    data = bundle.read_bytes()
    bundle.write_bytes(_flip(data, where(data)))
    with pytest.raises(ValueError, match=f"^{bundle}: the bundle's {match}"):
        OnnxPipeline(bundle)
    np.savez(
        tmp_path / "w.npz",
        signals=np.zeros((1, 64, 3), np.float32),
        labels=[0],
        class_names=["x"],
        rate_hz=800.0,
    )
    assert main(["predict", "--model", str(bundle), "--data", str(tmp_path / "w.npz")]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and re.match(f"tactile-torch predict: {bundle}: the bundle's {match}", err), (
        err
    )


def test_an_unsealed_bundle_is_refused_unless_allowed(tmp_path, capsys):
    # issue 41: a bundle whose digest was stripped loaded behind one warning (and, its class names swapped,
    # predicted wrong names): its integrity cannot be checked, so it is refused in one line
    old = energy_bundle(tmp_path / "old.onnx", window=16, sealed=False)
    with pytest.raises(ValueError, match=r"old\.onnx: the bundle has no digest .*integrity\.seal_bundle"):
        OnnxPipeline(old)
    assert main(["predict", "--model", str(old), "--data", str(old)]) == BAD_INPUT_EXIT
    assert capsys.readouterr().err.count("\n") == 1
    with pytest.warns(
        UnsealedBundleWarning, match=r"old\.onnx: the bundle has no digest .*integrity\.seal_bundle"
    ):
        pipe = OnnxPipeline(old, allow_unsealed=True)
    assert not pipe.sealed and DIGEST_KEY not in pipe.metadata
    with warnings.catch_warnings():  # once per file: not again
        warnings.simplefilter("error")
        OnnxPipeline(old, allow_unsealed=True)
    # a copy you trust gets its digest
    sealed = seal_bundle(old, tmp_path / "sealed.onnx")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert OnnxPipeline(sealed).sealed
    with pytest.raises(ValueError, match=r"refusing to overwrite|is an input|same file"):
        seal_bundle(old, old)


def test_two_digests_and_non_protobuf_bytes_are_refused(bundle, tmp_path):
    data = bundle.read_bytes()
    entry = data[data.rindex(DIGEST_KEY.encode()) - 4 :]
    with pytest.raises(ValueError, match="holds 2 digests"):
        check_digest(data + entry, "b.onnx")
    with pytest.raises(
        NotProtobufError, match=r"^b\.onnx: not an ONNX file: its protobuf is corrupt or truncated"
    ):
        check_digest(data[:-10], "b.onnx")
    bundle.write_bytes(data[:-10])
    with pytest.raises(ValueError, match=r"not an ONNX bundle onnxruntime can load .*corrupt or truncated"):
        OnnxPipeline(bundle)
