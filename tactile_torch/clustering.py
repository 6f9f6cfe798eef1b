"""Discover surfaces in a data file and write the results: what ``tactile-torch cluster`` runs.

The twin of :mod:`tactile_torch.training` for the unsupervised path (the clustering *study* of the
report is :mod:`tactile_torch.studies.clustering`). :func:`fit_clustering` turns data read by
:func:`tactile_torch.robot.files.data_sources.read_source` into what the mixture clusters (vibration recordings:
windows, their features (:func:`tactile_torch.features.files.load_features`), then the fitted
:class:`~tactile_torch.signal.ClusteringTransform` and its principal components; a ``features``
array as it is) and fits :class:`~tactile_torch.mixture.PitmanYorGMM` to it.

**Calibration of the novelty rule.** Recordings: the last ``calibrate`` share (default a third) of
each recording's windows is held out of the fit (and of the transform), and the mixture's novelty
thresholds are set on them (:meth:`~tactile_torch.mixture.PitmanYorGMM.calibrate_novelty`: the
``1 - false_alarm`` quantile of the novelty score, minus the log density, per number of
consecutive windows N = 1 … 10), so that the exported graph's ``novel`` output and ``tactile-torch
stream --discover N`` decide at a false-alarm rate set on windows the fit did not see. A feature
matrix is calibrated only when ``calibrate`` is given (a random hold-out: its rows have no time
order). **Sessions** (recordings of several days: day folders, a ``session`` array, an index CSV):
by default (``sessions="auto"``) the mixture is fitted with session effects
(:meth:`~tactile_torch.mixture.PitmanYorGMM.fit` with ``sessions=``: each surface's location may
move from session to session, so K counts surfaces across the sessions) whenever some session
holds recordings of several surfaces; ``"model"`` insists on it, ``"none"`` ignores the sessions,
``"standardise"`` standardises the components within each session instead
(:func:`tactile_torch.signal.sessions.standardise_per_session`; such a model cannot be exported:
the robot cannot standardise a session it has not seen). A model with session effects exports: a
window of a new session is classified with its session's effect integrated out.

:func:`write_clustering` writes the results into a directory: ``clustering.npz`` (the point estimate,
the MAP sample, the posterior samples of K and of the prior's parameters), ``model.npz`` (the model
file :func:`tactile_torch.clustering_model.save_clustering_model` writes, for ``tactile-torch export``) and
``summary.txt`` (:func:`clustering_summary`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

CLUSTERED_KINDS = ("vibration", "features")
"""Kinds of data (``.kind`` of what ``read_source`` returns) that can be clustered."""
RESULTS_FILE = "clustering.npz"
MODEL_FILE = "model.npz"
SUMMARY_FILE = "summary.txt"


@dataclass
class Clustering:
    """A fitted clustering of one data set.

    Attributes
    ----------
    mixture : PitmanYorGMM
        Fitted to ``X``.
    X : ndarray of shape (N, D)
        What the mixture was fitted to: principal components of the windows' features, or the
        file's features.
    truth : ndarray of shape (N,) or None
        The file's class of each row, when it has labels (for the pairwise accuracy only).
    source : dict
        How a row is made from raw input (the model file's ``source``).
    transform : ClusteringTransform or None
        Vibration windows: the fitted features-to-components transform.
    fitted_rows, calibration_rows : ndarray of int
        Rows of ``X`` the mixture (and the transform) were fitted to, and the held-out rows its
        novelty thresholds were calibrated on (empty: not calibrated), in time order per recording.
    per_session : bool
        ``X`` was standardised within each recording session.
    false_alarm : float or None
        The false-alarm rate the thresholds were calibrated for (None: not calibrated).
    sessions : ndarray of str (N,) or None
        The session of every row of ``X`` (None: the data have none).
    session_mode : {"model", "standardised", "none"}
        How the sessions were used: session effects in the mixture, per-session standardisation,
        or not at all.
    sessions_from : str or None
        Where the sessions came from (``"their folders"``, ``"the file's session array"``, ...),
        for the summary.
    """

    mixture: object
    X: np.ndarray
    truth: np.ndarray | None
    source: dict
    transform: object | None = None
    fitted_rows: np.ndarray | None = None
    calibration_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    per_session: bool = False
    false_alarm: float | None = None
    sessions: np.ndarray | None = None
    session_mode: str = "none"
    sessions_from: str | None = None

    def __post_init__(self) -> None:
        if self.fitted_rows is None:
            self.fitted_rows = np.arange(len(self.X))


DEFAULT_CALIBRATE = 1 / 3
"""Share of each recording's windows held out of the fit to calibrate the novelty thresholds: a third
(issue 32, decision (c); docs/mixture.md: on HapMat and BorealTC it keeps the false alarms after 3
windows at 2.3 % and 1.3 %, where 20 % gave 8.4 % and 9.1 %)."""
NOVELTY_COMPONENTS = 5
"""Principal components of the novelty rule's density (recordings); the first ``components`` of them count K."""
MAX_WINDOWS = 10
"""Thresholds are calibrated for decisions after N = 1 … ``MAX_WINDOWS`` consecutive windows."""
SESSION_MODES = ("auto", "model", "standardise", "none")
"""How :func:`fit_clustering` uses the recordings' sessions (its ``sessions`` argument)."""


def holdout_rows(
    n_rows: int,
    share: float,
    *,
    recording: np.ndarray | None = None,
    position: np.ndarray | None = None,
    random_state: object = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Return (fitted rows (sorted), held-out rows) as int arrays: the last ``share`` of each recording, or a random share.

    With ``recording`` and ``position`` (windows of recordings), the held-out rows are the last
    ``round(share * n)`` windows of each recording of ``n`` windows (later in time than every fitted
    window of it), ordered by recording then position. Without, ``round(share * n_rows)`` rows drawn
    at random (``random_state``), sorted.
    """
    from .validation import numpy_rng

    if not (isinstance(share, int | float) and not isinstance(share, bool) and 0.0 < share < 1.0):
        raise ValueError(f"calibrate must be a share in (0, 1), got {share!r}")
    held = np.zeros(n_rows, dtype=bool)
    if recording is None:
        pick = numpy_rng(random_state).choice(n_rows, size=round(share * n_rows), replace=False)
        held[pick] = True
        return np.flatnonzero(~held), np.flatnonzero(held)
    order = np.lexsort((position, recording))
    for r in np.unique(recording):
        idx = order[recording[order] == r]
        held[idx[idx.size - round(share * idx.size) :]] = True
    held_rows = order[held[order]]  # recording-major, in time order
    return np.flatnonzero(~held), held_rows


def fit_clustering(
    data,
    *,
    window: int = 800,
    step: int | None = None,
    components: int = 3,
    novelty_components: int | None = NOVELTY_COMPONENTS,
    sensor_range_g: float | None = None,
    name: str = "data",
    log: Callable[[str], None] | None = None,
    calibrate: float | None = None,
    false_alarm: float = 0.02,
    sessions: str = "auto",
    sessions_from: str | None = None,
    **mixture_params,
) -> Clustering:
    """Return the clustering of ``data``: its rows, and the mixture fitted to them.

    Parameters
    ----------
    data : DataArrays
        What :func:`tactile_torch.robot.files.data_sources.read_source` returned, of kind ``"vibration"``
        (recordings) or ``"features"`` (a matrix ``(N, D)``, labels optional).
    window, step : int
        Vibration: window length and hop in samples (default hop: ``window``).
    components : int
        Vibration: principal components that the mixture counts and clusters (K, the labels).
    novelty_components : int or None
        Vibration: principal components of the novelty rule's density (default 5): the transform
        keeps ``max(components, novelty_components)`` components, the mixture clusters the first
        ``components`` and scores novelty on all (:class:`~tactile_torch.mixture.PitmanYorGMM`'s
        ``cluster_features``); the exported graph computes them side by side. ``None``: the same
        ``components`` for both.
    sensor_range_g : float, optional
        Vibration: the sensor's range declared by the user, kept in ``source`` (the export's
        default range). ``None`` or ``inf``: not kept.
    name : str
        How messages name the data.
    log : callable, optional
        Called with one line once the rows are ready, before the (long) fit.
    calibrate : float, optional
        Share of the rows held out of the fit to calibrate the novelty thresholds on: the last
        ``calibrate`` of each recording's windows (default for recordings: a third,
        :data:`DEFAULT_CALIBRATE`), or for a feature matrix a random share (default: none, no
        calibration; the draw uses ``random_state``). ``0``: no hold-out, the model's own rule.
    false_alarm : float
        Target share of novel decisions on windows of known surfaces: the thresholds are the
        ``1 - false_alarm`` quantiles on the held-out rows.
    sessions : {"auto", "model", "standardise", "none"}
        How to use the recordings' sessions (days): ``"model"``, session effects in the mixture
        (K counts surfaces across sessions; :func:`check_session_effects` must pass);
        ``"standardise"``, standardise the components within each session (:func:`check_sessions`
        must pass; not exportable); ``"none"``, ignore them; ``"auto"`` (default), ``"model"``
        when :func:`check_session_effects` passes, else ``"none"``.
    sessions_from : str, optional
        Where the sessions came from, for the summary (``"their folders"``).
    **mixture_params
        Passed to :class:`~tactile_torch.mixture.PitmanYorGMM` (``model``, ``coarsen``, ``alpha``,
        ``n_iter``, ``random_state``, ``progress``, ...), which validates them at ``fit``.

    Raises
    ------
    ValueError
        ``data`` of another kind (images), ``sessions`` that the data cannot serve, a hold-out
        that leaves no row to fit or to calibrate, or data and parameters the readers or the
        mixture refuse.
    """
    from .mixture import PitmanYorGMM

    if sessions not in SESSION_MODES:
        raise ValueError(f"sessions must be one of {', '.join(map(repr, SESSION_MODES))}, got {sessions!r}")

    if isinstance(false_alarm, bool) or not (isinstance(false_alarm, int | float) and 0 < false_alarm < 1):
        raise ValueError(f"false_alarm must be a number in (0, 1), got {false_alarm!r}")
    if novelty_components is not None and (
        isinstance(novelty_components, bool)
        or not isinstance(novelty_components, int)
        or novelty_components < 1
    ):
        raise ValueError(f"novelty_components must be an integer >= 1 or None, got {novelty_components!r}")
    transform = None
    mode = _session_mode(
        data, sessions, name
    )  # before any work: a fit on meaningless sessions runs for minutes
    row_sessions = None
    if data.kind == "features":  # labels optional: clustering does not need them
        X, truth = data.features, data.labels
        source = {"kind": "features", "n_features": int(X.shape[1])}
        rows = _holdout(len(X), calibrate, None, None, mixture_params.get("random_state"), name)
    elif data.kind == "vibration":
        from .features.files import load_features
        from .signal import fit_clustering_transform

        features = load_features(data, window=window, step=step, name=name)
        truth, source = features.y, dict(features.source)
        if sensor_range_g is not None and sensor_range_g != float("inf"):
            source["sensor_range_g"] = float(sensor_range_g)
        share = DEFAULT_CALIBRATE if calibrate is None else calibrate
        rows = _holdout(len(features.X), share, features.recording, features.position, None, name)
        # the novelty rule's components where the data afford them (min(rows, 12 mapped features))
        width = max(components, min(novelty_components or components, len(rows[0]), 12))
        transform, X = fit_clustering_transform(features.X, width, fit_rows=rows[0])
        if width > components:
            mixture_params = {"cluster_features": components} | mixture_params
        if data.session is not None:
            row_sessions = np.asarray(data.session).astype(str)[features.recording]
        if mode == "standardised":
            X = _standardise_sessions(X, data, features.recording, name)
        if log is not None:
            held = f", {rows[1].size} held out to calibrate the novelty rule" if rows[1].size else ""
            counted = f" (K counted on the first {components})" if X.shape[1] > components else ""
            log(
                f"{name}: {len(X)} windows of {window} samples -> {X.shape[1]} principal components{counted}{held}"
            )
    else:
        raise ValueError(
            f"{name}: data must hold vibration recordings ('signals') or a 'features' array (n, D) to "
            f"cluster, got {data.kind} data"
        )
    fitted, held = rows
    mixture = PitmanYorGMM(**mixture_params)
    mixture.fit(X[fitted], sessions=row_sessions[fitted] if mode == "model" else None)
    rate = None
    if held.size:
        groups = None if data.kind == "features" else features.recording[held]
        mixture.calibrate_novelty(X[held], false_alarm=false_alarm, max_windows=MAX_WINDOWS, groups=groups)
        rate = float(false_alarm)
    return Clustering(
        mixture, X, truth, source, transform, fitted, held, mode == "standardised", rate, row_sessions, mode,
        sessions_from if row_sessions is not None else None,
    )  # fmt: skip


def _session_mode(data, sessions: str, name: str) -> str:
    """``"model"``, ``"standardised"`` or ``"none"``: how :func:`fit_clustering` uses the sessions; refuse what cannot be."""
    if sessions == "none":
        return "none"
    if data.kind != "vibration":
        if sessions in ("model", "standardise") and data.kind == "features":
            raise ValueError(
                f"{name}: sessions={sessions!r} needs vibration recordings with sessions, got a feature matrix"
            )
        return "none"
    if data.session is None and sessions == "auto":
        return "none"
    if sessions == "standardise":
        check_sessions(data, name)
        return "standardised"
    if sessions == "model":
        check_session_effects(data, name)
        return "model"
    try:  # auto
        check_session_effects(data, name)
    except ValueError:
        return "none"
    return "model"


def _several_sessions(data, name: str, what: str) -> np.ndarray:
    """The recordings' sessions as strings; ``ValueError`` (``"<name>: <what> recordings of at least two sessions ..."``) when fewer."""
    session = None if data.session is None else np.asarray(data.session).astype(str)
    if session is None or np.unique(session).size < 2:
        raise ValueError(
            f"{name}: {what} recordings of at least two sessions (a 'session' array, CSV logs named "
            "<class>_<session>.csv, or one folder per session), got "
            + ("none" if session is None else f"one ({session[0]!r})")
        )
    return session


def check_session_effects(data, name: str = "data") -> None:
    """Refuse recordings whose sessions cannot inform session effects (``cluster --sessions model``), in one line.

    A session effect is told from a surface by the other surfaces recorded in the same session:
    refused are fewer than two sessions, and sessions that each hold a single recording, or (with
    labels of several classes) recordings of a single surface each (every session would then be a
    surface, and its effect could take any surface onto another).

    Raises
    ------
    ValueError
        Naming the data and what its sessions hold.
    """
    session = _several_sessions(data, name, "session effects need")
    labels = np.asarray(data.labels) if data.labels is not None else np.zeros(len(session), dtype=np.int64)
    several = np.unique(labels).size > 1
    shared = [
        s
        for s in np.unique(session)
        if np.unique(labels[session == s] if several else np.flatnonzero(session == s)).size > 1
    ]
    if not shared:
        alone = all(np.count_nonzero(session == s) == 1 for s in np.unique(session))
        what = "a single recording" if alone or not several else "recordings of a single surface"
        raise ValueError(
            f"{name}: each of the {np.unique(session).size} sessions holds {what}; a session effect is told from "
            "a surface by other surfaces recorded in the same session (one folder per day holding several "
            "surfaces, or an index CSV, index=); pass sessions='none'"
        )


def _holdout(n_rows, share, recording, position, random_state, name) -> tuple[np.ndarray, np.ndarray]:
    """(fitted rows, held-out rows): every row fitted when ``share`` is None or 0."""
    if share is None or (share == 0 and not isinstance(share, bool)):
        return np.arange(n_rows), np.zeros(0, dtype=np.int64)
    if isinstance(share, bool) or not (isinstance(share, int | float) and 0 < share < 1):
        raise ValueError(f"calibrate must be 0 (no hold-out) or a share in (0, 1), got {share!r}")
    fitted, held = holdout_rows(
        n_rows, share, recording=recording, position=position, random_state=random_state
    )
    if fitted.size < 2 or held.size < 1:
        raise ValueError(
            f"{name}: holding out {share:g} of the {n_rows} rows to calibrate the novelty rule leaves "
            f"{fitted.size} to fit and {held.size} to calibrate; pass another share (calibrate=) or 0"
        )
    return fitted, held


def check_sessions(data, name: str = "data") -> None:
    """Refuse recordings whose sessions cannot be standardised within (``cluster --sessions``), in one line.

    Standardising within a session removes what its recordings share; that is the session's gain
    shift only when the session holds several surfaces. Refused: no sessions, a single session, every
    session one recording, and (with several classes) a session whose recordings are all of one class,
    which standardising would erase.

    Raises
    ------
    ValueError
        Naming the data, the session and what it holds.
    """
    session = _several_sessions(data, name, "sessions needs")
    if all(np.count_nonzero(session == s) == 1 for s in np.unique(session)):
        raise ValueError(
            f"{name}: every session holds one recording; standardising within it would remove what "
            "tells its surface from the others (sessions must each hold the same mix of surfaces)"
        )
    labels = np.asarray(data.labels)
    if np.unique(labels).size < 2:
        return
    single = [s for s in np.unique(session) if np.unique(labels[session == s]).size == 1]
    if single:
        s = str(single[0])
        surface = data.class_names[int(labels[session == s][0])]
        raise ValueError(
            f"{name}: {len(single)} of {np.unique(session).size} sessions hold a single surface (session {s!r}: "
            f"{np.count_nonzero(session == s)} recording(s), all {surface!r}); standardising within such a session "
            "would remove its surface (sessions must each hold the same mix of surfaces: one folder per "
            "session, or an index CSV, index=)"
        )


def _standardise_sessions(X: np.ndarray, data, recording: np.ndarray, name: str) -> np.ndarray:
    """``X`` standardised within each recording session (:func:`check_sessions` has passed)."""
    from .signal.sessions import standardise_per_session

    return standardise_per_session(X, np.asarray(data.session).astype(str)[recording])


def clustering_summary(clustering: Clustering) -> str:
    """Return the mixture's summary (posterior of K first), how sessions were used and, with labels, the agreement with them."""
    model = clustering.mixture
    summary = model.summary()
    for line in (sessions_line(clustering), novelty_line(clustering), labels_line(clustering)):
        if line:
            summary += "\n" + line
    return summary


def sessions_line(clustering: Clustering) -> str:
    """Return one line on how the recordings' sessions were used ("" when the data have none)."""
    if clustering.sessions is None:
        return ""
    names = np.unique(clustering.sessions)
    listed = ", ".join(names[:6]) + (", ..." if names.size > 6 else "")
    where = f" from {clustering.sessions_from}" if clustering.sessions_from else ""
    head = f"sessions: {names.size}{where} ({listed})"
    if clustering.session_mode == "model":
        lam = clustering.mixture.session_scale_
        return (
            f"{head}; K counts surfaces across them: a session may move every surface by a common offset and "
            f"each by its own effect (variance {lam:.3g} times the surface's spread, posterior mean); a window "
            "of a new session is classified with its session's offset and effect integrated out"
        )
    if clustering.session_mode == "standardised":
        return f"{head}; the components were standardised within each session (not exportable)"
    return f"{head}; not used: K counts blobs of any session as surfaces (sessions='model' to use them)"


def labels_line(clustering: Clustering) -> str:
    """Return one line comparing the point estimate and the MAP sample with the data's labels ("" without labels)."""
    from sklearn.metrics import adjusted_rand_score

    from .metrics import pairwise_accuracy

    if clustering.truth is None:
        return ""
    truth = np.asarray(clustering.truth)[clustering.fitted_rows]
    model = clustering.mixture
    n_classes = np.unique(truth).size

    def scores(labels: np.ndarray) -> str:
        return (
            f"pairwise accuracy {pairwise_accuracy(truth, labels):.4f}, "
            f"adjusted Rand index {adjusted_rand_score(truth, labels):.4f}"
        )

    return (
        f"against the data's labels ({n_classes} classes, {truth.size} fitted windows): point estimate "
        f"({model.n_clusters_} clusters) {scores(model.labels_)}; MAP sample ({model.map_n_clusters_}) "
        f"{scores(model.map_labels_)}. Pairwise accuracy is the share of window pairs put together or "
        "apart as the labels do (high whenever most pairs are of different classes); the adjusted Rand "
        "index is 1 for the labels' partition and 0 for chance"
    )


def novelty_line(clustering: Clustering) -> str:
    """Return one line on the calibrated novelty thresholds ("" when not calibrated)."""
    t = clustering.mixture.novelty_thresholds_
    if t is None or clustering.false_alarm is None:
        return ""
    after = ", ".join(f"{n} windows {t[n - 1]:.4g}" for n in (3, 5, 10) if n <= t.size)
    return (
        f"novelty: a window is novel when its score (minus its log density) exceeds {t[0]:.4g}, set for "
        f"{clustering.false_alarm:.1%} false alarms on the {clustering.calibration_rows.size} held-out "
        f"windows; the mean over N windows (stream --discover N): {after}"
    )


def _session_header(clustering: Clustering) -> dict | None:
    """The model file's ``sessions`` entry of a mixture fitted with session effects (None otherwise)."""
    if clustering.session_mode != "model":
        return None
    return {
        "names": [str(s) for s in np.unique(clustering.sessions[clustering.fitted_rows])],
        "scale": float(clustering.mixture.session_scale_),
    }


def write_clustering(out_dir: str | Path, clustering: Clustering) -> dict[str, Path]:
    """Write the results of ``clustering`` into ``out_dir`` (made if missing); return the paths by role.

    The roles are ``"results"`` (``clustering.npz``: ``labels``, ``map_labels`` (of the fitted
    rows), ``means``, ``covariances``, ``precisions_cholesky``, ``weights``, ``n_clusters_samples``,
    ``n_clusters_interval``, ``alpha_samples``, ``discount_samples``, ``fitted_rows`` and
    ``calibration_rows`` (indices of the data's rows), ``novelty_thresholds`` (``(N,)``, empty when
    not calibrated), ``per_session``, ``sessions`` (of every row, empty without), ``session_mode``
    and ``session_scale`` (lambda, NaN without session effects)), ``"summary"``
    (``summary.txt``) and ``"model"`` (``model.npz``, for ``tactile-torch export``).
    """
    from .clustering_model import save_clustering_model

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = clustering.mixture
    ks = model.n_clusters_summary_
    thresholds = model.novelty_thresholds_
    np.savez(
        out / RESULTS_FILE,
        labels=model.labels_,
        map_labels=model.map_labels_,
        means=model.means_,
        covariances=model.covariances_,
        precisions_cholesky=model.precisions_cholesky_,
        weights=model.weights_,
        n_clusters_samples=model.n_clusters_samples_,
        n_clusters_interval=np.array(ks["interval"]),
        alpha_samples=model.alpha_samples_,
        discount_samples=model.discount_samples_,
        fitted_rows=clustering.fitted_rows,
        calibration_rows=clustering.calibration_rows,
        novelty_thresholds=np.zeros(0) if thresholds is None else thresholds,
        per_session=np.array(clustering.per_session),
        sessions=np.zeros(0, dtype=str) if clustering.sessions is None else clustering.sessions,
        session_mode=np.array(clustering.session_mode),
        session_scale=np.array(np.nan if model.session_scale_ is None else model.session_scale_),
    )
    save_clustering_model(
        out / MODEL_FILE,
        model,
        source=clustering.source,
        transform=clustering.transform,
        per_session=clustering.per_session,
        sessions=_session_header(clustering),
        novelty={
            "false_alarm": clustering.false_alarm,
            "calibration_rows": int(clustering.calibration_rows.size),
        }
        if clustering.false_alarm is not None
        else None,
    )
    (out / SUMMARY_FILE).write_text(clustering_summary(clustering) + "\n")
    return {"results": out / RESULTS_FILE, "summary": out / SUMMARY_FILE, "model": out / MODEL_FILE}
