"""tactile_torch.tradeoff.stopping: the early stops of a study never drop a candidate that could be recommended.

The tests are statistical (the level of each check, checked by simulation under the model the rule
assumes) and logical (the bookkeeping: who stops whom, the resumes when a premise failed), with no
study run: the study's own end-to-end use is in tests/tradeoff/test_tradeoff.py.
"""

import numpy as np
import pytest

from tactile_torch.tradeoff.stopping import (
    MIN_UNITS,
    STOP_RISK,
    EarlyStopping,
    chance_to_beat,
    chance_to_reach,
    stop_level,
)


def test_the_level_of_a_check_shares_the_risk_between_two_candidates_and_the_folds():
    assert stop_level(5) == pytest.approx(STOP_RISK / 8)
    assert stop_level(2) == pytest.approx(STOP_RISK / 2)
    assert 2 * (10 - 1) * stop_level(10) == pytest.approx(STOP_RISK)


def test_a_candidate_that_ends_more_accurate_is_stopped_at_most_at_the_checks_level():
    """Under the model the rule assumes (exchangeable units), a candidate whose differences to the leader
    average below zero over all units (it ends more accurate) is stopped with probability below the level."""
    rng = np.random.default_rng(0)
    level, g, stopped, beats = 0.01, 10, 0, 0
    for _ in range(4000):
        d = rng.normal(0.0, 0.1, g)  # leader minus candidate, per unit; mean 0: a coin toss who ends ahead
        if d.mean() >= 0:
            continue
        beats += 1
        for k in range(MIN_UNITS, g):  # every check of a study, on the units seen so far
            if chance_to_beat(d[:k], g - k) < level:
                stopped += 1
                break
    assert beats > 1500
    assert stopped / beats < (g - MIN_UNITS) * level  # at most one level per check


def test_a_clearly_worse_and_costlier_candidate_is_stopped_and_a_close_one_is_not():
    assert chance_to_beat([0.30, 0.28, 0.33, 0.29, 0.31, 0.30], 4, floor=0.02) < 1e-4
    assert chance_to_beat([0.02, -0.01, 0.03], 2, floor=0.02) > 0.05
    assert chance_to_beat([0.5], 4) == 1.0  # one unit: no check
    assert chance_to_beat([0.1, 0.2], 0) == 0.0  # every unit seen: the order is known
    assert chance_to_reach([0.40, 0.42, 0.38], 3, 0.9, floor=0.03) < stop_level(5)
    assert chance_to_reach([0.88, 0.92, 0.90], 3, 0.9, floor=0.03) > 0.2


def _study(stops: EarlyStopping, units: list[str], accuracy: dict[str, list[float]], n: int = 50) -> None:
    for name, values in accuracy.items():
        for unit, a in zip(units, values, strict=False):
            stops.record(name, "windows-800", [unit], [round(a * n)], [n])


def test_only_a_costlier_candidate_stops_and_never_against_one_that_costs_about_the_same():
    units = [f"day{i}" for i in range(10)]
    stops = EarlyStopping({"windows-800": 10}, folds=5)
    accurate, poor = [0.90, 0.92, 0.91, 0.93, 0.90], [0.40, 0.42, 0.38, 0.41, 0.39]
    _study(stops, units, {"LDA": accurate, "CNN": poor, "kNN": poor})
    stops.set_cost("LDA", 0.80)
    stops.set_cost("CNN", 0.95)  # costlier than LDA by more than the 10 % tolerance
    stops.set_cost("kNN", 0.85)  # within it: it may still win on size, so it runs on
    new = stops.check(2)
    assert set(new) == {"CNN"} and new["CNN"].by == "LDA" and "cheaper" in new["CNN"].reason
    assert stops.running(["LDA", "CNN", "kNN"]) == ["LDA", "kNN"]
    assert stops.check(3) == {}  # a stop is final; nothing new


def test_exhaustive_stops_nothing_and_an_unexported_candidate_stops_at_once():
    units = [f"day{i}" for i in range(10)]
    exhaustive = EarlyStopping({"windows-800": 10}, folds=5, enabled=False)
    _study(exhaustive, units, {"LDA": [0.9] * 5, "CNN": [0.1] * 5})
    exhaustive.set_cost("LDA", 0.8)
    exhaustive.set_cost("CNN", 0.9)
    exhaustive.set_cost("SVC", None)
    assert exhaustive.check(2) == {} and exhaustive.stopped == {}
    stops = EarlyStopping({"windows-800": 10}, folds=5)
    stops.set_cost("SVC", None)
    assert stops.stopped["SVC"].by == "no exported file"


def test_with_a_target_a_candidate_stops_when_its_mean_cannot_reach_it_whatever_the_costs():
    units = [f"day{i}" for i in range(10)]
    stops = EarlyStopping({"windows-800": 10}, folds=5, target=0.95)
    _study(stops, units, {"cheap": [0.60, 0.62, 0.59, 0.61], "good": [0.96, 0.97, 0.98, 0.96]})
    stops.set_cost("cheap", 0.2)
    stops.set_cost("good", 0.8)
    assert set(stops.check(2)) == {"cheap"}


def test_a_candidate_stopped_by_one_that_ends_below_the_baseline_is_resumed_through_a_chain():
    units = [f"day{i}" for i in range(10)]
    stops = EarlyStopping({"windows-800": 10}, folds=5)
    _study(
        stops,
        units,
        {
            "A": [0.95, 0.96, 0.94, 0.95, 0.96],
            "B": [0.60, 0.61, 0.59, 0.60, 0.62],
            "C": [0.20, 0.22, 0.21, 0.19, 0.20],
        },
    )
    stops.set_cost("A", 0.1)
    stops.set_cost("B", 0.5)
    stops.set_cost("C", 1.0)
    stops.check(2)
    assert stops.stopped["B"].by == "A" and stops.stopped["C"].by in ("A", "B")
    assert stops.to_resume({"A": True}) == []  # the chain ends in an adequate candidate
    assert sorted(stops.to_resume({"A": False})) == ["B", "C"]  # it did not: both run on
    assert stops.stopped == {}
