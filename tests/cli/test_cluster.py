"""Tests of ``tactile-torch cluster``: the clustering it writes and its one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.metrics import pairwise_accuracy
from tests.mixture_data import blobs

# Short chains in these tests: their R-hat warnings are expected, not failures.
pytestmark = pytest.mark.filterwarnings("ignore:PitmanYorGMM. R-hat:RuntimeWarning")


# ------------------------------------------------------------------------------------------------
# command line and report
# ------------------------------------------------------------------------------------------------
def test_cli_cluster_writes_the_clustering(tmp_path, capsys):
    from tactile_torch.cli import main

    X, y = blobs(n_clusters=3, per=15, dim=2)
    np.savez(tmp_path / "f.npz", features=X, labels=y)
    out = tmp_path / "out"
    args = [
        "cluster",
        "--data",
        str(tmp_path / "f.npz"),
        "--out",
        str(out),
        "--n-iter",
        "40",
        "--burn-in",
        "10",
    ]
    assert main([*args, "--quiet", "--seed", "3", "--chains", "2"]) == 0
    res = np.load(out / "clustering.npz")
    assert pairwise_accuracy(y, res["labels"]) == 1.0 and res["means"].shape == (3, 2)
    assert res["n_clusters_samples"].shape == (60,)  # 2 chains x 30 sweeps after burn-in
    summary = (out / "summary.txt").read_text()
    assert summary.splitlines()[1].startswith("K, posterior: mode 3")
    assert "pairwise accuracy: point estimate 1.0000" in summary
    assert (out / "model.npz").is_file()  # for tactile-torch export (tests/test_pipeline.py)
    np.savez(tmp_path / "bad.npz", X=X)
    assert main(["cluster", "--data", str(tmp_path / "bad.npz"), "--out", str(out)]) == 2
    assert "or a feature matrix ('features'), found keys ['X']" in capsys.readouterr().err


def test_cli_cluster_says_in_one_line_what_a_recordings_file_lacks(tmp_path, capsys):
    from tactile_torch.cli import BAD_INPUT_EXIT, main
    from tactile_torch.data.stylus import make_vibration_recordings

    rec = make_vibration_recordings(3, duration_s=1.0, random_state=0)
    signals = np.stack(rec.signals)
    common = ["--window", "400", "--n-iter", "30", "--burn-in", "10", "--quiet", "--out", str(tmp_path / "o")]
    for name, arrays, missing in (
        ("nolabels.npz", dict(signals=signals, rate_hz=rec.rate_hz), "'labels', 'class_names'"),
        ("norate.npz", dict(signals=signals, labels=rec.labels, class_names=rec.class_names), "'rate_hz'"),
    ):
        np.savez(tmp_path / name, **arrays)
        assert main(["cluster", "--data", str(tmp_path / name), *common]) == BAD_INPUT_EXIT
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and f"missing {missing}" in err, err


def test_cli_cluster_budgets_default_to_the_estimators():
    from tactile_torch.cli import ARGUMENT_FLAGS, build_parser, with_flags
    from tactile_torch.mixture import PitmanYorGMM

    args = build_parser().parse_args(["cluster", "--data", "x.npz"])
    defaults = PitmanYorGMM()
    assert (args.max_iter, args.max_seconds) == (defaults.max_iter, defaults.max_seconds)
    args = build_parser().parse_args(
        ["cluster", "--data", "x.npz", "--max-seconds", "60", "--max-iter", "900"]
    )
    assert (args.max_iter, args.max_seconds) == (900, 60.0)
    # the budget warning names the argument; the command line shows the option
    flags = {k: v for k, v in ARGUMENT_FLAGS.items() if k in ("max_iter", "max_seconds")}
    assert with_flags("raise it, e.g. max_seconds=600", flags) == "raise it, e.g. --max-seconds 600"
