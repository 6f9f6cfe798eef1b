"""Report section: where each model breaks (``tactile_torch.robustness``).

For the study's models and the other candidates of both methods, every degradation of
:data:`tactile_torch.robustness.degradations.FACTORS` is swept until accuracy falls halfway from its clean value to
chance; the section reports that breaking point with its 95 % interval (cluster bootstrap), a table
per method and one chart per factor with every candidate's curve, the study's Table 4 (image noise
on the 5 x 5 grid of mean x variance, ``--full``) and its Fig. 4 (the first three preprocessing steps
under four noise settings).

Sizes: the default run (``make run``) sweeps a subset of the bundled data with fewer levels, folds
and trials, so that it fits its time budget; ``tactile-torch report --full`` sweeps every level of
every factor on more data with every candidate; ``--quick`` is the smoke run of the tests.
"""

from __future__ import annotations

import dataclasses

import numpy as np

TITLE = "Breaking points: where each model fails"

# Per run size: explorations per class and frames kept (method 1), seconds of every recording kept
# (method 2), folds, trials of the random degradations, and the candidates swept.
SIZES = {
    "quick": {
        "per_class": 3,
        "frames": 10,
        "seconds": 6.0,
        "folds": 2,
        "trials": {"feature SNR": 1, "image noise": 1, "sensor noise": 1, "training samples": 1},
        "image_models": ("fused + LDA", "fused + kNN"),  # 3 per class: too few for the HM-SVM
        "vibration_models": ("21 features + RBF SVM", "21 features + LDA"),
    },
    "default": {
        "per_class": 24,
        "frames": 30,
        "seconds": 15.0,
        "folds": 3,
        "trials": {"feature SNR": 2, "image noise": 1, "sensor noise": 2, "training samples": 2},
        "image_models": ("fused + HM-SVM", "fused + LDA", "fused + kNN"),
        "vibration_models": ("21 features + RBF SVM", "21 features + LDA", "21 features + kNN"),
    },
    "full": {
        "per_class": 40,
        "frames": 100,
        "seconds": 120.0,
        "folds": 5,
        # the study's 10 trials per SNR; one draw of image noise (25 cells x 160 explorations x 100 frames)
        "trials": {"feature SNR": 10, "image noise": 1, "sensor noise": 10, "training samples": 3},
        "image_models": None,  # every candidate
        "vibration_models": None,
    },
}
FULL_ONLY = ("image noise", "sensel grid")
"""Factors left to ``--full`` (and the quick smoke run): each level rewrites every pixel of every frame
(Gaussian numbers for the whole set, or a coarser grid shown again at full size), several seconds per
level even on this section's subset. The image_classification section shows image noise on the
diagonal of Table 4 in every run."""
FIG4_NOISE = ((0.0, 0.0), (0.1, 0.01), (0.3, 0.05), (0.5, 0.09))
"""The four noise settings (mean, variance) of the Fig. 4 figure; (0, 0) is the clean frame."""


def _factors(kind: str, ctx):
    """The factors of ``kind`` at this run's levels (the full run: every level of the records)."""
    from ..robustness.degradations import QUICK_LEVELS, factors_for

    chosen = []
    for f in factors_for(kind):
        if ctx.mode == "default" and f.name in FULL_ONLY:
            continue
        if ctx.mode != "full" and f.name in QUICK_LEVELS:
            levels = QUICK_LEVELS[f.name]
            f = dataclasses.replace(f, levels=levels[-2:] if ctx.quick else levels, path=None)
        chosen.append(f)
    return chosen


def image_data(ctx):
    """The method-1 explorations of this section: the first ``per_class`` explorations of each class
    of the bundled set (``image_features`` section), first ``frames`` frames; and the texture pitch in
    pixels (median over the objects)."""
    from ..data.images import OBJECTS, SENSEL_PITCH_MM
    from . import image_features

    size = SIZES[ctx.mode]
    data = image_features.dataset(ctx)
    labels = data.labels.numpy()
    keep = np.concatenate([np.flatnonzero(labels == c)[: size["per_class"]] for c in np.unique(labels)])
    frames = data.frames[keep, : size["frames"]]
    sensels = min(24, data.frames.shape[-1] // 2)  # as image_features.dataset generated them
    px_per_mm = data.frames.shape[-1] / (sensels * SENSEL_PITCH_MM)
    pitch_px = float(np.median([o.pitch_mm for o in OBJECTS]) * px_per_mm)
    return frames, labels[keep], data.groups.numpy()[keep], pitch_px, data.class_names


def vibration_data(ctx):
    """The method-2 windows of this section: the first ``seconds`` of every bundled recording
    (``vibration_features`` section) cut into W = 800 windows, with time-block groups and positions."""
    from dataclasses import replace

    from ..robustness.sweeps import recording_blocks
    from .vibration_features import bundled_recordings

    rec = bundled_recordings(ctx)
    n = int(SIZES[ctx.mode]["seconds"] * rec.rate_hz)
    ds = replace(rec, signals=[s[:n] for s in rec.signals]).windows(800)
    recording, position = ds.recording.numpy(), ds.position.numpy()
    per_recording = np.bincount(recording)[recording]
    context = {"position": (position + 0.5) / per_recording, "recording": recording}
    groups = recording_blocks(recording, position, n_blocks=5)
    return ds.windows, ds.labels.numpy(), groups, context, ds.class_names


def image_sweep(ctx, progress: bool = True):
    """Sweep the method-1 candidates over the image factors; returns (result, frames, labels)."""
    from ..robustness.sweeps import sweep
    from ._models import image_candidates

    size = SIZES[ctx.mode]
    frames, labels, _, pitch_px, _ = image_data(ctx)
    models = image_candidates(ctx.seed("breaking_points", "image estimators"), names=size["image_models"])
    result = sweep(
        models,
        frames,
        labels,
        None,  # explorations are independent recordings (see the section text)
        factors=_factors("image", ctx),
        context={"pitch_px": pitch_px},
        n_splits=size["folds"],
        n_trials=size["trials"],
        random_state=ctx.seed("breaking_points", "image sweep"),
        progress=progress,
    )
    return result, frames, labels, pitch_px


def vibration_sweep(ctx, progress: bool = True):
    """Sweep the method-2 candidates over the vibration factors; returns (result, windows)."""
    from ..robustness.sweeps import sweep
    from ._models import vibration_candidates

    size = SIZES[ctx.mode]
    windows, labels, groups, context, _ = vibration_data(ctx)
    models = vibration_candidates(
        ctx.seed("breaking_points", "vibration estimators"), names=size["vibration_models"]
    )
    result = sweep(
        models,
        windows,
        labels,
        groups,
        factors=_factors("vibration", ctx),
        context=context,
        n_splits=size["folds"],
        n_trials=size["trials"],
        random_state=ctx.seed("breaking_points", "vibration sweep"),
        progress=progress,
    )
    return result, windows


def add_results(section, result, *, name: str, study_model: str) -> None:
    """Add a sweep's breaking table, a chart per factor (panels of one figure) and the skipped factors."""
    from ..robustness.charts import plot_factors
    from ..robustness.output import breaking_table

    section.table(
        breaking_table(result.curves),
        caption=f"{name}: breaking points (the level where accuracy falls halfway from clean to chance; "
        "95 % cluster-bootstrap interval in brackets, over the pooled test predictions of "
        f"{result.n_splits} folds)",
    )
    factors = list(result.by_factor().values())
    section.figure(
        plot_factors(result.curves),
        f"breaking-{name}",
        f"{name}: accuracy of every candidate against each factor (one panel per factor; band: 95 % interval; "
        f"dotted: halfway threshold; triangle: breaking point; the study's model is {study_model}). "
        + " ".join(f"**{group[0].factor.name}**: {group[0].factor.description}." for group in factors),
    )
    if result.skipped:
        section.text("Not swept here: " + "; ".join(f"{n} ({why})" for n, why in result.skipped) + ".")


def _grid(section, result, ctx) -> None:
    from ..robustness.charts import plot_grid
    from ..robustness.degradations import IMAGE_NOISE_MEANS, IMAGE_NOISE_VARIANCES

    grid = [c for c in result.curves if c.factor.name == "image noise" and c.factor.path is not None]
    if not grid:
        section.text(
            "Image noise on the study's 5 x 5 grid of Table 4 and the sensel grid run under `--full` (every level "
            "rewrites every pixel of every frame): "
            f"`{dataclasses.replace(ctx, quick=False, full=True).command('breaking_points')}`; the `image_classification` "
            "section shows image noise on Table 4's diagonal in every run."
        )
        return
    for c in grid:
        acc = dict(zip(c.levels, c.accuracy, strict=True))
        rows = [
            {
                "mean \\ variance": m,
                **{f"{v:g}": acc.get((m, v), float("nan")) for v in IMAGE_NOISE_VARIANCES},
            }
            for m in IMAGE_NOISE_MEANS
        ]
        section.table(
            rows, caption=f"Table 4 (study): accuracy of {c.model} with Gaussian noise on the raw frames"
        )
    study = grid[0]
    section.figure(
        plot_grid(study, IMAGE_NOISE_MEANS, IMAGE_NOISE_VARIANCES),
        "breaking-image-noise-grid",
        f"Table 4 as a map for {study.model}: cells at or below the halfway threshold are hatched.",
    )


def _fig4(section, frames, ctx) -> None:
    """The study's Fig. 4: grayscale, threshold and erosion of one frame under four noise settings."""
    import matplotlib.pyplot as plt
    import torch

    from .. import image
    from ..noise import gaussian_image_noise

    one = frames[:1]
    gray = image.to_grayscale(one)
    t = int(image.pressure_mask(gray)[0].sum((-1, -2)).argmax())  # the frame with the most contact
    frame = one[:, t : t + 1]
    fig, axes = plt.subplots(len(FIG4_NOISE), 3, figsize=(6.6, 2.2 * len(FIG4_NOISE)))
    for row, (mean, var) in enumerate(FIG4_NOISE):
        noisy = (
            gaussian_image_noise(frame, mean, var, generator=ctx.seed("breaking_points", "figure 4 noise"))
            if var
            else frame.float() / 255
        )
        g = image.to_grayscale(noisy)
        mask = image.pressure_mask(g)
        eroded = image.erode(mask, image.DEFAULT_EROSION)
        panels = (
            ("grayscale", g, "gray"),
            ("I < 240/255", mask, "gray_r"),
            ("eroded 10 x 10", eroded, "gray_r"),
        )
        for col, (title, img, cmap) in enumerate(panels):
            ax = axes[row, col]
            ax.imshow(torch.as_tensor(img)[0, 0].numpy(), cmap=cmap, vmin=0, vmax=1, interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if row == 0:
                ax.set_title(title, fontsize=9)
        axes[row, 0].set_ylabel("clean" if not var else f"mean {mean:g}, var {var:g}", fontsize=8)
    section.figure(
        fig,
        "breaking-fig4-noise-stages",
        f"The study's Fig. 4: the first three preprocessing steps of frame {t} of one exploration under four "
        "noise settings (Gaussian noise on the 0-1 frame, clipped).",
    )


def run(section, ctx) -> None:
    """Add this section to the report (BLAS held at one thread meanwhile, see ``serial_blas``)."""
    from ._models import serial_blas

    with serial_blas():
        _run(section, ctx)


def _run(section, ctx) -> None:
    size = SIZES[ctx.mode]
    section.text(
        "For every factor, each candidate is cross-validated at increasingly harsh levels; its **breaking "
        "point** is the first level where accuracy falls halfway from its clean value to chance (1 / classes), "
        "interpolated between levels, with a 95 % interval from a cluster bootstrap over the groups (the model "
        "is not refitted). Disturbances met at run time (noise on features, images or signals) hit the test "
        "data of a model trained on clean data; sensor and protocol settings (frames, sensels, window, rate, "
        "quantisation, range, erosion) are applied to training and test data alike and the model is "
        "retrained; the learning curve shrinks the training split; drift trains on the first 30 % of every "
        "recording and tests on later segments. A curve that stops early could not be fitted there. "
        "Definitions and API: `docs/robustness.md` (`tactile_torch.robustness`)."
    )
    section.command(ctx.command("breaking_points"))
    progress = not ctx.quick

    result, frames, _, pitch_px = image_sweep(ctx, progress)
    section.text(
        f"**Method 1** (tactile images): the first {size['per_class']} explorations of each class of the bundled "
        f"synthetic set, first {frames.shape[1]} frames ({frames.shape[1] / 10:g} s), "
        f"{frames.shape[-2]}x{frames.shape[-1]} px; folds stratified over explorations (each one an independent "
        "recording; objects recur across folds as in the study's protocol; the `claims` section also tests on "
        f"unseen objects). Texture pitch for the erosion factor: {pitch_px:.1f} px (median over the objects). "
        "Draws per level of the random factors: "
        + ", ".join(f"{name} {n}" for name, n in size["trials"].items())
        + "."
    )
    if ctx.mode == "default":
        clean = [c.clean for c in result.curves]
        section.text(
            f"This subset (short explorations, few per class) leaves the clean accuracies at {min(clean):.2f} ... "
            f"{max(clean):.2f} against a chance of {result.curves[0].chance:.2f}, so the intervals are wide and a "
            "breaking point may fall 'before' the mildest level: read them as a first look. `--full` sweeps 40 "
            "explorations of 10 s per class with every candidate."
        )
    add_results(section, result, name="method 1", study_model="fused + HM-SVM")
    _grid(section, result, ctx)
    _fig4(section, frames, ctx)

    result, windows = vibration_sweep(ctx, progress)
    section.text(
        f"**Method 2** (vibration): the first {size['seconds']:g} s of every bundled stylus recording "
        f"({windows.shape[0]} windows of W = 800, 28 surfaces); folds grouped by blocks of consecutive windows "
        "(5 per recording), so that no test window has a training neighbour. The study's model is the RBF SVM "
        "(C = 16, gamma = 0.0186) on the 21 features scaled to unit standard deviation."
    )
    add_results(section, result, name="method 2", study_model="21 features + RBF SVM")
    _real_sets(section, ctx, progress)


def _real_sets(section, ctx, progress: bool) -> None:
    """The same sweeps on real data under ``--full`` (when ``../shared/data`` is present): are the
    breaking points a property of the method or of the bundled generator? HapMat (100 Hz IMU, 5
    materials) for method 2, the Drimus pressure-array grasps (5 objects) for method 1."""
    from ..data import shared_data_dir
    from ..robustness.sweeps import recording_blocks, sweep
    from ._models import erosion_for, image_candidates, vibration_candidates

    size = SIZES[ctx.mode]
    done = []
    if not ctx.full:
        section.text(
            "The same sweeps on real data (`hapmat_imu5` for method 2, `drimus_sdh_tactile` for method 1) run "
            f"under `--full`: `{dataclasses.replace(ctx, quick=False, full=True).command('breaking_points')}`."
        )
        return
    if shared_data_dir("hapmat_imu5") is not None:
        from ..data import load_hapmat_imu5

        rec = load_hapmat_imu5()
        ds = rec.windows(round(rec.rate_hz))  # 1 s windows, as W = 800 at 800 Hz
        recording, position = ds.recording.numpy(), ds.position.numpy()
        result = sweep(
            vibration_candidates(
                ctx.seed("breaking_points", "hapmat estimators"), names=size["vibration_models"]
            ),
            ds.windows,
            ds.labels.numpy(),
            recording_blocks(recording, position, n_blocks=5),
            factors=_factors("vibration", ctx),
            context={
                "position": (position + 0.5) / np.bincount(recording)[recording],
                "recording": recording,
            },
            n_splits=size["folds"],
            n_trials=size["trials"],
            random_state=ctx.seed("breaking_points", "hapmat sweep"),
            progress=progress,
        )
        section.text(
            f"**Method 2 on real data**: `hapmat_imu5` (an IMU on a stick swiped over 5 materials, one 60 s "
            f"recording each, 100 Hz; {len(ds)} windows of 1 s = {ds.windows.shape[-1]} samples; folds grouped "
            "by blocks of consecutive windows). Its levels are the same numbers as the stylus's (g, samples), "
            "on a signal 8 times slower and of a different scale."
        )
        add_results(section, result, name="method 2, hapmat_imu5", study_model="21 features + RBF SVM")
        done.append("hapmat_imu5")
    if shared_data_dir("drimus_sdh_tactile") is not None:
        from ..data.grasps import load_drimus_grasps

        data = load_drimus_grasps()
        erosion = erosion_for(data.frames)
        models = image_candidates(
            ctx.seed("breaking_points", "drimus estimators"),
            erosion=erosion,
            names=("fused + LDA", "concatenated + LDA"),
        )
        result = sweep(
            models,
            data.frames,
            data.labels.numpy(),
            None,
            factors=_factors("image", ctx),
            n_splits=size["folds"],
            n_trials=size["trials"],
            random_state=ctx.seed("breaking_points", "drimus sweep"),
            progress=progress,
        )
        section.text(
            f"**Method 1 on real data**: `drimus_sdh_tactile` (a Schunk hand's 14 x 6 pressure array, 5 grasped "
            f"objects, {len(data)} grasps of {data.frames.shape[1]} frames rendered at "
            f"{data.frames.shape[-2]}x{data.frames.shape[-1]} px; erosion {erosion} px, the study's 10 px scaled to "
            "the frame; objects, not textures, so no texture pitch: the erosion factor is not swept)."
        )
        add_results(section, result, name="method 1, drimus_sdh_tactile", study_model="fused + LDA")
        done.append("drimus_sdh_tactile")
    if not done:
        section.text(
            "The real data sets were not found (`../shared/data`): breaking points on the bundled data only."
        )
