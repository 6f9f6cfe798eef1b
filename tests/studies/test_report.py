import json
import subprocess
import sys

import matplotlib.pyplot as plt
import pytest

from tactile_torch.studies import STUDIES, run_report
from tactile_torch.studies.report import Report


def test_report_writes_markdown_tables_and_figures(tmp_path):
    rep = Report(tmp_path)
    sec = rep.section("Demo section")
    sec.text("Some text.")
    sec.table([{"a": 1, "b": 0.123456}, {"a": 2, "b": float("nan")}], caption="numbers")
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    png = sec.figure(fig, "Demo Figure", "a line")
    path = rep.write()
    md = path.read_text()
    assert "## Demo section" in md
    assert "| a | b |" in md and "| 1 | 0.1235 |" in md and "| 2 | nan |" in md
    assert "![a line](figures/demo-figure.png)" in md
    assert png.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    data = json.loads((tmp_path / "report.json").read_text())
    assert data["sections"][0]["tables"][0]["rows"][0] == {"a": 1, "b": 0.123456}


def test_report_table_rejects_empty_rows(tmp_path):
    with pytest.raises(ValueError, match="rows must hold at least one row"):
        Report(tmp_path).section("x").table([])


def test_run_report_environment(tmp_path):
    path = run_report(tmp_path, quick=True, only=["environment"], log=lambda s: None)
    text = path.read_text()
    assert "## Environment and data" in text and "torch" in text
    assert "Not built yet" not in text  # only asked for a study that exists
    with pytest.raises(ValueError, match="only must name studies"):
        run_report(tmp_path, only=["nope"])
    assert "environment" in STUDIES


def test_cli_help_lists_every_design_subcommand():
    out = subprocess.run(
        [sys.executable, "-m", "tactile_torch.cli", "--help"], capture_output=True, text=True, check=True
    ).stdout
    for name in ["train", "cluster", "export", "predict", "stream", "simulate-sensor", "bench", "report"]:
        assert name in out


def test_quick_and_full_are_exclusive_in_the_library_and_the_cli(tmp_path, capsys):
    """Every study reads one size of run (RunContext.mode): both at once is refused, before any work."""
    from tactile_torch.cli import main
    from tactile_torch.studies import RunContext

    assert [RunContext(quick=q, full=f).mode for q, f in ((1, 0), (0, 1), (0, 0))] == [
        "quick",
        "full",
        "default",
    ]
    with pytest.raises(ValueError, match="quick and full are exclusive"):
        run_report(tmp_path / "r", quick=True, full=True)
    assert not (tmp_path / "r").exists()
    with pytest.raises(SystemExit) as stop:
        main(["report", "--quick", "--full", "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert (
        stop.value.code == 2 and err.count("\n") == 1 and "--full: not allowed with argument --quick" in err
    )
