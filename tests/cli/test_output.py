"""What the command line prints besides its results, and where it writes: warnings as one line, a
progress line for a long silent step, ``bench --out``, and no output outside the named directory."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import pytest

from tactile_torch import cli
from tactile_torch.cli import _output
from tactile_torch.cli import bench as bench_command


def test_a_warning_prints_as_one_line_without_source(monkeypatch, tmp_path, capsys):
    def handler(args):
        warnings.warn("R-hat > 1.01:\n  the chains disagree", RuntimeWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(bench_command, "run_bench", handler)
    before = warnings.showwarning
    assert cli.main(["bench", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert err == "tactile-torch bench: warning: R-hat > 1.01: the chains disagree\n"
    assert warnings.showwarning is before  # the caller's display is restored


def test_debug_leaves_warnings_to_python(monkeypatch, tmp_path, capsys):
    def handler(args):
        warnings.warn("plain", UserWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(bench_command, "run_bench", handler)
    with pytest.warns(UserWarning, match="plain"):  # shown the usual way, with its file and line
        assert cli.main(["--debug", "bench", "--out", str(tmp_path)]) == 0
    assert "tactile-torch bench: warning" not in capsys.readouterr().err


def test_bench_writes_under_out_and_not_into_the_checkout(monkeypatch, tmp_path, capsys):
    calls = []
    monkeypatch.setattr(bench_command.subprocess, "call", lambda cmd: calls.append(cmd) or 0)
    monkeypatch.chdir(tmp_path)
    assert cli.main(["bench", "--only", "signal"]) == 0
    assert cli.main(["bench", "--out", "elsewhere"]) == 0
    default, named = calls
    assert default[default.index("--out") + 1] == str(tmp_path / "runs" / "bench")
    assert named[named.index("--out") + 1] == str(tmp_path / "elsewhere")
    assert "results go to runs/bench" in capsys.readouterr().err


def test_bench_runner_takes_out(tmp_path):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    try:
        from bench import run
    finally:
        sys.path.pop(0)
    with pytest.raises(SystemExit):  # an unknown benchmark is refused before anything is written
        run.main(["--only", "no-such-benchmark", "--out", str(tmp_path / "b")])
    assert not (tmp_path / "b").exists()


def test_a_long_silent_step_shows_its_label_and_clears_it(capsys):
    with _output.stage("export: tracing", delay=0):
        pass
    assert "export: tracing: 00:00" in capsys.readouterr().err
    with _output.stage("export: tracing"):  # a step quicker than the delay prints nothing
        pass
    assert capsys.readouterr().err == ""


def test_run_tradeoff_needs_the_output_directory():
    from tactile_torch.tradeoff import run_tradeoff

    with pytest.raises(TypeError, match="out_dir"):
        run_tradeoff("recordings.npz", quick=True)
