"""Why tactile-torch does not use kornia: its ops against ours on the method-1 steps (one thread).

    pip install kornia   # not a dependency of tactile-torch
    python bench/kornia_check.py

Compares, on the same inputs and in one process, kornia's grayscale (``rgb_to_grayscale`` with the
study's weights), Sobel (``filters.spatial_gradient``, unnormalised) and erosion
(``morphology.erosion``, flat 10 x 10 square) with the kernels of :mod:`tactile_torch.image`:
agreement with the NumPy/SciPy reference, time (fastest of 5, ms) and, for the erosion under
autograd, the peak memory of one forward and backward pass (each in a fresh process). Prints a
Markdown table; docs/image.md quotes its output. Not part of ``make bench``.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import kornia  # noqa: E402

from bench.common import peak_memory_mib  # noqa: E402
from tactile_torch import image  # noqa: E402
from tactile_torch.data.images import make_explorations  # noqa: E402
from tactile_torch.image import _kernels  # noqa: E402
from tests import reference_image as reference  # noqa: E402

WEIGHTS = torch.tensor(image.GRAY_WEIGHTS)


def _best_ms(fn, repeat: int = 5) -> float:
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * min(times)


def _kornia_sobel(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    g = kornia.filters.spatial_gradient(x.unsqueeze(1), normalized=False)
    return g[:, 0, 0], g[:, 0, 1]


def _erosion_memory(which: str) -> float:
    masks = torch.rand(100, 96, 96, generator=torch.Generator().manual_seed(0)).requires_grad_()
    if which == "ours":
        return peak_memory_mib(lambda: image.erode(masks, 10, temperature=0.05).sum().backward())
    square = torch.ones(10, 10)
    return peak_memory_mib(
        lambda: kornia.morphology.erosion(masks.unsqueeze(1), square, engine=which).sum().backward()
    )


def main() -> None:
    torch.set_num_threads(1)
    rows = []
    # grayscale: every uint8 colour, against the NumPy reference 0.2989 R + 0.5870 G + 0.1140 B
    code = np.arange(1 << 24)
    colours = np.stack([code >> 16, (code >> 8) & 255, code & 255]).astype(np.uint8).reshape(3, 1, -1)
    want = reference.grayscale(colours, np.float32).ravel()
    x = torch.from_numpy(colours).float() / 255
    ours = _kernels._gray(x, torch.float32).numpy().ravel()
    theirs = kornia.color.rgb_to_grayscale(x, rgb_weights=WEIGHTS).numpy().ravel()
    frames = make_explorations(1, n_frames=100, frame_size=96, random_state=0).frames.float() / 255
    rows.append(
        (
            "grayscale, study's weights",
            f"ours {int((ours != want).sum())}, kornia {int((theirs != want).sum())} of 2^24 colours differ "
            "from NumPy in float32",
            _best_ms(lambda: _kernels._gray(frames, torch.float32)),
            _best_ms(lambda: kornia.color.rgb_to_grayscale(frames, rgb_weights=WEIGHTS)),
        )
    )
    # Sobel on binary masks (the hard path) and on float64 images (the soft path)
    masks = (torch.rand(400, 96, 96, generator=torch.Generator().manual_seed(1)) > 0.5).float()
    exact = all(torch.equal(a, b) for a, b in zip(_kernels._sobel(masks), _kornia_sobel(masks), strict=True))
    soft = torch.rand(400, 96, 96, dtype=torch.float64, generator=torch.Generator().manual_seed(2))
    diff = max(
        float((a - b).abs().max()) for a, b in zip(_kernels._sobel(soft), _kornia_sobel(soft), strict=True)
    )
    rows.append(
        (
            "Sobel (gx, gy), 400 masks 96 x 96",
            f"binary masks: {'equal' if exact else 'DIFFERENT'}; float64: max diff {diff:.1e}",
            _best_ms(lambda: _kernels._sobel(masks)),
            _best_ms(lambda: _kornia_sobel(masks)),
        )
    )
    grad = soft[:100].clone().requires_grad_()

    def backward(sobel):
        gx, gy = sobel(grad)
        (gx * gx + gy * gy).sum().backward()

    rows.append(
        (
            "Sobel forward + backward, 100 float64 images",
            "soft path",
            _best_ms(lambda: backward(_kernels._sobel)),
            _best_ms(lambda: backward(_kornia_sobel)),
        )
    )
    # erosion: exact agreement (odd and even squares, scipy's origin), time, memory under autograd
    agree = []
    for k in (2, 3, 4, 10):
        m = (torch.rand(3, 17, 19, generator=torch.Generator().manual_seed(k)) > 0.3).float()
        agree.append(
            torch.equal(image.erode(m, k), kornia.morphology.erosion(m.unsqueeze(1), torch.ones(k, k))[:, 0])
        )
    square = torch.ones(10, 10)
    for engine in ("shift", "unfold"):
        rows.append(
            (
                f"erosion 10 x 10, 400 masks, kornia engine={engine!r}",
                f"k = 2, 3, 4, 10: {'equal' if all(agree) else 'DIFFERENT'} (no soft variant in kornia)",
                _best_ms(lambda: image.erode(masks, 10), repeat=3),
                _best_ms(
                    lambda e=engine: kornia.morphology.erosion(masks.unsqueeze(1), square, engine=e), repeat=3
                ),
            )
        )
    memory = {}
    for which in ("ours", "shift", "unfold"):
        out = subprocess.run(
            [sys.executable, __file__, "--memory", which], capture_output=True, text=True, check=True
        )
        memory[which] = float(out.stdout.strip())
    print("| op | agreement | ours ms | kornia ms | kornia / ours |")
    print("|---|---|---|---|---|")
    for name, agreement, ours_ms, kornia_ms in rows:
        print(f"| {name} | {agreement} | {ours_ms:.1f} | {kornia_ms:.1f} | {kornia_ms / ours_ms:.1f} |")
    print()
    print(
        "Peak memory of one forward + backward erosion (10 x 10) of 100 float32 frames of 96 x 96 "
        f"(3.5 MiB): ours (soft, t = 0.05) {memory['ours']:.0f} MiB, kornia shift {memory['shift']:.0f} MiB, "
        f"kornia unfold {memory['unfold']:.0f} MiB"
    )


if __name__ == "__main__":
    if sys.argv[1:2] == ["--memory"]:
        torch.set_num_threads(1)
        print(_erosion_memory(sys.argv[2]))
    else:
        main()
