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


# --------------------------------------------------------------------------------------------------
# start-up: import and a default fit of 100 points, each in a fresh process
# --------------------------------------------------------------------------------------------------
STARTUP_POINTS = 100
STARTUP_DIMS = (3, 21)
STARTUP_REPEAT = 3

# Runs in a fresh interpreter: the import is timed from a bare interpreter (numpy included), the data
# are read untimed, then the default fit (4 chains, default sweeps, progress bar on) is timed.
_STARTUP = """
import sys, time
t0 = time.perf_counter()
from tactile_torch.mixture import PitmanYorGMM
t1 = time.perf_counter()
import numpy as np
X = np.load(sys.argv[1])
t2 = time.perf_counter()
model = PitmanYorGMM(random_state=0).fit(X)
t3 = time.perf_counter()
print(t1 - t0, t3 - t2, model.n_iter_, model.trace_["n_clusters"].shape[0])
"""

# The floor any numba-compiled scikit-learn estimator pays: numpy, scikit-learn's estimator base
# (which imports scipy.stats), numba, and numba's set-up at the first cached kernel it loads.
_FLOOR = """
import sys, time
sys.path.insert(0, sys.argv[1])
t0 = time.perf_counter()
import numpy
t1 = time.perf_counter()
import sklearn.base
t2 = time.perf_counter()
import numba
t3 = time.perf_counter()
import floor_kernel
t4 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, t4 - t3)
"""
_FLOOR_KERNEL = """
from numba import njit, types

@njit(types.float64(types.float64), cache=True)
def one_more(x):
    return x + 1.0
"""


def startup_data(dim: int, n: int = STARTUP_POINTS, n_clusters: int = 4, seed: int = 0) -> np.ndarray:
    """``n`` points of ``n_clusters`` Gaussian clusters (sd 0.3) in ``dim`` dimensions, centres uniform in [-20, 20].

    As :func:`study_data` without its separation check: with seed 0 the centres are >= 24 apart in
    D = 3 and >= 63 apart in D = 21.
    """
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-20, 20, size=(n_clusters, dim))
    labels = np.arange(n) % n_clusters
    return centers[labels] + rng.normal(0.0, 0.3, size=(n, dim))


def _child(code: str, args: list[str], env: dict | None = None) -> list[float]:
    out = subprocess.run(
        [sys.executable, "-c", code, *args], env=env, capture_output=True, text=True, check=True
    )
    return [float(v) for v in out.stdout.split()]


def startup(cold: bool = True, repeat: int = STARTUP_REPEAT) -> dict:
    """Rows for the start-up: ``from tactile_torch.mixture import PitmanYorGMM`` and a default fit of 100 points.

    Every measurement is a fresh process. *Cold*: an empty numba cache (``NUMBA_CACHE_DIR``), so the
    kernels compile (at the first fit), as a user's first call would without ``make install``. *Warm*: the
    installed cache (one untimed process first fills it if needed); fastest of ``repeat`` processes.
    The floor row times what any numba-compiled scikit-learn estimator imports, without tactile_torch.
    """
    rows, notes = [], []
    with tempfile.TemporaryDirectory() as tmp:
        data = {}
        for dim in STARTUP_DIMS:
            data[dim] = os.path.join(tmp, f"x{dim}.npy")
            np.save(data[dim], startup_data(dim))
        with open(os.path.join(tmp, "floor_kernel.py"), "w") as f:
            f.write(_FLOOR_KERNEL)
        floor_env = {**os.environ, "NUMBA_CACHE_DIR": os.path.join(tmp, "floor-cache")}
        _child(_FLOOR, [tmp], floor_env)  # untimed: compiles the one-line kernel
        _child(_STARTUP, [data[3]])  # untimed: fills the installed cache if it is empty
        runs = []
        if cold:
            cold_env = {**os.environ, "NUMBA_CACHE_DIR": os.path.join(tmp, "cold-cache")}
            runs.append(("cold (empty numba cache: the first fit compiles the kernels)", 3, [cold_env]))
        # the floor and the warm runs take turns, so that a change of load hits them alike
        floors, warm = [], {dim: [] for dim in STARTUP_DIMS}
        for _ in range(repeat):
            floors.append(_child(_FLOOR, [tmp], floor_env))
            for dim in STARTUP_DIMS:
                warm[dim].append(_child(_STARTUP, [data[dim]]))
        measured = [
            (label, dim, [_child(_STARTUP, [data[dim]], env) for env in envs]) for label, dim, envs in runs
        ]
        measured += [("warm (kernels cached)", dim, warm[dim]) for dim in STARTUP_DIMS]
        for label, dim, results in measured:
            imp, fit, n_iter, n_chains = min(results, key=lambda r: r[0] + r[1])
            rows.append(
                {
                    "what": f"start-up, {label}: from tactile_torch.mixture import PitmanYorGMM + default fit of "
                    f"{STARTUP_POINTS} points in D = {dim} ({n_chains:.0f} chains x {n_iter:.0f} sweeps)",
                    "N": STARTUP_POINTS,
                    "seconds": imp + fit,
                    "import_s": imp,
                    "fit_s": fit,
                }
            )
    floor = min(floors, key=sum)
    rows.append(
        {
            "what": "start-up floor: import numpy + sklearn.base + numba, load one cached kernel, warm",
            "seconds": sum(floor),
            "import_s": sum(floor),
        }
    )
    notes.append(
        "Start-up floor (no tactile_torch; fastest of {} fresh processes): numpy {:.2f} s, sklearn.base "
        "{:.2f} s (it imports scipy.stats), numba {:.2f} s, numba's set-up at the first cached kernel "
        "{:.2f} s.".format(repeat, *floor)
    )
    notes.append(
        f"Start-up: every row is a fresh process (interpreter start excluded); warm rows are the fastest of "
        f"{repeat}; data: {STARTUP_POINTS} points, 4 Gaussian clusters (sd 0.3, centres uniform in [-20, 20]^D, "
        "24 or more apart), seed 0; "
        "`PitmanYorGMM(random_state=0).fit(X)`, progress bar on, as a user calls it. The compiled kernels "
        "(and numba) load at the first fit, so `import_s` is numpy and scikit-learn and `fit_s` includes "
        "numba's import and the kernels' loading. Target (issue 13): import + fit under 2 s warm."
    )
    return {"rows": rows, "notes": notes}


def first_sweep_hitting(trace: np.ndarray, k: int) -> int | None:
    hits = np.flatnonzero(trace == k)
    return int(hits[0]) if hits.size else None


def run(quick: bool) -> dict:
    n_sweeps = 300 if quick else 10_000
    n_clusters, per = (8, 20) if quick else (28, 50)
    X, y = study_data(n_clusters, per)
    n = X.shape[0]
    rows, notes = [], []

    # start-up: import + default fit of 100 points in fresh processes, cold and warm
    # (the target: under 2 s warm)
    first = startup(cold=not quick, repeat=1 if quick else STARTUP_REPEAT)
    rows += first["rows"]
    notes += first["notes"]

    with threads(1):
        for label, n_sm, prior in (
            ("ours, split-merge (default), Pitman-Yor", 5, "pyp"),
            ("ours, split-merge (default), mixture of finite mixtures", 5, "mfm"),
            ("ours, no split-merge (= reference sampler)", 0, "pyp"),
        ):
            t0 = time.perf_counter()
            model = PitmanYorGMM(
                model=prior,
                coarsen=None,
                n_iter=n_sweeps,
                burn_in=n_sweeps // 5,
                n_chains=1,
                n_split_merge=n_sm,
                random_state=0,
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
                model="pyp",
                coarsen=None,
                n_iter=400 if not quick else 150,
                burn_in=50,
                n_chains=1,
                init=init,
                random_state=1,
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
        model = PitmanYorGMM(
            model="pyp",
            coarsen=None,
            n_iter=sweeps,
            burn_in=sweeps // 4,
            n_chains=4,
            n_jobs=jobs,
            random_state=0,
        )
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
        "Compilation is excluded from the sweep times; the start-up rows show it (cold: fresh cache, a "
        "one-time cost per installation; warm: cached kernels, loaded once per process).",
        "Time to true K = (first sweep with K = truth + 1) x mean sweep time; `sweeps` for "
        "BayesianGaussianMixture is its number of EM-like iterations.",
    ]
    return {"rows": rows, "notes": notes}


def update_startup_results(result: dict, path: str | None = None, *, conditions: str = "") -> None:
    """Replace the start-up rows of ``bench/results/mixture.{json,md}`` with ``result``'s, other rows unchanged.

    The rows of ``result`` go first (where :func:`run` puts them), its notes replace the start-up
    notes, and a note says when, by which command and under which ``conditions`` (free text, e.g. the
    load average) the start-up rows were measured.
    """
    import datetime as dt
    import json
    from pathlib import Path

    from bench.run import RESULTS

    json_path = Path(path) if path else RESULTS / "mixture.json"
    record = json.loads(json_path.read_text())
    kept = [r for r in record["rows"] if not r["what"].startswith("start-up")]
    notes = [n for n in record["notes"] if not n.startswith("Start-up")]
    date = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    record["rows"] = result["rows"] + kept
    record["notes"] = [
        *result["notes"],
        f"Start-up rows measured on {date} by `{STARTUP_COMMAND}`{conditions}; the other rows by the "
        f"command above, on {record['date']}.",
        *notes,
    ]
    write_results(record, json_path)


def write_results(record: dict, json_path) -> None:
    """Write ``record`` to ``json_path`` and its table to the ``.md`` beside it, as ``bench/run.py`` does."""
    import json

    from bench.run import markdown_table

    json_path.write_text(json.dumps(record, indent=1) + "\n")
    md = [f"# {record['title']}", "", f"`{record['command']}` on {record['machine']}, {record['date']}", ""]
    md += [markdown_table(record["rows"]), ""] + [f"- {n}" for n in record["notes"]]
    json_path.with_suffix(".md").write_text("\n".join(md) + "\n")


STARTUP_COMMAND = "python -m bench.bench_mixture --startup"

if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description="Run only the start-up rows of the mixture benchmark.")
    parser.add_argument("--startup", action="store_true", help="measure start-up and update bench/results")
    parser.add_argument("--no-cold", action="store_true", help="skip the cold (empty cache) row")
    args = parser.parse_args()
    if not args.startup:
        parser.error("nothing to do: pass --startup (the whole benchmark runs with python bench/run.py)")
    load_before = os.getloadavg()[0]
    result = startup(cold=not args.no_cold)
    load = f" (1-minute load average {load_before:.2f} before, {os.getloadavg()[0]:.2f} after, on 2 shared cores)"
    for row in result["rows"]:
        print(row)
    print(*result["notes"], sep="\n")
    update_startup_results(result, conditions=load)
