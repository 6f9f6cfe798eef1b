"""Model files (tactile_torch.robot.files.model_file): nothing in them runs, everything in them is validated.

Torch-free, as on the robot."""

import json
import pickle
import zipfile

import numpy as np
import pytest

from tactile_torch import __version__
from tactile_torch.robot.files.model_file import (
    FORMAT,
    FORMAT_VERSION,
    load_model_file,
    save_model_file,
    validate_model,
)
from tests.conftest import run_without_torch


class _RunsCode:
    """Unpickling this creates ``path``: a stand-in for whatever code a crafted pickle would run."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


def _svm_model(n_features=3, n_sv=4, **header):
    """A minimal valid classifier: a binary SVM on a feature matrix."""
    rng = np.random.default_rng(0)
    base = {
        "kind": "classifier",
        "method": "svm",
        "class_names": ["cork", "felt"],
        "source": {"kind": "features", "n_features": n_features},
        "params": {"C": 16.0},
        "head": {"type": "svm", "mode": "binary", "kernel": "rbf", "gamma": 0.5, "depth": 0},
    }
    base.update(header)
    arrays = {
        "scale": np.ones(n_features),
        "head.support_vectors": rng.normal(size=(n_sv, n_features)),
        "head.dual_coef": rng.normal(size=(1, n_sv)),
        "head.intercept": np.zeros(1),
    }
    return base, arrays


def _torch_save_layout(path, obj):
    """Write ``obj`` as torch.save lays it out: a zip archive whose ``<name>/data.pkl`` is its pickle."""
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("model/data.pkl", pickle.dumps(obj))
        archive.writestr("model/version", "3\n")
    return path


def test_a_crafted_torch_pickle_runs_nothing(tmp_path):
    crafted = _torch_save_layout(
        tmp_path / "model.pt", {"format": FORMAT, "payload": _RunsCode(str(tmp_path / "ran"))}
    )
    # the file is genuinely malicious: unpickling it (torch.load(weights_only=False), tactile-torch 0.1's
    # loader) runs its code (with a real torch.save file and the export command: tests/cli/test_training_inputs.py)
    proof = _torch_save_layout(tmp_path / "proof.pt", {"payload": _RunsCode(str(tmp_path / "ran-before"))})
    with zipfile.ZipFile(proof) as archive:
        pickle.loads(archive.read("model/data.pkl"))["payload"].close()  # the file it opened
    assert (tmp_path / "ran-before").exists()
    with pytest.raises(ValueError, match=r"model\.pt: a torch\.save \(pickle\) file.*no longer unpickled"):
        load_model_file(crafted)
    assert not (tmp_path / "ran").exists()


def test_a_crafted_object_array_in_a_model_file_runs_nothing(tmp_path):
    header, arrays = _svm_model()
    evil = np.empty(1, dtype=object)
    evil[0] = _RunsCode(str(tmp_path / "ran"))
    np.savez(
        tmp_path / "m.npz", header=np.array(json.dumps({"format": FORMAT, **header})), evil=evil, **arrays
    )
    with pytest.raises(ValueError, match=r"m\.npz: evil is a pickled object array"):
        load_model_file(tmp_path / "m.npz")
    assert not (tmp_path / "ran").exists()


def test_round_trip_fills_format_version_and_library_version(tmp_path):
    header, arrays = _svm_model()
    path = save_model_file(tmp_path / "model.npz", header, arrays)
    model = load_model_file(path, kind="classifier")
    assert model.header["format"] == FORMAT and model.header["format_version"] == 1 < FORMAT_VERSION
    assert model.header["library_version"] == __version__ and model.path == path
    assert model.kind == "classifier" and model.method == "svm" and model.class_names == ["cork", "felt"]
    assert sorted(model.part("head")) == ["dual_coef", "intercept", "support_vectors"]
    np.testing.assert_array_equal(model.arrays["head.support_vectors"], arrays["head.support_vectors"])
    with pytest.raises(ValueError, match=r"model\.npz: expected a clustering model file, got a classifier"):
        load_model_file(path, kind="clustering")


def _tree_model():
    """A valid 3-class HM-SVM: root splits {0} | {1, 2}, then {1} | {2}."""
    header, arrays = _svm_model(mode="tree")
    header = {**header, "class_names": ["a", "b", "c"], "method": "hmsvm"}
    header["head"] = {"type": "svm", "mode": "tree", "kernel": "rbf", "gamma": 0.5, "depth": 2}
    arrays.update(
        {
            "head.dual_coef": np.ones((2, 4)),
            "head.intercept": np.zeros(2),
            "head.left": np.array([1, 1, 3, 3, 4]),
            "head.right": np.array([2, 1, 4, 3, 4]),
            "head.column": np.array([0, 0, 1, 0, 0]),
            "head.leaf_label": np.array([0, 0, 0, 1, 2]),
            "head.path_sign": np.array([[-1, 0], [1, -1], [1, 1]]),
        }
    )
    return header, arrays


def _changed(model, header=None, arrays=None, drop=()):
    h, a = model
    h = {**h, **(header or {})}
    a = {**a, **(arrays or {})}
    for key in drop:
        a.pop(key)
    return h, a


@pytest.mark.parametrize(
    ("model", "match"),
    [
        (_changed(_svm_model(), {"format_version": 4}), "written by a newer tactile-torch .* version 4"),
        (_changed(_svm_model(), {"format_version": "1"}), "format_version must be an int >= 1"),
        (_changed(_svm_model(), {"kind": "regressor"}), "kind must be one of"),
        (
            _changed(_svm_model(), {"method": "qda"}),
            r"method of a classifier must be one of \('hmsvm', 'svm', 'lda', 'knn', 'ncm'\)",
        ),
        (_changed(_svm_model(), {"class_names": []}), "class_names must be a non-empty list of strings"),
        (_changed(_svm_model(), {"source": {"kind": "audio"}}), "source.kind must be 'vibration', 'image'"),
        (
            _changed(
                _svm_model(), {"source": {"kind": "vibration", "window": "800", "step": 800, "rate_hz": 800}}
            ),
            "source.window must be int",
        ),
        (_changed(_svm_model(), {"head": {"type": "forest"}}), "head.type must be one of"),
        (
            _changed(
                _svm_model(),
                {"head": {"type": "svm", "mode": "dag", "kernel": "rbf", "gamma": 1, "depth": 0}},
            ),
            "head.mode must be one of",
        ),
        (_changed(_svm_model(), {"head": {"type": "svm", "mode": "binary"}}), "head.kernel is missing"),
        (_changed(_svm_model(), drop=["head.intercept"]), "array 'head.intercept' is missing"),
        (
            _changed(_svm_model(), arrays={"head.dual_coef": np.ones((1, 5))}),
            r"head.dual_coef has shape \(1, 5\): axis 1 \(support vectors\) must be 4",
        ),
        (
            _changed(_svm_model(), arrays={"scale": np.ones(4)}),
            r"scale has shape \(4,\): axis 0 \(features the head takes\) must be 3",
        ),
        (_changed(_svm_model(), arrays={"scale": np.zeros(3)}), "scale must be > 0"),
        (
            _changed(_svm_model(), arrays={"head.intercept": np.array([np.nan])}),
            "head.intercept must be finite",
        ),
        (
            _changed(_svm_model(), arrays={"head.intercept": np.array([1])}),
            "head.intercept must be float, got int64",
        ),
        (
            _changed(_tree_model(), arrays={"head.left": np.array([1, 1, 3, 3, 9])}),
            r"head.left must lie in 0\.\.4",
        ),
        (
            _changed(_tree_model(), arrays={"head.path_sign": np.full((3, 2), 2)}),
            "head.path_sign must hold -1, 0 or 1",
        ),
        (
            _changed(_tree_model(), {"class_names": ["a", "b"]}),
            r"head.dual_coef has shape \(2, 4\): axis 0 \(decision functions\) must be 1",
        ),
        (_changed(_svm_model(), {"class_names": ["cork", "cork"]}), "class_names must be distinct"),
        (_changed(_svm_model(), {"class_names": ["cork\nx", "felt"]}), "class_names must hold no control"),
        (_changed(_svm_model(), {"ood": {"type": "euclid"}}), "ood.type must be 'mahalanobis'"),
        (
            _changed(_svm_model(), {"ood": {"type": "mahalanobis", "quantile": 0.995, "threshold": -1.0}}),
            "ood must have 0 < quantile <= 1 and threshold > 0",
        ),
        (
            _changed(
                _svm_model(),
                {"ood": {"type": "mahalanobis", "quantile": 0.995, "threshold": 3.0}},
                {"ood.means": np.zeros((2, 3)), "ood.precision_cholesky": np.eye(4)},
            ),
            r"ood.precision_cholesky has shape \(4, 4\): axis 0 \(features the head takes\) must be 3",
        ),
    ],
)
def test_validation_names_the_field(tmp_path, model, match):
    header, arrays = model
    with pytest.raises(ValueError, match=match):
        save_model_file(tmp_path / "m.npz", header, arrays)  # refused before writing
    assert not (tmp_path / "m.npz").exists()
    np.savez(
        tmp_path / "m.npz",
        header=np.array(json.dumps({"format": FORMAT, "format_version": 1, **header})),
        **arrays,
    )
    with pytest.raises(ValueError, match=r"m\.npz: " + match):  # and when reading a file written elsewhere
        load_model_file(tmp_path / "m.npz")


def test_valid_tree_passes():
    header, arrays = _tree_model()
    validate_model({"format": FORMAT, "format_version": 1, **header}, arrays)


@pytest.mark.parametrize(
    ("write", "match"),
    [
        (lambda p, good: p.write_bytes(b""), r"empty file \(0 bytes\), expected a tactile-torch model file"),
        (
            lambda p, good: p.write_bytes(good[: len(good) * 2 // 3]),
            "truncated or corrupt tactile-torch model file",
        ),
        (
            lambda p, good: np.savez(p, frames=np.zeros(3)),
            r"not a tactile-torch model file \(no 'header'.*a data file\?",
        ),
        (lambda p, good: np.savez(p, header=np.array("{not json")), "header is not valid JSON"),
        (lambda p, good: np.savez(p, header=np.zeros(2)), "header must be one JSON string"),
        (lambda p, good: p.write_bytes(b"\x08\x07onnx-ish protobuf"), "expected a tactile-torch model file"),
    ],
)
def test_broken_files_get_one_line_naming_the_file(tmp_path, write, match):
    good = save_model_file(tmp_path / "good.npz", *_svm_model()).read_bytes()
    path = tmp_path / "model.npz"
    write(path, good)
    with pytest.raises(ValueError, match=r"model\.npz: " + match) as err:
        load_model_file(path)
    assert "\n" not in str(err.value)


def _zip_headers(data: bytes) -> list[int]:
    """Offsets of every byte of a zip archive's local, central-directory and end records (their fixed parts)."""
    sizes = {b"PK\x03\x04": 30, b"PK\x01\x02": 46, b"PK\x05\x06": 22}
    offsets, i = [], data.find(b"PK")
    while i >= 0:
        offsets += range(i, i + sizes.get(data[i : i + 4], 0))
        i = data.find(b"PK", i + 2)
    return offsets


def test_a_flipped_byte_in_any_zip_header_is_one_line(tmp_path):
    # issue 41: a flipped byte in a zip header (the compression method, the version, the encryption flag)
    # raised NotImplementedError or RuntimeError from zipfile: an internal error of export
    good = save_model_file(tmp_path / "good.npz", *_svm_model()).read_bytes()
    path = tmp_path / "model.npz"
    refused = 0
    for offset in _zip_headers(good):
        damaged = bytearray(good)
        damaged[offset] ^= 0xFF
        path.write_bytes(bytes(damaged))
        try:
            load_model_file(path)  # a byte that changes nothing read (a time stamp) loads
        except (ValueError, OSError) as err:
            assert "\n" not in str(err) and str(err).startswith(str(path)), (offset, err)
            refused += 1
    assert refused > 100  # most header bytes matter


def test_model_files_load_without_torch(tmp_path):
    path = save_model_file(tmp_path / "model.npz", *_svm_model())
    out = run_without_torch(
        f"""
        from tactile_torch.robot.files.model_file import load_model_file

        print(load_model_file({str(path)!r}).header["source"])
        """
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "{'kind': 'features', 'n_features': 3}"


def _linear_model(**arrays):
    header = {
        "format": FORMAT,
        "format_version": 2,
        "kind": "classifier",
        "method": "lda",
        "class_names": ["cork", "felt", "glass"],
        "source": {"kind": "features", "n_features": 5},
        "head": {"type": "linear", "mode": "multiclass"},
    }
    base = {
        "scale": np.ones(3),
        "center": np.zeros(3),
        "select": np.array([0, 2, 4]),
        "head.coef": np.ones((3, 3)),
        "head.intercept": np.zeros(3),
    }
    return header, {**base, **arrays}


@pytest.mark.parametrize(
    ("arrays", "head", "says"),
    [
        ({"select": np.array([0, 2, 5])}, None, r"select must lie in 0\.\.4, got 0\.\.5"),
        ({"select": np.array([0.0, 2.0, 4.0])}, None, "select must be integers"),
        ({"center": np.zeros(4)}, None, r"center has shape \(4,\)"),
        ({"head.coef": np.ones((2, 3))}, None, r"head.coef has shape \(2, 3\)"),
        (
            {"head.samples": np.ones((4, 3)), "head.labels": np.array([0, 1, 2, 3])},
            {"type": "neighbours", "n_neighbors": 3, "weights": "distance", "p": 1},
            r"head.labels must lie in 0\.\.2",
        ),
        (
            {"head.samples": np.ones((4, 3)), "head.labels": np.array([0, 1, 2, 2])},
            {"type": "neighbours", "n_neighbors": 3, "weights": "distance", "p": 3},
            "head must have weights 'uniform' or 'distance', p 1 or 2",
        ),
    ],
)
def test_version_2_fields_are_validated(arrays, head, says):
    header, full = _linear_model(**arrays)
    if head is not None:
        header = {**header, "method": "knn", "head": head}
        full = {k: v for k, v in full.items() if not k.startswith("head.coef") and k != "head.intercept"}
    with pytest.raises(ValueError, match=says):
        validate_model(header, full)
    validate_model(*_linear_model())  # the unchanged model is valid
