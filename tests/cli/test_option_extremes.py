"""Every numeric option of every command with a negative, a zero and a huge value: one line, or a value it takes.

Issue 41: ``tradeoff --erosion -1`` was accepted by the parser and failed 5 s later inside scikit-learn
(``InvalidParameterError``, a regression from one line). Every numeric option now declares its lower
bound, and a number without a declared upper bound is at most ``INT_CAP`` or ``FLOAT_CAP``: -1, 0 and
1e300 are refused by the parser in one line naming the option, or are values the option documents.
The values that pass and reach a C library (onnxruntime's threads, the serial port, DDS's queue) are
run once through ``stream`` too. Torch-free.
"""

from __future__ import annotations

import argparse
import math

import pytest

from tactile_torch.cli import BAD_INPUT_EXIT, STREAM_NO_DATA_EXIT, build_parser, main
from tactile_torch.cli._options import CPUS, FLOAT_CAP, INT_CAP, Number
from tests.cli.test_options import NUMERIC
from tests.stream_helpers import energy_bundle

EXTREMES = ("-1", "0", "1e300")
ANY_LEVEL = {("predict", "--onset"), ("predict", "--release"), ("stream", "--onset"), ("stream", "--release")}
"""Options that take any finite number: a touch level at or below 0 makes every frame a touch (legal)."""


def test_every_numeric_option_declares_its_lower_bound():
    loose = [
        f"{command} {action.option_strings[-1]}"
        for command, action in NUMERIC
        if isinstance(action.type, Number)
        and action.type.low is None
        and (command, action.option_strings[-1]) not in ANY_LEVEL
    ]
    assert not loose, loose


def test_negative_zero_and_huge_values_are_refused_in_one_line_or_taken_as_declared(capsys):
    parser = build_parser()
    for command, action in NUMERIC:
        option, number = action.option_strings[-1], action.type
        for text in EXTREMES:
            try:
                value = number(text)  # what the parser does with it
            except argparse.ArgumentTypeError:  # refused: by the parser, in one line naming the option
                with pytest.raises(SystemExit) as stop:
                    parser.parse_args([command, f"{option}={text}"])
                err = capsys.readouterr().err
                assert stop.value.code == BAD_INPUT_EXIT and err.count("\n") == 1, (
                    command,
                    option,
                    text,
                    err,
                )
                assert f"argument {'/'.join(action.option_strings)}: expected" in err, (
                    command,
                    option,
                    text,
                    err,
                )
                continue
            if not isinstance(number, Number) or isinstance(value, str):
                continue
            if number.low is not None:
                assert value > number.low if number.open_low else value >= number.low, (command, option, text)
            high = number.high if number.high is not None else (INT_CAP if number.kind is int else FLOAT_CAP)
            assert value <= high or (number.allow_inf and value == math.inf), (command, option, text)


def test_erosion_minus_one_is_one_line_before_any_work(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["tradeoff", "--data", "missing.npz", "--erosion", "-1"])
    assert stop.value.code == BAD_INPUT_EXIT
    assert capsys.readouterr().err == (
        "tactile-torch tradeoff: argument --erosion: expected 'relative' or a whole number in [1, 4096], got '-1'\n"
    )


@pytest.mark.parametrize(
    "extreme",
    [
        ("--threads", str(CPUS)),
        ("--threads", "0"),
        ("--vote", str(INT_CAP)),
        ("--step", str(INT_CAP)),
        ("--silence", "1e12"),
        ("--max-results", str(INT_CAP)),
        ("--discover", "0"),
        ("--baud", str(INT_CAP)),
    ],
)
def test_the_largest_and_smallest_values_the_stream_takes_run(tmp_path, capsys, extreme):
    bundle = energy_bundle(tmp_path / "e.onnx", window=16)
    status = main(["stream", "--model", str(bundle), "--port", "loop://", "--start-timeout", "0.3", *extreme])
    err = capsys.readouterr().err
    assert status in (STREAM_NO_DATA_EXIT, BAD_INPUT_EXIT), err
    assert "internal error" not in err and "Traceback" not in err
