"""Report section: does a learned model earn its cost?

Classical models (the study's features with LDA, or with a hinge-loss linear head), small neural networks on the raw input
(:mod:`tactile_torch.neural`), method 1's front end learned through the differentiable ops, and int8
variants of exported models, evaluated on the same grouped folds by
:func:`tactile_torch.tradeoff.comparison.compare_models`: accuracy with a group-level 95 % interval, the
learned numbers, ONNX latency at batch 1, file size and the peak memory of the onnxruntime session.

Sizes: ``make run`` keeps this section small: the bundled vibration recordings only, 10 windows of 800
samples per surface, 3 folds, LDA on the 21 features against the small 1-D CNN and its int8 variant.
``tactile-torch report --only learned_models --full`` runs the whole comparison on 4 folds: the bundled
vibration (16 windows per surface; both CNN sizes, the hand-set and learned spectral cut-off, int8 of the
networks) and image explorations (12 per class; the exploration CNN, hand-set and learned front ends
with the same hinge-loss head, LDA on the fused 12),
and the real sets when ``../shared/data`` is present (``hapmat_imu5`` vibration, ``drimus_sdh_tactile``
pressure arrays: the taxel CNN against the per-taxel features, the front ends on the rendered maps).
Each data set's rows are also written to ``<report>/learned_models/<data set>/rows.json``. The
classical models' int8 variants are in ``tactile-torch tradeoff`` (:mod:`tactile_torch.tradeoff.learned`).
"""

from __future__ import annotations

TITLE = "Does a learned model earn its cost?"

COLUMNS = [
    "name",
    "family",
    "n_parameters",
    "accuracy",
    "accuracy_low",
    "accuracy_high",
    "units",
    "fit_s",
    "latency_ms",
    "size_kib",
    "memory_mib",
    "onnx_agreement",
]


def _classical(features: object, classifier: object):
    from ..catalogue import classifier_pipeline

    return classifier_pipeline(classifier, features)


def _vibration_specs(ctx, full: bool) -> list:
    """LDA on the 21 features and the small CNN (int8 too); ``full``: the large CNN, and the hand-set
    and learned spectral cut-off under the same hinge head."""
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    from ..features.transformers import WindowFeatureTransformer
    from ..neural import LearnedCutoffClassifier, WindowCNNClassifier
    from ..tradeoff.comparison import ModelSpec

    seed = ctx.seed("learned_models", "estimators")
    lda = _classical(WindowFeatureTransformer(), LinearDiscriminantAnalysis())
    small = WindowCNNClassifier("small", max_epochs=60 if full else 40, learning_rate=1e-2, random_state=seed)
    specs = [
        ModelSpec("LDA | 21 features", "classical", lda),
        ModelSpec("1-D CNN small | raw window", "neural", small, int8=True),
    ]
    if full:
        large = WindowCNNClassifier("large", max_epochs=40, learning_rate=3e-3, random_state=seed)
        specs += [
            ModelSpec("1-D CNN large | raw window", "neural", large, int8=True),
            ModelSpec(
                "hinge | hand-set cut-off", "classical", LearnedCutoffClassifier(False, random_state=seed)
            ),
            ModelSpec(
                "hinge | learned cut-off",
                "learned front end",
                LearnedCutoffClassifier(True, random_state=seed),
            ),
        ]
    return specs


def _image_specs(ctx, erosion: int) -> list:
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    from ..features.transformers import ImageFeatureTransformer
    from ..neural import ExplorationCNNClassifier
    from ..neural.front_end import LearnedFrontEndClassifier
    from ..tradeoff.comparison import ModelSpec

    seed = ctx.seed("learned_models", "estimators")
    return [
        ModelSpec(
            "LDA | fused 12",
            "classical",
            _classical(
                ImageFeatureTransformer(threshold=240 / 255, erosion=erosion), LinearDiscriminantAnalysis()
            ),
        ),
        ModelSpec(
            "hinge | hand-set front end",
            "classical",
            LearnedFrontEndClassifier(False, erosion=erosion, random_state=seed),
        ),
        ModelSpec(
            "hinge | learned front end",
            "learned front end",
            LearnedFrontEndClassifier(True, erosion=erosion, random_state=seed),
        ),
        ModelSpec(
            "CNN | mean and max darkness",
            "neural",
            ExplorationCNNClassifier(learning_rate=1e-2, random_state=seed),
            int8=True,
        ),
    ]


def _taxel_specs(ctx) -> list:
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    from ..features.transformers import TaxelFeatureTransformer
    from ..neural import TaxelCNNClassifier
    from ..tradeoff.comparison import ModelSpec

    seed = ctx.seed("learned_models", "estimators")
    return [
        ModelSpec(
            "LDA | per-taxel features",
            "classical",
            _classical(TaxelFeatureTransformer(), LinearDiscriminantAnalysis()),
        ),
        ModelSpec(
            "temporal CNN | taxels",
            "neural",
            TaxelCNNClassifier(learning_rate=1e-2, random_state=seed),
            int8=True,
        ),
    ]


def _size(ctx) -> tuple[int, int]:
    """(samples per class, folds) of the run's mode."""
    return {"quick": (4, 2), "default": (10, 3), "full": (16, 4)}[ctx.mode]


def _bundled_vibration(ctx) -> list[dict]:
    from ..tradeoff.inputs import vibration_samples
    from .vibration_features import bundled_recordings

    per_class, folds = _size(ctx)
    rec = bundled_recordings(ctx)
    samples = vibration_samples(
        rec,
        800,
        n_folds=folds,
        max_per_class=per_class,
        random_state=ctx.seed("learned_models", "bundled vibration folds"),
    )
    specs = _vibration_specs(ctx, ctx.mode == "full")
    return [
        {"name": "bundled vibration", "samples": samples, "classes": list(rec.class_names), "specs": specs}
    ]


def _bundled_images(ctx) -> list[dict]:
    from ..image import relative_erosion
    from ..tradeoff.inputs import TradeoffData, exploration_samples
    from .image_features import dataset

    per_class, folds = _size(ctx)
    images = dataset(ctx)
    data = TradeoffData(
        "image",
        tuple(images.class_names),
        "bundled explorations",
        raw=images.frames.numpy(),
        labels=images.labels.numpy(),
        groups=images.groups.numpy(),
        rate_hz=10.0,
    )
    h, w = images.frames.shape[-2:]
    samples = exploration_samples(
        data,
        n_folds=folds,
        max_per_class=min(per_class, 12),
        random_state=ctx.seed("learned_models", "bundled image folds"),
    )
    specs = _image_specs(ctx, relative_erosion(h, w))
    return [
        {"name": "bundled images", "samples": samples, "classes": list(images.class_names), "specs": specs}
    ]


def _hapmat(ctx) -> list[dict]:
    from ..data import shared_data_dir
    from ..tradeoff.inputs import vibration_samples

    if shared_data_dir("hapmat_imu5") is None:
        return []
    from ..data.recordings import load_hapmat_imu5

    hap = load_hapmat_imu5()
    _, folds = _size(ctx)
    samples = vibration_samples(
        hap, 100, n_folds=folds, max_per_class=60, random_state=ctx.seed("learned_models", "hapmat folds")
    )
    specs = _vibration_specs(ctx, True)
    return [
        {"name": "hapmat_imu5 (real)", "samples": samples, "classes": list(hap.class_names), "specs": specs}
    ]


def _drimus(ctx) -> list[dict]:
    import numpy as np

    from ..data import shared_data_dir
    from ..image import relative_erosion
    from ..tradeoff.inputs import TradeoffData, exploration_samples

    if shared_data_dir("drimus_sdh_tactile") is None:
        return []
    from ..data.grasps import load_drimus_grasps

    _, folds = _size(ctx)
    grasps = load_drimus_grasps()
    labels, names = grasps.labels.numpy(), tuple(grasps.class_names)
    maps = grasps.pressure.numpy().astype(np.float32)
    pressure = TradeoffData("pressure", names, "drimus", raw=maps, labels=labels, rate_hz=15.0)
    rendered = TradeoffData("image", names, "drimus", raw=grasps.frames.numpy(), labels=labels, rate_hz=15.0)
    h, w = grasps.frames.shape[-2:]
    seed = ctx.seed("learned_models", "drimus folds")
    return [
        {
            "name": "drimus_sdh_tactile pressure maps (real)",
            "samples": exploration_samples(pressure, n_folds=folds, random_state=seed),
            "classes": list(names),
            "specs": _taxel_specs(ctx),
        },
        {
            "name": "drimus_sdh_tactile rendered frames (real)",
            "samples": exploration_samples(rendered, n_folds=folds, random_state=seed),
            "classes": list(names),
            "specs": _image_specs(ctx, relative_erosion(h, w)),
        },
    ]


SOURCES = {
    "bundled vibration": _bundled_vibration,
    "hapmat": _hapmat,
    "drimus": _drimus,
    "bundled images": _bundled_images,
}
"""The data sets of the section, in report order (the real sets before the bundled explorations, the
slowest to export); ``make run`` (and ``--quick``) has the bundled vibration only."""


def _sources(ctx, only: tuple[str, ...] | None = None) -> list[dict]:
    """The data sets of this run (``only``: those of :data:`SOURCES` named): name, samples with folds,
    class names, model specs."""
    names = list(SOURCES) if ctx.mode == "full" else ["bundled vibration"]
    out = []
    for name in names:
        if only is None or name in only:
            out += SOURCES[name](ctx)
    return out


def _chart(section, rows: list[dict], name: str, chance: float) -> None:
    import matplotlib.pyplot as plt

    markers = {"classical": "o", "neural": "s", "learned front end": "D"}
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for row in rows:
        int8 = row["quantisation"] is not None
        ax.errorbar(
            row["latency_ms"],
            row["accuracy"],
            yerr=[[row["accuracy"] - row["accuracy_low"]], [row["accuracy_high"] - row["accuracy"]]],
            fmt=markers[row["family"]],
            mfc="none" if int8 else None,
            capsize=3,
            label=row["name"],
        )
    ax.axhline(chance, color="grey", linestyle=":", label=f"chance ({chance:.2f})")
    ax.set_xscale("log")
    from matplotlib.ticker import FuncFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    ax.xaxis.set_major_formatter(plain)
    ax.xaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}" if str(f"{v:g}")[0] in "25" else ""))
    ax.set_xlabel("ONNX latency at batch 1 (ms, log scale)")
    ax.set_ylabel("accuracy (group-level 95 % interval)")
    ax.set_ylim(0, 1.05)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    ax.set_title(name)
    section.figure(fig, f"learned-{name}", f"{name}: accuracy against latency (open markers: int8)")


def _verdict(rows: list[dict]) -> str:
    """One sentence: the cheapest model within one standard error of the best, and what the others cost."""
    best = max(rows, key=lambda r: r["accuracy"])
    eligible = [r for r in rows if r["accuracy"] >= best["accuracy"] - best["accuracy_se"]]
    chosen = min(eligible, key=lambda r: (r["latency_ms"], r["size_kib"]))
    text = (
        f"Best mean accuracy: {best['name']} ({best['accuracy']:.3f}); the cheapest model within one standard "
        f"error of it is **{chosen['name']}** ({chosen['family']}, {chosen['accuracy']:.3f}, "
        f"{chosen['latency_ms']:.2f} ms, {chosen['size_kib']:.0f} KiB, {chosen['memory_mib']:.1f} MiB)."
    )
    return text


def run(section, ctx) -> None:
    import json

    from ..robot.files.naming import slug
    from ..tradeoff.comparison import compare_models

    mode = ctx.mode
    section.text(
        "Classical models on the study's features, small neural networks on the raw input, the method-1 "
        "front end learned through the differentiable ops (threshold, edge threshold, temperatures) under a "
        "hinge-loss head, and int8 variants, on the same grouped folds. Accuracy: out-of-fold, interval "
        "over the held-out groups (recording time blocks, objects); latency: the exported ONNX file on one "
        "sample; memory: the peak resident memory the onnxruntime session adds (docs/neural.md)."
    )
    if mode != "full":
        section.text(
            "`make run` keeps this section small (bundled vibration, 10 windows per surface, 3 folds); "
            "`--full` adds the image explorations, the large CNN, the hand-set and learned front ends "
            "and the real data sets when present (`tradeoff` gives int8 variants of the classical models too)."
        )
    section.command(ctx.command("learned_models"))
    out = ctx.out_dir / "learned_models"
    for source in _sources(ctx):
        samples = source["samples"]
        where = out / slug(source["name"])
        rows = compare_models(source["specs"], samples, source["classes"], where, log=lambda _: None)
        (where / "rows.json").write_text(json.dumps(rows, indent=1, default=str))
        for row in rows:
            row["size_kib"] = row["size_bytes"] / 1024
        section.text(f"**{source['name']}**: {samples.split}.")
        section.table(rows, columns=COLUMNS, caption=source["name"])
        settings = [r for r in rows if "settings" in r and r["family"] == "learned front end"]
        for r in settings:
            s = r["settings"]
            if "cutoff" in s:
                section.text(
                    f"Learned cut-off ({source['name']}, first fold): {s['cutoff'][0]:.3f} → {s['cutoff'][1]:.4f} "
                    f"of the Nyquist frequency (temperature {s['temperature'][0]} → {s['temperature'][1]:.4f})."
                )
                continue
            section.text(
                f"Learned front end ({source['name']}, first fold): threshold {s['threshold'][0]:.4f} → "
                f"{s['threshold'][1]:.4f}, edge threshold {s['edge_threshold'][0]:.3f} → {s['edge_threshold'][1]:.3f}, "
                f"temperatures {[round(t, 4) for t in s['temperatures'][1]]} (from {s['temperatures'][0]})."
            )
        _chart(section, rows, source["name"], 1.0 / len(source["classes"]))
        section.text(_verdict(rows))
