"""The trade-off's options and their defaults (tactile_torch.tradeoff.job), read by the library and the
command line: one set of defaults, checked once, and the reproduce line built from them."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from tactile_torch.cli import build_parser
from tactile_torch.cli.tradeoff import reproduce_line, tradeoff_options
from tactile_torch.tradeoff.job import TradeoffOptions
from tactile_torch.tradeoff.runner import plan_tradeoff


def test_the_defaults_are_the_library_defaults():
    keywords = TradeoffOptions().run_keywords()
    signature = inspect.signature(plan_tradeoff).parameters
    shared = [name for name in keywords if name in signature]
    assert len(shared) >= 14
    for name in shared:
        assert keywords[name] == signature[name].default, name
    assert keywords["deploy"] == ["recommended"] and keywords["target"] is None


@pytest.mark.parametrize(
    ("options", "says"),
    [
        ({"n_folds": 1}, "n_folds must be a whole number >= 2, got 1"),
        ({"max_per_class": 0}, "max_per_class must be 'auto' or a whole number >= 2, got 0"),
        ({"frame_rate_hz": 0.0}, "frame_rate_hz must be a number of frames/s > 0, got 0"),
        ({"target": 1.5}, r"target must be an accuracy in \(0, 1\], got 1.5"),
    ],
)
def test_bad_options_are_refused_naming_the_argument(options, says):
    with pytest.raises(ValueError, match=says):
        TradeoffOptions(**options)


def test_the_command_line_gives_options_and_the_reproduce_line_keeps_what_changed():
    argv = ["tradeoff", "--data", "x.npz", "--folds", "3", "--seed", "0", "--threshold", "auto"]
    args = build_parser().parse_args([*argv, "--windows", "200,400", "--quick", "--classifiers", "NCM,LDA"])
    options = tradeoff_options(args)
    assert options == TradeoffOptions(quick=True, n_folds=3, windows=(200, 400), classifiers=("NCM", "LDA"))
    assert options.changed() == ["quick", "n_folds", "windows", "classifiers"]
    assert reproduce_line(args, options) == (
        "tactile-torch tradeoff --data x.npz --out runs/tradeoff --quick --folds 3 --windows 200,400 "
        "--classifiers NCM,LDA"
    )
    plain = build_parser().parse_args(["tradeoff", "--data", "x.npz"])
    assert tradeoff_options(plain) == TradeoffOptions()
    assert (
        reproduce_line(plain, TradeoffOptions()) == "tactile-torch tradeoff --data x.npz --out runs/tradeoff"
    )


def test_the_library_notes_name_arguments_and_the_command_prints_options(tmp_path, monkeypatch, capsys):
    """Library side: no option in a note or in the rule; command side: the notes as options (with_flags)."""
    from types import SimpleNamespace

    import tactile_torch.tradeoff
    import tactile_torch.tradeoff.job
    from tactile_torch.cli import main
    from tactile_torch.cli.tradeoff import with_flags
    from tactile_torch.data.images import make_explorations, save_explorations
    from tactile_torch.image import DEFAULT_FRAME_RATE_HZ as RATE
    from tactile_torch.tradeoff import load_tradeoff_data
    from tactile_torch.tradeoff.output import COST, INTERVAL, RULE

    explorations = make_explorations(2, n_frames=3, frame_size=12, sensels=4, random_state=0)
    path = save_explorations(tmp_path / "ex.npz", explorations)  # it states the generator's frame rate
    data = load_tradeoff_data(path)
    assert data.notes == [] and data.rate_hz == RATE
    # a file that states no frame rate: refused in one line, never assumed (issue 42)
    bare = tmp_path / "bare.npz"
    np.savez(bare, frames=explorations.frames.permute(0, 1, 3, 4, 2).numpy(), labels=[0, 0, 1, 1, 2, 2, 3, 3],
             class_names=list(explorations.class_names))  # fmt: skip
    says = "holds explorations without 't' or 'frame_rate_hz', so their frame rate is unknown; give it"
    with pytest.raises(ValueError, match=rf"^frame_rate_hz: .*bare\.npz {says} \(frame_rate_hz=\)$"):
        load_tradeoff_data(bare)
    assert main(["tradeoff", "--data", str(bare), "--out", str(tmp_path / "b")]) == 2
    assert capsys.readouterr().err.splitlines()[-1].endswith(f"{says} (--frame-rate)")
    notes = ["threshold: from each training fold's histogram (Otsu) (threshold= to set one)"]
    for text in (*notes, RULE, COST, INTERVAL):
        assert "--" not in text, text
    assert with_flags(RULE).startswith("with --target ACC: the cheapest candidate")
    assert (
        with_flags("feature set 'top 7' left out (features=)") == "feature set 'top 7' left out (--features)"
    )
    assert (
        with_flags("n_consecutive= is not an option of tradeoff")
        == "n_consecutive= is not an option of tradeoff"
    )

    # the command prints the summary and the notes of the run through with_flags
    result = SimpleNamespace(
        notes=notes,
        status="recommended",
        seconds=1.0,
        incomplete=[],
    )
    monkeypatch.setattr(tactile_torch.tradeoff, "load_tradeoff_data", lambda *a, **k: None)
    monkeypatch.setattr(tactile_torch.tradeoff.job, "run_tradeoff_job", lambda *a, **k: (result, {}))
    monkeypatch.setattr(tactile_torch.tradeoff, "summary_lines", lambda r: [f"recommended: x ({RULE[:20]})"])
    assert main(["tradeoff", "--data", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert capsys.readouterr().out.splitlines()[:2] == [
        "recommended: x (with --target ACC: the)",
        "note:        --threshold: from each training fold's histogram (Otsu) (--threshold to set one)",
    ]
    # a late stage that failed (a bug): what was complete is written; one line, status 1, never 2
    result.incomplete = [{"stage": "breaking points", "error": "ValueError: x must have shape (B, F)"}]
    assert main(["tradeoff", "--data", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 1
    assert capsys.readouterr().err.splitlines() == [
        "tactile-torch tradeoff: internal error in breaking points: ValueError: x must have shape (B, F) "
        "(that part is missing; everything else is written; please report it)"
    ]
