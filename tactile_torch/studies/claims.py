"""Report section: do the conclusions of the docs and the report hold beyond the bundled generator?

Every conclusion drawn elsewhere is re-tested on other data: the bundled generators at their
default knobs and at a harder setting (coarser sensels, a larger contact, finer textures, look-alike
objects, more noise; for the stylus: more noise, less alike sessions, near-duplicate surfaces), and the
real sets when ``../shared/data`` is present (``drimus_sdh_tactile`` and ``icub_grasp`` pressure arrays,
``hapmat_imu5`` and ``borealtc_imu`` accelerometers). A conclusion that does not hold on every
source is reported as data-dependent. Checked here:

1. *Fusing the frames beats concatenating their features* (method 1; docs/image.md, the study):
   fused (12) against concatenated (12 per frame) features for LDA, kNN and the HM-SVM, McNemar's
   test on the pooled cross-validated predictions; the map of where fusion helps. ``--full`` adds a
   sweep of every generator knob (one at a time) and more data.
2. *Objects never seen in training are harder* (docs/image.md): stratified folds against folds
   grouped by object (synthetic sets; the real sets hold one object per class).
3. *Longer windows classify better* (method 2; docs/vibration.md): the study's RBF SVM at window
   lengths of 0.25 ... 2 s, trained on the first two thirds of every recording, tested on the last third.
4. *Our HM-SVM is as accurate as libsvm's one-vs-one SVC on the vibration features*
   (``vibration_classification`` section, README): same C and gamma, McNemar's test.
"""

from __future__ import annotations

import dataclasses

import numpy as np

TITLE = "Claims checked beyond one generator"

# The harder settings of the bundled generators (knobs of make_explorations / make_vibration_recordings).
HARD_IMAGES = {
    "sensel_pitch_mm": 2.0,
    "contact_mm": (9.0, 12.0),
    "texture_scale": 0.8,
    "near_duplicates": 0.25,
    "noise_counts": 4.0,
}
HARD_STYLUS = {"noise_lsb": 4.0, "session_jitter": 0.15, "alike_distance": 0.3}
# One knob at a time around the defaults (--full): the fusion map.
KNOBS = {
    "sensel_pitch_mm": (0.9, 2.0),
    "contact_mm": ((4.0, 6.0), (9.0, 12.0)),
    "texture_scale": (0.7, 1.5),
    "near_duplicates": (0.5,),
    "noise_counts": (6.0,),
    "n_frames": (20, 100),
}
SIZES = {  # generated image sets (explorations per class, frames; the knob map's), stylus seconds, folds
    "quick": {
        "per_class": 4,
        "frames": 10,
        "knob_per_class": 4,
        "knob_frames": 10,
        "stylus_s": 12.0,
        "folds": 2,
    },
    "default": {
        "per_class": 12,
        "frames": 20,
        "knob_per_class": 0,
        "knob_frames": 0,
        "stylus_s": 30.0,
        "folds": 5,
    },
    "full": {
        "per_class": 30,
        "frames": 100,
        "knob_per_class": 20,
        "knob_frames": 50,
        "stylus_s": 120.0,
        "folds": 5,
    },
}
WINDOW_SECONDS = (0.25, 0.5, 1.0, 2.0)  # the study's W = 200 ... 1600 at 800 Hz (default run: 0.25, 1, 2)


# ------------------------------------------------------------------------------------ image sources
def image_sources(ctx) -> list[dict]:
    """The method-1 data sources: name, frames, labels, groups (objects, or None), erosion."""
    from ..data import shared_data_dir
    from ..data.images import make_explorations
    from ._models import erosion_for
    from .image_features import dataset

    size = SIZES[ctx.mode]
    sources = []
    bundled = dataset(ctx)
    sources.append(
        {"name": "bundled generator (default knobs)", "data": bundled, "groups": bundled.groups.numpy()}
    )
    hard = make_explorations(
        size["per_class"],
        n_frames=size["frames"],
        random_state=ctx.seed("claims", "hard image set"),
        **HARD_IMAGES,
    )
    sources.append({"name": "bundled generator (hard knobs)", "data": hard, "groups": hard.groups.numpy()})
    if shared_data_dir("drimus_sdh_tactile") is not None:
        from ..data.grasps import load_drimus_grasps

        for sensor in ("ts1_f1_proximal", "ts2_f1_distal") if ctx.mode == "full" else ("ts1_f1_proximal",):
            sources.append(
                {
                    "name": f"drimus_sdh_tactile {sensor} (real)",
                    "data": load_drimus_grasps(sensor=sensor),
                    "groups": None,
                }
            )
    if shared_data_dir("icub_grasp") is not None:
        from ..data.grasps import load_icub_grasps

        sources.append({"name": "icub_grasp (real)", "data": load_icub_grasps(), "groups": None})
    for s in sources:
        s["erosion"] = erosion_for(s["data"].frames)
    return sources


def _predictions(fused, concat, y, groups, folds: int, ctx) -> tuple[dict, int]:
    """Cross-validated predictions ``{(scheme, classifier, features): labels}``: stratified folds, and
    folds grouped by ``groups`` (unseen objects) when given; seeded from ``ctx``."""
    from ..catalogue import classifier_pipeline
    from ..model_selection import fold_predictions, group_folds, stratified_folds
    from ._models import IMAGE_SVM_C, classifiers

    n = int(min(folds, np.bincount(y)[np.unique(y)].min()))
    schemes = {"stratified": stratified_folds(y, n, ctx.seed("claims", "cv folds"))}
    if groups is not None and len(np.unique(groups)) >= n:
        schemes["unseen objects"] = group_folds(y, groups, n)
    preds = {}
    for scheme, cv in schemes.items():
        for clf_name, clf in classifiers(ctx.seed("claims", "image estimators"), svm_c=IMAGE_SVM_C).items():
            if ctx.quick and clf_name == "HM-SVM":
                continue  # the quick sets have too few explorations per class to train it
            for feats, X in (("fused", fused), ("concatenated", concat)):
                model = classifier_pipeline(clf)
                preds[scheme, clf_name, feats] = fold_predictions(model, X, y, cv)
    return preds, n


def _verdict(y, a, b, better: str, worse: str) -> tuple[float, float, float, str]:
    """Accuracies of predictions ``a`` and ``b``, McNemar's chi2 and a verdict at 5 %."""
    from ..metrics import mcnemar

    test = mcnemar(y, a, b)
    acc_a, acc_b = float(np.mean(a == y)), float(np.mean(b == y))
    verdict = "no significant difference"
    if test.reject:
        verdict = better if acc_a > acc_b else worse
    return acc_a, acc_b, float(test.chi2), verdict


def _fusion_rows(name: str, preds: dict, y, n: int) -> list[dict]:
    """Claim 1: fused against concatenated, per fold scheme and classifier."""
    rows = []
    for scheme, clf_name in dict.fromkeys((k[0], k[1]) for k in preds):
        a, b, chi2, verdict = _verdict(
            y,
            preds[scheme, clf_name, "fused"],
            preds[scheme, clf_name, "concatenated"],
            "fusion better",
            "concatenation better",
        )
        rows.append(
            {
                "source": name,
                "folds": f"{scheme} ({n})",
                "classifier": clf_name,
                "fused": a,
                "concatenated": b,
                "gain": a - b,
                "McNemar chi2": chi2,
                "verdict (5 %)": verdict,
            }
        )
    return rows


def _unseen_rows(name: str, preds: dict, y) -> list[dict]:
    """Claim 2: stratified folds against folds of unseen objects (the same samples: McNemar applies)."""
    rows = []
    for (scheme, clf_name, feats), pred in preds.items():
        if scheme != "unseen objects":
            continue
        a, b, chi2, verdict = _verdict(
            y, preds["stratified", clf_name, feats], pred, "unseen objects harder", "unseen objects easier"
        )
        rows.append(
            {
                "source": name,
                "classifier": clf_name,
                "features": feats,
                "stratified": a,
                "unseen objects": b,
                "McNemar chi2": chi2,
                "verdict (5 %)": verdict,
            }
        )
    return rows


def _features(data, erosion: int):
    from ._models import image_features

    return image_features(data.frames, erosion=erosion), image_features(
        data.frames, fuse=False, erosion=erosion
    )


def fusion_map(ctx, sources: list[dict]) -> tuple[list[dict], list[dict]]:
    """Rows of claim 1 and of claim 2 on every source."""
    from tqdm.auto import tqdm

    from .image_features import features

    size = SIZES[ctx.mode]
    rows, unseen = [], []
    for s in tqdm(sources, desc="claims: image sources", disable=ctx.quick, leave=False):
        if s["name"].startswith("bundled generator (default"):
            cached = features(ctx)  # computed by the image_features section with the study's erosion
            fused, concat = cached["fused"], cached["unfused"]
        else:
            fused, concat = _features(s["data"], s["erosion"])
        y = s["data"].labels.numpy()
        preds, n = _predictions(fused, concat, y, s["groups"], size["folds"], ctx)
        rows += _fusion_rows(s["name"], preds, y, n)
        unseen += _unseen_rows(s["name"], preds, y)
    return rows, unseen


def knob_map(ctx) -> list[dict]:
    """Fusion gain with one generator knob at a time away from its default (``--full``)."""
    from tqdm.auto import tqdm

    from ..data.images import make_explorations

    size = SIZES[ctx.mode]
    rows = []
    settings = [(knob, value) for knob, values in KNOBS.items() for value in values]
    for knob, value in tqdm(settings, desc="claims: generator knobs", disable=ctx.quick, leave=False):
        kwargs = {"n_frames": size["knob_frames"]} | {knob: value}
        data = make_explorations(
            size["knob_per_class"], random_state=ctx.seed("claims", "knob map image sets"), **kwargs
        )
        fused, concat = _features(data, 10)
        y = data.labels.numpy()
        preds, n = _predictions(fused, concat, y, None, size["folds"], ctx)
        for row in _fusion_rows(f"{knob} = {value}", preds, y, n):
            rows.append({"knob": knob, "value": str(value), **row})
    return rows


def _summary(rows: list[dict], key: str = "source") -> list[dict]:
    """Per source: how many classifier x fold settings favour fusion, concatenation or neither."""
    out: dict[str, dict] = {}
    for r in rows:
        s = out.setdefault(
            r[key], {key: r[key], "fusion better": 0, "concatenation better": 0, "no difference": 0}
        )
        v = r["verdict (5 %)"]
        s["no difference" if v.startswith("no") else v] += 1
        s.setdefault("gains", []).append(r["gain"])
    for s in out.values():
        gains = s.pop("gains")
        s["mean gain"] = float(np.mean(gains))
        s["where"] = (
            "fusion helps"
            if s["fusion better"] and not s["concatenation better"]
            else "concatenation helps"
            if s["concatenation better"] and not s["fusion better"]
            else "mixed"
            if s["fusion better"]
            else "no significant difference"
        )
    return list(out.values())


# -------------------------------------------------------------------------------- vibration sources
def vibration_sources(ctx) -> list[dict]:
    """The method-2 recordings: bundled (default and hard knobs) and the real IMU sets."""
    from dataclasses import replace

    from .. import data
    from ..data.stylus import make_vibration_recordings
    from .vibration_features import bundled_recordings

    size = SIZES[ctx.mode]
    bundled = bundled_recordings(ctx)
    n = round(size["stylus_s"] * bundled.rate_hz)  # as long as the hard set's recordings
    sources = [
        {
            "name": "bundled stylus (default knobs)",
            "rec": replace(bundled, signals=[s[:n] for s in bundled.signals]),
        }
    ]
    hard = make_vibration_recordings(
        28, duration_s=size["stylus_s"], random_state=ctx.seed("claims", "hard stylus set"), **HARD_STYLUS
    )
    sources.append({"name": "bundled stylus (hard knobs)", "rec": hard})
    for name, loader in (("hapmat_imu5", "load_hapmat_imu5"), ("borealtc_imu", "load_borealtc_imu")):
        if data.shared_data_dir(name) is not None:
            sources.append({"name": f"{name} (real, 100 Hz)", "rec": getattr(data, loader)()})
    return sources


def _time_split(rec, size: int):
    """Windows of ``size`` samples; train = first two thirds of every recording, test = the rest."""
    from fractions import Fraction

    from ..model_selection import time_holdout
    from ._models import vibration_features

    ds = rec.windows(size)
    # the first floor(2 m / 3) of a recording's m windows (rounded down, unlike the novelty study's split)
    train = time_holdout(ds.recording.numpy(), ds.position.numpy(), (Fraction(2, 3),), rounding="floor") == 0
    return vibration_features(ds.windows), ds.labels.numpy(), train


def _svm_accuracy(
    X, y, train, C: float, gamma: float, model: str = "libsvm", random_state: int | None = None
) -> tuple[float, np.ndarray]:
    """Test accuracy and predictions of libsvm's SVC or our HM-SVM (seeded by ``random_state``; libsvm's
    SVC draws nothing) trained on ``train``."""
    from sklearn.svm import SVC

    from ..catalogue import classifier_pipeline
    from ..svm import HierarchicalSVC

    clf = (
        SVC(C=C, gamma=gamma)
        if model == "libsvm"
        else HierarchicalSVC(C=C, gamma=gamma, random_state=random_state)
    )
    pipe = classifier_pipeline(clf, scaling="unit-population").fit(X[train], y[train])
    pred = pipe.predict(X[~train])
    return float(np.mean(pred == y[~train])), pred


def window_rows(sources: list[dict], seconds: tuple[float, ...] = WINDOW_SECONDS) -> list[dict]:
    """Claim 3: accuracy against window length on every source."""
    rows = []
    for s in sources:
        rec = s["rec"]
        accs, ns, sizes = [], [], []
        row = {"source": s["name"]}
        for length in seconds:
            size = max(2, round(length * rec.rate_hz))
            X, y, train = _time_split(rec, size)
            if len(np.unique(y[train])) < len(np.unique(y)) or (~train).sum() == 0:
                continue
            acc, _ = _svm_accuracy(X, y, train, 1000.0, 0.0186)
            accs.append(acc)
            ns.append(int((~train).sum()))
            sizes.append(str(size))
            row[f"{length:g} s"] = acc
        row["W (samples)"] = " / ".join(sizes)
        if len(accs) < 2:
            continue
        diff = accs[-1] - accs[0]
        se = np.sqrt(accs[-1] * (1 - accs[-1]) / ns[-1] + accs[0] * (1 - accs[0]) / ns[0])
        row["longest - shortest"] = diff
        row["verdict (95 %)"] = (
            "rises" if diff - 1.96 * se > 0 else "falls" if diff + 1.96 * se < 0 else "no significant change"
        )
        rows.append(row)
    return rows


def svm_rows(sources: list[dict], full: bool, *, random_state: int) -> list[dict]:
    """Claim 4: HM-SVM against libsvm one-vs-one, same C and gamma, W = 1 s (``random_state``: the HM-SVM's)."""
    from ..metrics import mcnemar

    rows = []
    for s in sources:
        rec = s["rec"]
        if len(rec.class_names) > 10 and not full:
            continue  # 28-class HM-SVM fits are slow: --full only (vibration_classification covers default)
        size = round(rec.rate_hz)
        X, y, train = _time_split(rec, size)
        gamma = 1.0 / X.shape[1]
        ours, pred_ours = _svm_accuracy(X, y, train, 16.0, gamma, model="hmsvm", random_state=random_state)
        lib, pred_lib = _svm_accuracy(X, y, train, 16.0, gamma)
        test = mcnemar(y[~train], pred_ours, pred_lib)
        rows.append(
            {
                "source": s["name"],
                "W": size,
                "HM-SVM": ours,
                "libsvm OvO": lib,
                "difference": ours - lib,
                "McNemar chi2": test.chi2,
                "verdict (5 %)": "differ" if test.reject else "as accurate",
            }
        )
    return rows


def run(section, ctx) -> None:
    """Add this section to the report (BLAS held at one thread meanwhile, see ``serial_blas``)."""
    from ._models import serial_blas

    with serial_blas():
        _run(section, ctx)


def _run(section, ctx) -> None:
    import matplotlib.pyplot as plt

    section.text(
        "Each conclusion drawn in the docs or the report is re-tested here on other data: the bundled "
        "generators at their default knobs and at a harder setting "
        f"(images: `{HARD_IMAGES}`; stylus: `{HARD_STYLUS}`), and the real sets when present. A conclusion "
        "that fails on some source is data-dependent, and the docs say so."
    )
    section.command(ctx.command("claims"))
    size = SIZES[ctx.mode]

    sources = image_sources(ctx)
    section.text(
        "Method 1 sources: "
        + "; ".join(
            f"{s['name']}: {len(s['data'])} explorations of {s['data'].frames.shape[1]} frames, "
            f"{s['data'].frames.shape[-2]}x{s['data'].frames.shape[-1]} px, {len(s['data'].class_names)} classes, "
            f"erosion {s['erosion']} px"
            for s in sources
        )
        + ". Erosion: the study's 10 px per 96 px of frame, scaled to the frame. The real sets hold objects, "
        "not textures."
    )
    rows, unseen = fusion_map(ctx, sources)
    summary = _summary(rows)
    section.table(
        summary,
        caption="Where fusion helps: per source, how many classifier x fold settings favour fused (12) or "
        "concatenated (12 per frame) features (McNemar, 5 %), and the mean accuracy gain of fusion",
    )
    section.table(
        rows,
        caption="Claims 1 and 2: cross-validated accuracy of fused vs concatenated features per classifier "
        "(stratified folds; grouped by object where objects are known: 'unseen objects')",
    )
    if unseen:
        section.table(
            unseen,
            caption="Claim 2: the same samples under stratified folds and under folds of unseen objects "
            "(synthetic sets, whose objects are known; McNemar on the paired predictions)",
        )
    if ctx.full:
        knobs = knob_map(ctx)
        section.table(
            _summary(knobs, key="source"),
            caption=f"The fusion map along each generator knob (one at a time, {size['knob_per_class']} "
            f"explorations per class, {size['knob_frames']} frames unless n_frames is the knob; stratified "
            "5-fold)",
        )
        section.table(knobs, caption="Every knob setting, classifier and verdict")
    else:
        section.text(
            "The map along every generator knob (sensel pitch, contact size, texture scale, look-alike objects, "
            "noise, frames) runs under `--full`: "
            f"`{dataclasses.replace(ctx, quick=False, full=True).command('claims')}`."
        )
    fig, ax = plt.subplots(figsize=(6.4, 0.5 + 0.35 * len(summary)))
    ax.barh([s["source"] for s in summary], [s["mean gain"] for s in summary], color="C0")
    ax.axvline(0.0, color="k", lw=0.8)
    ax.set_xlabel("mean accuracy gain of fusion over concatenation")
    ax.invert_yaxis()
    section.figure(
        fig, "claims-fusion-gain", "Fusion gain per source (mean over classifiers and fold schemes)"
    )

    vib = vibration_sources(ctx)
    section.text(
        "Method 2 sources: "
        + "; ".join(
            f"{s['name']}: {len(s['rec'])} recordings, {len(s['rec'].class_names)} classes" for s in vib
        )
        + ". Train on the first two thirds of every recording, test on the last third (no neighbouring windows "
        "across the split); 21 features scaled to unit standard deviation."
    )
    lengths = WINDOW_SECONDS if ctx.full else (0.25, 1.0, 2.0)
    section.table(
        window_rows(vib, lengths),
        caption="Claim 3: accuracy of the RBF SVM (C = 1000, gamma = 0.0186) against window length "
        "(verdict: the longest against the shortest window, 95 % normal interval)",
    )
    svm = svm_rows(vib, ctx.full, random_state=ctx.seed("claims", "hm-svm"))
    if svm:
        section.table(
            svm,
            caption="Claim 4: our HM-SVM against libsvm's one-vs-one SVC, same C = 16 and gamma = 1/21, "
            "W = 1 s (28-class sets under --full only)",
        )
