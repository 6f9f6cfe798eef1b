"""tactile_torch.robot.files.naming: classes and sessions from file names, folders and index files (issues 34, 42)."""

import numpy as np
import pytest

from tactile_torch.robot.files.naming import check_class_names, folder_names, recording_names


def test_sessions_come_from_folders_named_as_days():
    paths = [f"logs/day{d}/{s}.csv" for d in (1, 2, 3, 4) for s in ("carpet", "cork")]
    names = recording_names(paths)
    assert names.classes == ("carpet", "cork") * 4
    assert names.sessions == ("day1", "day1", "day2", "day2", "day3", "day3", "day4", "day4")
    assert names.layout == "folder per session"


def test_a_folder_named_as_a_day_is_the_session_of_a_numbered_file():
    names = recording_names(["day1/felt_3.csv", "day2/felt.csv", "day2/cork_03.csv"])
    assert names.classes == ("felt", "felt", "cork") and names.sessions == ("day1", "day2", "day2")


def test_numbered_files_in_folders_that_are_no_sessions_keep_their_numbers():
    names = recording_names(["logs/felt_3.csv", "more/felt_4.csv", "more/cork_03.csv"])
    assert names.classes == ("felt", "felt", "cork") and names.sessions == ("3", "4", "3")
    assert names.layout == "file names"


def test_files_of_one_folder_are_each_their_own_session():
    names = recording_names(["logs/glass.csv", "logs/cork.csv"])
    assert (names.classes, names.sessions) == (("glass", "cork"), ("glass", "cork"))
    assert names.layout == "file names" and folder_names(["logs/glass.csv", "logs/cork.csv"]) is None


def test_two_folders_of_one_name_stay_two_sessions():
    assert folder_names(["a/day1/x.csv", "b/day1/x.csv"]) == ["a/day1", "b/day1"]
    assert recording_names(["a/day1/x.csv", "b/day1/x.csv"]).sessions == ("a/day1", "b/day1")


def test_an_index_overrides_the_rule(tmp_path):
    (tmp_path / "index.csv").write_text("file,class,session\nrun_1.csv,felt,monday\nrun_2.csv,cork,monday\n")
    paths = [tmp_path / "run_1.csv", tmp_path / "run_2.csv"]
    names = recording_names(paths, index=tmp_path / "index.csv")
    assert (names.classes, names.sessions) == (("felt", "cork"), ("monday", "monday"))
    assert (
        names.layout == "index"
        and names.reason == f"classes and sessions from the index {tmp_path / 'index.csv'}"
    )


def test_class_names_must_be_distinct():
    with pytest.raises(ValueError, match=r"names must be distinct, got 'a' at indices 0 and 1"):
        check_class_names(np.array(["a", "a"]).tolist(), "names")
