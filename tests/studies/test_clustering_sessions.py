"""The sources and rows of ``python -m tactile_torch.studies.clustering_sessions`` (how many surfaces across days, issue 38).

Its full runs take an hour (docs/mixture.md gives the commands); here the sources are checked for
what they claim to be, and the rows against the fits they describe, on short chains.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.studies import clustering_sessions as cs


def test_multi_day_is_surfaces_times_days_with_a_near_duplicate_pair_and_a_gain_per_day():
    from tactile_torch.data.stylus import SURFACES

    rec = cs.multi_day_recordings(5, 3, 0, duration_s=4.0)
    assert len(rec.signals) == 15 and sorted(set(rec.session)) == ["day0", "day1", "day2"]
    assert np.array_equal(np.bincount(rec.labels), [3] * 5)
    names = {s.name: s for s in SURFACES}
    assert names[rec.class_names[1]].alike_of == rec.class_names[0]  # the near-duplicate pair
    assert len(set(rec.class_names)) == 5
    X, y, day = cs.multi_day(5, 3, 0, duration_s=4.0)
    assert X.shape == (len(y), 3) and np.array_equal(np.bincount(day), [len(y) // 3] * 3)
    np.testing.assert_array_equal(cs.multi_day(5, 3, 0, duration_s=4.0)[0], X)  # seeded
    # every day moves every surface: the day means differ beyond the windows' spread of their mean
    for c in range(5):
        means = np.stack([X[(y == c) & (day == k)].mean(0) for k in range(3)])
        assert np.ptp(means, axis=0).max() > 0.05


@pytest.mark.filterwarnings("ignore:PitmanYorGMM. R-hat:RuntimeWarning")
def test_rows_describe_the_fits_they_come_from():
    X, y, day = cs.multi_day(5, 3, 0, duration_s=4.0)
    rows = cs.session_rows({"five": (X, y, day)}, n_iter=30, burn_in=10, n_chains=2)
    assert [r["way"] for r in rows] == list(cs.WAYS)
    for r in rows:
        lo, hi = (int(v) for v in r["K 95% interval"].strip("[]").split(","))
        assert r["surfaces"] == 5 and r["n"] == len(y) and lo <= r["K mode"] <= hi
        assert r["covers"] == (
            "yes" if lo <= 5 <= hi else ("K - 1 (a pair merged)" if lo <= 4 <= hi else "no")
        )
        assert r["within K +- 1"] == ("yes" if 4 <= lo and hi <= 6 else "no")
        assert 0.0 <= r["pairwise accuracy"] <= 1.0 and -1.0 <= r["ARI"] <= 1.0
    assert rows[0]["lambda"] is None and rows[2]["lambda"] > 0  # only the session effects have one


def test_unknown_names_are_refused_in_one_line(capsys):
    with pytest.raises(SystemExit) as exit_:
        cs._main(["--only", "days-99x1-seed0"])
    assert exit_.value.code == 2 and "--only: unknown 'days-99x1-seed0'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cs._main(["--ways", "coarsened"])
    assert "--ways: unknown 'coarsened'" in capsys.readouterr().err
