"""``python -m tactile_torch.studies.novelty``: its command line (the rules themselves: tests/mixture/test_novelty.py)."""

from __future__ import annotations

import pytest

from tactile_torch.studies import novelty


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--only", "bundled", "nowhere"], "'nowhere'"),
        (["--rules", "new component", "coin toss"], "'coin toss'"),
    ],
)
def test_the_command_refuses_an_unknown_source_or_rule_in_one_line(argv, named, capsys):
    # refused before any data is read or model fitted (it printed nothing, or failed minutes later)
    with pytest.raises(SystemExit) as exit_info:
        novelty._main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"{argv[0]}: unknown {named}; expected some of " in err


def test_every_listed_source_has_withheld_sets():
    assert novelty.SOURCES[0] == "bundled" and "bundled-new-session" in novelty.SOURCES
    for name in novelty.SOURCES:
        assert novelty.withheld_sets(name, [0, 1, 2])  # each source withholds something
