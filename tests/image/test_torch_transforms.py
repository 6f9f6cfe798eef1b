"""tactile_torch.image under torch's transforms: torch.func.vmap, torch.jit.trace (no warning of
ours), torch.compile(fullgraph=True); each gives the eager results."""

from __future__ import annotations

import warnings

import pytest
import torch

from tactile_torch import image

JIT_DEPRECATION = "ignore:`torch.jit.trace` is deprecated"  # torch's own, on every trace


def pressed_frames(batch: int, n_frames: int, height: int, width: int, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    frames = torch.full((batch, n_frames, 3, height, width), 255, dtype=torch.uint8)
    inside = (batch, n_frames, 3, height - 7, width - 7)
    frames[..., 3 : height - 4, 2 : width - 5] = torch.randint(0, 200, inside, dtype=torch.uint8, generator=g)
    return frames


CASES = {
    "hard uint8": lambda x: image.exploration_features(x, erosion=3),
    "hard float, per frame": lambda x: image.exploration_features(x.float() / 255, erosion=3, fuse=False),
    "soft": lambda x: image.exploration_features(x.double() / 255, erosion=3, temperature=0.05),
}


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("case", sorted(CASES))
def test_vmap_gives_the_per_call_results(case):
    fn = CASES[case]
    stacked = torch.stack([pressed_frames(2, 3, 16, 16, seed=s) for s in range(3)])  # (3, 2, 3, 3, 16, 16)
    got = torch.vmap(fn)(stacked)
    torch.testing.assert_close(got, torch.stack([fn(x) for x in stacked]), rtol=1e-6, atol=1e-6)


def test_vmap_runs_the_soft_pipeline_per_sample_with_its_own_threshold():
    frames = pressed_frames(3, 2, 12, 12).double() / 255
    thresholds = torch.tensor([0.5, 0.7, 0.9], dtype=torch.float64)

    def one(x, t):  # a single exploration, its own threshold tensor
        return image.exploration_features(x[None], threshold=t, erosion=2, temperature=0.05)[0]

    got = torch.vmap(one)(frames, thresholds)
    want = torch.stack([one(x, t) for x, t in zip(frames, thresholds, strict=True)])
    torch.testing.assert_close(got, want)


@pytest.mark.filterwarnings(JIT_DEPRECATION)
@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("case", sorted(CASES))
def test_jit_trace_is_quiet_and_replays_at_other_batch_sizes_and_frame_counts(case):
    fn = CASES[case]
    traced = torch.jit.trace(fn, (pressed_frames(2, 3, 16, 16),))
    for shape in ((5, 3, 16, 16), (1, 6, 16, 16)):
        x = pressed_frames(*shape, seed=1)
        torch.testing.assert_close(traced(x), fn(x), rtol=1e-6, atol=1e-6)
    with pytest.raises(RuntimeError, match="expanded size"):  # the frame size is the trace's
        traced(pressed_frames(2, 3, 20, 24))


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("case", ["hard uint8", "soft"])
def test_compile_fullgraph_has_no_graph_break(case):
    # backend="eager": dynamo's tracing alone, which is where a graph break would fail fullgraph=True
    # (a few seconds); the compiled kernels are the slow test below
    x = pressed_frames(2, 2, 12, 12)
    compiled = torch.compile(CASES[case], fullgraph=True, backend="eager")
    torch.testing.assert_close(compiled(x), CASES[case](x), rtol=1e-6, atol=1e-6)


_INDUCTOR_BUG = (
    "torch 2.13's inductor fails on the hard per-frame path (erosion, edges and the statistics fused: "
    "InductorError 'vr must not be None for symbol q1', also with dynamic=False; each step compiles "
    "alone): docs/image.md says so; dynamo itself has no graph break (the eager-backend test)"
)


@pytest.mark.slow
@pytest.mark.parametrize(
    "case",
    [
        pytest.param(case, marks=pytest.mark.xfail(strict=True, reason=_INDUCTOR_BUG))
        if case == "hard float, per frame"
        else case
        for case in sorted(CASES)
    ],
)
def test_compile_fullgraph_with_inductor_gives_the_eager_results(case):  # 1-8 min per case
    fn = CASES[case]
    compiled = torch.compile(fn, fullgraph=True)
    for shape in ((2, 3, 16, 16), (4, 3, 16, 16)):
        x = pressed_frames(*shape)
        torch.testing.assert_close(compiled(x), fn(x), rtol=1e-5, atol=1e-5)


def test_value_checks_are_skipped_under_vmap_and_kept_in_eager_mode():
    bad = torch.full((1, 1, 1, 3, 8, 8), float("nan"))
    with pytest.raises(ValueError, match="frames must be finite"):
        image.exploration_features(bad[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = torch.vmap(lambda x: image.exploration_features(x, erosion=2, temperature=0.1))(bad)
    assert out.shape == (1, 1, 12)  # documented: not checked, the features are undefined (check first)
