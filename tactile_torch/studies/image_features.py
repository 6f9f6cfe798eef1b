"""Report section: method-1 features of the synthetic tactile-image explorations.

Generates (or reuses) the seeded synthetic set, computes the fused (12) and unfused (T x 12) features,
shows the pipeline stages of one exploration and the fused image of one exploration per class, and
measures how well two simple classifiers separate the classes on each feature set (the HM-SVM study
is the ``image_classification`` section).

Shared with later sections through ``ctx.cached``: ``"image_dataset"`` (an
:class:`~tactile_torch.data.images.ImageExplorations`) and ``"image_features"`` (a dict with ``fused``
``(N, 12)`` and ``unfused`` ``(N, T * 12)`` float64 numpy arrays, ``labels``, ``groups``,
``class_names``).
"""

from __future__ import annotations

import time

import numpy as np

TITLE = "Method 1: tactile-image features"

FULL = {"n_per_class": 60, "n_frames": 100, "frame_size": 96}  # --full (and the claims behind the docs)
DEFAULT = {"n_per_class": 40, "n_frames": 100, "frame_size": 96}  # make run: within its time budget
QUICK = {"n_per_class": 3, "n_frames": 20, "frame_size": 96}


def dataset(ctx):
    """The bundled synthetic explorations of this run (cached in ``ctx``)."""
    from ..data.images import make_explorations

    size = QUICK if ctx.quick else FULL if ctx.full else DEFAULT
    return ctx.cached(
        "image_dataset",
        lambda: make_explorations(
            size["n_per_class"],
            n_frames=size["n_frames"],
            frame_size=size["frame_size"],
            sensels=min(24, size["frame_size"] // 2),
            random_state=ctx.seed("image_features", "bundled explorations"),
        ),
    )


def features(ctx):
    """Fused and unfused method-1 features of :func:`dataset` (cached in ``ctx``)."""
    from ..image import exploration_features

    def make():
        data = dataset(ctx)
        start = time.perf_counter()
        fused = exploration_features(data.frames).double().numpy()
        seconds = time.perf_counter() - start
        unfused = exploration_features(data.frames, fuse=False).double().numpy()
        return {
            "fused": fused,
            "unfused": unfused,
            "labels": data.labels.numpy(),
            "groups": data.groups.numpy(),
            "class_names": data.class_names,
            "seconds_fused": seconds,
        }

    return ctx.cached("image_features", make)


def _accuracies(feats: dict, cv_seed: int) -> list[dict]:
    """5-fold CV accuracy (stratified, and grouped by object) of LDA and an RBF SVC on each feature set."""
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
    from sklearn.svm import SVC

    from ..catalogue import classifier_pipeline
    from ..model_selection import fold_scores, group_folds, stratified_folds

    y, groups = feats["labels"], feats["groups"]
    n_splits = int(min(5, np.bincount(y).min(), len(np.unique(groups))))
    splits = {
        "stratified 5-fold": stratified_folds(y, n_splits, cv_seed),
        "5-fold, unseen objects": group_folds(y, groups, n_splits),
    }
    classifiers = {
        "LDA": lambda: classifier_pipeline(LinearDiscriminantAnalysis()),
        "SVC (RBF, C=10)": lambda: classifier_pipeline(SVC(C=10.0)),
    }
    rows = []
    for fused in (True, False):
        x = feats["fused" if fused else "unfused"]
        for name, make in classifiers.items():
            row = {"features": f"{'fused' if fused else 'unfused'} ({x.shape[1]})", "classifier": name}
            for split, folds in splits.items():
                scores = fold_scores(make(), x, y, folds)
                row[split] = f"{scores.mean():.3f} ± {scores.std():.3f}"
            rows.append(row)
    return rows


def _stage_figure(data, index: int):
    import matplotlib.pyplot as plt

    from .. import image

    frames = data.frames[index : index + 1]
    gray = image.to_grayscale(frames)
    mask = image.pressure_mask(gray)
    eroded = image.erode(mask, image.DEFAULT_EROSION)
    edges = image.sobel_edges(eroded)
    fused = image.fuse_edges(edges)
    # the frame with the largest pressed area shows every stage best
    t = int(mask[0].sum((-1, -2)).argmax())
    n_frames = frames.shape[1]
    panels = [
        (f"1. RGB, frame {t}", frames[0, t].permute(1, 2, 0).numpy(), None),
        ("2. grayscale I", gray[0, t].numpy(), "gray"),
        ("3. pressed: I < 240/255", mask[0, t].numpy(), "gray_r"),
        (f"4. eroded ({image.DEFAULT_EROSION}x{image.DEFAULT_EROSION})", eroded[0, t].numpy(), "gray_r"),
        ("5. Sobel edges", edges[0, t].numpy(), "gray_r"),
        (f"6. fused: OR of the\nedge images of all {n_frames} frames", fused[0].numpy(), "gray_r"),
    ]
    fig, axes = plt.subplots(1, len(panels), figsize=(2.6 * len(panels), 3.2), sharex=True, sharey=True)
    for ax, (title, img, cmap) in zip(axes, panels, strict=True):
        ax.imshow(img, cmap=cmap, vmin=0, vmax=1 if cmap else None, interpolation="nearest")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("x (px)", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0].set_ylabel("y (px)", fontsize=8)
    # steps 1-5 act on one frame; step 6 combines step 5 over every frame: framed apart
    for spine in axes[-1].spines.values():
        spine.set_edgecolor("tab:red")
        spine.set_linewidth(1.5)
    fig.tight_layout()
    return fig, t


def _fused_figure(data):
    import matplotlib.pyplot as plt

    from .. import image
    from ..data.images import OBJECTS

    labels = data.labels.numpy()
    picks = [int(np.flatnonzero(labels == c)[0]) for c in range(len(data.class_names))]
    fig, axes = plt.subplots(2, len(picks), figsize=(2.6 * len(picks), 5.4))
    for col, i in enumerate(picks):
        frames = data.frames[i : i + 1]
        edges = image.sobel_edges(image.erode(image.pressure_mask(image.to_grayscale(frames))))
        # the sum over frames of the pressure display, to show the explored texture
        footprint = (255 - frames[0].float().mean(1)).mean(0).numpy()
        axes[0, col].imshow(footprint, cmap="magma")
        axes[0, col].set_title(
            f"{data.class_names[labels[i]]}\n{OBJECTS[int(data.groups[i])].name}", fontsize=8
        )
        axes[1, col].imshow(image.fuse_edges(edges)[0].numpy(), cmap="gray_r", interpolation="nearest")
        for ax in axes[:, col]:
            ax.tick_params(labelsize=7)
        axes[1, col].set_xlabel("x (px)", fontsize=8)
    axes[0, 0].set_ylabel("mean display darkness\ny (px)", fontsize=8)
    axes[1, 0].set_ylabel("fused edges (OR over frames)\ny (px)", fontsize=8)
    fig.tight_layout()
    return fig


def run(section, ctx) -> None:
    from ..image import FEATURE_NAMES

    cmd = ctx.command("image_features")
    data = dataset(ctx)
    feats = features(ctx)
    n, t = data.frames.shape[:2]
    size = tuple(data.frames.shape[-2:])
    section.text(
        "Synthetic set (`tactile_torch.data.images.make_explorations`, seed "
        f"{ctx.seed('image_features', 'bundled explorations')}, derived from `--seed {ctx.random_state}`): "
        f"{n} explorations of {t} frames ({t / 10:.0f} s at 10 frames/s), {size[0]}x{size[1]} px, "
        f"{len(data.class_names)} classes ({', '.join(data.class_names)}), "
        f"{len(np.unique(feats['groups']))} objects. Features of the whole set in "
        f"{feats['seconds_fused']:.2f} s (fused, {1e3 * feats['seconds_fused'] / n:.1f} ms per exploration)."
    )
    saved = ctx.out_dir / "image_features.npz"
    saved.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        saved,
        fused=feats["fused"],
        unfused=feats["unfused"],
        labels=feats["labels"],
        groups=feats["groups"],
        class_names=np.asarray(feats["class_names"]),
        feature_names=np.asarray(FEATURE_NAMES),
    )
    section.text(
        f"The features are saved in `{saved.name}` next to this report (`fused` ({n}, 12), `unfused` "
        f"({n}, {feats['unfused'].shape[1]}), `labels`, `groups` = object index, `class_names`, `feature_names`)."
    )
    section.command(cmd)
    fig, frame = _stage_figure(data, 0)
    section.figure(
        fig,
        "image-pipeline-stages",
        f"Pipeline stages of exploration 0 ({data.class_names[int(data.labels[0])]}): steps 1-5 on frame "
        f"{frame} (black = 1 in the binary images), step 6 the logical OR of the Sobel edge images (step 5) "
        f"of all {data.frames.shape[1]} frames, the image whose gradient statistics are the 12 features.",
    )
    section.figure(
        _fused_figure(data),
        "image-fused-per-class",
        "One exploration per class: the explored texture (mean over frames of the display's darkness) "
        "and the fused edge image whose gradient statistics are the features.",
    )
    rows = []
    for c, name in enumerate(data.class_names):
        x = feats["fused"][feats["labels"] == c]
        rows.append(
            {
                "class": name,
                **{
                    f: f"{m:.3g} ± {s:.2g}"
                    for f, m, s in zip(FEATURE_NAMES, x.mean(0), x.std(0), strict=True)
                },
            }
        )
    section.table(rows, caption="Fused features per class (mean ± standard deviation over explorations)")
    section.table(
        _accuracies(feats, ctx.seed("image_features", "cv folds")),
        caption="Accuracy (mean ± std over folds) of simple classifiers on the fused vs unfused features; "
        "chance is 0.25",
    )
    section.command(cmd)
