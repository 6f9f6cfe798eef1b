"""The sources and rows of ``python -m tactile_torch.studies.clustering_k`` (how many surfaces, issue 22).

The study's full runs take minutes (docs/mixture.md gives the commands); here its sources are
checked for what they claim to be, and its rows against the fits they describe, on short chains.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.studies import clustering_k as ck

SHORT = {"n_iter": 120, "burn_in": 40, "n_chains": 2}


def test_gaussian_three_is_three_seeded_clusters_of_fifty():
    X, y = ck.gaussian_three(0)
    assert X.shape == (150, 3) and np.array_equal(np.bincount(y), [50, 50, 50])
    np.testing.assert_array_equal(ck.gaussian_three(0)[0], X)
    assert not np.array_equal(ck.gaussian_three(1)[0], X)
    means = np.stack([X[y == c].mean(0) for c in range(3)])
    d = np.linalg.norm(means[:, None] - means[None], axis=-1)[np.triu_indices(3, 1)]
    assert np.all(np.abs(d - 5.0) < 0.6)  # centres 5 apart, means of 50 points with sd 1


def test_sessions_3x3_shifts_the_gain_per_session_and_standardising_removes_it():
    from tactile_torch.data import make_vibration_recordings

    X, y = ck.sessions_3x3(0)
    Xs, ys = ck.sessions_3x3(0, per_session=True)
    assert X.shape == Xs.shape == (270, 3) and np.array_equal(y, ys)
    assert np.array_equal(np.bincount(y), [90, 90, 90])
    rec = make_vibration_recordings(3, duration_s=30, n_sessions=3, random_state=0)
    session = np.array([int(str(s).rsplit("/", 1)[1]) for s in rec.session])[
        rec.windows(800).recording.numpy()
    ]
    for k in range(3):
        np.testing.assert_allclose(Xs[session == k].mean(0), 0.0, atol=1e-9)
        np.testing.assert_allclose(Xs[session == k].std(0), 1.0, rtol=1e-9)
    # without standardisation the sessions sit apart: the gain moves every surface of a session
    centres = np.stack([X[session == k].mean(0) for k in range(3)])
    assert np.linalg.norm(centres[0] - centres[2]) > 0.5
    assert ck.sessions_3x3(0, components=5)[0].shape == (270, 5)  # --components reaches the transform


def test_session_overlap_is_a_distance_table_of_the_nine_groups():
    D = ck.session_overlap(0)
    assert D.shape == (9, 9) and np.all(np.isfinite(D))
    np.testing.assert_allclose(D, D.T, atol=1e-9)
    np.testing.assert_allclose(np.diag(D), 0.0, atol=1e-9)
    assert D.min() >= -1e-9


@pytest.mark.filterwarnings(
    "ignore:PitmanYorGMM. R-hat:RuntimeWarning"
)  # short chains, as the study's own fits
def test_rows_describe_the_fits_they_come_from():
    from tactile_torch.mixture import PitmanYorGMM

    X, y = ck.gaussian_three(0)
    sources = {"gaussian-3": (X, y)}
    (row,) = ck.k_coverage(sources, {"mfm": {"model": "mfm"}}, random_state=0, **SHORT)
    model = PitmanYorGMM(model="mfm", random_state=0, progress=False, **SHORT).fit(X)
    lo, hi = model.n_clusters_summary_["interval"]
    assert row["K 95% interval"] == f"[{lo}, {hi}]" and row["K mode"] == model.n_clusters_summary_["mode"]
    assert row["covers"] == ("yes" if lo <= 3 <= hi else "no") and row["true K"] == 3 and row["n"] == 150
    assert row["sweeps"] == 120 and row["K point estimate"] == model.n_clusters_summary_["point_estimate"]
    # a made-up truth outside the interval is reported as not covered
    assert ck.coverage_row("x", np.arange(150) % (hi + 1), "mfm", model, 1.0)["covers"] == "no"

    (mix,) = ck.mixing_rows(sources, random_state=0, **SHORT)
    assert mix["K 95% interval"] == row["K 95% interval"] and mix["sweeps"] == 120
    assert mix["R-hat K"] == row["R-hat K"] and mix["ESS K"] == row["ESS K"]

    curve = ck.coarsening_curve(X, (30.0, None), random_state=0, **SHORT)
    assert [r["coarsen"] for r in curve] == [30.0, "none"]
    assert curve[1]["K mode"] == row["K mode"]  # coarsen=None is the exact posterior fitted above
    assert all(np.isfinite(r["mean log density"]) for r in curve)


@pytest.mark.parametrize(
    ("argv", "named"), [(["--only", "no-such-source"], "'no-such-source'"), (["--settings", "pyp"], "'pyp'")]
)
def test_the_command_refuses_an_unknown_source_or_setting_in_one_line(argv, named, capsys):
    with pytest.raises(SystemExit) as exit_info:
        ck._main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"{argv[0]}: unknown {named}; expected some of " in err


def test_the_command_refuses_no_components(capsys):
    with pytest.raises(SystemExit) as exit_info:
        ck._main(["--components", "0", "--overlap"])
    assert exit_info.value.code == 2
    assert (
        "--components: expected a positive number of principal components, got 0" in capsys.readouterr().err
    )


def test_a_source_without_its_data_is_said_to_be_skipped(monkeypatch, capsys):
    monkeypatch.setattr(ck, "k_sources", lambda quick, components: {"gaussian-3": ck.gaussian_three()})
    ck._main(["--only", "hapmat", "--quick"])
    out = capsys.readouterr()
    assert (
        out.err.strip() == "clustering_k: hapmat: skipped, its data set is not found here" and out.out == ""
    )


def test_every_source_returned_is_a_listed_name():
    assert set(ck.k_sources(quick=True)) <= set(ck.SOURCE_NAMES)


def test_gain_invariant_features_do_not_move_with_a_sessions_gain():
    # issue 32, decision (b): a gain multiplies every axis of a session; these 20 features stay put
    import torch

    from tactile_torch.signal import window_features
    from tactile_torch.studies.clustering_k import gain_invariant_features

    w = torch.as_tensor(np.random.default_rng(0).standard_t(5, size=(4, 3, 256)))
    a = gain_invariant_features(window_features(w).numpy())
    b = gain_invariant_features(window_features(1.25 * w).numpy())
    assert a.shape == (4, 20) and np.isfinite(a).all()
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
    # the features it is built from do move
    assert not np.allclose(window_features(w).numpy(), window_features(1.25 * w).numpy())
