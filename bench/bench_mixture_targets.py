"""Time to a converged posterior of K at the defaults: before and after issue 38, and what a user would pick instead.

Four sources (:func:`sources`): the README example (3 Gaussian clusters, 150 points, D = 3), the
bundled 28 surfaces (1,680 windows of 800 samples, PCA-3 features), 7 surfaces recorded on 5 days
(1,295 windows, PCA-3; :func:`tactile_torch.studies.clustering_sessions.multi_day`, seed 2) and
100 points of 4 clusters in D = 21 (the start-up data of ``bench_mixture``). On each, in this one run:

- **after**: ``PitmanYorGMM(random_state=0).fit(X)`` of this checkout, its defaults (``n_iter="auto"``:
  until R-hat of K < 1.01 and bulk ESS of K >= 400, or an early stop with its reason); on the
  multi-day source also ``fit(X, sessions=day)``, what ``tactile-torch cluster`` now fits there;
- **before**: the same call in a fresh process on the checkout of :data:`BEFORE` (main before
  issue 38), extracted with ``git archive`` into a temporary directory, its compiled kernels cached
  in ``bench/.cache/mixture-before`` (the first run compiles them: minutes). Skipped, with a note,
  when git or that commit is not available;
- **scikit-learn**: ``BayesianGaussianMixture`` (Dirichlet-process prior, variational, 2 sqrt(n)
  components at most, K = components that own points) and BIC over ``GaussianMixture`` (K = 1 ..
  2 sqrt(n), one start each), the answers a user would otherwise get, with their wall time.

Reported: wall time of the fit, sweeps per chain, sweeps per second (all chains), bulk ESS of K and
effective samples of K per second, R-hat of K, K's mode and 95 % interval, why the run stopped, and
the machine's one-minute load average when the fit started (``os.getloadavg``).
The two cores are shared with other jobs: absolute times are noisy, the before / after ratio is
taken within the run. Where a sweep's time goes (:func:`sweep_profile`): the compiled sweep with
one part switched off at a time, on the fitted state of the README example and of the bundled data.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

TITLE = "Mixture: time to a converged posterior of K (before / after issue 38; scikit-learn side by side)"

BEFORE = "81032b6"
"""main before issue 38: algorithm 8 with a bound per component and one exponential per weight, no session effects."""

ROOT = Path(__file__).resolve().parents[1]
BEFORE_CACHE = ROOT / "bench" / ".cache" / "mixture-before"

# Runs in a fresh interpreter on a checkout: its PitmanYorGMM at the defaults on X (a .npy), one line of JSON.
_FIT = """
import json, sys, time, warnings
sys.path.insert(0, sys.argv[1])
import numpy as np
import tactile_torch
from tactile_torch.mixture import PitmanYorGMM
X = np.load(sys.argv[2])
PitmanYorGMM(n_iter=20, burn_in=5, n_chains=2, random_state=0, progress=False).fit(X[:20])  # load the kernels
t0 = time.perf_counter()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    m = PitmanYorGMM(random_state=0, progress=False).fit(X)
seconds = time.perf_counter() - t0
conv = {r["quantity"]: r for r in m.convergence_}
print(json.dumps({"file": tactile_torch.__file__, "seconds": seconds, "n_iter": int(m.n_iter_),
    "chains": int(m.trace_["n_clusters"].shape[0]), "ess": float(conv["K"]["ESS bulk"]),
    "rhat": float(conv["K"]["R-hat"]), "mode": int(m.n_clusters_summary_["mode"]),
    "interval": [int(v) for v in m.n_clusters_summary_["interval"]], "stopped_by": m.stopped_by_,
    "reason": getattr(m, "stop_reason_", None)}))
"""


MULTI_DAY = "7 surfaces x 5 days (1,295, PCA-3)"
"""The multi-day source: its rows fit with and without the sessions."""


def sources(quick: bool = False) -> dict[str, tuple[np.ndarray, np.ndarray | None]]:
    """Return {name: (X, sessions or None)}: the README example, the bundled 28 surfaces and 7 x 5 days (not with ``quick``), D = 21."""
    from bench.bench_mixture import startup_data
    from tactile_torch.studies.clustering_k import bundled_28, gaussian_three
    from tactile_torch.studies.clustering_sessions import multi_day

    out = {"README example: 3 Gaussian clusters (150, D = 3)": (gaussian_three(0)[0], None)}
    if not quick:
        out["bundled 28 surfaces, W = 800 (1,680, PCA-3)"] = (bundled_28(0)[0], None)
        X, _, day = multi_day(7, 5, 2)
        out[MULTI_DAY] = (X, day)
    out["4 clusters in D = 21 (100, start-up data)"] = (startup_data(21), None)
    return out


def fit_after(X: np.ndarray, sessions: np.ndarray | None = None) -> dict:
    """This checkout's default fit of ``X`` (with ``sessions`` when given): the numbers of :data:`_FIT`."""
    from tactile_torch.mixture import PitmanYorGMM

    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = PitmanYorGMM(random_state=0, progress=False).fit(X, sessions=sessions)
    seconds = time.perf_counter() - t0
    conv = {r["quantity"]: r for r in m.convergence_}
    return {
        "seconds": seconds,
        "n_iter": int(m.n_iter_),
        "chains": int(m.trace_["n_clusters"].shape[0]),
        "ess": float(conv["K"]["ESS bulk"]),
        "rhat": float(conv["K"]["R-hat"]),
        "mode": int(m.n_clusters_summary_["mode"]),
        "interval": list(m.n_clusters_summary_["interval"]),
        "stopped_by": m.stopped_by_,
        "reason": m.stop_reason_,
    }


def before_checkout(tmp: Path) -> Path | None:
    """Extract :data:`BEFORE` into ``tmp`` with ``git archive``; None when git or the commit is missing."""
    try:
        archive = subprocess.run(
            ["git", "archive", BEFORE, "tactile_torch"], cwd=ROOT, check=True, capture_output=True
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive, check=True, capture_output=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    return tmp


def fit_before(checkout: Path, data: Path) -> dict:
    """The default fit of :data:`BEFORE` on ``data`` (.npy), in a fresh process with its own kernel cache."""
    BEFORE_CACHE.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(BEFORE_CACHE)}
    out = subprocess.run(
        [sys.executable, "-c", _FIT, str(checkout), str(data)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if not result.pop("file").startswith(str(checkout)):
        raise RuntimeError("the before run imported this checkout's tactile_torch, not the extracted one")
    return result


def _row(source: str, who: str, r: dict, load: float) -> dict:
    sweeps = r["n_iter"] * r["chains"]
    return {
        "source": source,
        "what": who,
        "load": load,
        "seconds": r["seconds"],
        "sweeps_per_chain": r["n_iter"],
        "sweeps_per_s": sweeps / r["seconds"],
        "ESS_K": r["ess"],
        "ESS_K_per_s": r["ess"] / r["seconds"],
        "R-hat_K": r["rhat"],
        "K": f"{r['mode']} [{r['interval'][0]}, {r['interval'][1]}]",
        "stopped_by": r["stopped_by"],
    }


def scikit_learn_rows(source: str, X: np.ndarray) -> list[dict]:
    """BayesianGaussianMixture (DP) and BIC over GaussianMixture on ``X``: wall time and the K each finds."""
    from sklearn.mixture import BayesianGaussianMixture, GaussianMixture

    kmax = min(len(X), math.ceil(2 * math.sqrt(len(X))))
    rows = []
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ConvergenceWarning of the variational fit
        bgm = BayesianGaussianMixture(
            n_components=kmax,
            weight_concentration_prior_type="dirichlet_process",
            max_iter=1000,
            random_state=0,
        ).fit(X)
    k = int(np.unique(bgm.predict(X)).size)
    rows.append({"source": source, "what": f"BayesianGaussianMixture (DP, variational, {kmax} components)",
                 "seconds": time.perf_counter() - t0, "K": str(k)})  # fmt: skip
    t0 = time.perf_counter()
    bics = [GaussianMixture(k, random_state=0).fit(X).bic(X) for k in range(1, kmax + 1)]
    rows.append({"source": source, "what": f"BIC over GaussianMixture, K = 1 .. {kmax}",
                 "seconds": time.perf_counter() - t0, "K": str(int(np.argmin(bics)) + 1)})  # fmt: skip
    return rows


def sweep_profile(name: str, X: np.ndarray, sweeps: int) -> list[dict]:
    """Microseconds per sweep of one chain on its fitted state, with one part of the sweep switched off at a time.

    Thread CPU time (the work itself, whatever the load), the fastest of 3 runs of ``sweeps``
    sweeps. Parts: the split-merge moves (``n_split_merge=0``), the allocation (``allocate=False``:
    the component and hyperparameter updates and the log density remain), and the Python between
    compiled calls (a whole default fit's wall time against its chains' sweeps).
    """
    from tactile_torch.mixture import PitmanYorGMM
    from tactile_torch.mixture import _gibbs as g

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = PitmanYorGMM(n_iter=300, burn_in=100, n_chains=1, random_state=0, progress=False).fit(X)
    Xw = np.ascontiguousarray(np.linalg.solve(m.data_scale_, (X - m.data_mean_).T).T)
    from tactile_torch.mixture._chains import neighbours

    nbr = neighbours(Xw)
    base = g.Settings(5, 5, 3, True, False, False, True, 0.0, 1e-10, 10**9, 0.9, True, len(X), False)
    cases = {
        "whole sweep": base,
        "without split-merge": base._replace(n_split_merge=0),
        "component + hyperparameter updates only": base._replace(allocate=False),
        "with restricted-Gibbs split-merge (before)": base._replace(sequential=False),
    }
    n = len(X)
    out = {}
    for label, cfg in cases.items():
        best = math.inf
        for r in range(3):
            st = g.ChainState(*(a.copy() for a in m._map_state))
            trace = np.zeros((sweeps, len(g.TRACE_NAMES)))
            t0 = time.thread_time()
            g.run_sweeps(
                Xw, st, cfg, np.random.default_rng(r), 0, sweeps, trace, np.zeros(4, dtype=np.int64),
                g.ChainState(*(a.copy() for a in st)), np.array([np.inf]), nbr, np.zeros(0, dtype=np.int64),
                np.zeros((0, n), dtype=np.int32),
            )  # fmt: skip
            best = min(best, time.thread_time() - t0)
        out[label] = 1e6 * best / sweeps
    whole = out["whole sweep"]
    rows = [{"source": name, "what": f"sweep profile: {k}", "us_per_sweep": v} for k, v in out.items()]
    rows.append(
        {
            "source": name,
            "what": "sweep profile: split-merge share",
            "us_per_sweep": whole - out["without split-merge"],
        }
    )
    rows.append({"source": name, "what": "sweep profile: allocation share",
                 "us_per_sweep": out["without split-merge"] - out["component + hyperparameter updates only"]})  # fmt: skip
    return rows


def run(quick: bool) -> dict:
    rows, notes = [], []
    data = sources(quick)
    with tempfile.TemporaryDirectory() as tmp:
        checkout = None if quick else before_checkout(Path(tmp))
        for name, (X, day) in data.items():
            path = Path(tmp) / f"{len(rows)}.npy"
            np.save(path, X)
            if checkout is not None:  # before and after alternate per source: the load falls on both
                load = os.getloadavg()[0]
                before = fit_before(checkout, path)
                rows.append(
                    _row(name, f"before ({BEFORE}): PitmanYorGMM(random_state=0).fit(X)", before, load)
                )
            load = os.getloadavg()[0]
            after = fit_after(X)
            rows.append(_row(name, "after: PitmanYorGMM(random_state=0).fit(X)", after, load))
            if after["reason"]:
                notes.append(f"{name}: stopped early ({after['stopped_by']}): {after['reason']}")
            if checkout is not None:
                rows.append({"source": name, "what": "time before / after", "ratio": before["seconds"] / after["seconds"],
                             "ESS_K_per_s_ratio": (after["ess"] / after["seconds"]) / (before["ess"] / before["seconds"])})  # fmt: skip
            if day is not None:
                load = os.getloadavg()[0]
                with_days = fit_after(X, day)
                rows.append(
                    _row(name, "after: PitmanYorGMM(random_state=0).fit(X, sessions=day)", with_days, load)
                )
                if checkout is not None:
                    rows.append({"source": name, "what": "time before / after with sessions",
                                 "ratio": before["seconds"] / with_days["seconds"],
                                 "ESS_K_per_s_ratio": (with_days["ess"] / with_days["seconds"]) / (before["ess"] / before["seconds"])})  # fmt: skip
            rows += scikit_learn_rows(name, X)
    if checkout is None and not quick:
        notes.append(f"before rows skipped: git or commit {BEFORE} not available (git archive failed)")
    for name, (X, _) in list(data.items())[:2]:
        rows += sweep_profile(name, X, 200 if quick or len(X) > 1000 else 2000)
    notes += [
        "after / before: `PitmanYorGMM(random_state=0).fit(X)` with every default (4 chains on the default threads, "
        "n_iter='auto'); before runs the checkout of " + BEFORE + " in a fresh process (kernels cached in "
        "bench/.cache/mixture-before), after runs this checkout in this process, kernels loaded; both alternate "
        "source by source.",
        "sweeps_per_s counts the sweeps of every chain; ESS_K is the bulk ESS of K over the chains after the burn-in.",
        "scikit-learn: BayesianGaussianMixture(weight_concentration_prior_type='dirichlet_process', "
        "n_components=ceil(2 sqrt(n)), max_iter=1000) and GaussianMixture(k).bic for k = 1 .. ceil(2 sqrt(n)), "
        "random_state=0, default threads; their K: components that own points, and the BIC minimiser.",
        "Sweep profile: thread CPU time of one chain on the state of a 300-sweep fit, fastest of 3.",
        "The machine's 2 cores are shared with other jobs: absolute times are noisy; ratios are within this run; "
        "load: the one-minute load average when each fit started.",
    ]
    return {"rows": rows, "notes": notes}
