"""``tactile-torch export``: a model file written by train or cluster -> one ONNX bundle
(:func:`tactile_torch.export.model_graph.export_pipeline`)."""

from __future__ import annotations

import argparse

from ._options import Number, parse_range_g
from ._output import stage


def register(sub) -> None:
    """Add the ``export`` command to the subparsers ``sub``."""
    p = sub.add_parser(
        "export",
        help="export a trained pipeline (raw input -> label and scores) to one ONNX file",
        description="Read a model written by 'tactile-torch train --out' (SVMs) or 'tactile-torch cluster' "
        "and write the whole inference graph, with its metadata, to one .onnx file (dynamic batch).",
    )
    p.add_argument("--model", required=True, help="model file (model.npz) written by train or cluster")
    p.add_argument("--out", required=True, help="the .onnx file to write")
    p.add_argument(
        "--sensor-range",
        type=Number(low=0, open_low=True, unit="g"),
        metavar="G",
        help="vibration models: the sensor's range in g, kept in the bundle (predict and stream reject "
        "samples beyond it; default: 5, the ADXL345 of the study)",
    )
    p.set_defaults(handler=run_export)


def run_export(args: argparse.Namespace) -> int:
    """Export the model to ONNX and say what was written; return the exit status."""
    from ..export.model_graph import export_pipeline, pipeline_from_model
    from ..robot.files.model_file import load_model_file

    sensor_range = parse_range_g(args.sensor_range, "--sensor-range", off=False)
    with stage("export: building the pipeline"):
        pipeline = pipeline_from_model(load_model_file(args.model), sensor_range_g=sensor_range)
    with stage("export: tracing the pipeline to ONNX and checking it"):
        path = export_pipeline(pipeline, args.out, inputs=[args.model])
    size = path.stat().st_size / 1024
    print(
        f"exported {pipeline.name}: input ({pipeline.input_layout}) = {pipeline.input_shape}, "
        f"{len(pipeline.class_names)} classes -> {path} ({size:.0f} KiB)"
    )
    if "k_exported" in pipeline.extra_metadata:  # a clustering: say which K, and why
        print(pipeline.extra_metadata["k_exported"])
        print(pipeline.extra_metadata["novelty_rule"])
    return 0
