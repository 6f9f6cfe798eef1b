"""Pitman-Yor mixture sampler: 10,000 sweeps on the study's setting (28 surfaces x 50 windows, D = 3).

Ours (numba kernels, ``tactile_torch.mixture.PitmanYorGMM``) runs the full 10,000 sweeps, with and
without split-merge moves; the plain NumPy reference of the same sampler (``tests.reference_mixture``,
no split-merge) is timed over a few sweeps in the same run and extrapolated to 10,000. Time to the
true K from a one-cluster start and from the default k-means start is compared with scikit-learn's
variational ``BayesianGaussianMixture`` (Dirichlet-process prior).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from bench.common import threads, time_call
from tactile_torch.metrics import pairwise_accuracy
from tactile_torch.mixture import PitmanYorGMM
from tests.reference_mixture import reference_gibbs

TITLE = "Pitman-Yor mixture: Gibbs sweeps (numba kernels vs plain NumPy), time to the true K"


def study_data(n_clusters: int = 28, per: int = 50, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Well-separated Gaussian clusters in D = 3 (the PCA space of the study), centres >= 3 apart."""
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-20, 20, size=(n_clusters, 3))
    while True:
        d = np.linalg.norm(centers[:, None] - centers[None], axis=-1) + np.eye(n_clusters) * 1e9
        if d.min() > 3.0:
            break
        centers[np.argmin(d.min(1))] = rng.uniform(-20, 20, size=3)
    X = np.concatenate([rng.normal(c, 0.3, size=(per, 3)) for c in centers])
    return X, np.repeat(np.arange(n_clusters), per)


def cold_compile_seconds() -> float:
    """Seconds to compile the numba kernels from scratch (fresh process, empty cache directory)."""
    with tempfile.TemporaryDirectory() as cache:
        code = (
            "import time; t = time.perf_counter(); from tactile_torch import warmup; warmup.warm_up(); "
            "print(time.perf_counter() - t)"
        )
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        out = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
    return float(out.stdout.strip().splitlines()[-1])


_STARTUP = """
import time
t0 = time.perf_counter()
import numpy as np
from tactile_torch.mixture import PitmanYorGMM
t1 = time.perf_counter()
rng = np.random.default_rng(0)
X = np.concatenate([rng.normal(c, 0.3, size=(25, 3)) for c in (0, 3, 6, 9)])
PitmanYorGMM(random_state=0, progress=False).fit(X)
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def warm_startup_seconds() -> tuple[float, float]:
    """(import, fit) seconds of ``import tactile_torch.mixture`` and a default fit of 100 points, fresh process."""
    out = subprocess.run([sys.executable, "-c", _STARTUP], capture_output=True, text=True, check=True)
    imp, fit = (float(v) for v in out.stdout.split())
    return imp, fit


def first_sweep_hitting(trace: np.ndarray, k: int) -> int | None:
    hits = np.flatnonzero(trace == k)
    return int(hits[0]) if hits.size else None


def run(quick: bool) -> dict:
    n_sweeps = 300 if quick else 10_000
    n_clusters, per = (8, 20) if quick else (28, 50)
    X, y = study_data(n_clusters, per)
    n = X.shape[0]
    rows, notes = [], []

    # start-up: a cold compile (what make install does once), and import + default fit of 100 points
    # in a fresh process with the compiled kernels cached (the target: under 2 s)
    cold = float("nan") if quick else cold_compile_seconds()
    rows.append({"what": "numba kernels: cold compile (make install, once)", "N": n, "seconds": cold})
    imp, fit = warm_startup_seconds()
    rows.append(
        {
            "what": "import tactile_torch.mixture + default fit of 100 points (4 chains x 1000 sweeps), warm",
            "N": 100,
            "seconds": imp + fit,
            "import_s": imp,
            "fit_s": fit,
        }
    )

    with threads(1):
        for label, n_sm in (
            ("ours, split-merge (default)", 5),
            ("ours, no split-merge (= reference sampler)", 0),
        ):
            t0 = time.perf_counter()
            model = PitmanYorGMM(
                n_iter=n_sweeps, burn_in=n_sweeps // 5, n_chains=1, n_split_merge=n_sm, random_state=0
            )
            model.set_params(progress=False).fit(X)
            total = time.perf_counter() - t0
            rows.append(
                {
                    "what": label,
                    "N": n,
                    "sweeps": n_sweeps,
                    "seconds": total,
                    "ms_per_sweep": 1e3 * model.sweep_seconds_,
                    "K_mode": model.n_clusters_summary_["mode"],
                    "pairwise_acc": pairwise_accuracy(y, model.labels_),
                }
            )
        ours_ms = rows[-1]["ms_per_sweep"]
        for n_threads in (1, None):
            with threads(n_threads) as used:
                n_ref = 2 if quick else 5
                timing = time_call(
                    lambda n_ref=n_ref: reference_gibbs(X, n_iter=n_ref, random_state=0), repeat=1, warmup=0
                )
                ref_ms = 1e3 * timing["median_s"] / n_ref
                rows.append(
                    {
                        "what": f"reference NumPy Neal-8 (threads={used})",
                        "N": n,
                        "sweeps": n_ref,
                        "seconds": timing["median_s"],
                        "ms_per_sweep": ref_ms,
                        "extrapolated_10k_s": ref_ms * 10,
                        "ratio_vs_ours_same_sampler": ref_ms / ours_ms,
                    }
                )

        # time to the true K
        for init in ("one", "kmeans"):
            t0 = time.perf_counter()
            model = PitmanYorGMM(
                n_iter=400 if not quick else 150, burn_in=50, n_chains=1, init=init, random_state=1
            )
            model.set_params(progress=False).fit(X)
            hit = first_sweep_hitting(model.trace_["n_clusters"], n_clusters)
            rows.append(
                {
                    "what": f"time to true K, ours from init={init!r}",
                    "N": n,
                    "sweeps": hit,
                    "seconds": float("nan") if hit is None else (hit + 1) * model.sweep_seconds_,
                    "K_MAP": model.map_n_clusters_,
                    "pairwise_acc": pairwise_accuracy(y, model.labels_),
                }
            )
    # chains in parallel threads: 4 chains should take about the wall time of 2 on 2 cores (never
    # more than 4 one after the other); the default thread count against one thread, same run
    sweeps = 150 if quick else 1000
    for jobs in (1, None):
        t0 = time.perf_counter()
        model = PitmanYorGMM(n_iter=sweeps, burn_in=sweeps // 4, n_chains=4, n_jobs=jobs, random_state=0)
        model.set_params(progress=False).fit(X)
        rows.append(
            {
                "what": f"4 chains, n_jobs={jobs} (threads), whole fit incl. point estimate",
                "N": n,
                "sweeps": sweeps,
                "seconds": time.perf_counter() - t0,
                "ms_per_sweep": 1e3 * model.sweep_seconds_,
                "K_mode": model.n_clusters_summary_["mode"],
                "pairwise_acc": pairwise_accuracy(y, model.labels_),
            }
        )
    with threads(1):
        from sklearn.mixture import BayesianGaussianMixture

        t0 = time.perf_counter()
        bgm = BayesianGaussianMixture(
            n_components=50,
            weight_concentration_prior_type="dirichlet_process",
            max_iter=1000,
            random_state=0,
        ).fit(X)
        labels = bgm.predict(X)
        rows.append(
            {
                "what": "BayesianGaussianMixture (variational DP, 50 components)",
                "N": n,
                "sweeps": int(bgm.n_iter_),
                "seconds": time.perf_counter() - t0,
                "K_MAP": int(np.unique(labels).size),
                "pairwise_acc": pairwise_accuracy(y, labels),
            }
        )
    notes += [
        f"Data: {n_clusters} well-separated Gaussian clusters x {per} points in D = 3 (the study's 28 surfaces x 50 "
        "windows after PCA to 3), seed 0.",
        "Ours runs every sweep; the reference is timed over a few sweeps and extrapolated to 10,000 "
        "(`extrapolated_10k_s`). `ratio_vs_ours_same_sampler` compares the reference with ours without "
        "split-merge moves, i.e. the same sampler.",
        "One chain's numba kernels are single-threaded: the thread setting applies to the reference (NumPy/BLAS) "
        "only; chains run in parallel threads (`n_jobs`, default: one per chain up to the available cores). "
        "Compilation is excluded from the sweep times and reported on its own row (cold: fresh cache, a "
        "one-time cost per installation; load: cached kernels, per process).",
        "Time to true K = (first sweep with K = truth + 1) x mean sweep time; `sweeps` for "
        "BayesianGaussianMixture is its number of EM-like iterations.",
    ]
    return {"rows": rows, "notes": notes}
