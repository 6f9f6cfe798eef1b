"""Report section: speed against accuracy on the bundled data, and the simplest model each method needs.

Runs :func:`tactile_torch.tradeoff.run_tradeoff` (what ``tactile-torch tradeoff`` runs on a user's
file) on the bundled synthetic vibration recordings and tactile-image explorations of this run, and
shows per data set the candidates' accuracy (mean over the data's units, with the 95 % prediction
interval for a new unit, or the range over fewer than 5 units), fit time, ONNX latency at batch 1, size
and time to a decision, the chance level and the majority-class baseline, the charts, and the
recommendation (the one-standard-error rule among the candidates above the baseline; docs/tradeoff.md).

The learned models (networks, learned front ends) have their own section (:mod:`.learned_models`), so
this one runs the classical candidates only (``learned=False``).

Sizes: ``make run`` uses the quick candidate set (every classifier on the reference feature set, the
HM-SVM and LDA on the others) on a subset of the bundled data, so that the section stays within its
time budget; ``tactile-torch report --full`` runs every candidate (every window size, three
best-ranked subsets) on up to 300 samples per class; ``--quick`` is the smoke run on the quick data
(one window size, fused image features; its numbers mean nothing on 3 explorations per class).
Every candidate's ONNX file, ``tradeoff.json`` and ``tradeoff.md`` are written under
``<report>/tradeoff/<data set>/``.
"""

from __future__ import annotations

from pathlib import Path

TITLE = "Speed against accuracy: the simplest model each method needs"

# (max windows per class, window sizes) of the vibration part, and explorations per class of the image part.
VIBRATION = {"quick": (8, (800,)), "default": (16, (800, 200)), "full": (300, None)}
# (explorations per class, feature sets) of the image part: make run leaves the per-frame ablation (and
# its slow export) to --full and to the image_classification section.
IMAGES = {"quick": (None, ("fused",)), "default": (20, ("fused",)), "full": (None, None)}


def _vibration_data(ctx):
    from ..tradeoff.inputs import vibration_data
    from .vibration_features import bundled_recordings

    return vibration_data(bundled_recordings(ctx), "bundled stylus recordings")


def _image_data(ctx):
    """The run's explorations, with the fused and per-frame features the ``image_features`` section
    computed (same pipeline and constants: the study's 240/255 and 10-pixel erosion on 96-pixel frames)."""
    import time

    import numpy as np

    from ..data.images import FRAME_RATE_HZ
    from ..image import DEFAULT_EROSION, exploration_features, relative_erosion
    from ..tradeoff.inputs import TradeoffData
    from .image_features import dataset, features

    data = dataset(ctx)
    n, t, _, h, w = data.frames.shape
    precomputed = {}
    if relative_erosion(h, w) == DEFAULT_EROSION:
        feats = features(ctx)
        # The section timed the fused features only; time the per-frame ones on a few explorations.
        start = time.perf_counter()
        exploration_features(data.frames[:4], fuse=False)
        per_frame = (time.perf_counter() - start) * n / 4
        precomputed = {
            "fused 12": (np.asarray(feats["fused"]), float(feats["seconds_fused"])),
            f"per-frame {t * 12}": (np.asarray(feats["unfused"]), per_frame),
        }
    return TradeoffData(
        kind="image",
        class_names=tuple(data.class_names),
        description=f"bundled explorations: {n} of {t} frames of {h} x {w} pixels, {len(data.class_names)} "
        f"classes, grouped by object",
        raw=data.frames.numpy(),
        labels=data.labels.numpy(),
        groups=data.groups.numpy(),
        rate_hz=FRAME_RATE_HZ,
        precomputed=precomputed,
    )


def _show(section, ctx, title: str, result, out: Path, paths: dict) -> None:
    from ..tradeoff.output import describe, summary_lines, table_rows

    section.text(
        f"### {title}\n\n{result.data.description}. "
        + " ".join(f"`{k}`: {v}." for k, v in result.splits.items())
    )
    lines = [f"**{line}**  " for line in summary_lines(result)]
    if result.study_model is not None and result.row(result.study_model)["decision_s"] is not None:
        lines.append(f"the study's model: {describe(result.row(result.study_model))}")
    section.text("\n".join(lines))
    section.table(
        table_rows(result),
        caption=f"{title}: every candidate, cheapest (time to a decision) first; accuracy = mean over the units "
        "named in the interval column (docs/tradeoff.md)",
    )
    for kind in ("latency", "size", "decision"):
        if kind in paths:
            rel = paths[kind].relative_to(ctx.out_dir).as_posix()
            section.text(f"![{title}: accuracy against {kind}]({rel})")
    if result.touch_time:  # frame data: how long the hand must hold (docs/tradeoff.md)
        from ..tradeoff.touch_time import touch_time_markdown

        rel = paths["touch"].relative_to(ctx.out_dir).as_posix() if "touch" in paths else None
        lines = touch_time_markdown(result.touch_time, rel)[2:]
        section.text(
            "**Accuracy against time into the touch** (how long the hand must hold). " + "\n".join(lines)
        )
    if result.notes:
        section.text("Notes: " + "; ".join(result.notes) + ".")
    section.text(
        f"{len(result.rows)} candidates in {result.seconds:.1f} s ({result.exports} ONNX exports); files in "
        f"`{out.relative_to(ctx.out_dir).as_posix()}/`."
    )


def run(section, ctx) -> None:
    from ..export.parts import ExportPool
    from ..tradeoff import write_outputs
    from ..tradeoff.evaluation import submit_fronts
    from ..tradeoff.execution import execute_plan
    from ..tradeoff.runner import plan_tradeoff

    mode = ctx.mode
    quick = mode != "full"
    section.text(
        "Every candidate (classifier x feature set) is cross-validated with folds that keep related samples "
        "apart, exported to one ONNX file and timed under onnxruntime on one sample; the recommendation is "
        "the cheapest candidate (time to a decision) on the Pareto front whose accuracy is within one "
        "standard error of the best, among those significantly above the majority-class baseline; intervals "
        "are for a new session, recording, object or time block, whichever the data hold (docs/tradeoff.md). "
        + (
            "This is the quick candidate set on a subset of the bundled data; `--full` runs every candidate."
            if quick
            else "Full candidate set."
        )
    )
    section.command(ctx.command("tradeoff"))
    cap, windows = VIBRATION[mode]
    image_cap, image_features = IMAGES[mode]
    runs = [
        (
            "Vibration (method 2)",
            "vibration",
            _vibration_data(ctx),
            {"windows": windows, "max_per_class": cap},
        ),
        (
            "Tactile images (method 1)",
            "images",
            _image_data(ctx),
            {"max_per_class": image_cap, "features": image_features},
        ),
    ]
    plans = [
        (
            title,
            name,
            plan_tradeoff(
                data,
                quick=quick,
                random_state=ctx.seed("tradeoff", name),
                log=lambda s: None,
                learned=False,
                **options,
            ),
        )
        for title, name, data, options in runs
    ]
    # One export process for both data sets: the image feature graphs (the slowest exports) are made
    # while the vibration candidates are cross-validated, and classifier graphs are shared.
    with ExportPool(ctx.out_dir / "tradeoff" / "parts") as pool:
        for _, _, plan in plans:
            submit_fronts(plan.candidates, plan.inputs, pool)
        for title, name, plan in plans:
            out = ctx.out_dir / "tradeoff" / name
            result = execute_plan(plan, pool, out_dir=out, progress=False, log=lambda s: None)
            paths = write_outputs(result, out, command=ctx.command("tradeoff"))
            _show(section, ctx, title, result, out, paths)
