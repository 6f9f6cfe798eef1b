"""The model file of a clustering: header and arrays of a fitted Pitman-Yor mixture and its transform.

Classifiers are written by :func:`tactile_torch.training.save_model`; clusterings (``tactile-torch
cluster``) by :func:`save_clustering_model` here. Both build their kind's header and arrays and write
them through the one writer, :func:`tactile_torch.robot.files.model_file.save_model_file` (which validates
them); every command reads them back through :func:`tactile_torch.robot.files.model_file.load_model_file`.
:func:`tactile_torch.export.model_graph.pipeline_from_model` turns either into an inference graph.
"""

from __future__ import annotations

from pathlib import Path

from torch import nn

from .robot.files.model_file import save_model_file


def save_clustering_model(
    path: str | Path,
    mixture: object,
    *,
    source: dict,
    transform: nn.Module | None = None,
    per_session: bool = False,
    sessions: dict | None = None,
    novelty: dict | None = None,
) -> Path:
    """Write a fitted :class:`~tactile_torch.mixture.PitmanYorGMM` (and the transform before it) to a model file.

    The file (:mod:`tactile_torch.robot.files.model_file`, no pickle) holds the MAP mixture's arrays, the
    fitted transform's, ``source`` and the posterior summary.

    Parameters
    ----------
    path : str or Path
    mixture : PitmanYorGMM
        Fitted; its point estimate's components (and novelty flag) are what the exported pipeline
        classifies with (:meth:`~tactile_torch.mixture.PitmanYorGMM.to_module`).
    source : dict
        How the mixture's input is made: ``{"kind": "vibration", "window", "step", "rate_hz"}`` (raw
        windows → :class:`~tactile_torch.signal.WindowFeatures` → ``transform``) or
        ``{"kind": "features", "n_features"}``.
    transform : ClusteringTransform, optional
        Required for ``kind="vibration"``.
    per_session : bool
        The mixture was fitted to features standardised within each session (recorded as the
        header's ``per_session``; such a model cannot be exported).
    sessions : dict, optional
        The mixture was fitted with session effects: ``{"names": [...], "scale": lambda}``, kept as
        the header's ``sessions`` (the head's components are already those of a window of a new
        session, so the file exports as any other).
    novelty : dict, optional
        How the novelty thresholds were calibrated (``false_alarm``, ``calibration_rows``), kept
        in the header's ``novelty``; the thresholds themselves are the head's ``novelty_thresholds``.
    """
    if source.get("kind") == "vibration" and transform is None:
        raise ValueError("a vibration clustering needs the fitted ClusteringTransform (transform=)")
    module = mixture.to_module()
    k = int(module.means.shape[0])
    header = {
        "kind": "clustering",
        "method": "pyp",
        "class_names": [f"component {i}" for i in range(k)],
        "source": dict(source),
        "head": {"type": "gaussian-mixture"}
        | ({"cluster_features": module.cluster_features} if module.cluster_features is not None else {}),
        "summary": mixture.summary(),
        "k_summary": {
            k: (list(v) if isinstance(v, tuple) else v) for k, v in mixture.n_clusters_summary_.items()
        },
    }
    if per_session:
        header["per_session"] = True
    if sessions is not None:
        header["sessions"] = dict(sessions)
    if novelty is not None:
        header["novelty"] = dict(novelty)
    arrays = {f"head.{name}": buf.numpy() for name, buf in module.named_buffers()}
    if transform is not None:
        header["transform"] = {
            "type": "clustering",
            "n_components": int(transform.n_components),
            "standardize": bool(transform.standardize),
            "eps": float(transform.eps),
        }
        fitted = ("mean_", "scale_", "components_", "explained_variance_", "explained_variance_ratio_")
        arrays.update({f"transform.{name}": getattr(transform, name) for name in fitted})
    return save_model_file(path, header, arrays)


__all__ = ["save_clustering_model"]
