"""Train the three default pipelines on the bundled synthetic data and export each to one ONNX file.

Thin program over :func:`tactile_torch.default_bundles.build_default_bundles`: writes ``<name>.npz`` and
``<name>.onnx`` for ``vibration-hmsvm``, ``vibration-pyp`` and ``image-hmsvm`` and prints, per bundle,
the held-out accuracy and the agreement of onnxruntime with torch.

Examples
--------
python export/default_bundles.py --out runs/bundles            # a few minutes
python export/default_bundles.py --out runs/bundles --quick    # under a minute
"""

from __future__ import annotations

import argparse
import sys

from tactile_torch.default_bundles import build_default_bundles
from tactile_torch.export.model_graph import compare_with_runtime
from tactile_torch.robot.runtime import OnnxPipeline


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="runs/bundles", help="output directory (default: runs/bundles)")
    parser.add_argument("--quick", action="store_true", help="less data, fewer sweeps")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    args = parser.parse_args(argv)
    status = 0
    for name, bundle in build_default_bundles(args.out, quick=args.quick, random_state=args.seed).items():
        onnx = OnnxPipeline(bundle.path)
        agree, diff = compare_with_runtime(bundle.pipeline, onnx, bundle.raw)
        accuracy = (onnx.predict(bundle.raw) == bundle.labels).mean()
        quality = "" if name.endswith("pyp") else f"held-out accuracy {accuracy:.4f}, "
        print(
            f"{name}: {quality}onnxruntime vs torch: labels agree {agree:.4f}, max rel. score diff {diff:.2g}"
        )
        status |= int(agree < 1.0 or diff > 1e-5)
    return status


if __name__ == "__main__":
    sys.exit(main())
