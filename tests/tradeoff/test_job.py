"""The trade-off's options and their defaults (tactile_torch.tradeoff.job), read by the library and the
command line: one set of defaults, checked once, and the reproduce line built from them."""

from __future__ import annotations

import inspect

import pytest

from tactile_torch.cli import build_parser
from tactile_torch.cli.tradeoff import reproduce_line, tradeoff_options
from tactile_torch.tradeoff.job import TradeoffOptions
from tactile_torch.tradeoff.runner import plan_tradeoff


def test_the_defaults_are_the_library_defaults():
    keywords = TradeoffOptions().run_keywords()
    signature = inspect.signature(plan_tradeoff).parameters
    shared = [name for name in keywords if name in signature]
    assert len(shared) >= 15
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
