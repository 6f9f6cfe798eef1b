"""tactile_torch.tradeoff.progress: the estimate of the time a study has left, on scripted schedules.

No timing: a schedule is a list of tasks with the seconds each took, fed to the estimator in the order a
study runs them (every candidate's first fold, one of each family first; then fold by fold); after the
first tenth of the work the estimated total (done + left) stays within a factor of 2 of the real one.
"""

import numpy as np
import pytest

from tactile_torch.tradeoff.progress import RemainingTime, Task, minutes, probe_first


def _study(seed: int, *, load: float = 1.0, stop_networks_after: int | None = None):
    """A vibration-like study: 30 classical candidates (4 families of cost), 3 networks costing 20-60x;
    5 folds; ``load`` multiplies every task's seconds from the second half on; networks may stop early."""
    rng = np.random.default_rng(seed)
    candidates = []
    for i in range(30):
        family = ("classical", "svm")[i % 2]
        candidates.append((f"c{i}", family, rng.uniform(0.2, 2.0) * (3 if family == "svm" else 1)))
    for i in range(3):
        candidates.append((f"net{i}", "neural", rng.uniform(20, 60)))
    plan, order = [], []
    for k in range(5):
        tasks = [Task((name, k), name, family, 1.0) for name, family, _ in candidates]
        plan += tasks
        order += probe_first(tasks) if k == 0 else tasks
    seconds = {name: cost for name, _, cost in candidates}
    schedule = []
    for task in order:
        name, k = task.key
        if stop_networks_after is not None and name.startswith("net") and k >= stop_networks_after:
            continue
        schedule.append((task, seconds[name] * rng.uniform(0.8, 1.25)))
    half = sum(s for _, s in schedule) / 2
    done, out = 0.0, []
    for task, s in schedule:
        out.append((task, s * (load if done > half else 1.0)))
        done += s
    return plan, out


def _estimated_totals(plan, schedule, *, after=0.0, stops=None):
    """Feed ``schedule`` to a clock planned with ``plan``; return it and the estimated totals (done + left)
    as shares of the real total, from the share ``after`` of the work on; ``stops(key)`` lists the tasks a
    finished task's check stops."""
    clock = RemainingTime()
    clock.plan(plan)
    total = sum(s for _, s in schedule)
    ratios = []
    for task, s in schedule:
        clock.finish(task.key, s)
        if stops is not None:
            clock.drop(stops(task.key))
        if clock.elapsed >= after * total:
            ratios.append((clock.elapsed + clock.remaining()) / total)
    return clock, ratios


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("load", [1.0, 1.8])
def test_after_the_first_tenth_the_estimated_total_is_within_a_factor_of_two(seed, load):
    _, ratios = _estimated_totals(*_study(seed, load=load), after=0.1)
    assert ratios and 0.5 <= min(ratios) and max(ratios) <= 2.0


def test_stopped_tasks_leave_the_estimate_when_dropped():
    def stops(key):  # the study stops the networks after their second fold
        return [(f"net{i}", j) for i in range(3) for j in range(2, 5)] if key == ("net2", 1) else []

    clock, ratios = _estimated_totals(*_study(0, stop_networks_after=2), stops=stops)
    # once the stops are known the estimate is right to within the schedule's noise
    assert 0.8 < ratios[-1] <= 1.0 + 1e-9
    assert clock.remaining() == 0.0


def test_a_family_not_yet_seen_is_estimated_from_its_prior_and_a_group_from_its_own_tasks():
    clock = RemainingTime()
    clock.plan(
        [Task(("a", 0), "a", "classical"), Task(("a", 1), "a", "classical"), Task(("n", 0), "n", "neural")]
    )
    assert clock.remaining() == 0.0  # nothing done: no rate yet
    clock.finish(("a", 0), 2.0)
    assert clock.estimate(Task(("a", 1), "a", "classical")) == pytest.approx(2.0)
    assert clock.estimate(Task(("n", 0), "n", "neural")) == pytest.approx(2.0 * 20)  # PRIORS["neural"]
    assert clock.remaining() == pytest.approx(2.0 + 40.0)
    assert clock.fraction_done() == pytest.approx(2.0 / 44.0)


def test_probe_first_and_minutes():
    tasks = [Task(i, f"g{i}", f) for i, f in enumerate(["a", "a", "b", "a", "c", "b"])]
    assert [t.key for t in probe_first(tasks)] == [0, 2, 4, 1, 3, 5]
    assert minutes(12) == "about 10 s" and minutes(400) == "about 7 min"
