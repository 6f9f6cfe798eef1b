"""Folder-per-class and folder-per-session trees read right, or refused in one line (issue 42, point 1).

One rule (:func:`tactile_torch.robot.files.naming.recording_names`) for every command's ``--data``: the
tree says which level names the classes (the names that repeat across folders, and which of them read
as dates or sessions), ``class_from`` / ``session_from`` override it, an ambiguous tree is refused with
the fix. Torch-free, as on the robot.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tactile_torch.robot.files.data_sources import DataOptions, read_source
from tactile_torch.robot.files.naming import looks_like_sessions, recording_names
from tests.robot_data import surface_recordings, write_log

DATES = ("2026-11-02", "2026-11-03", "2026-11-05")
SURFACES = ("cork", "felt", "glass", "rubber")


def _trees(root: Path) -> tuple[list[Path], list[Path]]:
    """The same 4 surfaces x 3 days as ``<surface>/<date>.csv`` and ``<date>/<surface>.csv``."""
    rec = surface_recordings(4, 1.0)
    per_class, per_session = [], []
    for day, date in enumerate(DATES):
        for k, surface in enumerate(SURFACES):
            signal = np.roll(rec.signals[k], 37 * day, axis=0)
            for tree, path in (
                (per_class, f"a/{surface}/{date}.csv"),
                (per_session, f"b/{date}/{surface}.csv"),
            ):
                (root / path).parent.mkdir(parents=True, exist_ok=True)
                tree.append(write_log(root / path, signal, rec.rate_hz))
    return sorted(per_class), sorted(per_session)


def test_a_folder_per_class_reads_as_its_mirror(tmp_path):
    per_class, per_session = _trees(tmp_path)
    a, b = read_source(per_class), read_source(per_session)
    assert a.class_names == b.class_names == SURFACES
    for data, paths in ((a, per_class), (b, per_session)):
        pairs = sorted(
            (data.class_names[label], session, p.read_bytes())
            for label, session, p in zip(data.labels, data.session, paths, strict=True)
        )
        assert [(c, s) for c, s, _ in pairs] == [(c, d) for c in SURFACES for d in DATES]
    # the same recording is the same class and session in both trees
    assert sorted(zip(a.labels.tolist(), a.session.tolist(), strict=True)) == sorted(
        zip(b.labels.tolist(), b.session.tolist(), strict=True)
    )


def test_the_decision_names_the_layout_the_classes_and_the_sessions(tmp_path):
    per_class, per_session = _trees(tmp_path)
    names = recording_names(per_class)
    assert names.layout == "folder per class"
    line = names.describe()
    assert "12 files read as folder per class" in line and "4 classes (cork, felt, glass, rubber)" in line
    assert "3 sessions (2026-11-02, 2026-11-03, 2026-11-05)" in line
    assert "the file names (2026-11-02, 2026-11-03, 2026-11-05) look like dates" in line
    assert line.endswith("class_from='file' reads them the other way") and "\n" not in line
    other = recording_names(per_session)
    assert other.layout == "folder per session" and other.describe().endswith(
        "class_from='folder' reads them the other way"
    )


def test_class_from_and_session_from_override_the_tree(tmp_path):
    per_class, _ = _trees(tmp_path)
    flipped = recording_names(per_class, class_from="file")
    assert set(flipped.classes) == set(DATES) and set(flipped.sessions) == set(SURFACES)
    assert recording_names(per_class, session_from="folder").classes == flipped.classes
    each = recording_names(per_class, session_from="recording")
    assert set(each.classes) == set(SURFACES) and len(set(each.sessions)) == 12
    assert (
        flipped.reason == "as told: class_from='file', session_from='folder'"
        and flipped.layout == "folder per session"
    )


@pytest.mark.parametrize(
    ("paths", "says"),
    [
        (
            [f"x/day{d}/run{r}.csv" for d in (1, 2) for r in (1, 2)],
            r"^x: cannot tell the classes from the sessions: the folder names \(day1, day2\) and the file names "
            r"\(run1, run2\) both look like dates or sessions; say where the classes are: class_from='folder' "
            r"\(day1/run1\.csv: class day1, session run1\) or class_from='file' \(day1/run1\.csv: class run1, "
            r"session day1\), or give an index CSV",
        ),
        (
            [f"l/{lab}/{s}.csv" for lab in ("lab_a", "lab_b") for s in SURFACES],
            r"^l: cannot tell the classes from the sessions: the file names \(cork, felt, glass and 1 more\) "
            r"repeat across the folders \(lab_a, lab_b\) and neither looks like dates or sessions",
        ),
    ],
)
def test_an_ambiguous_tree_is_refused_with_the_fix(paths, says):
    with pytest.raises(ValueError, match=says) as err:
        recording_names(paths)
    assert "\n" not in str(err.value)


def test_overrides_that_cannot_hold_are_one_line(tmp_path):
    one_folder = ["logs/cork.csv", "logs/felt.csv"]
    with pytest.raises(ValueError, match=r"^class_from='folder': the files all lie in one folder \(logs\)"):
        recording_names(one_folder, class_from="folder")
    with pytest.raises(ValueError, match=r"class_from and session_from cannot both be 'folder'"):
        recording_names(["a/x.csv", "b/y.csv"], class_from="folder", session_from="folder")
    with pytest.raises(ValueError, match=r"class_from must be one of \('folder', 'file'\), got 'path'"):
        recording_names(one_folder, class_from="path")
    (tmp_path / "index.csv").write_text("file,class\ncork.csv,cork\n")
    with pytest.raises(ValueError, match=r"index= gives every file's class and session; class_from"):
        recording_names([tmp_path / "cork.csv"], index=tmp_path / "index.csv", class_from="file")


@pytest.mark.parametrize(
    ("paths", "layout", "first"),
    [
        (["h/Fabric_1.csv", "h/Wood_1.csv"], "file names", ("Fabric", "1")),
        (
            ["d/day1/felt_3.csv", "d/day2/felt.csv", "d/day2/cork_03.csv"],
            "folder per session",
            ("felt", "day1"),
        ),
        (["c/cork/cork_1.csv", "c/cork/cork_2.csv", "c/felt/felt_1.csv"], "file names", ("cork", "1")),
        (["o/cork/a.csv", "o/cork/b.csv", "o/felt/c.csv"], "folder per class", ("cork", "a")),
        (["logs/cork_9.csv", "other/day2/felt.csv"], "file names", ("cork", "9")),  # a file per folder
        (
            ["b/ASPHALT/imu_00.csv", "b/ASPHALT/imu_02.csv", "b/ICE/imu_00.csv"],
            "folder per class",
            ("ASPHALT", "imu_00"),
        ),
        (
            ["w/monday/cork.csv", "w/tuesday/cork.csv", "w/tuesday/felt.csv"],
            "folder per session",
            ("cork", "monday"),
        ),
    ],
)
def test_the_trees_labs_keep(paths, layout, first):
    names = recording_names(paths)
    assert names.layout == layout
    assert (names.classes[0], names.sessions[0]) == first


def test_what_reads_as_a_session():
    assert looks_like_sessions(["2026-11-02", "20261103", "2026-11-04T10-30"])
    assert looks_like_sessions(["day1", "day2"]) and looks_like_sessions(["session_03", "run-2", "s1"])
    assert looks_like_sessions(["monday", "tue"]) and looks_like_sessions(["1", "2", "10"])
    assert looks_like_sessions(["imu_00", "imu_08"])  # one word and a number: the word tells nothing apart
    assert not looks_like_sessions(["cork", "felt"]) and not looks_like_sessions(["p120", "p150"])
    assert not looks_like_sessions(["felt_1", "cork_1"]) and not looks_like_sessions(["day1", "cork"])


def test_borealtc_reads_as_five_terrains(shared_data):
    root = shared_data("borealtc_imu")
    paths = sorted(root.glob("*/imu_*.csv"))
    names = recording_names(paths)
    assert names.layout == "folder per class"
    assert sorted(set(names.classes)) == ["ASPHALT", "FLOORING", "ICE", "SANDY_LOAM", "SNOW"]
    data = read_source(paths, DataOptions(columns="time,ax,ay,az", units="m/s2", sensor_range_g=16.0))
    assert (
        data.class_names == ("ASPHALT", "FLOORING", "ICE", "SANDY_LOAM", "SNOW") and len(data.signals) == 15
    )
