"""tactile_torch.signal under torch's transforms: torch.func.vmap, torch.jit.trace (no warning of
ours), torch.compile(fullgraph=True); each gives the eager results."""

from __future__ import annotations

import pytest
import torch

from tactile_torch.signal import clustering_features, window_features

JIT_DEPRECATION = "ignore:`torch.jit.trace` is deprecated"  # torch's own, on every trace


def windows(batch: int, width: int = 200, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return torch.randn(batch, 3, width, generator=g, dtype=torch.float64)


def chain(x: torch.Tensor) -> torch.Tensor:
    return clustering_features(window_features(x))


@pytest.mark.filterwarnings("error")
def test_vmap_gives_the_per_call_results():
    stacked = torch.stack([windows(4, seed=s) for s in range(3)])
    for fn in (window_features, chain):
        torch.testing.assert_close(torch.vmap(fn)(stacked), torch.stack([fn(x) for x in stacked]))


@pytest.mark.filterwarnings(JIT_DEPRECATION)
@pytest.mark.filterwarnings("error")
def test_jit_trace_is_quiet_and_replays_at_other_batch_sizes():
    traced = torch.jit.trace(chain, (windows(4),))
    x = windows(9, seed=1)
    torch.testing.assert_close(traced(x), chain(x))
    with pytest.raises(RuntimeError):  # the window length is the trace's
        traced(windows(2, width=300))


@pytest.mark.filterwarnings("error")
def test_compile_fullgraph_has_no_graph_break():
    # backend="eager": dynamo's tracing alone (where a graph break fails fullgraph=True)
    x = windows(5)
    torch.testing.assert_close(torch.compile(chain, fullgraph=True, backend="eager")(x), chain(x))


@pytest.mark.slow
def test_compile_fullgraph_with_inductor_gives_the_eager_results():  # about a minute
    compiled = torch.compile(chain, fullgraph=True)
    for batch in (5, 8):
        x = windows(batch, seed=batch)
        torch.testing.assert_close(compiled(x), chain(x), rtol=1e-9, atol=1e-9)
