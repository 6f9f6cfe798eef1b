"""Training of a network by mini-batch gradient descent with early stopping on an inner validation split.

:func:`inner_split` holds out part of the *training* data (grouped when groups are given, so that a
group's samples are all on one side, as in the outer folds); :func:`train_network` minimises a loss
with Adam on the rest, evaluates the held-out loss after every epoch, stops after ``patience`` epochs
without improvement and restores the best weights. Randomness (the split, the order of the mini-batches)
comes from the generators passed in; nothing global is seeded.

The networks are small: on a loaded 2-core machine one training step of the small vibration CNN took
0.23 s with torch's two intra-op threads against 0.013 s on one (load about 6). So the training runs
its torch ops serially in the calling thread (:func:`tactile_torch._parallel.serial_torch_ops_in_this_thread`,
a setting of this thread only; ``torch.set_num_threads`` and other threads are untouched).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import nn

from .._parallel import serial_torch_ops_in_this_thread


def inner_split(
    y: np.ndarray, groups: np.ndarray | None, fraction: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(train, validation)`` indices: about ``fraction`` of every class held out.

    Per class, ``round(fraction * n)`` units (at least one when the class has two or more) are drawn
    without replacement, where a unit is a group (``groups`` given and the class has at least two
    groups) or a sample. Every sample of a drawn group is held out. A class with a single unit stays
    whole in training; the validation set can then be empty (tiny data), which the caller handles.
    """
    held = np.zeros(len(y), dtype=bool)
    for c in np.unique(y):
        members = np.flatnonzero(y == c)
        units = np.unique(groups[members]) if groups is not None else members
        if groups is not None and len(units) < 2:
            units = members
            by_group = False
        else:
            by_group = groups is not None
        if len(units) < 2:
            continue
        n = min(len(units) - 1, max(1, round(fraction * len(units))))
        drawn = rng.choice(units, size=n, replace=False)
        if by_group:
            held |= np.isin(groups, drawn) & (y == c)
        else:
            held[drawn] = True
    return np.flatnonzero(~held), np.flatnonzero(held)


@dataclass
class TrainingLog:
    """What :func:`train_network` did.

    Attributes
    ----------
    epochs : int
        Epochs run.
    best_epoch : int
        Epoch (1-based) whose weights were kept.
    train_loss, validation_loss : list of float
        Per epoch; ``validation_loss`` is empty without a validation set.
    """

    epochs: int = 0
    best_epoch: int = 0
    train_loss: list[float] = field(default_factory=list)
    validation_loss: list[float] = field(default_factory=list)


def _batches(n: int, size: int, generator: torch.Generator) -> list[torch.Tensor]:
    order = torch.randperm(n, generator=generator)
    return list(order.split(size))


def _mean_loss(network: nn.Module, loss_fn: Callable, X: torch.Tensor, y: torch.Tensor, size: int) -> float:
    total = 0.0
    with torch.no_grad():
        for start in range(0, len(X), size):
            out = network(X[start : start + size])
            total += float(loss_fn(out, y[start : start + size])) * len(out)
    return total / len(X)


@serial_torch_ops_in_this_thread()  # a fresh context per call (contextlib's decorator form)
def train_network(  # noqa: PLR0913
    network: nn.Module,
    X: torch.Tensor,
    y: torch.Tensor,
    *,
    validation: tuple[torch.Tensor, torch.Tensor] | None,
    loss_fn: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
    generator: torch.Generator,
    max_epochs: int,
    batch_size: int,
    learning_rate: float,
    weight_decay: float,
    patience: int,
    progress: bool,
    description: str = "training",
) -> TrainingLog:
    """Train ``network`` in place (Adam); return what happened.

    Parameters
    ----------
    network : nn.Module
        Maps a batch of ``X`` to what ``loss_fn`` takes with the labels.
    X, y : tensor
        Training inputs and int64 labels (class indices).
    validation : (X, y) or None
        Held-out data for early stopping; ``None`` (or empty): every epoch runs and the last weights
        are kept.
    loss_fn : callable
        ``loss_fn(network(X_batch), y_batch)`` → scalar.
    generator : torch.Generator
        Orders the mini-batches.
    max_epochs, batch_size, learning_rate, weight_decay, patience
        Usual meanings; training stops after ``patience`` epochs without a lower validation loss.
    progress : bool
        A tqdm bar over the epochs (stderr), with the losses.
    """
    optimiser = torch.optim.Adam(network.parameters(), lr=learning_rate, weight_decay=weight_decay)
    has_validation = validation is not None and len(validation[0]) > 0
    log = TrainingLog()
    best, best_state, waited = float("inf"), None, 0
    epochs = range(max_epochs)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(epochs, desc=description, leave=False, dynamic_ncols=True)
        epochs = bar
    for epoch in epochs:
        network.train()
        total = 0.0
        for index in _batches(len(X), batch_size, generator):
            optimiser.zero_grad()
            loss = loss_fn(network(X[index]), y[index])
            loss.backward()
            optimiser.step()
            total += float(loss.detach()) * len(index)
        network.eval()
        log.train_loss.append(total / len(X))
        log.epochs = epoch + 1
        if not has_validation:
            log.best_epoch = epoch + 1
            continue
        current = _mean_loss(network, loss_fn, *validation, batch_size)
        log.validation_loss.append(current)
        if bar is not None:
            bar.set_postfix(train=f"{log.train_loss[-1]:.3f}", val=f"{current:.3f}")
        if current < best - 1e-6:
            best, waited, log.best_epoch = current, 0, epoch + 1
            best_state = copy.deepcopy(network.state_dict())
        else:
            waited += 1
            if waited >= patience:
                break
    if bar is not None:
        bar.close()
    if best_state is not None:
        network.load_state_dict(best_state)
    network.eval()
    return log


__all__ = ["TrainingLog", "inner_split", "train_network"]
