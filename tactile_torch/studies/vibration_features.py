"""Report section: vibration windows and their 21 features (method 2, ``tactile_torch.signal``).

Shows the bundled synthetic stylus data (the surfaces, example windows like Fig. 3 of the study), the
feature distributions, the unsupervised transform's first components, how separable the generated
surfaces are for a quick scikit-learn RBF SVC at W = 200 ... 1600 (a check of the generator, not the
study's classifier, which is ``vibration_classification``), and the same features on the real
accelerometer sets when ``../shared/data`` is present.

Other studies reuse the recordings through ``ctx.cached(RECORDINGS_KEY, ...)`` (see
:func:`bundled_recordings`).
"""

from __future__ import annotations

import numpy as np

TITLE = "Vibration windows and features (method 2)"
RECORDINGS_KEY = "vibration_recordings"
WINDOW_SIZES = (200, 400, 800, 1600)
# A large C for the generator check: how separable the synthetic surfaces are when the margin is hard.
GENERATOR_CHECK_C = 1000.0
# Surfaces shown in the example-window and distribution figures: an alike pair and distinct characters.
EXAMPLES = ("glass", "sandpaper-p120", "carpet", "rubber", "ceramic-tiles", "felt", "velvet")


def bundled_recordings(ctx):
    """The synthetic recordings of ``make run``: 28 surfaces, 120 s each (6 s in quick mode), seeded.

    Cached in ``ctx`` under :data:`RECORDINGS_KEY`, so every study of the run uses the same data.
    """
    from ..data.stylus import make_vibration_recordings

    duration = 6.0 if ctx.quick else 120.0
    return ctx.cached(
        RECORDINGS_KEY,
        lambda: make_vibration_recordings(
            28, duration_s=duration, random_state=ctx.seed("vibration_features", "bundled recordings")
        ),
    )


def run(section, ctx) -> None:
    from ..data.stylus import surface_table
    from ..model_selection import VIBRATION_STUDY_C, VIBRATION_STUDY_GAMMA
    from ..signal import window_features

    rec = bundled_recordings(ctx)
    section.text(
        f"Data: `make_vibration_recordings(28, duration_s={rec.durations_s[0]:g}, "
        f"random_state={ctx.seed('vibration_features', 'bundled recordings')})` (the seed derived from "
        f"`--seed {ctx.random_state}`), a simulated ADXL345 stylus (800 Hz, 3.9 mg, ±5 g, "
        "58.9 cm/s) on 28 synthetic surfaces, one recording each. Parameters are invented, not fitted "
        "to measurements; "
        "see `docs/vibration.md` for the model. Alike pairs share their random jitter."
    )
    section.command(ctx.command("vibration_features"))
    section.table(
        [
            {
                "surface": s.name,
                "rms (g)": s.rms_g,
                "corner (Hz)": s.corner_hz,
                "hardness": s.hardness,
                "texture (mm)": s.texture_mm or "",
                "impacts": (f"{s.impacts_hz:g}/s" if s.impacts_hz else "")
                + (f"every {s.bump_mm:g} mm" if s.bump_mm else ""),
                "stick-slip (Hz)": s.slip_hz or "",
                "alike of": s.alike_of,
            }
            for s in surface_table(len(rec.class_names))
        ],
        caption="Synthetic surfaces (nominal parameters, before the per-seed jitter of 8 %)",
    )

    by_size = {}
    for size in WINDOW_SIZES:
        windows = rec.windows(size)
        by_size[size] = (windows, window_features(windows.windows))
    _example_windows(section, rec)
    ds, feats = by_size[800]
    _feature_distributions(section, ds, feats)
    _clustering_scatter(section, ds, feats)
    rows = [_svc_accuracy(size, ds, feats) for size, (ds, feats) in by_size.items()]
    section.text(
        "Generator check: a quick scikit-learn RBF SVC on the 21 features scaled to unit standard "
        "deviation (fitted on the training windows), odd/even window split as in the study. With the "
        f"study's gamma = {VIBRATION_STUDY_GAMMA}, C = {VIBRATION_STUDY_C:g} and with "
        f"C = {GENERATOR_CHECK_C:g}. The tuned torch SVM of "
        "`vibration_classification` is the study's classifier; this table only shows that the "
        "synthetic surfaces are separable but not trivially, and which are confused."
    )
    section.table(rows, caption="Quick SVC accuracy on the synthetic surfaces (test = odd windows)")
    _real_data(section, ctx)


def _example_windows(section, rec) -> None:
    import matplotlib.pyplot as plt

    names = [n for n in EXAMPLES if n in rec.class_names]
    size = int(rec.rate_hz)  # one second
    fig, axes = plt.subplots(len(names), 1, figsize=(8, 1.5 * len(names)), sharex=True)
    t = np.arange(size) / rec.rate_hz
    for ax, name in zip(np.atleast_1d(axes), names, strict=True):
        signal = rec.signals[rec.class_names.index(name)]
        mid = max(0, len(signal) // 2 - size // 2)
        window = signal[mid : mid + size]
        for axis, colour in zip(range(3), ("tab:blue", "tab:orange", "tab:green"), strict=True):
            ax.plot(t[: len(window)], window[:, axis], lw=0.6, color=colour, label="xyz"[axis])
        ax.set_ylabel("g")
        ax.set_title(name, fontsize=9, loc="left")
    np.atleast_1d(axes)[-1].set_xlabel("time (s)")
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.3 / fig.get_figheight()))
    # above the panels: inside one it covered the trace near 1 g
    handles, labels = np.atleast_1d(axes)[0].get_legend_handles_labels()
    fig.legend(handles, [f"axis {a}" for a in labels], ncol=3, fontsize=8, loc="upper right", frameon=False)
    section.figure(
        fig,
        "vibration-example-windows",
        "One-second windows (W = 800) of seven synthetic surfaces, x/y/z in g",
    )


# Unit of each per-axis feature (the signal is in g), for the axis labels.
_FEATURE_UNITS = {"var": "g²", "skew": "", "kurt": "", "m5": "", "tv": "g", "cross": "crossings", "hf": "g"}


def _feature_distributions(section, ds, feats) -> None:
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    from ..signal import AXES, AXIS_FEATURES, FEATURE_NAMES

    names = [n for n in EXAMPLES if n in ds.class_names]
    labels = ds.labels.numpy()
    values = feats.numpy()
    fig, axes = plt.subplots(3, len(AXIS_FEATURES), figsize=(17, 8.5))
    for j, name in enumerate(FEATURE_NAMES):
        row, col = divmod(j, len(AXIS_FEATURES))
        ax = axes[row, col]
        feature = AXIS_FEATURES[col]
        log = feature in ("var", "tv", "hf", "cross")
        shown = np.log10(np.maximum(values[:, j], 1e-12)) if log else values[:, j]
        lo, hi = np.percentile(shown, [0.5, 99.5])
        bins = np.linspace(lo, hi if hi > lo else lo + 1, 40)
        for k, surface in enumerate(names):
            counts, _ = np.histogram(shown[labels == ds.class_names.index(surface)], bins=bins)
            ax.stairs(counts, bins, color=plt.cm.tab10(k), lw=1.0, label=surface)
        unit = _FEATURE_UNITS[feature]
        quantity = f"{name} ({unit})" if unit else name
        ax.set_xlabel(f"log10 {quantity}" if log else quantity, fontsize=9)
        if col == 0:
            ax.set_ylabel(f"windows per surface\n(axis {AXES[row]})", fontsize=9)
        ax.xaxis.set_major_locator(MaxNLocator(4))
        ax.yaxis.set_major_locator(MaxNLocator(3, integer=True))
        ax.tick_params(labelsize=8)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.4 / fig.get_figheight()))
    # above the panels: inside one it covered the histograms
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, ncol=len(labels), fontsize=9, loc="upper center", frameon=False)
    section.figure(
        fig,
        "vibration-feature-distributions",
        "Distributions of the 21 features (W = 800) for seven surfaces: one row per accelerometer axis, "
        "one column per feature, counts of windows per surface (log10 of the scale features); felt and "
        "velvet are an alike pair",
    )


def _clustering_scatter(section, ds, feats) -> None:
    import matplotlib.pyplot as plt

    from ..signal import fit_clustering_transform

    transform, comps = fit_clustering_transform(feats, 3)
    labels = ds.labels.numpy()
    ratio = transform.explained_variance_ratio_
    fig, ax = plt.subplots(figsize=(8.5, 5.5))
    markers = ("o", "^", "s", "D")
    for c, name in enumerate(ds.class_names):
        sel = labels == c
        # 10 colours x 4 markers: no two surfaces share a colour and a marker (up to 40 surfaces)
        ax.scatter(
            comps[sel, 0],
            comps[sel, 1],
            s=6,
            color=plt.cm.tab10(c % 10),
            marker=markers[(c // 10) % len(markers)],
            label=name,
        )
    ax.set_xlabel(f"PC 1 ({100 * ratio[0]:.0f} % of the variance)")
    ax.set_ylabel(f"PC 2 ({100 * ratio[1]:.0f} % of the variance)")
    # the legend beside the axes, never over the data
    ax.legend(
        fontsize=6, ncol=2, markerscale=1.5, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0
    )
    fig.tight_layout()
    section.figure(
        fig,
        "vibration-clustering-transform",
        "Unsupervised transform (sqrt var, log tv/cross/hf, standardised, PCA), W = 800, first two of "
        f"three components (explained variance {ratio[0]:.2f}, {ratio[1]:.2f}, {ratio[2]:.2f})",
    )


def _svc_accuracy(size, ds, feats) -> dict:
    from sklearn.svm import SVC

    from ..model_selection import VIBRATION_STUDY_C, VIBRATION_STUDY_GAMMA, odd_even_split
    from ..signal import FeatureScaler

    train, test = odd_even_split(ds.position)
    scaled = FeatureScaler().fit(feats[train]).transform(feats).numpy()
    y = ds.labels.numpy()
    row = {"W": size, "train windows": len(train), "test windows": len(test)}
    for c in (VIBRATION_STUDY_C, GENERATOR_CHECK_C):
        pred = SVC(gamma=VIBRATION_STUDY_GAMMA, C=c).fit(scaled[train], y[train]).predict(scaled[test])
        row[f"acc (gamma {VIBRATION_STUDY_GAMMA}, C {c:g})"] = float((pred == y[test]).mean())
    truth = y[test]
    confusion = np.zeros((len(ds.class_names),) * 2, dtype=int)
    np.add.at(confusion, (truth, pred), 1)
    np.fill_diagonal(confusion, 0)
    a, b = np.unravel_index(confusion.argmax(), confusion.shape)
    row[f"most confused (C {GENERATOR_CHECK_C:g})"] = (
        f"{ds.class_names[a]} → {ds.class_names[b]} ({confusion[a, b]})" if confusion.any() else "none"
    )
    return row


def _real_data(section, ctx) -> None:
    import torch

    from ..data import shared_data_dir
    from ..data.recordings import load_borealtc_imu, load_hapmat_imu5
    from ..model_selection import VIBRATION_STUDY_GAMMA
    from ..signal import FeatureScaler, window_features

    loaders = {"hapmat_imu5": load_hapmat_imu5, "borealtc_imu": load_borealtc_imu}
    present = {name: load for name, load in loaders.items() if shared_data_dir(name) is not None}
    if not present:
        section.text(
            "The real accelerometer sets (`../shared/data/hapmat_imu5`, `borealtc_imu`) are absent: skipped."
        )
        return
    from sklearn.svm import SVC

    rows = []
    for name, load in present.items():
        rec = load()
        size = int(2 * rec.rate_hz)  # 2 s windows at the native 100 Hz
        ds = rec.windows(size)
        feats = window_features(ds.windows)
        # Time split inside each recording (first 2/3 train, last 1/3 test): adjacent windows of one
        # continuous recording are too alike for an odd/even split to mean much.
        counts = np.bincount(ds.recording.numpy())
        train = ds.position.numpy() < (2 * counts[ds.recording.numpy()]) // 3
        scaled = FeatureScaler().fit(feats[train]).transform(feats).numpy()
        y = ds.labels.numpy()
        pred = SVC(gamma=VIBRATION_STUDY_GAMMA, C=GENERATOR_CHECK_C).fit(scaled[train], y[train])
        pred = pred.predict(scaled[~train])
        rows.append(
            {
                "data set": name,
                "recordings": len(rec),
                "classes": len(rec.class_names),
                "rate (Hz)": rec.rate_hz,
                "W (2 s)": size,
                "windows": len(ds),
                "finite features": bool(torch.isfinite(feats).all()),
                "SVC acc (time split)": float((pred == y[~train]).mean()),
                "chance": 1.0 / len(rec.class_names),
            }
        )
    section.text(
        "Real accelerometer data, loaded by `tactile_torch.data.load_hapmat_imu5` / `load_borealtc_imu` "
        "(100 Hz IMU logs, not an 800 Hz stylus: nothing above 50 Hz, so only a sanity check of the "
        "pipeline on real signals). Same 21 features, 2 s windows, quick RBF SVC "
        f"(gamma {VIBRATION_STUDY_GAMMA}, C {GENERATOR_CHECK_C:g}) "
        "trained on the first two thirds of every recording and tested on the last third."
    )
    section.table(rows, caption="Real data sets under ../shared/data")
