"""The torch networks of the neural candidates: raw input → class logits, and their inference graph.

Three networks, one per raw input of the trade-off study (shapes as in docs/formats.md):

* :class:`WindowCNN`: vibration windows ``(B, 3, W)`` in g. Each window's mean is removed per axis
  (gravity and sensor offset), the axes are divided by their standard deviation over the training
  windows, then strided 1-D convolutions (kernel 7, stride 2, ReLU), global average pooling over time
  and a linear layer. Two sizes (:data:`WINDOW_WIDTHS`): ``"small"`` (about 4-5 k parameters with 5-28
  classes) and ``"large"`` (about 90-100 k).
* :class:`TaxelCNN`: raw pressure maps ``(B, T, H, W)``. Every taxel's time series is one input channel
  (``H * W`` channels over ``T`` steps), scaled by the training maps' mean and standard deviation;
  two strided 1-D convolutions over time, global average and maximum pooling, a linear layer.
* :class:`ExplorationCNN`: image explorations ``(B, T, 3, H, W)`` uint8 RGB. What it sees: the
  exploration's **mean and maximum darkness** (``1 - gray``, i.e. pressure on a white display) over its
  ``T`` frames, two channels average-pooled by ``pool`` pixels (so a 96 x 96 display becomes 24 x 24),
  then three 3 x 3 convolutions (8, 16, 32 channels, ReLU, max pooling between them), global average
  pooling and a linear layer. The order of the frames (the motion) is not seen.

:class:`ClassifierGraph` wraps any of them into the exported form: raw input → ``(labels, scores)``
with scores the softmax probabilities (float32), the outputs :class:`tactile_torch.robot.runtime.OnnxPipeline`
reads.

Every network is built by :func:`build` and initialised from an explicit ``torch.Generator`` (uniform
in ``+-1/sqrt(fan_in)``, PyTorch's default bound): torch's global random state is the same after a
build as before it.
"""

from __future__ import annotations

import math

import torch
from torch import nn

WINDOW_WIDTHS = {"small": (12, 16, 16), "large": (32, 64, 64, 96)}
"""Channels of the convolution stages of :class:`WindowCNN` by size."""
WINDOW_KERNEL = 7
TAXEL_WIDTH = 32
IMAGE_WIDTHS = (8, 16, 32)
GRAY_WEIGHTS = (0.2989, 0.5870, 0.1140)


def build(cls: type[nn.Module], *args: object, generator: torch.Generator) -> nn.Module:
    """Return ``cls(*args)`` with every parameter drawn from ``generator``.

    Weights and biases are uniform in ``[-b, b]`` with ``b = 1 / sqrt(fan_in)`` (PyTorch's default
    bound for linear and convolution layers), drawn layer by layer in module order. The layers'
    own default initialisation (which draws from the global generator) runs inside
    ``torch.random.fork_rng``, so the caller's global random state is left as it was.
    """
    with torch.random.fork_rng(devices=[]):
        module = cls(*args)
    for sub in module.modules():
        weight = getattr(sub, "weight", None)
        if not isinstance(weight, nn.Parameter):
            continue
        fan_in = weight[0].numel()
        bound = 1.0 / math.sqrt(fan_in)
        with torch.no_grad():
            weight.copy_((torch.rand(weight.shape, generator=generator) * 2 - 1) * bound)
            if getattr(sub, "bias", None) is not None:
                sub.bias.copy_((torch.rand(sub.bias.shape, generator=generator) * 2 - 1) * bound)
    return module


def count_parameters(module: nn.Module) -> int:
    """Return the number of trainable scalars of ``module``."""
    return int(sum(p.numel() for p in module.parameters() if p.requires_grad))


class WindowCNN(nn.Module):
    """Vibration windows ``(B, 3, W)`` → logits ``(B, C)`` (see the module notes).

    Parameters
    ----------
    n_classes : int
    widths : tuple of int
        Channels of each strided convolution.
    """

    def __init__(self, n_classes: int, widths: tuple[int, ...] = WINDOW_WIDTHS["small"]) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        channels = 3
        for width in widths:
            layers += [
                nn.Conv1d(channels, width, WINDOW_KERNEL, stride=2, padding=WINDOW_KERNEL // 2),
                nn.ReLU(),
            ]
            channels = width
        self.body = nn.Sequential(*layers)
        self.head = nn.Linear(channels, n_classes)
        self.register_buffer("scale", torch.ones(3, 1))  # (3, 1): exported as is, not as a derived constant

    def set_input_scale(self, windows: torch.Tensor) -> None:
        """Take the per-axis standard deviation of the mean-removed training ``windows`` ``(N, 3, W)``."""
        centred = windows - windows.mean(-1, keepdim=True)
        std = centred.transpose(0, 1).reshape(3, -1).std(-1)
        self.scale = torch.where(std > 0, std, torch.ones_like(std)).to(torch.float32)[:, None]

    def embed(self, windows: torch.Tensor) -> torch.Tensor:
        """Return what the last layer classifies, ``(B, widths[-1])``: the pooled convolution channels."""
        x = windows.to(torch.float32)
        x = (x - x.mean(-1, keepdim=True)) / self.scale
        return self.body(x).mean(-1)

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        return self.head(self.embed(windows))


class TaxelCNN(nn.Module):
    """Pressure maps ``(B, T, H, W)`` → logits ``(B, C)``: a temporal CNN with one channel per taxel.

    Parameters
    ----------
    n_classes : int
    n_taxels : int
        ``H * W``.
    width : int
        Channels of both temporal convolutions.
    """

    def __init__(self, n_classes: int, n_taxels: int, width: int = TAXEL_WIDTH) -> None:
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv1d(n_taxels, width, 5, stride=2, padding=2),
            nn.ReLU(),
            nn.Conv1d(width, width, 5, stride=2, padding=2),
            nn.ReLU(),
        )
        self.head = nn.Linear(2 * width, n_classes)
        self.register_buffer("mean", torch.zeros(()))
        self.register_buffer("scale", torch.ones(()))

    def set_input_scale(self, maps: torch.Tensor) -> None:
        """Take the mean and standard deviation of the training ``maps`` ``(N, T, H, W)``."""
        std = maps.to(torch.float32).std()
        self.mean = maps.to(torch.float32).mean()
        self.scale = std if bool(std > 0) else torch.ones(())

    def embed(self, maps: torch.Tensor) -> torch.Tensor:
        """Return what the last layer classifies, ``(B, 2 * width)``: each channel's mean and maximum over time."""
        x = (maps.to(torch.float32) - self.mean) / self.scale
        x = x.flatten(2).transpose(1, 2)  # (B, H * W, T): one channel per taxel
        h = self.body(x)
        return torch.cat([h.mean(-1), h.amax(-1)], dim=1)

    def forward(self, maps: torch.Tensor) -> torch.Tensor:
        return self.head(self.embed(maps))


class ExplorationCNN(nn.Module):
    """RGB explorations ``(B, T, 3, H, W)`` uint8 → logits ``(B, C)`` (see the module notes).

    Parameters
    ----------
    n_classes : int
    pool : int
        Side of the average pooling applied to the mean and maximum darkness images.
    """

    def __init__(self, n_classes: int, pool: int = 4) -> None:
        super().__init__()
        a, b, c = IMAGE_WIDTHS
        self.pool = int(pool)
        self.body = nn.Sequential(
            nn.Conv2d(2, a, 3, padding=1),
            nn.ReLU(),
            nn.MaxPool2d(2, ceil_mode=True),
            nn.Conv2d(a, b, 3, padding=1),
            nn.ReLU(),
            nn.MaxPool2d(2, ceil_mode=True),
            nn.Conv2d(b, c, 3, padding=1),
            nn.ReLU(),
        )
        self.head = nn.Linear(c, n_classes)

    def seen(self, frames: torch.Tensor) -> torch.Tensor:
        """Return what the network sees: ``(B, 2, H', W')`` mean and maximum darkness, pooled."""
        weights = torch.tensor(GRAY_WEIGHTS, dtype=torch.float32).reshape(1, 1, 3, 1, 1) / 255.0
        darkness = 1.0 - (frames.to(torch.float32) * weights).sum(2)  # (B, T, H, W), uint8 frames
        x = torch.stack([darkness.mean(1), darkness.amax(1)], dim=1)
        if self.pool > 1:
            x = nn.functional.avg_pool2d(x, self.pool, ceil_mode=True)
        return x

    def classify(self, seen: torch.Tensor) -> torch.Tensor:
        """Return the logits of what :meth:`seen` returned (the trained part of the network)."""
        return self.head(self.body(seen).mean((-2, -1)))

    def embed(self, frames: torch.Tensor) -> torch.Tensor:
        """Return what the last layer classifies, ``(B, IMAGE_WIDTHS[-1])``: the pooled channels."""
        return self.body(self.seen(frames)).mean((-2, -1))

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        return self.classify(self.seen(frames))


class SeenClassifier(nn.Module):
    """:meth:`ExplorationCNN.classify` as a module (training on inputs ``seen`` once, not every epoch)."""

    def __init__(self, network: ExplorationCNN) -> None:
        super().__init__()
        self.network = network

    def forward(self, seen: torch.Tensor) -> torch.Tensor:
        return self.network.classify(seen)


class ClassifierGraph(nn.Module):
    """Raw input → ``(labels (B,) int64, scores (B, C) float32)``: argmax and softmax of ``network``'s logits.

    :meth:`embed` and :meth:`classify` split it where the last layer starts (``forward(raw) ==
    classify(embed(raw))``), so that a graph can measure something on the embedding too (the "unknown"
    rule's distance) without computing the network twice.
    """

    def __init__(self, network: nn.Module) -> None:
        super().__init__()
        self.network = network

    def embed(self, raw: torch.Tensor) -> torch.Tensor:
        """Return the network's embedding ``(B, E)`` of ``raw``: the input of its last (linear) layer."""
        return self.network.embed(raw)

    def classify(self, embedding: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Return ``(labels, scores)`` of an embedding (the last layer, then softmax)."""
        scores = torch.softmax(self.network.head(embedding), dim=-1)
        return scores.argmax(-1), scores

    def forward(self, raw: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        scores = torch.softmax(self.network(raw), dim=-1)
        return scores.argmax(-1), scores


__all__ = [
    "IMAGE_WIDTHS",
    "WINDOW_WIDTHS",
    "ClassifierGraph",
    "ExplorationCNN",
    "SeenClassifier",
    "TaxelCNN",
    "WindowCNN",
    "build",
    "count_parameters",
]
