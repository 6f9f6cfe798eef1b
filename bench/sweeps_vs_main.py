"""Sweep time of one chain (28 clusters x 50 points, D = 3, 1,500 sweeps), for interleaved comparisons of two checkouts.

    python bench/sweeps_vs_main.py REPO "KWARGS" REPEATS

runs ``PitmanYorGMM(n_iter=1500, burn_in=300, n_chains=1, random_state=0, **KWARGS)`` from the checkout
REPO (its sources and its compiled kernels) and prints the mean sweep time with the 1-minute load
average. Alternate two checkouts in one shell loop so that both see the same load.
"""

import ast
import os
import sys

sys.path.insert(0, sys.argv[1])
os.chdir(sys.argv[1])

from bench.bench_mixture import study_data  # noqa: E402
from tactile_torch.mixture import PitmanYorGMM  # noqa: E402

X, y = study_data()
kw = ast.literal_eval(sys.argv[2]) if len(sys.argv) > 2 else {}  # a dict literal
PitmanYorGMM(n_iter=5, burn_in=1, n_chains=1, random_state=0, progress=False, **kw).fit(X)  # load kernels
for _ in range(int(sys.argv[3]) if len(sys.argv) > 3 else 2):
    m = PitmanYorGMM(n_iter=1500, burn_in=300, n_chains=1, random_state=0, progress=False, **kw).fit(X)
    print(sys.argv[1], kw, f"{1e3 * m.sweep_seconds_:.3f} ms/sweep", os.getloadavg()[0], flush=True)
