"""The one builder of the report's "reproduce with" lines keeps every option and parses back."""

import re
import shlex
from pathlib import Path

import pytest

import tactile_torch.studies
from tactile_torch.cli import build_parser
from tactile_torch.studies import RunContext, run_report
from tactile_torch.studies._reproduce import report_command


def _parsed(line: str):
    words = shlex.split(line)
    assert words[:2] == ["tactile-torch", "report"]
    return build_parser().parse_args(words[1:])


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        (
            {
                "out_dir": "my runs/seed 7",
                "random_state": 7,
                "quick": True,
                "only": ["claims", "tradeoff"],
            },
            {"out": "my runs/seed 7", "seed": 7, "quick": True, "full": False, "only": "claims,tradeoff"},
        ),
        (
            {"out_dir": Path("runs/latest"), "random_state": 0},
            {"out": "runs/latest", "seed": 0, "quick": False, "full": False, "only": ""},
        ),
        (
            {"out_dir": "o", "random_state": 12, "full": True, "only": ["breaking_points"]},
            {"out": "o", "seed": 12, "quick": False, "full": True, "only": "breaking_points"},
        ),
    ],
)
def test_report_command_keeps_every_option_and_parses_back(options, expected):
    line = report_command(**options)
    for flag in ("--seed", "--out"):
        assert flag in line
    for flag in ("--quick", "--full", "--only"):
        assert (flag in line) == bool(expected[flag[2:]])
    args = _parsed(line)
    assert {key: getattr(args, key) for key in expected} == expected


def test_run_context_command_uses_the_run_options():
    ctx = RunContext(random_state=3, full=True, out_dir=Path("elsewhere"))  # quick and full are exclusive
    args = _parsed(ctx.command("image_features", "image_classification"))
    assert (args.seed, args.quick, args.full, args.out, args.only) == (
        3,
        False,
        True,
        "elsewhere",
        "image_features,image_classification",
    )


def test_report_preamble_reproduces_the_run(tmp_path):
    out = tmp_path / "a dir"
    md = run_report(out, random_state=5, quick=True, only=["environment"], log=lambda s: None).read_text()
    line = re.search(r"Written by `([^`]+)`", md).group(1)
    args = _parsed(line)
    assert (args.seed, args.quick, args.full, args.out, args.only) == (
        5,
        True,
        False,
        str(out),
        "environment",
    )


def test_no_study_writes_its_own_report_command():
    package = Path(tactile_torch.studies.__file__).parent
    by_hand = [
        path.name
        for path in package.glob("*.py")
        if path.name != "_reproduce.py"
        and re.search(r"[\"']tactile-torch report -", path.read_text())  # a string literal
    ]
    assert by_hand == []
