"""SVMs: our compiled solver, HM-SVM and batched grid search against scikit-learn's SVC (libsvm).

Same data, same C, gamma, tol and kernel cache for both, in the same process and run; at one thread
and at the default thread count. Ratios are libsvm time / ours (> 1: ours faster).

Data, 21 features and 28 classes, the size of method 2's study (~3,400 training windows) and 10x
that, 1,000 test samples, from two sources (plus the real IMU sets when present):

- ``vibration``: the study's problem: the 21 vibration features
  (:func:`tactile_torch.signal.window_features`) of 800-sample windows (step 400) of the library's 28
  synthetic surfaces (:func:`tactile_torch.data.make_vibration_recordings`, seed 0), split odd/even
  by window position as in the study (even: training; 1,000 seeded odd windows: test), each feature
  scaled to unit standard deviation on the training part as :mod:`tactile_torch.training` does;
- ``make_classification``: 21 features (15 informative), 28 Gaussian classes (seeded), standardised
  on the training part: a harder, less study-like problem (every class against many neighbours in
  15 dimensions), kept as a stress test;
- ``hapmat_imu5``, ``borealtc_imu``: real 100 Hz IMU recordings (``tactile_torch.data`` loaders),
  W = 100, odd/even split, when ``../shared/data`` holds them.

Rows (``task``):

- ``binary (HM-SVM root)``: our ``SVC`` vs libsvm on the binary problem at the root of the HM-SVM
  tree, with the dual objective and support sets compared;
- ``HM-SVM vs libsvm OvO``: our ``HierarchicalSVC`` (27 binary SVMs) vs scikit-learn's ``SVC``
  (one-vs-one, 378 binary SVMs), what a user would otherwise run;
- ``HM-SVM vs HM-SVM with libsvm nodes``: the same tree with every node fitted by libsvm: what the
  method costs in accuracy (the tree) apart from the solver;
- ``SVC OvO vs libsvm OvO``: our one-vs-one ``SVC`` against libsvm's (same 378 problems);
- ``grid search ...``: the study's selection of C and gamma (10-fold stratified, method 2; the
  60/20/20 rotation with a standardising pipeline, method 1), our batched search against
  ``GridSearchCV(SVC())`` and against ``GridSearchCV`` running our HM-SVM one fit at a time;
- ``threads``: ours at the default thread count against ours at one thread (fit, predict, search);
- ``start-up``: a fresh process importing ``tactile_torch.svm`` and fitting a small HM-SVM, with the
  compiled kernels loaded from the on-disk cache (warm) or compiled (cold, empty cache).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from functools import partial

import numpy as np
from sklearn.datasets import make_classification
from sklearn.model_selection import GridSearchCV, StratifiedKFold
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC as LibSVC

from bench.common import DEFAULT_THREADS, threads, time_call, time_threads_alternately
from tactile_torch.data import make_vibration_recordings, shared_data_dir
from tactile_torch.model_selection import SVMGridSearchCV, grid_search_validation, rotating_splits
from tactile_torch.signal import window_features
from tactile_torch.svm import SVC, HierarchicalSVC, TreeNode, scale_gamma, split_classes
from tests import reference_svm as ref

TITLE = "SVM: compiled libsvm solver, HM-SVM and batched grid search vs scikit-learn's SVC (libsvm)"

C = 16.0
CACHE_MB = 1024.0
N_TEST = 1000
WINDOW, STEP = 800, 400
# The study's grid (method 2 chose gamma = 0.0186, C = 16): C and gamma by factors of 4 around it.
GRID = {"C": [1.0, 4.0, 16.0, 64.0], "gamma": [0.0186 / 4, 0.0186, 0.0186 * 4]}


def make_vibration_data(n_train: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return scaled ``(X_train, y_train, X_test, y_test)``: 21 vibration features of 28 surfaces.

    Recordings are long enough for ``n_train`` even windows (about; 28 equal recordings); the
    test part is 1,000 odd windows drawn with ``seed`` (all of them if fewer).
    """
    per_recording = -(-n_train // 28)  # even windows per recording
    duration_s = (2 * per_recording * STEP + WINDOW - STEP) / 800.0
    windows = make_vibration_recordings(28, duration_s=duration_s, random_state=seed).windows(WINDOW, STEP)
    X = window_features(windows.windows).double().numpy()
    y = windows.labels.numpy()
    even = (windows.position % 2 == 0).numpy()
    train = np.flatnonzero(even)
    odd = np.flatnonzero(~even)
    test = np.random.default_rng(seed).choice(odd, min(N_TEST, odd.size), replace=False)
    std = X[train].std(axis=0, ddof=1)
    scale = np.where(std > 0, std, 1.0)
    return X[train] / scale, y[train], X[test] / scale, y[test]


def make_classification_data(
    n_train: int, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return standardised ``(X_train, y_train, X_test, y_test)``: 21 features, 28 classes."""
    X, y = make_classification(
        n_samples=n_train + N_TEST,
        n_features=21,
        n_informative=15,
        n_redundant=3,
        n_classes=28,
        n_clusters_per_class=1,
        class_sep=2.0,
        random_state=seed,
    )
    scaler = StandardScaler().fit(X[:n_train])
    return scaler.transform(X[:n_train]), y[:n_train], scaler.transform(X[n_train:]), y[n_train:]


def real_imu_data(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """The W = 100 windows of a real IMU set, odd/even split, scaled on the training part (or None)."""
    if shared_data_dir(name) is None:
        return None
    from tactile_torch import data

    rec = data.load_hapmat_imu5() if name == "hapmat_imu5" else data.load_borealtc_imu()
    ds = rec.windows(100)
    X = window_features(ds.windows).double().numpy()
    y = ds.labels.numpy()
    even = (ds.position % 2 == 0).numpy()
    std = X[even].std(axis=0, ddof=1)
    X = X / np.where(std > 0, std, 1.0)
    return X[even], y[even], X[~even], y[~even]


def _fit_time(make, X, y, repeat: int) -> tuple[object, float]:
    """Fitted model and the fastest of ``repeat`` fits (a loaded machine adds, never removes, time)."""
    best, model = np.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        model = make().fit(X, y)
        best = min(best, time.perf_counter() - start)
    return model, best


class LibsvmTree:
    """The tree of a fitted :class:`HierarchicalSVC` with every node refitted by libsvm."""

    def __init__(self, tree: TreeNode, **params) -> None:
        self.tree, self.params = tree, params

    def fit(self, X: np.ndarray, y: np.ndarray) -> LibsvmTree:
        self.models = {}
        for node in self.tree.nodes():
            if not node.is_leaf:
                rows = np.isin(y, node.classes)
                self.models[node.index] = LibSVC(**self.params).fit(
                    X[rows], np.isin(y[rows], node.right.classes)
                )
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        out = np.empty(X.shape[0], dtype=np.int64)

        def descend(node: TreeNode, rows: np.ndarray) -> None:
            if node.is_leaf:
                out[rows] = node.classes[0]
            elif rows.size:
                right = self.models[node.index].decision_function(X[rows]) > 0
                descend(node.left, rows[~right])
                descend(node.right, rows[right])

        descend(self.tree, np.arange(X.shape[0]))
        return out


def _predict_times(model, X_test) -> tuple[float, float]:
    batch = (
        time_call(lambda: model.predict(X_test[:1000]), repeat=3, warmup=1)["median_s"]
        / X_test[:1000].shape[0]
    )
    one = time_call(lambda: model.predict(X_test[:1]), repeat=50, warmup=3, min_time=0.2)["median_s"]
    return batch, one


def _row(data, task, n, n_threads, ours, ours_fit, lib, lib_fit, X_test, y_test) -> dict:
    ours_batch, ours_one = _predict_times(ours, X_test)
    lib_batch, lib_one = _predict_times(lib, X_test)
    pred_ours, pred_lib = ours.predict(X_test), lib.predict(X_test)
    return {
        "data": data,
        "task": task,
        "n_train": n,
        "threads": n_threads,
        "fit ours s": ours_fit,
        "fit libsvm s": lib_fit,
        "fit ratio": lib_fit / ours_fit,
        "predict/sample @1000 ours us": ours_batch * 1e6,
        "predict/sample @1000 libsvm us": lib_batch * 1e6,
        "predict @1000 ratio": lib_batch / ours_batch,
        "predict @1 ours us": ours_one * 1e6,
        "predict @1 libsvm us": lib_one * 1e6,
        "predict @1 ratio": lib_one / ours_one,
        "accuracy ours": float(np.mean(pred_ours == y_test)),
        "accuracy libsvm": float(np.mean(pred_lib == y_test)),
        "prediction agreement": float(np.mean(pred_ours == pred_lib)),
    }


def _classification_rows(data_name, X, y, X_test, y_test, n_threads, repeat) -> list[dict]:
    """Binary root, HM-SVM vs OvO, HM-SVM vs libsvm nodes, our OvO vs libsvm OvO."""
    n = X.shape[0]
    gamma = scale_gamma(X)
    params = {"C": C, "gamma": gamma, "cache_size": CACHE_MB}
    classes = np.unique(y)
    means = np.stack([X[y == c].mean(0) for c in classes])
    group = split_classes(means, random_state=0)
    in_group = dict(zip(classes.tolist(), group.tolist(), strict=True))
    yb, yb_test = np.array([in_group[c] for c in y]), np.array([in_group.get(c, False) for c in y_test])
    rows = []
    ours, ours_fit = _fit_time(partial(SVC, **params), X, yb, repeat)
    lib, lib_fit = _fit_time(partial(LibSVC, **params), X, yb, repeat)
    row = _row(data_name, "binary (HM-SVM root)", n, n_threads, ours, ours_fit, lib, lib_fit, X_test, yb_test)
    cmp = ref.compare_binary(ours, lib, X, X_test, kind="rbf", gamma=gamma)
    row.update(
        {
            "dual objective rel diff": cmp["objective_rel"],
            "SVs ours/libsvm": f"{cmp['n_sv_ours']}/{cmp['n_sv_ref']}",
            "SV sym diff (ties)": f"{cmp['support_other'] + cmp['support_ties']} ({cmp['support_ties']})",
        }
    )
    rows.append(row)
    hm, hm_fit = _fit_time(partial(HierarchicalSVC, **params, random_state=0), X, y, repeat)
    ovo, ovo_fit = _fit_time(partial(LibSVC, **params), X, y, repeat)
    row = _row(data_name, "HM-SVM vs libsvm OvO", n, n_threads, hm, hm_fit, ovo, ovo_fit, X_test, y_test)
    row["SVs ours/libsvm"] = f"{hm.support_.size}/{ovo.support_.size}"
    rows.append(row)
    tree, tree_fit = _fit_time(partial(LibsvmTree, hm.tree_, **params), X, y, repeat)
    rows.append(
        _row(
            data_name,
            "HM-SVM vs HM-SVM with libsvm nodes",
            n,
            n_threads,
            hm,
            hm_fit,
            tree,
            tree_fit,
            X_test,
            y_test,
        )
    )
    our_ovo, our_ovo_fit = _fit_time(partial(SVC, **params), X, y, repeat)
    row = _row(
        data_name, "SVC OvO vs libsvm OvO", n, n_threads, our_ovo, our_ovo_fit, ovo, ovo_fit, X_test, y_test
    )
    row["SVs ours/libsvm"] = f"{our_ovo.support_.size}/{ovo.support_.size}"
    rows.append(row)
    return rows


def _search_rows(X, y, n_threads, quick) -> list[dict]:
    """Method 2's stratified 10-fold search and method 1's 60/20/20 rotation, ours vs scikit-learn's."""
    rows = []
    cv = StratifiedKFold(3 if quick else 10, shuffle=True, random_state=0)
    start = time.perf_counter()
    ours = SVMGridSearchCV(HierarchicalSVC(random_state=0), GRID, cv=cv, refit=False).fit(X, y)
    ours_s = time.perf_counter() - start
    refs = {
        "GridSearchCV(sklearn SVC)": GridSearchCV(LibSVC(), GRID, cv=cv, refit=False),
        "GridSearchCV(our HM-SVM, one fit at a time)": GridSearchCV(
            HierarchicalSVC(random_state=0), GRID, cv=cv, refit=False
        ),
    }
    n_folds = cv.get_n_splits()
    for name, search in refs.items():
        start = time.perf_counter()
        search.fit(X, y)
        ref_s = time.perf_counter() - start
        best_ref = search.best_index_
        se = search.cv_results_["std_test_score"][best_ref] / np.sqrt(n_folds)
        ours_at_ref = ours.cv_results_["mean_test_score"][best_ref]
        rows.append(
            {
                "data": "vibration",
                "task": f"grid search {n_folds}-fold (4 C x 3 gamma): batched HM-SVM vs {name}",
                "n_train": X.shape[0],
                "threads": n_threads,
                "search ours s": ours_s,
                "search reference s": ref_s,
                "search ratio": ref_s / ours_s,
                "chosen ours": str(ours.best_params_),
                "chosen reference": str(search.best_params_),
                "CV accuracy ours (at our choice)": ours.best_score_,
                "CV accuracy reference (at its choice)": search.best_score_,
                "ours at reference's choice - reference": ours_at_ref - search.best_score_,
                "standard error of the folds": se,
            }
        )
    # Method 1: the 60/20/20 rotation, standardised per round, C and gamma chosen on validation.
    splits = rotating_splits(y, random_state=0)[: 2 if quick else 5]
    pipe_grid = {f"svc__{k}": v for k, v in GRID.items()}
    times = {}
    for label, estimator in (
        ("ours", make_pipeline(StandardScaler(), HierarchicalSVC(random_state=0))),
        ("reference", make_pipeline(StandardScaler(), LibSVC())),
    ):
        grid = {k.replace("svc__", f"{estimator.steps[-1][0]}__"): v for k, v in pipe_grid.items()}
        start = time.perf_counter()
        chosen = [grid_search_validation(estimator, grid, X, y, s.train, s.validation)[0] for s in splits]
        times[label] = (time.perf_counter() - start, chosen)
    rows.append(
        {
            "data": "vibration",
            "task": f"grid search 60/20/20 x {len(splits)} rounds (4 C x 3 gamma, standardising pipeline): "
            "batched HM-SVM vs a loop over sklearn SVC",
            "n_train": X.shape[0],
            "threads": n_threads,
            "search ours s": times["ours"][0],
            "search reference s": times["reference"][0],
            "search ratio": times["reference"][0] / times["ours"][0],
            "chosen ours": str([tuple(c.values()) for c in times["ours"][1]]),
            "chosen reference": str([tuple(c.values()) for c in times["reference"][1]]),
        }
    )
    return rows


_STARTUP = """
import time
start = time.perf_counter()
import numba, numpy as np, sklearn.svm, torch
from sklearn.datasets import make_blobs
X, y = make_blobs(300, centers=4, random_state=0)
dependencies = time.perf_counter()
from tactile_torch.svm import HierarchicalSVC
HierarchicalSVC(C=10.0, random_state=0).fit(X, y).predict(X)
print(dependencies - start, time.perf_counter() - dependencies)
"""


def _startup_rows() -> list[dict]:
    """Seconds for a fresh process to import the package and fit a small HM-SVM, cache warm or cold."""
    rows = []
    with tempfile.TemporaryDirectory() as empty:
        for label, env in (
            ("warm (compiled kernels loaded from the on-disk cache)", {}),
            ("cold (empty cache: every kernel compiled)", {"NUMBA_CACHE_DIR": empty}),
        ):
            out = subprocess.run(
                [sys.executable, "-c", _STARTUP],
                env={**os.environ, **env},
                capture_output=True,
                text=True,
                check=True,
            )
            dependencies, ours = (float(v) for v in out.stdout.strip().splitlines()[-1].split())
            rows.append(
                {
                    "data": "make_blobs (300 x 2, 4 classes)",
                    "task": f"start-up: import tactile_torch.svm + first HM-SVM fit, {label}",
                    "threads": DEFAULT_THREADS,
                    "start-up s": ours,
                    "importing torch, numba, scikit-learn before it s": dependencies,
                }
            )
    return rows


def _thread_rows(data_name, X, y, X_test, search: bool, quick: bool) -> list[dict]:
    """Ours at the default thread count against ours at one thread, measured alternately.

    Each operation runs at one thread, then at the default count, again and again; the fastest of
    each is kept, so that the machine's load (which changes over minutes on a shared machine) falls
    on both alike.
    """
    gamma = scale_gamma(X)
    params = {"C": C, "gamma": gamma, "cache_size": CACHE_MB}
    hm = HierarchicalSVC(**params, random_state=0).fit(X, y)
    ovo = SVC(**params).fit(X, y)
    cv = StratifiedKFold(3 if quick else 10, shuffle=True, random_state=0)
    operations = {
        "fit HM-SVM": lambda: HierarchicalSVC(**params, random_state=0).fit(X, y),
        "fit SVC OvO": lambda: SVC(**params).fit(X, y),
        "predict HM-SVM, 1000 samples": lambda: hm.predict(X_test[:1000]),
        "predict SVC OvO, 1000 samples": lambda: ovo.predict(X_test[:1000]),
    }
    if search:
        operations["grid search 10-fold (4 C x 3 gamma)"] = lambda: SVMGridSearchCV(
            HierarchicalSVC(random_state=0), GRID, cv=cv, refit=False
        ).fit(X, y)
    rows = []
    for what, operation in operations.items():
        repeat = 3 if what.startswith("grid") or X.shape[0] > 10000 else 7
        seconds = time_threads_alternately(operation, repeat=repeat, warmup=0)
        rows.append(
            {
                "data": data_name,
                "task": f"threads: {what}",
                "n_train": X.shape[0],
                "threads": DEFAULT_THREADS,
                "ours 1 thread s": seconds[1],
                "ours default threads s": seconds[DEFAULT_THREADS],
                "default / 1 thread": seconds[DEFAULT_THREADS] / seconds[1],
            }
        )
    return rows


def run(quick: bool) -> dict:
    sizes = [600] if quick else [3400, 34000]
    rows, thread_rows = [], []
    thread_counts = sorted({1, DEFAULT_THREADS})
    sets = [("vibration", make_vibration_data), ("make_classification", make_classification_data)]
    for (data_name, make_data), size in ((d, n) for d in sets for n in sizes):
        X, y, X_test, y_test = make_data(size)
        for n_threads in thread_counts:
            with threads(n_threads):
                rows += _classification_rows(
                    data_name, X, y, X_test, y_test, n_threads, 5 if size < 10000 else 1
                )
        first = size == sizes[0]
        if data_name == "vibration" and first:
            for n_threads in thread_counts:
                with threads(n_threads):
                    rows += _search_rows(X, y, n_threads, quick)
        if DEFAULT_THREADS > 1 and (data_name == "vibration" or first):
            thread_rows += _thread_rows(data_name, X, y, X_test, data_name == "vibration" and first, quick)
    for name in ("hapmat_imu5", "borealtc_imu"):
        real = real_imu_data(name)
        if real is not None:
            with threads(1):
                rows += _classification_rows(f"{name} (W = 100)", *real, 1, 5)
    rows += thread_rows
    if not quick:
        rows += _startup_rows()
    notes = [
        "Data 'vibration': the study's problem (21 vibration features of 800-sample windows, step 400, "
        "of make_vibration_recordings(28, seed 0); even windows train, 1000 seeded odd windows test; "
        "unit std on the training part). Data 'make_classification': a harder, less study-like "
        "stress test: make_classification(21 features, 15 informative, 28 classes, class_sep=2, seed 0), "
        f"standardised; {N_TEST} test samples. Real sets (when present): W = 100 windows of the 100 Hz IMU "
        f"recordings, odd/even split. C={C}, gamma='scale' (the same float for both), tol 1e-3 and "
        f"cache {CACHE_MB:.0f} MiB for both.",
        "Ratios are libsvm (or scikit-learn) time / ours: > 1 means ours is faster. Fit times are the "
        "fastest of 5 fits below 10,000 samples (1 above); predict times medians.",
        "Targets: HM-SVM fit no slower than libsvm's one-vs-one (fit ratio >= 1 on the "
        "'HM-SVM vs libsvm OvO' rows at 1 thread, 2 the target) with accuracy within 0.5 points; "
        "binary SVC fit within 1.5x of libsvm (fit ratio >= 0.67 on the binary rows); grid search >= 3x "
        "faster than GridSearchCV(SVC()) at 1 thread choosing the same parameters or within the folds' "
        "standard error; default threads no slower than 1 thread ('default / 1 thread' <= 1 on the "
        "'threads:' rows, which alternate one thread and the default count and keep the fastest of each).",
        "'HM-SVM with libsvm nodes': the tree of our HM-SVM (same 2-means splits) with every node fitted "
        "by sklearn's SVC; its 'accuracy libsvm' is the HM-SVM method with libsvm's solver, so a gap "
        "between ours and OvO that equals it is the method's, not our solver's. Its predict times are a "
        "Python loop over sklearn calls per node, for reference only.",
        "Grid search rows: GRID = C in {1, 4, 16, 64} x gamma in {0.0186/4, 0.0186, 0.0186*4} (the study's "
        "C = 16, gamma = 0.0186 at the centre); 'ours at reference's choice - reference' and the folds' "
        "standard error (std / sqrt(folds) at the reference's choice) say whether a different choice is "
        "within noise.",
        "Binary rows: 'dual objective rel diff' and the support sets' symmetric difference (ties: samples "
        "within 1e-2 of the margin by libsvm's decision function) compare our solution with libsvm's.",
        "The machine is a 2-core machine shared with other developers' jobs: ratios are measured in one "
        "process, the reference and ours back to back, so that load affects both.",
    ]
    return {"rows": rows, "notes": notes}
