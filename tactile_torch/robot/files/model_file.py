"""Model files: what ``tactile-torch train --out`` and ``cluster`` write and ``export`` reads.

A model file is a ``.npz`` archive of plain numeric arrays plus one JSON header (a string array named
``header``), read with ``numpy.load(allow_pickle=False)``: loading one parses JSON and ``.npy``
headers and copies numbers, so a crafted file cannot run code (``torch.load`` unpickles, and even
its ``weights_only=True`` mode runs an unpickler over the file; this format has none). This module
needs NumPy only, so a robot can read and check a model file's header without torch.

Layout (``docs/formats.md``; the versions: :data:`FORMAT_VERSION`):

``header`` (JSON)
    ``format`` = ``"tactile-torch/model"``, ``format_version``, ``library_version``, ``kind``
    (``"classifier"`` or ``"clustering"``), ``method`` (``hmsvm``, ``svm``, ``lda``, ``knn``, ``ncm``,
    ``pyp``), ``class_names`` (in the order of the head's labels), ``source`` (how the raw input becomes
    features: ``kind`` ``"vibration"`` with ``window``, ``step``, ``rate_hz``; ``"image"`` with ``fuse``,
    ``frame_shape`` ``[T, 3, H, W]`` and optionally ``threshold`` (gray level, default 240/255), ``erosion``
    (pixels, default 10) and ``features`` (``"per-taxel"``: each pixel's time series, instead of the image
    features); ``"pressure"`` (raw pressure maps) with ``frame_shape`` ``[T, H, W]`` and ``features``
    ``"per-taxel"``; frame sources also keep what the live stream needs: ``frame_rate_hz``, ``touch_levels``,
    ``value_range``, ``early_decision``; ``"features"`` with ``n_features``), ``head`` (its ``type`` and
    settings), optional ``transform``, ``params`` (hyper-parameters), ``test_accuracy``, ``summary``;
    classifiers: ``ood`` (``type`` ``"mahalanobis"``, ``quantile``, ``threshold``: the out-of-distribution
    distance of :mod:`tactile_torch.ood`); clusterings: ``per_session`` (bool, optional: fitted to features
    standardised per session; not exportable), ``novelty`` (optional: ``false_alarm``, ``calibration_rows``:
    how ``head.novelty_thresholds`` were set).
``scale`` ``(F,)``
    classifiers: the training standard deviation each feature is divided by.
``center`` ``(F,)`` (optional)
    classifiers: subtracted before the division (a ``StandardScaler``'s mean; absent: 0).
``select`` ``(F,)`` int (optional)
    classifiers: the columns of the front end's features the head takes (best-ranked subsets),
    applied before ``center`` and ``scale``.
``head.<name>``
    the head's arrays: an SVM's ``support_vectors`` ``(S, F)``, ``dual_coef`` ``(M, S)``, ``intercept``
    ``(M,)`` (and the tree tables of a hierarchical SVM); a linear head's (LDA, nearest class mean) ``coef``
    ``(M, F)``, ``intercept`` ``(M,)``; a nearest-neighbour head's training ``samples`` ``(T, F)`` and
    ``labels`` ``(T,)``; a mixture's ``means`` ``(K, D)``, ``precisions_cholesky`` ``(K, D, D)``,
    ``log_weights`` ``(K,)`` and optionally ``novelty_thresholds`` ``(W,)`` (the calibrated threshold of the
    mean novelty score over N = 1 … W windows; empty: not calibrated) and the new-component density
    (``novelty_means``, ...); with the head's ``cluster_features`` K (< F): ``means`` ``(C, K)`` on the first
    K features and the novelty density over all F, ``density_means`` ``(Q, F)``,
    ``density_precisions_cholesky`` ``(Q, F, F)``, ``density_log_weights`` ``(Q,)``.
``ood.means`` ``(C, F)``, ``ood.precision_cholesky`` ``(F, F)``, ``ood.offset`` ``(F,)``, and the second view ``ood.floor`` ``(F,)``, ``ood.log_means``, ``ood.log_precision_cholesky``, ``ood.norm`` ``(2,)``
    classifiers: the statistics of the out-of-distribution distance (:mod:`tactile_torch.ood`; older
    files lack them, or the offset and the second view).
``transform.<name>``
    clusterings of vibration windows: the fitted attributes of the
    :class:`~tactile_torch.signal.ClusteringTransform` (``mean_``, ``scale_``, ``components_``, ...).

:func:`load_model_file` validates all of it against :data:`HEADS` and :data:`TRANSFORMS` (field types, shapes
that agree with each other, finite values, indices in range) and refuses anything else with one line naming
the file and the field. What the arrays mean is the business of :mod:`tactile_torch.training` (classifiers)
and :mod:`tactile_torch.clustering_model` (clusterings), which build their kind's header and arrays and write
them through :func:`save_model_file`, the one writer; :func:`load_model_file` is the one reader, used by every
command. Building the torch pipeline from any model file is :mod:`tactile_torch.export.model_graph`'s.
"""

from __future__ import annotations

import json
import math
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..stream.windows import MAX_WINDOW, MIN_WINDOW
from .naming import check_class_names
from .npz import MAX_READ_ENV, PathLike, max_read_bytes, read_npz, write_npz

FORMAT = "tactile-torch/model"
FORMAT_VERSION = 3
"""Newest layout read and written here (2: ``center``, ``select``, ``linear`` and ``neighbours`` heads; 3:
per-taxel sources, ``source.features`` and the ``pressure`` kind; files without them are written as the
oldest version that holds them); files of a newer version are refused with a clear message."""
MODEL_KINDS = ("classifier", "clustering")
HEADER = "header"

# Shapes name dimensions (the same name must have the same size everywhere in one file: F is the
# number of features the head takes, C the number of classes, ...); "f" arrays are float and finite,
# "i" arrays integers.
HEADS: dict[str, dict] = {
    "svm": {
        "arrays": {
            "support_vectors": (("S", "F"), "f"),
            "dual_coef": (("M", "S"), "f"),
            "intercept": (("M",), "f"),
        },
        # per mode: further arrays, and the number of decision functions M for C classes
        "modes": {
            "binary": ({}, lambda c: 1),
            "ovr": ({}, lambda c: c),
            # one-vs-one (libsvm's layout): dual_coef (C - 1, S), one intercept per pair of classes
            "ovo": ({"intercept": (("P",), "f"), "n_support": (("C",), "i")}, lambda c: c - 1),
            "tree": (
                {
                    "left": (("N",), "i"),
                    "right": (("N",), "i"),
                    "column": (("N",), "i"),
                    "leaf_label": (("N",), "i"),
                    "path_sign": (("C", "M"), "i"),
                },
                lambda c: c - 1,
            ),
        },
        "settings": {"mode": str, "kernel": str, "gamma": float, "depth": int},
    },
    "linear": {
        # LDA and nearest class mean: scores x @ coef.T + intercept; two classes may have one row ([-f, f])
        "arrays": {"coef": (("M", "F"), "f"), "intercept": (("M",), "f")},
        "modes": {"multiclass": ({}, lambda c: c), "binary": ({}, lambda c: 1)},
        "settings": {"mode": str},
    },
    "neighbours": {
        # k nearest training samples (city-block p = 1 or Euclidean p = 2), uniform or 1/d weights
        "arrays": {"samples": (("T", "F"), "f"), "labels": (("T",), "i")},
        "settings": {"n_neighbors": int, "weights": str, "p": int},
    },
    "gaussian-mixture": {
        "arrays": {
            "means": (("C", "F"), "f"),
            "precisions_cholesky": (("C", "F", "F"), "f"),
            "log_weights": (("C",), "f"),
        },
        "settings": {},
    },
}
"""The heads a model file may hold: arrays (shape, float/int), modes and settings."""

TRANSFORMS: dict[str, dict] = {
    "clustering": {
        "arrays": {
            "mean_": (("G",), "f"),
            "scale_": (("G",), "f"),
            "components_": (("F", "G"), "f"),
            "explained_variance_": (("F",), "f"),
            "explained_variance_ratio_": (("F",), "f"),
        },
        "settings": {"n_components": int, "standardize": bool, "eps": float},
    },
}
"""Transforms between the front end's features and the head (their output size is the head's F)."""

DIMENSIONS = {
    "C": "classes: len(class_names)",
    "F": "features the head takes",
    "S": "support vectors",
    "M": "decision functions",
    "P": "pairs of classes",
    "N": "tree nodes",
    "G": "clustering features",
    "T": "training samples of a nearest-neighbour head",
    "R": "features the front end makes (before 'select')",
    "W": "numbers of consecutive windows with a novelty threshold",
    "V": "views of the out-of-distribution distance (2)",
    "K": "features a mixture counts and clusters on (head.cluster_features)",
    "Q": "components of a mixture's novelty density",
}
"""What each named dimension of :data:`HEADS` and :data:`TRANSFORMS` counts (for error messages)."""
METHODS = {"classifier": ("hmsvm", "svm", "lda", "knn", "ncm"), "clustering": ("pyp",)}
VIBRATION_FEATURES = 21  # window_features: 7 per axis
IMAGE_FEATURES = 12  # exploration_features per fused image (or per frame without fusion)
TAXEL_FEATURES = 7  # window features of one taxel's time series (per-taxel features)


@dataclass(frozen=True)
class ModelFile:
    """The validated contents of a model file.

    Attributes
    ----------
    header : dict
        The JSON header (see the module docstring).
    arrays : dict of str to ndarray
        Every array by name (``scale``, ``head.<name>``, ``transform.<name>``).
    path : Path or None
        Where it was read from.
    """

    header: dict
    arrays: dict[str, np.ndarray] = field(repr=False)
    path: Path | None = None

    @property
    def kind(self) -> str:
        """``"classifier"`` or ``"clustering"``."""
        return self.header["kind"]

    @property
    def method(self) -> str:
        """``"hmsvm"``, ``"svm"`` or ``"pyp"``."""
        return self.header["method"]

    @property
    def class_names(self) -> list[str]:
        """Name of each label of the head."""
        return list(self.header["class_names"])

    @property
    def source(self) -> dict:
        """How raw input becomes the features: ``{"kind": "vibration", "window", "step", "rate_hz"}`` ..."""
        return dict(self.header["source"])

    def part(self, prefix: str) -> dict[str, np.ndarray]:
        """Return the arrays stored under ``prefix.`` (``"head"``, ``"transform"``), without the prefix."""
        start = prefix + "."
        return {k[len(start) :]: v for k, v in self.arrays.items() if k.startswith(start)}


def save_model_file(path: PathLike, header: Mapping, arrays: Mapping[str, np.ndarray]) -> Path:
    """Validate and write a model file (atomically: no truncated file is ever left at ``path``).

    ``header`` gets ``format``, ``format_version`` and ``library_version`` filled in; it must be
    JSON-serialisable. Returns ``path`` (written as given, whatever its extension).
    """
    from ... import __version__

    arrays = {k: np.asarray(v) for k, v in arrays.items()}
    head_type = (header.get("head") or {}).get("type") if isinstance(header.get("head"), dict) else None
    # Each version adds what the previous one's reader would misread or refuse (2: centring, column selection,
    # the linear and nearest-neighbour heads; 3: per-taxel and pressure sources); a file is written as the
    # oldest version that holds it, readable by older versions of tactile-torch.
    newer = "center" in arrays or "select" in arrays or head_type in ("linear", "neighbours")
    source = header.get("source") if isinstance(header.get("source"), dict) else {}
    taxels = "features" in source or source.get("kind") == "pressure"
    header = {
        "format": FORMAT,
        "format_version": 3 if taxels else 2 if newer else 1,
        "library_version": __version__,
        **dict(header),
    }
    if HEADER in arrays:
        raise ValueError(f"arrays must not be named {HEADER!r} (the JSON header)")
    validate_model(header, arrays, where="model")
    return write_npz(path, {HEADER: np.array(json.dumps(header)), **arrays})


def load_model_file(path: PathLike, *, kind: str | None = None) -> ModelFile:
    """Read and validate a model file; ``kind`` (``"classifier"``/``"clustering"``) restricts it.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        One line naming the file and what is wrong: not a model file (e.g. a data file or an ONNX
        bundle), empty, truncated or corrupt, a pickle-based ``torch.save`` file, a newer format
        version, a missing or malformed field, arrays whose shapes disagree, non-finite values.
    """
    path = Path(path)
    _refuse_torch_save(path)
    arrays = read_npz(path, what="tactile-torch model file")
    if HEADER not in arrays:
        raise ValueError(
            f"{path}: not a tactile-torch model file (no '{HEADER}'; it holds {sorted(arrays)}: a data "
            "file?); model files come from 'tactile-torch train --out' or 'tactile-torch cluster'"
        )
    raw = arrays.pop(HEADER)
    if raw.ndim != 0 or raw.dtype.kind != "U":
        raise ValueError(f"{path}: {HEADER} must be one JSON string, got {raw.dtype} {raw.shape}")
    try:
        header = json.loads(str(raw[()]))
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: {HEADER} is not valid JSON ({err})") from None
    validate_model(header, arrays, where=str(path))
    if kind is not None and header["kind"] != kind:
        raise ValueError(f"{path}: expected a {kind} model file, got a {header['kind']} ({header['method']})")
    return ModelFile(header, arrays, path)


def _refuse_torch_save(path: Path) -> None:
    # torch.save writes a zip holding "<name>/data.pkl": say what it is rather than "not a model file".
    try:
        with zipfile.ZipFile(path) as z:
            pickled = any(name.endswith("data.pkl") for name in z.namelist())
    except (zipfile.BadZipFile, OSError, ValueError, NotImplementedError, RuntimeError):
        return  # read_npz gives the precise reason
    if pickled:
        raise ValueError(
            f"{path}: a torch.save (pickle) file, e.g. a model.pt of tactile-torch 0.1; model files are "
            "no longer unpickled (a crafted one runs code when loaded): train or cluster again to write "
            "the safe format (docs/formats.md)"
        )


# ------------------------------------------------------------------------------------ validation
def _fail(where: str, message: str) -> None:
    raise ValueError(f"{where}: {message}")


def _check_type(where: str, name: str, value: object, want: type) -> None:
    ok = (
        isinstance(value, bool)
        if want is bool
        else isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if want is float
        else isinstance(value, want) and not isinstance(value, bool)
    )
    if not ok:
        _fail(where, f"{name} must be {want.__name__}, got {value!r}")


def _check_settings(where: str, prefix: str, spec: Mapping, given: object, known: Mapping) -> dict:
    if not isinstance(given, dict) or given.get("type") not in known:
        _fail(where, f"{prefix}.type must be one of {sorted(known)}, got {given!r:.80}")
    for name, want in spec.items():
        if name not in given:
            _fail(where, f"{prefix}.{name} is missing")
        _check_type(where, f"{prefix}.{name}", given[name], want)
    return given


def _check_arrays(where: str, prefix: str, spec: Mapping, arrays: Mapping, dims: dict[str, int]) -> None:
    """Check ``prefix.<name>`` arrays against ``spec``; bind named dimensions in ``dims``."""
    for name, (shape, kind) in spec.items():
        key = f"{prefix}.{name}" if prefix else name
        if key not in arrays:
            _fail(where, f"array {key!r} is missing")
        value = arrays[key]
        if value.ndim != len(shape):
            _fail(where, f"{key} must have shape ({', '.join(shape)}), got {value.shape}")
        for axis, (dim, size) in enumerate(zip(shape, value.shape, strict=True)):
            if dims.setdefault(dim, size) != size:
                _fail(
                    where,
                    f"{key} has shape {value.shape}: axis {axis} ({DIMENSIONS[dim]}) must be {dims[dim]} "
                    f"to agree with the rest of the file, got {size}",
                )
        if kind == "f":
            if not np.issubdtype(value.dtype, np.floating):
                _fail(where, f"{key} must be float, got {value.dtype}")
            if not np.isfinite(value).all():
                _fail(where, f"{key} must be finite, got {int((~np.isfinite(value)).sum())} NaN/inf value(s)")
        elif not np.issubdtype(value.dtype, np.integer):
            _fail(where, f"{key} must be integers, got {value.dtype}")


def _check_source(where: str, source: object) -> int | None:
    """Validate ``source``; return the number of features the front end makes (None: not fixed here)."""
    if not isinstance(source, dict):
        _fail(where, f"source must be an object, got {source!r:.80}")
    kind = source.get("kind")
    if kind == "vibration":
        for name, want in (("window", int), ("step", int), ("rate_hz", float)):
            _check_type(where, f"source.{name}", source.get(name), want)
        # what train makes; checked before any allocation
        if not MIN_WINDOW <= source["window"] <= MAX_WINDOW:
            _fail(
                where,
                f"source.window must be a number of samples in {MIN_WINDOW} .. {MAX_WINDOW:,} (what train makes), "
                f"got {source['window']}",
            )
        if not 1 <= source["step"] <= MAX_WINDOW or not 0 < source["rate_hz"] < float("inf"):
            _fail(
                where, f"source must have step in 1 .. {MAX_WINDOW:,} and a finite rate_hz > 0, got {source}"
            )
        return VIBRATION_FEATURES
    if kind == "image" or kind == "pressure":
        return _check_frame_source(where, source)
    if kind == "features":
        _check_type(where, "source.n_features", source.get("n_features"), int)
        if source["n_features"] < 1:
            _fail(where, f"source.n_features must be >= 1, got {source['n_features']}")
        return source["n_features"]
    _fail(where, f"source.kind must be 'vibration', 'image', 'pressure' or 'features', got {kind!r}")
    return None


def _check_frame_source(where: str, source: dict) -> int:
    """Validate an ``image`` or ``pressure`` source; return the number of features its front end makes."""
    rgb = source["kind"] == "image"
    features = source.get("features", "per-taxel" if not rgb else None)
    if features not in ((None, "per-taxel") if rgb else ("per-taxel",)):
        want = "absent (image features) or 'per-taxel'" if rgb else "'per-taxel'"
        _fail(where, f"source.features must be {want} for {source['kind']} input, got {features!r:.40}")
    if rgb:
        _check_type(where, "source.fuse", source.get("fuse"), bool)
        if "threshold" in source:
            _check_type(where, "source.threshold", source["threshold"], float)
            if not 0 < source["threshold"] <= 1:
                _fail(where, f"source.threshold must be a gray level in (0, 1], got {source['threshold']!r}")
        if "erosion" in source:
            _check_type(where, "source.erosion", source["erosion"], int)
            if source["erosion"] < 1:
                _fail(where, f"source.erosion must be >= 1 pixel, got {source['erosion']!r}")
    shape = source.get("frame_shape")
    if not (
        isinstance(shape, list)
        and len(shape) == (4 if rgb else 3)
        and all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in shape)
        and (shape[1] == 3 or not rgb)
    ):
        _fail(
            where, f"source.frame_shape must be {'[T, 3, H, W]' if rgb else '[T, H, W]'}, got {shape!r:.80}"
        )
    if 4 * math.prod(shape) > max_read_bytes():  # one float32 exploration: checked before any allocation
        _fail(
            where,
            f"source.frame_shape {shape} makes one exploration of {4 * math.prod(shape):,} bytes, more than the "
            f"read limit of {max_read_bytes():,} bytes (raise it with {MAX_READ_ENV}=MB if the file is trusted)",
        )
    if features == "per-taxel":
        if shape[0] < 2:
            _fail(where, f"source.frame_shape must have T >= 2 frames for per-taxel features, got {shape}")
        return TAXEL_FEATURES * shape[-2] * shape[-1]
    return IMAGE_FEATURES if source["fuse"] else IMAGE_FEATURES * shape[0]


def validate_model(header: object, arrays: Mapping[str, np.ndarray], *, where: str = "model") -> None:
    """Raise ``ValueError`` (``"<where>: <what is wrong>"``) unless header and arrays form a valid model."""
    kind, names = _check_identity(where, header)
    n_features = _check_source(where, header.get("source"))
    dims: dict[str, int] = {"C": len(names)}
    head = _check_settings(where, "head", {}, header.get("head"), HEADS)
    spec = HEADS[head["type"]]
    _check_settings(where, "head", spec["settings"], head, HEADS)
    head_arrays = dict(spec["arrays"])
    if "modes" in spec:
        if head["mode"] not in spec["modes"]:
            _fail(where, f"head.mode must be one of {sorted(spec['modes'])}, got {head['mode']!r}")
        more, n_functions = spec["modes"][head["mode"]]
        head_arrays.update(more)
        dims["M"] = n_functions(len(names))
    transform = header.get("transform")
    if transform is not None:
        tspec = TRANSFORMS[_check_settings(where, "transform", {}, transform, TRANSFORMS)["type"]]
        _check_settings(where, "transform", tspec["settings"], transform, TRANSFORMS)
        tdims = {"F": transform["n_components"]}
        _check_arrays(where, "transform", tspec["arrays"], arrays, tdims)
        dims["F"] = tdims["F"]
    elif n_features is not None:
        dims["F"] = n_features
    if (
        kind == "classifier" and "select" in arrays
    ):  # the head takes these columns of the front end's features
        dims["R"] = dims.pop("F")
        _check_arrays(where, "", {"select": (("F",), "i")}, arrays, dims)
        if arrays["select"].size and (arrays["select"].min() < 0 or arrays["select"].max() >= dims["R"]):
            _fail(
                where,
                f"select must lie in 0..{dims['R'] - 1}, got {arrays['select'].min()}..{arrays['select'].max()}",
            )
    if kind == "classifier":
        _check_arrays(where, "", {"scale": (("F",), "f")}, arrays, dims)
        if (arrays["scale"] <= 0).any():
            _fail(where, "scale must be > 0 (a standard deviation per feature)")
        if "center" in arrays:
            _check_arrays(where, "", {"center": (("F",), "f")}, arrays, dims)
    if head["type"] == "gaussian-mixture":
        head_arrays = _mixture_arrays(where, head, head_arrays, arrays, dims)
    _check_arrays(where, "head", head_arrays, arrays, dims)
    if kind == "classifier" and header.get("ood") is not None:
        _check_ood(where, header["ood"], arrays, dims)
    if kind == "clustering":
        _check_novelty(where, header, arrays)
    _check_head_values(where, head, arrays, dims)


def _check_identity(where: str, header: object) -> tuple[str, list[str]]:
    """Check what a model file says it is (format, version, kind, method, class names); return kind and names."""
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        got = header.get("format") if isinstance(header, dict) else type(header).__name__
        _fail(where, f"not a tactile-torch model file (header format must be {FORMAT!r}, got {got!r})")
    version = header.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        _fail(where, f"format_version must be an int >= 1, got {version!r}")
    if version > FORMAT_VERSION:
        _fail(
            where,
            f"written by a newer tactile-torch ({header.get('library_version')}, model format version "
            f"{version}); this one ({FORMAT_VERSION}) cannot read it: upgrade tactile-torch",
        )
    kind = header.get("kind")
    if kind not in MODEL_KINDS:
        _fail(where, f"kind must be one of {MODEL_KINDS}, got {kind!r}")
    if header.get("method") not in METHODS[kind]:
        _fail(where, f"method of a {kind} must be one of {METHODS[kind]}, got {header.get('method')!r}")
    names = header.get("class_names")
    if not isinstance(names, list) or not names or not all(isinstance(c, str) for c in names):
        _fail(where, f"class_names must be a non-empty list of strings, got {names!r:.80}")
    check_class_names(names, f"{where}: class_names")
    return kind, names


def _check_head_values(
    where: str, head: dict, arrays: Mapping[str, np.ndarray], dims: dict[str, int]
) -> None:
    """What a head's shapes do not say: a neighbours head's settings and labels, an SVM's tree or pairs."""
    if head["type"] == "neighbours":
        settings_ok = head["weights"] in ("uniform", "distance") and head["p"] in (1, 2)
        if not settings_ok or head["n_neighbors"] < 1:
            _fail(
                where,
                "head must have weights 'uniform' or 'distance', p 1 or 2 and n_neighbors >= 1, got "
                f"{head['weights']!r}, {head['p']!r}, {head['n_neighbors']!r}",
            )
        labels = arrays["head.labels"]
        if labels.size and (labels.min() < 0 or labels.max() >= dims["C"]):
            _fail(where, f"head.labels must lie in 0..{dims['C'] - 1}, got {labels.min()}..{labels.max()}")
    if head["type"] == "svm" and head["mode"] == "tree":
        _check_tree(where, arrays, dims, head["depth"])
    if head["type"] == "svm" and head["mode"] == "ovo":
        counts, pairs = arrays["head.n_support"], dims["C"] * (dims["C"] - 1) // 2
        if dims["P"] != pairs:
            _fail(where, f"head.intercept must hold one value per pair of classes ({pairs}), got {dims['P']}")
        if counts.min() < 0 or counts.sum() != dims["S"]:
            _fail(
                where,
                f"head.n_support must count the {dims['S']} support vectors per class, got {counts.tolist()}",
            )


def _check_ood(where: str, ood: object, arrays: Mapping[str, np.ndarray], dims: dict[str, int]) -> None:
    # the out-of-distribution distance (tactile_torch.ood): per-class means and a precision factor
    if not isinstance(ood, dict) or ood.get("type") != "mahalanobis":
        _fail(where, f"ood.type must be 'mahalanobis', got {ood!r:.80}")
    for name in ("quantile", "threshold"):
        _check_type(where, f"ood.{name}", ood.get(name), float)
    if not (0 < ood["quantile"] <= 1 and ood["threshold"] > 0):
        _fail(where, f"ood must have 0 < quantile <= 1 and threshold > 0, got {ood}")
    spec = {"means": (("C", "F"), "f"), "precision_cholesky": (("F", "F"), "f")}
    if "ood.offset" in arrays:  # the offset back from centred features (older files: none)
        spec["offset"] = (("F",), "f")
    second = ("floor", "log_means", "log_precision_cholesky", "norm")
    if any(f"ood.{name}" in arrays for name in second):  # the second view, all or nothing (older files: none)
        spec.update(
            floor=(("F",), "f"),
            log_means=(("C", "F"), "f"),
            log_precision_cholesky=(("F", "F"), "f"),
            norm=(("V",), "f"),
        )
    _check_arrays(where, "ood", spec, arrays, {**dims, "V": 2})
    if "floor" in spec and ((arrays["ood.floor"] <= 0).any() or (arrays["ood.norm"] <= 0).any()):
        _fail(where, "ood.floor and ood.norm must be > 0 (scales)")


def _mixture_arrays(where: str, head: Mapping, spec: dict, arrays: Mapping, dims: dict[str, int]) -> dict:
    # a mixture that counts and clusters on the first ``cluster_features`` of the F features and scores
    # novelty with the density of all F (head.density_*): its components are (C, K), K < F
    spec = dict(spec)
    if "cluster_features" in head:
        k = head["cluster_features"]
        _check_type(where, "head.cluster_features", k, int)
        if not 1 <= k < dims.get("F", k + 1):
            _fail(where, f"head.cluster_features must be in 1..{dims.get('F', k + 1) - 1}, got {k}")
        dims["K"] = k
        spec.update({"means": (("C", "K"), "f"), "precisions_cholesky": (("C", "K", "K"), "f")})
    if "cluster_features" in head or arrays.get("head.density_means", np.zeros(0)).size:
        spec.update(
            {
                "density_means": (("Q", "F"), "f"),
                "density_precisions_cholesky": (("Q", "F", "F"), "f"),
                "density_log_weights": (("Q",), "f"),
            }
        )
    return spec


def _check_novelty(where: str, header: Mapping, arrays: Mapping[str, np.ndarray]) -> None:
    # a clustering's calibrated novelty thresholds, how they were set, and per-session standardisation
    if "per_session" in header:
        _check_type(where, "per_session", header["per_session"], bool)
    novelty = header.get("novelty")
    if novelty is not None:
        if not isinstance(novelty, dict):
            _fail(where, f"novelty must be an object, got {novelty!r:.80}")
        _check_type(where, "novelty.false_alarm", novelty.get("false_alarm"), float)
        _check_type(where, "novelty.calibration_rows", novelty.get("calibration_rows"), int)
        if not (0 < novelty["false_alarm"] < 1 and novelty["calibration_rows"] >= 1):
            _fail(where, f"novelty must have 0 < false_alarm < 1 and calibration_rows >= 1, got {novelty}")
    if "head.novelty_thresholds" in arrays:
        _check_arrays(where, "head", {"novelty_thresholds": (("W",), "f")}, arrays, {})


def _check_tree(where: str, arrays: Mapping[str, np.ndarray], dims: dict[str, int], depth: int) -> None:
    # Indices in range, so that a crafted file cannot make the exported graph read out of bounds.
    bounds = {"left": dims["N"], "right": dims["N"], "column": dims["M"], "leaf_label": dims["C"]}
    for name, bound in bounds.items():
        value = arrays[f"head.{name}"]
        if value.size and (value.min() < 0 or value.max() >= bound):
            _fail(where, f"head.{name} must lie in 0..{bound - 1}, got {value.min()}..{value.max()}")
    if not np.isin(arrays["head.path_sign"], (-1, 0, 1)).all():
        _fail(where, "head.path_sign must hold -1, 0 or 1")
    if not 1 <= depth <= dims["N"]:
        _fail(where, f"head.depth must be in 1..{dims['N']}, got {depth}")


__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "HEADS",
    "MODEL_KINDS",
    "TRANSFORMS",
    "ModelFile",
    "load_model_file",
    "save_model_file",
    "validate_model",
]
