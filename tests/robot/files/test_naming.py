"""tactile_torch.robot.files.naming: classes and sessions from file names, folders and index files (issue 34)."""

import numpy as np
import pytest

from tactile_torch.robot.files.naming import (
    check_class_names,
    folder_sessions,
    names_for,
    session_source,
)


def test_sessions_come_from_folders_when_names_carry_none():
    paths = [f"logs/day{d}/{s}.csv" for d in (1, 2, 3, 4) for s in ("carpet", "cork")]
    classes, sessions = names_for(paths)
    assert classes == ["carpet", "cork"] * 4
    assert sessions == ["day1", "day1", "day2", "day2", "day3", "day3", "day4", "day4"]
    assert session_source(paths) == "their folders"


def test_a_number_in_the_name_wins_over_the_folder():
    classes, sessions = names_for(["day1/felt_3.csv", "day2/felt.csv", "day2/cork_03.csv"])
    assert classes == ["felt", "felt", "cork"] and sessions == ["3", "day2", "3"]
    assert (
        session_source(["day1/felt_3.csv", "day2/felt.csv"]) == "the numbers in their names and their folders"
    )


def test_files_of_one_folder_are_each_their_own_session():
    assert names_for(["logs/glass.csv", "logs/cork.csv"]) == (["glass", "cork"], ["glass", "cork"])
    assert session_source(["logs/glass.csv", "logs/cork.csv"]) == "each file (its own)"
    assert folder_sessions(["logs/glass.csv", "logs/cork.csv"]) is None


def test_two_folders_of_one_name_stay_two_sessions():
    assert folder_sessions(["a/day1/x.csv", "b/day1/x.csv"]) == ["a/day1", "b/day1"]


def test_an_index_overrides_the_rule(tmp_path):
    (tmp_path / "index.csv").write_text("file,class,session\nrun_1.csv,felt,monday\nrun_2.csv,cork,monday\n")
    paths = [tmp_path / "run_1.csv", tmp_path / "run_2.csv"]
    assert names_for(paths, index=tmp_path / "index.csv") == (["felt", "cork"], ["monday", "monday"])
    assert session_source(paths, index="index.csv") == "the index index.csv"


def test_class_names_must_be_distinct():
    with pytest.raises(ValueError, match=r"names must be distinct, got 'a' at indices 0 and 1"):
        check_class_names(np.array(["a", "a"]).tolist(), "names")
