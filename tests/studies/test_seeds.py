"""The report's one seed derivation: ``--seed`` reaches every draw; the same seed gives the same report."""

import json
import re
import shlex

import numpy as np
import pytest
import torch

from tactile_torch.cli import build_parser
from tactile_torch.studies import RunContext, run_report
from tactile_torch.studies._seeds import study_seed


def test_study_seed_is_a_function_of_root_study_and_purpose():
    seed = study_seed(0, "claims", "hard image set")
    assert seed == study_seed(0, "claims", "hard image set")
    others = {
        study_seed(1, "claims", "hard image set"),
        study_seed(0, "clustering", "hard image set"),
        study_seed(0, "claims", "hard stylus set"),
    }
    assert seed not in others and len(others) == 3
    seeds = [study_seed(root, "s", str(k)) for root in (0, 7, 2**40) for k in range(50)]
    assert all(0 <= s < 2**31 for s in seeds)  # scikit-learn's RandomState takes < 2**32
    assert len(set(seeds)) == len(seeds)


def test_run_context_seed_is_study_seed():
    ctx = RunContext(random_state=5)
    assert ctx.seed("image_features", "bundled explorations") == study_seed(
        5, "image_features", "bundled explorations"
    )


def test_bundled_data_follow_the_report_seed():
    from tactile_torch.studies import image_features, vibration_features

    def data(seed):
        ctx = RunContext(random_state=seed, quick=True)
        return image_features.dataset(ctx).frames, vibration_features.bundled_recordings(ctx).signals[0]

    (frames_a, signal_a), (frames_b, signal_b), (frames_c, signal_c) = data(3), data(3), data(4)
    assert torch.equal(frames_a, frames_b) and np.array_equal(signal_a, signal_b)
    assert not torch.equal(frames_a, frames_c)
    assert not np.array_equal(signal_a, signal_c)


@pytest.mark.parametrize("seed", [-1, 1.5, True])
def test_run_report_rejects_a_seed_that_is_not_a_non_negative_int(tmp_path, seed):
    with pytest.raises(ValueError, match="random_state must be a non-negative int"):
        run_report(tmp_path, random_state=seed, only=["environment"], log=lambda s: None)


# Columns that measure time or memory: they differ between two runs of the same seed.
_MEASURED = re.compile(r"second|\(ms\)|\(s\)|\bs\b|time|latency|memory|mib|kib|speed", re.IGNORECASE)


def _numbers(path) -> dict:
    """The tables of a report.json without its timing columns, by section title and caption."""
    data = json.loads((path.parent / "report.json").read_text())
    out = {}
    for section in data["sections"]:
        for k, table in enumerate(section["tables"]):
            keep = [c for c in table["columns"] if not _MEASURED.search(c)]
            out[section["title"], table["caption"] or k] = [
                [row.get(c) for c in keep] for row in table["rows"]
            ]
    return out


@pytest.mark.slow
def test_report_sections_differ_between_seeds_and_repeat_at_one_seed(tmp_path):
    only = ["image_features", "image_classification", "vibration_classification", "clustering", "claims"]
    paths = {
        name: run_report(tmp_path / name, random_state=seed, quick=True, only=only, log=lambda s: None)
        for name, seed in (("a", 11), ("b", 11), ("c", 12))
    }
    runs = {name: _numbers(path) for name, path in paths.items()}
    lines = re.findall(r"Reproduce with:\n\n```\n(.+)\n```", paths["c"].read_text())
    assert len(lines) >= len(only)
    for line in lines:  # every reproduce line carries this run's options
        args = build_parser().parse_args(shlex.split(line)[1:])
        assert (args.seed, args.quick, args.full, args.out) == (12, True, False, str(tmp_path / "c"))
    assert runs["a"] == runs["b"]
    titles = {title for title, _ in runs["a"]}
    assert len(titles) == len(only)
    for title in titles:  # every section moves with the seed
        keys = [key for key in runs["a"] if key[0] == title]
        assert any(runs["a"][key] != runs["c"][key] for key in keys), title
