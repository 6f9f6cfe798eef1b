"""The class tree of :class:`~tactile_torch.svm.HierarchicalSVC`: 2-means splits of the class means.

The class mean vectors are split in two groups by 2-means (:func:`split_classes`); each group is split
again until every leaf holds one class (:func:`build_tree`). The tree depends on the class means
only, so a grid search builds it once per training fold and reuses it for every C and gamma. The
2-means iterations are compiled (numba), so importing this module compiles them (or loads them
from the on-disk cache).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, types

from ..validation import RandomState, numpy_rng

if TYPE_CHECKING:  # the base class, not estimators.SVC: estimators imports this module
    from ._base import _KernelMachine


def split_classes(means: np.ndarray, *, n_init: int = 10, random_state: RandomState = None) -> np.ndarray:
    """Return a boolean mask splitting class mean vectors into two groups by 2-means.

    k-means++ seeding and Lloyd iterations, restarted ``n_init`` times; the split with the smallest
    within-group sum of squares wins. Neither group is ever empty: seeds are two distinct means,
    and should a Lloyd step empty a group, the mean farthest from the other group's centre moves
    into it. If every mean is the same point, the classes are split in two halves in their order.

    Parameters
    ----------
    means : array of shape (K, F), K >= 2
    n_init : int
        Restarts.
    random_state : int, numpy or torch Generator, or None

    Returns
    -------
    bool array of shape (K,): True for the second group. With two classes, ``[False, True]``.

    Examples
    --------
    >>> split_classes(np.array([[0.0], [0.1], [5.0], [5.2]]), random_state=0).tolist()
    [False, False, True, True]
    """
    means = np.ascontiguousarray(means, dtype=np.float64)
    k = means.shape[0]
    if k == 2:
        return np.array([False, True])
    rng = numpy_rng(random_state)
    group = np.zeros(k, dtype=bool)
    if not _best_split(means, rng.integers(k, size=n_init), rng.random(n_init), group):
        return np.arange(k) >= k // 2  # every mean is the same point
    return group


@njit(
    types.Tuple((types.Array(types.boolean, 1, "C"), types.float64))(
        types.Array(types.float64, 2, "C", readonly=True), types.int64, types.float64
    ),
    cache=True,
)
def _two_means(means, first, u):
    """One 2-means run seeded by k-means++ (``first``, then the mean drawn by the uniform ``u`` with
    probability proportional to its squared distance from it); return ``(group, inertia)``, the
    inertia -1 when every mean is the same point. Compiled: the splits of a tree are thousands of
    operations on a few dozen points, which NumPy's per-call overhead made most of a fit."""
    k, n_feat = means.shape
    d2 = np.empty(k)
    for c in range(k):
        d2[c] = np.sum((means[c] - means[first]) ** 2)
    total = d2.sum()
    group = np.zeros(k, dtype=np.bool_)
    if total == 0.0:
        return group, -1.0
    cdf = np.cumsum(d2 / total)
    second = min(int(np.searchsorted(cdf / cdf[-1], u, side="right")), k - 1)
    centres = np.empty((2, n_feat))
    centres[0], centres[1] = means[first], means[second]
    dist = np.empty((k, 2))
    for _ in range(100):
        for c in range(k):
            for g in range(2):
                dist[c, g] = np.sum((means[c] - centres[g]) ** 2)
            group[c] = dist[c, 1] < dist[c, 0]
        n_second = group.sum()
        if n_second == 0 or n_second == k:  # a group lost every member
            empty = 1 if n_second == 0 else 0
            group[np.argmax(dist[:, 1 - empty])] = empty == 1
        new = np.zeros((2, n_feat))
        sizes = np.zeros(2)
        for c in range(k):
            new[int(group[c])] += means[c]
            sizes[int(group[c])] += 1.0
        new[0] /= sizes[0]
        new[1] /= sizes[1]
        if np.array_equal(new, centres):
            break
        centres = new
    inertia = 0.0
    for c in range(k):
        inertia += np.sum((means[c] - centres[int(group[c])]) ** 2)
    return group, inertia


@njit(
    types.boolean(
        types.Array(types.float64, 2, "C", readonly=True),
        types.Array(types.int64, 1, "C", readonly=True),
        types.Array(types.float64, 1, "C", readonly=True),
        types.Array(types.boolean, 1, "C"),
    ),
    cache=True,
)
def _best_split(means, firsts, uniforms, best):
    """Write into ``best`` the restart of :func:`_two_means` with the lowest inertia (oriented so
    that the first class is in the negative group); return False if every mean is the same point."""
    best_inertia = np.inf
    for r in range(firsts.shape[0]):
        group, inertia = _two_means(means, firsts[r], uniforms[r])
        if inertia < 0.0:
            return False
        if inertia < best_inertia - 1e-12:
            flip = group[0]
            for c in range(group.shape[0]):
                best[c] = group[c] != flip
            best_inertia = inertia
    return True


@dataclass
class TreeNode:
    """One node of a :class:`HierarchicalSVC` tree.

    Attributes
    ----------
    index : int
        Node number (preorder; the root is 0).
    classes : tuple
        Class labels under this node.
    depth : int
    n_samples : int
        Training samples of those classes.
    svc : SVC or None
        The binary :class:`~tactile_torch.svm.SVC` of an internal node (``f > 0``: go to ``right``);
        None for a leaf.
    left, right : TreeNode or None
        Children on the negative and positive side.
    column : int
        Column of this node in ``HierarchicalSVC.node_decision_function`` (-1 for a leaf).
    members : ndarray or None
        Indices of ``classes`` in the estimator's ``classes_``.
    """

    index: int
    classes: tuple
    depth: int
    n_samples: int
    svc: _KernelMachine | None = None
    left: TreeNode | None = None
    right: TreeNode | None = None
    column: int = -1
    members: np.ndarray | None = None

    @property
    def is_leaf(self) -> bool:
        return self.left is None

    def copy(self) -> TreeNode:
        """Return a copy of the subtree's structure, without fitted SVMs."""
        twin = TreeNode(self.index, self.classes, self.depth, self.n_samples, members=self.members)
        if not self.is_leaf:
            twin.left, twin.right = self.left.copy(), self.right.copy()
        return twin

    def nodes(self) -> list[TreeNode]:
        """Return this node and every node below it, in preorder."""
        out = [self]
        for child in (self.left, self.right):
            if child is not None:
                out += child.nodes()
        return out

    def describe(self, indent: str = "", sign: str = "") -> str:
        """Return the subtree as indented text: ``-`` marks the negative side, ``+`` the positive."""
        names = ", ".join(str(c) for c in self.classes)
        if self.is_leaf:
            return f"{indent}{sign}leaf {self.index}: {names} ({self.n_samples} samples)"
        svc = self.svc
        line = (
            f"{indent}{sign}node {self.index}: {{{names}}} ({self.n_samples} samples, "
            f"{svc.support_.shape[0]} support vectors, {int(svc.n_iter_[0])} SMO iterations)"
        )
        inner = indent + ("   " if sign else "")
        return "\n".join([line, self.left.describe(inner, "- "), self.right.describe(inner, "+ ")])

    def __str__(self) -> str:
        return self.describe()


def build_tree(
    classes: np.ndarray, means: np.ndarray, counts: np.ndarray, *, n_init: int, random_state: RandomState
) -> TreeNode:
    """Return the root of the class tree (nodes numbered in preorder, no SVMs fitted yet).

    Parameters
    ----------
    classes : array of shape (K,)
        Class labels.
    means : array of shape (K, F)
        Mean feature vector of each class.
    counts : array of shape (K,)
        Training samples of each class.
    n_init : int
        Restarts of each 2-means split.
    random_state : int, numpy or torch Generator, or None
        Seeds the splits, which draw from it in preorder.
    """
    rng = numpy_rng(random_state)
    counter = iter(range(2 * len(classes)))

    def grow(members: np.ndarray, depth: int) -> TreeNode:
        node = TreeNode(next(counter), tuple(classes[members].tolist()), depth, int(counts[members].sum()))
        node.members = members
        if members.shape[0] > 1:
            positive = split_classes(means[members], n_init=n_init, random_state=rng)
            node.left = grow(members[~positive], depth + 1)
            node.right = grow(members[positive], depth + 1)
        return node

    return grow(np.arange(len(classes)), 0)


__all__ = ["TreeNode", "build_tree", "split_classes"]
