"""Export a trained model to one ONNX bundle and check it against torch on a data file.

Thin program over :mod:`tactile_torch.export.model_graph` (the same as ``tactile-torch export``, plus a parity
check): the model file comes from ``tactile-torch train --out model.npz`` (SVMs) or
``tactile-torch cluster`` (``OUT/model.npz``).

Examples
--------
python export/export_pipeline.py --model runs/vib/model.npz --out runs/vib/model.onnx --check rec.npz
"""

from __future__ import annotations

import argparse
import sys

from tactile_torch.export.model_graph import compare_with_runtime, export_pipeline, pipeline_from_model
from tactile_torch.robot.files.model_file import load_model_file
from tactile_torch.robot.runtime import OnnxPipeline


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", required=True, help="model file written by tactile-torch train or cluster")
    parser.add_argument("--out", required=True, help="the .onnx bundle to write")
    parser.add_argument("--check", default="", help="a data .npz to compare onnxruntime with torch on")
    parser.add_argument(
        "--sensor-range",
        type=float,
        default=None,
        help="vibration models: the sensor's range in g, kept in the bundle (default: 5, the ADXL345)",
    )
    args = parser.parse_args(argv)
    pipe = pipeline_from_model(load_model_file(args.model), sensor_range_g=args.sensor_range)
    path = export_pipeline(pipe, args.out)
    bundle = OnnxPipeline(path)
    print(f"{bundle!r}: {path.stat().st_size / 1024:.0f} KiB")
    if args.check:
        raw = bundle.read_npz(args.check).raw
        agree, diff = compare_with_runtime(pipe, bundle, raw)
        print(f"{len(raw)} samples: labels agree {agree:.4f}, max rel. score difference {diff:.2g}")
        if agree < 1.0 or diff > 1e-5:
            print("parity check FAILED", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
