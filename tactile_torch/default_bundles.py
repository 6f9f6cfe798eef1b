"""The three default bundles: trained on the bundled synthetic data, written as model files, exported.

:func:`build_default_bundles` is what ``export/default_bundles.py``, the export benchmark and the
stream benchmark run: it trains (:mod:`tactile_torch.training`, the Pitman-Yor mixture), writes the
model files (:func:`tactile_torch.training.save_model`,
:func:`tactile_torch.clustering_model.save_clustering_model`) and exports them
(:func:`tactile_torch.export.model_graph.export_pipeline`). Seeded: the same ``random_state`` gives the same
bundles.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .clustering_model import save_clustering_model
from .export.model_graph import InferencePipeline, export_pipeline, pipeline_from_model
from .robot.files.model_file import load_model_file


@dataclass
class Bundle:
    """One exported default pipeline (see :func:`build_default_bundles`).

    Attributes
    ----------
    pipeline : InferencePipeline
        The torch pipeline that was exported.
    path : Path
        Its ``.onnx`` file.
    raw : ndarray
        Held-out raw input of the pipeline's shape (uint8 frames, float32 windows).
    labels : ndarray of shape (N,) int64
        True class of each row of ``raw`` (index into the data set's classes).
    """

    pipeline: InferencePipeline
    path: Path
    raw: np.ndarray
    labels: np.ndarray


def build_default_bundles(
    out_dir: str | Path,
    *,
    quick: bool = False,
    random_state: int = 0,
    kinds: tuple[str, ...] = ("vibration-hmsvm", "vibration-pyp", "image-hmsvm"),
    log=print,
) -> dict[str, Bundle]:
    """Train the three default pipelines on the bundled synthetic data, export them, return them by name.

    ``vibration-hmsvm``: 28 synthetic surfaces, 60 s each at 800 Hz (``quick``: 10 s), W = 800
    windows, odd windows held out, HM-SVM with C = 16 and gamma ``"scale"`` on unit-std features.
    ``vibration-pyp``: the same windows → unsupervised transform (3 components) → Pitman-Yor mixture
    (300 sweeps, ``quick``: 40). ``image-hmsvm``: 20 synthetic explorations per class (``quick``: 8)
    of 100 frames of 96 x 96, half held out. Writes ``<name>.npz`` (the model file) and
    ``<name>.onnx`` to ``out_dir``.
    """
    from .features.files import FeatureSet
    from .training import save_model, train_classifier

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    built: dict[str, Bundle] = {}
    if any(k.startswith("vibration") for k in kinds):
        from .data.stylus import make_vibration_recordings
        from .model_selection import odd_even_split
        from .signal import window_features

        rec = make_vibration_recordings(28, duration_s=10 if quick else 60, random_state=random_state)
        ds = rec.windows(800)
        X = window_features(ds.windows).double().numpy()
        fit_on, held_out = odd_even_split(ds.position)  # the study's split: even-numbered windows held out
        source = {"kind": "vibration", "window": 800, "step": 800, "rate_hz": rec.rate_hz}
        raw, labels = ds.windows[held_out].numpy(), ds.labels[held_out].numpy()
        if "vibration-hmsvm" in kinds:
            train = FeatureSet(X[fit_on], ds.labels.numpy()[fit_on], ds.class_names, source)
            model = train_classifier(train, "hmsvm", n_folds=2, random_state=random_state)
            path = save_model(out / "vibration-hmsvm.npz", model, train)
            built["vibration-hmsvm"] = Bundle(pipeline_from_model(load_model_file(path)), path, raw, labels)
        if "vibration-pyp" in kinds:
            from .mixture import PitmanYorGMM
            from .signal import fit_clustering_transform

            transform, pcs = fit_clustering_transform(X[fit_on], 3)
            sweeps = 40 if quick else 300
            mixture = PitmanYorGMM(
                n_iter=sweeps, burn_in=sweeps // 4, random_state=random_state, progress=False
            )
            path = save_clustering_model(
                out / "vibration-pyp.npz", mixture.fit(pcs), source=source, transform=transform
            )
            built["vibration-pyp"] = Bundle(pipeline_from_model(load_model_file(path)), path, raw, labels)
    if "image-hmsvm" in kinds:
        from .data.images import make_explorations
        from .image import exploration_features

        data = make_explorations(8 if quick else 20, random_state=random_state)
        X = exploration_features(data.frames).double().numpy()
        held_out = np.arange(len(X)) % 2 == 1
        source = {"kind": "image", "fuse": True, "frame_shape": list(data.frames.shape[1:])}
        train = FeatureSet(X[~held_out], data.labels.numpy()[~held_out], data.class_names, source)
        model = train_classifier(train, "hmsvm", n_folds=2, random_state=random_state)
        path = save_model(out / "image-hmsvm.npz", model, train)
        raw = data.frames[held_out].numpy()
        built["image-hmsvm"] = Bundle(
            pipeline_from_model(load_model_file(path)), path, raw, data.labels[held_out].numpy()
        )
    for name, bundle in built.items():
        bundle.path = export_pipeline(bundle.pipeline, out / f"{name}.onnx")
        log(f"[bundles] {name}: {bundle.path} ({bundle.path.stat().st_size / 1024:.0f} KiB)")
    return built


__all__ = ["Bundle", "build_default_bundles"]
