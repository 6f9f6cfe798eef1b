"""The soft parameters of tactile_torch.image as tensors a user trains: gradients reaching each, the
whole-chain gradcheck at the documented temperatures, the soft direction's hard limit, the one-line
warnings of the hard mode and of an erosion that removes every contact."""

from __future__ import annotations

import math
import warnings

import pytest
import torch
import torch.nn.functional as F

from tactile_torch import image
from tactile_torch.data.images import make_explorations

DOCUMENTED_TEMPERATURES = (0.05, 0.1)
"""The temperatures README.md and docs/image.md use (0.05: the README's differentiable variant and the
docs' training example's start; 0.1: the step examples)."""


def soft_frames(seed: int, size: int = 6, *, blob: bool = False) -> torch.Tensor:
    """(1, 2, 3, size, size) float64 frames strictly inside (0, 1) (gradcheck perturbs them)."""
    g = torch.Generator().manual_seed(seed)
    if not blob:
        return 0.3 + 0.4 * torch.rand(1, 2, 3, size, size, generator=g, dtype=torch.float64)
    low = torch.rand(2, 1, 3, 3, generator=g, dtype=torch.float64)
    p = F.interpolate(low, size=(size, size), mode="bilinear", align_corners=False)
    rgb = torch.where(p > 0.5, 0.6 * p, torch.full((), 0.98, dtype=torch.float64))
    return rgb.expand(2, 3, size, size).reshape(1, 2, 3, size, size).clone()


def scalar(value: float) -> torch.Tensor:
    return torch.tensor(value, dtype=torch.float64, requires_grad=True)


# ------------------------------------------------------------------------------ gradients reach each
def test_every_soft_parameter_of_exploration_features_gets_a_gradient():
    frames = soft_frames(0, 8).requires_grad_()
    params = {"threshold": scalar(0.5), "edge_threshold": scalar(0.5), "temperature": scalar(0.05)}
    features = image.exploration_features(frames, erosion=2, **params)
    grads = torch.autograd.grad(features.sum(), [frames, *params.values()])
    for name, grad in zip(["frames", *params], grads, strict=True):
        assert torch.isfinite(grad).all() and grad.abs().sum() > 0, name


def test_step_functions_take_tensor_parameters_with_gradients():
    gray = image.to_grayscale(soft_frames(1, 8))
    threshold, t_mask, t_erode, edge, t_edge = (scalar(v) for v in (0.5, 0.05, 0.05, 0.5, 0.3))
    mask = image.pressure_mask(gray, threshold, temperature=t_mask)
    eroded = image.erode(mask, 3, temperature=t_erode)  # the border padding gives no NaN in d/dt
    edges = image.sobel_edges(eroded, edge, temperature=t_edge)
    magnitude, direction = image.gradient(image.fuse_edges(edges, soft=True), soft=True)
    out = image.gradient_statistics(magnitude).sum() + image.gradient_statistics(direction).sum()
    for grad in torch.autograd.grad(out, [threshold, t_mask, t_erode, edge, t_edge]):
        assert torch.isfinite(grad) and grad != 0


def test_modules_register_soft_parameters_for_an_optimiser():
    module = image.ExplorationFeatures(
        erosion=2,
        threshold=torch.nn.Parameter(torch.tensor(0.5)),
        edge_threshold=torch.nn.Parameter(torch.tensor(0.5)),
        temperature=torch.nn.Parameter(torch.tensor(0.05)),
    )
    assert sorted(n for n, _ in module.named_parameters()) == ["edge_threshold", "temperature", "threshold"]
    module(soft_frames(2, 8).float()).sum().backward()
    assert all(torch.isfinite(p.grad) and p.grad != 0 for p in module.parameters())


# ----------------------------------------------------------------------- gradcheck where docs use it
def _whole_chain(x, threshold, edge_threshold, t):
    return image.exploration_features(
        x, threshold=threshold, erosion=2, edge_threshold=edge_threshold, temperature=t
    )


@pytest.mark.parametrize("temperature", DOCUMENTED_TEMPERATURES)
@pytest.mark.parametrize("blob", [False, True])
def test_whole_chain_gradcheck_at_the_documented_temperatures(temperature, blob):
    # every feature (the direction statistics included), with respect to the frames and to every
    # soft parameter; fast mode checks the Jacobian along random directions (one numerical
    # derivative instead of one per input): the full check is the slow test below
    args = (soft_frames(3, blob=blob).requires_grad_(), scalar(0.5), scalar(0.5), scalar(temperature))
    assert torch.autograd.gradcheck(_whole_chain, args, eps=1e-6, atol=1e-5, rtol=1e-3, fast_mode=True)


@pytest.mark.slow
@pytest.mark.parametrize("temperature", DOCUMENTED_TEMPERATURES)
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("blob", [False, True])
def test_whole_chain_gradcheck_full_jacobian(temperature, seed, blob):  # ~30 s each
    args = (soft_frames(seed, blob=blob).requires_grad_(), scalar(0.5), scalar(0.5), scalar(temperature))
    assert torch.autograd.gradcheck(_whole_chain, args, eps=1e-6, atol=1e-5, rtol=1e-3)


def test_soft_direction_is_atan2_on_binary_images_and_continuous_across_the_cut():
    g = torch.Generator().manual_seed(4)
    binary = (torch.rand(20, 9, 9, generator=g) > 0.5).double()
    hard_m, hard_a = image.gradient(binary)
    soft_m, soft_a = image.gradient(binary, soft=True)
    assert torch.equal(soft_m, hard_m) and torch.equal(soft_a, hard_a)  # the hard limit is exact
    # a vertical step down to the right has gx < 0, gy = 0: atan2's cut, A = pi; tilted by +-1e-9
    # atan2 jumps to about -pi, the soft direction stays at pi
    step = torch.zeros(1, 5, 5, dtype=torch.float64)
    step[..., :, :2] = 1.0
    for tilt in (1e-9, -1e-9):
        tilted = step.clone()
        tilted[..., 1:, :2] += tilt * torch.arange(1, 5, dtype=torch.float64)[:, None]
        _, a = image.gradient(tilted, soft=True)
        assert a[0, 2, 2] == pytest.approx(math.pi, abs=1e-6)


# -------------------------------------------------------------------------- hard mode: one warning
def test_hard_mode_warns_once_when_a_gradient_is_asked_for():
    frames = soft_frames(5, 8).float()
    threshold = torch.tensor(0.5, requires_grad=True)
    with pytest.warns(UserWarning, match=r"^threshold requires gradients, but the hard mode") as record:
        out = image.exploration_features(frames, threshold=threshold, erosion=2)
    assert len(record) == 1 and "\n" not in str(record[0].message) and not out.requires_grad
    assert record[0].filename == __file__  # points at the caller
    with pytest.warns(UserWarning, match=r"^frames and edge_threshold require gradients"):
        image.exploration_features(
            frames.requires_grad_(), erosion=2, edge_threshold=torch.tensor(0.5, requires_grad=True)
        )
    with pytest.warns(UserWarning, match=r"^gray requires gradients"):
        image.pressure_mask(torch.full((1, 1, 2, 2), 0.5, requires_grad=True))
    with pytest.warns(UserWarning, match=r"^edge_threshold requires gradients"):
        image.sobel_edges(torch.zeros(4, 4), torch.tensor(0.5, requires_grad=True))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with torch.no_grad():  # evaluating a trained parameter in the hard mode: nothing to lose
            image.exploration_features(frames, threshold=threshold, erosion=2)
        image.erode(torch.rand(4, 4, requires_grad=True), 2)  # the hard minimum has a gradient


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        (
            {"temperature": torch.ones(2)},
            ValueError,
            r"temperature must be a number or a 0-d tensor, got .* \(2,\)",
        ),
        ({"temperature": torch.tensor(-0.1)}, ValueError, "temperature must be > 0 and finite, got -0.1"),
        ({"temperature": torch.tensor(float("inf"))}, ValueError, "temperature must be > 0 and finite"),
        ({"temperature": torch.tensor(1)}, TypeError, "temperature must have a floating dtype"),
        ({"edge_threshold": torch.tensor(-1.0)}, ValueError, "edge_threshold must be >= 0 and finite"),
        ({"edge_threshold": torch.tensor([0.5])}, ValueError, "edge_threshold must be a number or a 0-d"),
    ],
)
def test_tensor_parameters_are_validated(kwargs, error, match):
    with pytest.raises(error, match=match):
        image.exploration_features(torch.zeros(1, 1, 3, 8, 8), **kwargs)


# --------------------------------------------------------------------------- erosion: no silent zeros
def test_erosion_that_removes_every_contact_warns_with_the_size_to_try():
    frames = make_explorations(1, n_frames=6, frame_size=32, random_state=0).frames  # 4 explorations
    with pytest.warns(UserWarning, match=r"erosion=10 removed every pressed region of 4 of the 4") as record:
        zero = image.exploration_features(frames)
    assert len(record) == 1 and record[0].filename == __file__ and zero.abs().max() == 0
    size = int(str(record[0].message).split("try erosion <= ")[1].split(",")[0])
    # the size given is the largest that keeps a contact in every exploration
    kept = image.exploration_features(frames, erosion=size)
    assert (kept.abs().amax(1) > 0).all()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert (image.exploration_features(frames, erosion=size + 1).abs().amax(1) == 0).any()


def test_no_erosion_warning_for_blank_explorations_or_a_few_lost_contacts():
    blank = torch.full((2, 3, 3, 16, 16), 255, dtype=torch.uint8)
    pressed = blank.clone()
    pressed[:, :, :, 2:14, 2:14] = 0  # a 12 x 12 contact survives erosion=10
    light = blank.clone()
    light[0, :, :, 5:8, 5:8] = 0  # one exploration's 3 x 3 touch does not
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert image.exploration_features(blank).abs().max() == 0  # the documented zeros
        image.exploration_features(torch.cat([pressed, pressed, light[:1]]))  # 1 of 3 lost: no warning


# ---------------------------------------------------------------- training end to end, two sources
class _SoftTexture(torch.nn.Module):
    """A user's module as docs/image.md writes it: learnt threshold, edge threshold and temperature."""

    def __init__(self, n_classes: int, erosion: int) -> None:
        super().__init__()
        self.erosion = erosion
        self.threshold = torch.nn.Parameter(torch.tensor(240 / 255))
        self.log_edge_threshold = torch.nn.Parameter(torch.tensor(0.5).log())
        self.log_temperature = torch.nn.Parameter(torch.tensor(0.05).log())
        self.norm = torch.nn.BatchNorm1d(12)
        self.head = torch.nn.Linear(12, n_classes)

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        features = image.exploration_features(
            frames,
            threshold=self.threshold,
            erosion=self.erosion,
            edge_threshold=self.log_edge_threshold.exp(),
            temperature=self.log_temperature.exp(),
        )
        return self.head(self.norm(features))


def _real_or_synthetic_grasps(shared_data):
    """Two grasps of each object of drimus_sdh_tactile (real), or generated explorations when absent."""
    from tactile_torch.data import shared_data_dir
    from tactile_torch.data.grasps import DRIMUS, load_drimus_grasps

    if shared_data_dir(DRIMUS) is not None:
        data = load_drimus_grasps(shared_data(DRIMUS), n_frames=4)
        keep = torch.cat([torch.nonzero(data.labels == c).flatten()[:2] for c in data.labels.unique()])
        return "drimus_sdh_tactile", data.frames[keep], data.labels[keep]
    data = make_explorations(2, n_frames=4, frame_size=24, random_state=1)  # the same code, synthetic
    return "synthetic", data.frames, data.labels


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("source", ["generator", "real"])
def test_adam_trains_every_soft_parameter_end_to_end(source, shared_data):
    if source == "generator":
        data = make_explorations(2, n_frames=4, frame_size=24, random_state=0)
        frames, labels = data.frames, data.labels
    else:
        _, frames, labels = _real_or_synthetic_grasps(shared_data)
    torch.manual_seed(0)
    model = _SoftTexture(int(labels.max()) + 1, erosion=2)
    start = {n: p.detach().clone() for n, p in model.named_parameters()}
    optimiser = torch.optim.Adam(model.parameters(), lr=0.05)
    losses = []
    for _ in range(6):
        optimiser.zero_grad()
        loss = torch.nn.functional.cross_entropy(model(frames.float() / 255), labels)
        loss.backward()
        for name in ("threshold", "log_edge_threshold", "log_temperature"):
            grad = getattr(model, name).grad
            assert torch.isfinite(grad) and grad != 0, name
        optimiser.step()
        losses.append(loss.item())
    assert losses[-1] < losses[0]
    for name in ("threshold", "log_edge_threshold", "log_temperature"):
        assert not torch.equal(getattr(model, name).detach(), start[name]), name


@pytest.mark.parametrize(
    ("height", "width", "error", "message"),
    [
        (0, 5, ValueError, "height must be > 0, got 0"),
        (5, -1, ValueError, "width must be > 0, got -1"),
        (5.0, 5, TypeError, "height must be an integer, got 5.0"),
    ],
)
def test_relative_erosion_names_a_bad_frame_size(height, width, error, message):
    with pytest.raises(error, match=f"^{message}$"):
        image.relative_erosion(height, width)
