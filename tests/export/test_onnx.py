import numpy as np
import onnx
import pytest
import torch

from tactile_torch.export import export_onnx, run_onnx
from tactile_torch.robot.contract import DIGEST_KEY
from tactile_torch.robot.integrity import check_digest


class _Spectrum(torch.nn.Module):
    def forward(self, x):
        return torch.fft.rfft(x, dim=-1).abs().sum(-1), torch.quantile(x, 0.95, dim=-1)


def test_export_dynamic_batch_metadata_and_parity(tmp_path):
    path = export_onnx(
        _Spectrum(),
        (torch.randn(2, 3, 64),),
        tmp_path / "m.onnx",
        input_names=["x"],
        output_names=["hf", "p95"],
        metadata={"window_size": "64", "class_names": '["a", "b"]'},
    )
    model = onnx.load(str(path))
    metadata = {p.key: p.value for p in model.metadata_props}
    # the metadata given, and the digest every saved file carries (tactile_torch.robot.integrity)
    assert check_digest(path.read_bytes(), path) and metadata.pop(DIGEST_KEY).startswith("sha256:")
    assert metadata == {"window_size": "64", "class_names": '["a", "b"]'}
    x = torch.randn(5, 3, 64, generator=torch.Generator().manual_seed(0))  # a batch other than the export's
    got = run_onnx(path, x)
    want = _Spectrum()(x)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_allclose(g, w.numpy(), rtol=1e-5, atol=1e-4)
    with pytest.raises(ValueError):
        run_onnx(path, x, x)  # one input too many


def test_drop_unused_initializers_keeps_what_nodes_read():
    from onnx import TensorProto, helper, numpy_helper

    from tactile_torch.export._onnx import drop_unused_initializers

    scale = numpy_helper.from_array(np.array([2.0, 3.0], dtype=np.float32), "scale")
    unused = numpy_helper.from_array(np.arange(7, dtype=np.int64), "n_support")
    graph = helper.make_graph(
        [helper.make_node("Mul", ["x", "scale"], ["y"])],
        "g",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", 2])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["batch", 2])],
        initializer=[scale, unused],
    )
    model = helper.make_model(graph)
    assert drop_unused_initializers(model) == 1
    assert [init.name for init in model.graph.initializer] == ["scale"]
    onnx.checker.check_model(model, full_check=True)
    assert drop_unused_initializers(model) == 0


def test_a_saved_file_carries_no_build_machine_paths(tmp_path):
    # torch's exporter stamps every node with its Python stack trace (absolute source paths) and module
    # names; a bundle shipped to a robot keeps none of it, so its bytes do not depend on where it was built
    import tactile_torch

    path = export_onnx(_Spectrum(), (torch.randn(2, 3, 64),), tmp_path / "m.onnx")
    model = onnx.load(str(path))
    assert model.graph.node and not any(node.metadata_props for node in model.graph.node)
    source = str(__import__("pathlib").Path(tactile_torch.__file__).resolve().parent.parent)
    assert source.encode() not in path.read_bytes() and __file__.encode() not in path.read_bytes()
