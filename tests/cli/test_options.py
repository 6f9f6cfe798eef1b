"""Every numeric option of every command is checked by its parser: a value that is not a number, NaN or
out of range is one line naming the option, status 2, before any work (issue 34: ``--gamma abc``)."""

import argparse

import pytest

from tactile_torch.cli import BAD_INPUT_EXIT, build_parser
from tactile_torch.cli._options import Number, window_list


def _options():
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    for command, sub in commands.items():
        for action in sub._actions:
            if action.option_strings and action.nargs != 0 and action.dest != "help":
                yield command, action


OPTIONS = list(_options())
NUMERIC = [(c, a) for c, a in OPTIONS if isinstance(a.type, Number) or a.type is window_list]


def test_no_numeric_option_takes_a_bare_int_or_float():
    """A plain ``type=float`` accepts nan and -1; a numeric default without a checked type is a number
    the handler would parse itself. Both are declared with :class:`~tactile_torch.cli._options.Number`."""
    loose = [
        f"{command} {action.option_strings[-1]}"
        for command, action in OPTIONS
        if action.type in (int, float)
        or (
            isinstance(action.default, int | float)
            and not isinstance(action.default, bool)
            and not isinstance(action.type, Number)
        )
    ]
    assert not loose, loose
    assert len(NUMERIC) > 50  # every command's numbers, the shared data options included


@pytest.mark.parametrize("junk", ["abc", "nan"])
def test_every_numeric_option_names_itself_for_a_value_that_is_no_number(junk, capsys):
    parser = build_parser()
    for command, action in NUMERIC:
        option = action.option_strings[-1]
        with pytest.raises(SystemExit) as stop:
            parser.parse_args([command, option, junk])
        err = capsys.readouterr().err
        assert stop.value.code == BAD_INPUT_EXIT, (command, option)
        names = "/".join(action.option_strings)
        assert (
            err.startswith(f"tactile-torch {command}: argument {names}: expected ") and err.count("\n") == 1
        ), err
        assert err.endswith(f", got '{junk}'\n"), err


def test_bounds_are_checked_and_said():
    parser = build_parser()
    for command, action in NUMERIC:
        number = action.type
        if not isinstance(number, Number) or number.low is None:
            continue
        below = number.low - (1 if number.kind is int or not number.open_low else 0)
        with pytest.raises(SystemExit):
            parser.parse_args([command, action.option_strings[-1], f"{below:g}"])


@pytest.mark.parametrize(
    ("text", "number", "expected"),
    [
        ("3", Number(int, low=1), 3),
        ("1e3", Number(int, low=1), 1000),
        ("scale", Number(low=0, open_low=True, words=("scale",)), "scale"),
        ("inf", Number(low=0, open_low=True, allow_inf=True, unit="g"), float("inf")),
        ("0.5", Number(low=0, high=1, open_high=True), 0.5),
    ],
)
def test_numbers_and_words_pass(text, number, expected):
    assert number(text) == expected


@pytest.mark.parametrize(
    ("text", "number", "message"),
    [
        (
            "abc",
            Number(low=0, open_low=True, words=("scale",)),
            "expected 'scale' or a finite number > 0, got 'abc'",
        ),
        ("1.5", Number(int, low=1), "expected a whole number >= 1, got '1.5'"),
        ("inf", Number(low=0, open_low=True, unit="g"), "expected a finite number of g > 0, got 'inf'"),
        ("1", Number(low=0, high=1, open_high=True), "expected a finite number in [0, 1), got '1'"),
        (
            "-2",
            Number(low=0, open_low=True, allow_inf=True, unit="g"),
            "expected a number of g > 0 (inf: no check), got '-2'",
        ),
    ],
)
def test_refusals_say_what_was_expected(text, number, message):
    with pytest.raises(argparse.ArgumentTypeError) as refused:
        number(text)
    assert str(refused.value) == message


def test_gamma_abc_is_one_line_naming_gamma(capsys):
    from tactile_torch.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["train", "--data", "x.npz", "--gamma", "abc"])
    assert stop.value.code == BAD_INPUT_EXIT
    assert (
        capsys.readouterr().err
        == "tactile-torch train: argument --gamma: expected 'scale' or a finite number > 0, got 'abc'\n"
    )
