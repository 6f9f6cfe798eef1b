"""Per-stage times of the method-1 features, this checkout against an earlier revision (one thread).

    python bench/image_stages.py --before 4cc95be

Loads ``tactile_torch/image.py`` of ``--before`` (``git show``; a revision from before the module became
the ``tactile_torch/image/`` package) next to the current package and times, per
100-frame exploration, each hard-mode stage alone (CPU time, fastest of 7) on one block of the current
code (``CHUNK_PIXELS`` pixels of one exploration), the statistics of 8 fused images, and the whole call (wall time, fastest of 5) at one
thread and at the default thread count. Prints a Markdown table. Not part of ``make bench`` (it needs
git and an older revision); docs/image.md quotes its output.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
import types
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.common import DEFAULT_THREADS, source_at, threads  # noqa: E402
from tactile_torch import image  # noqa: E402
from tactile_torch.data.images import make_explorations  # noqa: E402
from tactile_torch.image import _kernels, _scheduler  # noqa: E402

# The current code under the names the single-module revisions used.
after = types.SimpleNamespace(
    **vars(_kernels),
    _pressed=_scheduler.pressed,
    exploration_features=image.exploration_features,
    CHUNK_PIXELS=image.CHUNK_PIXELS,
)


def _load(revision: str):
    source = source_at(revision, "tactile_torch/image.py")
    path = Path(tempfile.mkdtemp()) / "image_before.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("tactile_torch._image_before", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _best(fn, repeat: int, clock) -> float:
    fn()
    times = []
    for _ in range(repeat):
        start = clock()
        fn()
        times.append(clock() - start)
    return min(times)


def _stages(module, frames: torch.Tensor, new: bool) -> dict:
    """Stage callables of ``module`` on ``frames`` (the current code's block path or the old chunk path)."""
    threshold = torch.tensor(240 / 255)
    if new:
        mask = module._pressed(frames, threshold, torch.float32, None)
        pressed = lambda: module._pressed(frames, threshold, torch.float32, None)  # noqa: E731
    else:
        mask = module._pressure(module._gray(frames, torch.float32), threshold, None)
        pressed = lambda: module._pressure(module._gray(frames, torch.float32), threshold, None)  # noqa: E731
    eroded = module._erode(mask, 10, None)
    edges = module._edges(eroded, 0.5, None, ring=True) if new else module._edges(eroded, 0.5, None)
    return {
        "grayscale + threshold": pressed,
        "erosion (10 x 10)": lambda: module._erode(mask, 10, None),
        "Sobel edges": (lambda: module._edges(eroded, 0.5, None, ring=True))
        if new
        else (lambda: module._edges(eroded, 0.5, None)),
        "OR over frames": lambda: module._or_accumulate(None, edges, False),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default="4cc95be", help="git revision to compare with")
    before = _load(parser.parse_args().before)
    rows: dict[str, list[float]] = {}
    for size in (96, 192):
        data = make_explorations(2, n_frames=100, frame_size=size, random_state=0).frames
        frames = data[torch.arange(8) % len(data)].contiguous()
        block = frames[:1, : after.CHUNK_PIXELS // size**2]  # one block of the current code
        scale = 100 / block.shape[1]  # → per 100-frame exploration
        with threads(1):
            old_stages = _stages(before, block, new=False)
            new_stages = _stages(after, block, new=True)
            for name in old_stages:
                rows.setdefault(name, []).extend(
                    1e3 * scale * _best(s[name], 7, time.thread_time) for s in (old_stages, new_stages)
                )
            fused = (
                torch.rand(len(frames), size, size, generator=torch.Generator().manual_seed(0)) > 0.9
            ).float()
            rows.setdefault("statistics of the fused image", []).extend(
                1e3 * _best(lambda m=m, x=fused: m._image_features(x), 7, time.thread_time) / len(frames)
                for m in (before, after)
            )
        for n in sorted({1, DEFAULT_THREADS}):
            with threads(n):
                rows.setdefault(f"whole call, {n} thread(s), wall", []).extend(
                    1e3
                    * _best(lambda m=m, f=frames: m.exploration_features(f), 5, time.perf_counter)
                    / len(frames)
                    for m in (before, after)
                )
    print("| stage | 96 x 96 before | after | 192 x 192 before | after |")
    print("|---|---|---|---|---|")
    for name, values in rows.items():
        print(f"| {name} | " + " | ".join(f"{v:.2f}" for v in values) + " |")


if __name__ == "__main__":
    main()
