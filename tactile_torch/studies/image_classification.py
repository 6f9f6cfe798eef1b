"""Report section: method 1's classifiers on the tactile-image features (``tactile_torch.svm``).

HM-SVM (:class:`~tactile_torch.svm.HierarchicalSVC`) against LDA and kNN (k = 3, city-block distance,
inverse-distance weights; both from scikit-learn) on the fused (12) and unfused (T x 12) features of
the bundled synthetic explorations (``image_features`` section). Protocol of the study: 5 rounds of
60 % train / 20 % validation (C and gamma of the HM-SVM chosen there) / 20 % test, every exploration
tested once (:func:`~tactile_torch.model_selection.rotating_splits`). Reported: accuracy per round,
the chosen C and gamma, the class report of the pooled test predictions (per-class accuracy, Type-I
and Type-II errors), McNemar's test of the HM-SVM against each baseline, time to classify one
sample, and robustness to white noise on the (standardised) features (SNR 30 ... 1 dB, 10 trials)
and to Gaussian noise on the raw frames.

Features are standardised on each round's training part (a scikit-learn ``Pipeline``), so every
classifier sees the same inputs.
"""

from __future__ import annotations

import numpy as np

TITLE = "Method 1: HM-SVM vs LDA and kNN on tactile-image features"

SNR_DB = (30, 25, 20, 15, 10, 8, 5, 3, 1)
IMAGE_NOISE = ((0.1, 0.01), (0.2, 0.03), (0.3, 0.05), (0.4, 0.07), (0.5, 0.09))  # (mean, variance)


def classifiers(random_state: int) -> dict:
    """The three classifiers of the study (the catalogue's, :mod:`tactile_torch.catalogue`), each behind a
    standard scaler fitted on training data."""
    from .. import catalogue

    return {
        name: catalogue.classifier_pipeline(key, random_state=random_state)
        for key, name in (("hmsvm", "HM-SVM"), ("lda", "LDA"), ("knn", "kNN"))
    }


def svm_grid(n_features: int, quick: bool) -> dict:
    """C and gamma candidates; gamma relative to 1 / n_features (``"scale"`` on standardised data)."""
    cs = [1.0, 100.0] if quick else [1.0, 10.0, 100.0, 1000.0]
    rel = [1.0] if quick else [0.25, 1.0, 4.0]
    return {"classifier__C": cs, "classifier__gamma": [r / n_features for r in rel]}


def _data(ctx):
    """Features and frames: the ``image_features`` section's, or (if a class has fewer than 5
    explorations, as in its quick mode) a small set of 5 explorations per class made here."""
    from . import image_features

    feats = image_features.features(ctx)
    if np.bincount(feats["labels"]).min() >= 5:
        return feats, image_features.dataset(ctx).frames

    def make():
        from ..data.images import make_explorations
        from ..image import exploration_features

        data = make_explorations(
            5,
            n_frames=10,
            frame_size=48,
            sensels=24,
            random_state=ctx.seed("image_classification", "small explorations"),
        )
        small = {
            "fused": exploration_features(data.frames).double().numpy(),
            "unfused": exploration_features(data.frames, fuse=False).double().numpy(),
            "labels": data.labels.numpy(),
            "class_names": data.class_names,
            "seconds_fused": float("nan"),
        }
        return small, data.frames

    return ctx.cached("image_classification_small", make)


def run(section, ctx) -> None:
    import torch
    from sklearn.base import clone

    from ..metrics import class_report, mcnemar, time_per_sample
    from ..model_selection import rotating_splits, run_holdout_protocol

    feats, frames = _data(ctx)
    y = feats["labels"]
    names = list(feats["class_names"])
    n_folds = 5
    section.text(
        f"{len(y)} synthetic explorations ({len(names)} classes: {', '.join(names)}) from the "
        "`image_features` section. Protocol: 5 rounds over stratified folds, each round training on "
        "3 folds (60 %), choosing the HM-SVM's C and gamma on the 4th (validation, 20 %) and testing on "
        "the 5th (20 %); every exploration is tested exactly once. Features standardised on the training "
        "folds. LDA and kNN (k = 3, city-block, inverse-distance weights) are scikit-learn's."
    )
    section.command(ctx.command("image_features", "image_classification"))
    splits = rotating_splits(
        y, n_folds=n_folds, random_state=ctx.seed("image_classification", "rotating folds")
    )
    results, rows, chosen_rows = {}, [], []
    for feature_set in ("fused", "unfused"):
        X = feats[feature_set]
        for name, model in classifiers(ctx.seed("image_classification", "classifiers")).items():
            grid = svm_grid(X.shape[1], ctx.quick) if name == "HM-SVM" else None
            res = run_holdout_protocol(model, X, y, splits, grid)
            results[(name, feature_set)] = res
            rows.append(
                {
                    "classifier": name,
                    "features": f"{feature_set} ({X.shape[1]})",
                    "accuracy mean": res.mean_accuracy,
                    "accuracy std": float(np.std(res.fold_accuracy)),
                    "fit s (mean)": float(np.mean(res.fit_seconds)),
                }
            )
            if grid:
                for k, params in enumerate(res.chosen):
                    chosen_rows.append(
                        {
                            "features": feature_set,
                            "round": k + 1,
                            "C": params["classifier__C"],
                            "gamma": params["classifier__gamma"],
                            "validation accuracy": max(
                                s["validation accuracy"] for s in res.validation_scores[k]
                            ),
                            "test accuracy": res.fold_accuracy[k],
                        }
                    )
    section.table(
        rows, caption="Test accuracy over the 5 rounds (pooled test folds = every exploration once)"
    )
    section.table(chosen_rows, caption="HM-SVM: C and gamma chosen on each round's validation fold")

    for feature_set in ("fused", "unfused"):
        rep = class_report(
            y, results[("HM-SVM", feature_set)].y_pred, labels=np.arange(len(names)), names=names
        )
        section.table(
            rep.rows(),
            caption=f"HM-SVM, {feature_set} features: per-class accuracy, Type-I error (share of other "
            "classes' samples labelled as this class) and Type-II error (1 - accuracy), pooled test folds",
        )
    mc_rows = []
    for feature_set in ("fused", "unfused"):
        hm = results[("HM-SVM", feature_set)].y_pred
        for base in ("LDA", "kNN"):
            r = mcnemar(y, hm, results[(base, feature_set)].y_pred)
            mc_rows.append(
                {
                    "features": feature_set,
                    "HM-SVM vs": base,
                    "n01 (HM wrong, other right)": r.n01,
                    "n10 (HM right, other wrong)": r.n10,
                    "chi2": r.chi2,
                    "p-value": r.p_value,
                    "differ at 0.05": "yes" if r.reject else "no",
                }
            )
    section.table(
        mc_rows,
        caption="McNemar's test (continuity-corrected, reject when chi2 > 3.84) on the pooled test folds",
    )

    # One model per classifier from round 1 (its chosen parameters) for timing and robustness.
    split = splits[0]
    X = feats["fused"]
    fitted = {}
    for name, model in classifiers(ctx.seed("image_classification", "classifiers")).items():
        params = results[(name, "fused")].chosen[0]
        fitted[name] = clone(model).set_params(**params).fit(X[split.train], y[split.train])
    timing = [
        {
            "classifier": name,
            "one sample (ms)": 1e3 * time_per_sample(model.predict, X[split.test][:1]),
            "per sample in a batch of the test fold (ms)": 1e3
            * time_per_sample(model.predict, X[split.test]),
        }
        for name, model in fitted.items()
    ]
    section.table(
        timing, caption="Time to classify (fused features, round-1 models, features already computed)"
    )
    if np.isfinite(feats["seconds_fused"]):
        section.text(
            "Computing the fused features costs about "
            f"{1e3 * feats['seconds_fused'] / len(y):.1f} ms per exploration in this run (`image_features`)."
        )
    _feature_noise(section, ctx, fitted, X[split.test], y[split.test])
    _image_noise(section, ctx, fitted["HM-SVM"], frames[torch.from_numpy(split.test)], y[split.test])


def _feature_noise(section, ctx, fitted, X_test, y_test) -> None:
    import matplotlib.pyplot as plt
    import torch

    from ..noise import awgn

    trials = 3 if ctx.quick else 10
    snrs = SNR_DB[::4] if ctx.quick else SNR_DB
    rng = np.random.default_rng(ctx.seed("image_classification", "feature noise"))
    rows = []
    # The noise goes on the standardised features, the classifiers' input: the raw 12 features span
    # orders of magnitude, so a per-sample SNR on them would be set by the largest alone.
    scaled = {name: torch.from_numpy(model[:-1].transform(X_test)) for name, model in fitted.items()}
    for snr in snrs:
        row = {"SNR (dB)": snr}
        accs = {name: [] for name in fitted}
        for _ in range(trials):
            seed = int(rng.integers(2**31))  # the same noise draw for every classifier
            for name, model in fitted.items():
                noisy = awgn(scaled[name], float(snr), generator=seed).numpy()
                accs[name].append(float(np.mean(model[-1].predict(noisy) == y_test)))
        for name in fitted:
            row[f"{name} mean"] = float(np.mean(accs[name]))
            row[f"{name} std"] = float(np.std(accs[name]))
        rows.append(row)
    section.table(
        rows,
        caption=f"Accuracy with white Gaussian noise added to the standardised fused features of the round-1 "
        f"test fold (tactile_torch.noise.awgn, signal power measured per sample, {trials} trials per SNR)",
    )
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for name in fitted:
        ax.errorbar(
            [r["SNR (dB)"] for r in rows],
            [r[f"{name} mean"] for r in rows],
            yerr=[r[f"{name} std"] for r in rows],
            marker="o",
            capsize=3,
            label=name,
        )
    n_classes = len(next(iter(fitted.values()))[-1].classes_)
    ax.axhline(1.0 / n_classes, color="grey", ls="--", lw=0.8, label=f"chance (1/{n_classes})")
    ax.set_xlabel("feature SNR (dB), noisier to the right")
    ax.set_ylabel("test accuracy")
    ax.set_ylim(0.0, 1.02)
    ax.invert_xaxis()
    ax.legend(fontsize=8, loc="lower left")
    ax.grid(alpha=0.3)
    section.figure(
        fig,
        "image-classification-feature-noise",
        f"Accuracy vs feature SNR (fused features; mean and standard deviation over {trials} noise draws; "
        "dashed: chance)",
    )


def _image_noise(section, ctx, model, frames, y_test) -> None:
    from ..image import exploration_features
    from ..noise import gaussian_image_noise

    levels = IMAGE_NOISE[::2] if ctx.quick else IMAGE_NOISE
    rows = []
    rng = np.random.default_rng(ctx.seed("image_classification", "image noise"))
    for mean, var in levels:
        seed = int(rng.integers(2**31))
        parts = []
        for start in range(0, frames.shape[0], 8):  # bounded memory: 8 explorations at a time
            noisy = gaussian_image_noise(frames[start : start + 8], mean, var, generator=seed + start)
            parts.append(exploration_features(noisy).double().numpy())
        feats = np.concatenate(parts)
        rows.append(
            {
                "noise mean": mean,
                "noise variance": var,
                "HM-SVM accuracy": float(np.mean(model.predict(feats) == y_test)),
            }
        )
    section.table(
        rows,
        caption="HM-SVM (round-1 model, trained on clean data) on the round-1 test explorations with Gaussian "
        "noise added to the raw frames (0-1 scale, clipped; tactile_torch.noise.gaussian_image_noise), fused "
        "features recomputed",
    )
