"""The roadmap's sparse-graph tools: one integer key per node pair, component labels that join as edges come, and
shortest-path trees that know which nodes lost their tree path (app.planning.roadmap's search)."""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components


class SearchTree:
    """A shortest-path tree (scipy's predecessors) that knows which nodes' tree paths lost an edge."""

    def __init__(self, pred: np.ndarray):
        self.pred = pred
        # Each node's children, kids[first[v]:first[v + 1]] (the root and nodes off the tree have parent n): a cut
        # marks the subtree below it in one compiled walk.
        parent = np.where(pred >= 0, pred, len(pred))
        self._kids = np.argsort(parent, kind="stable")
        self._first = np.searchsorted(parent, np.arange(len(pred) + 1), sorter=self._kids)
        self.dead = np.zeros(len(pred), bool)  # a node's tree path to the root has lost an edge

    def cut(self, P: np.ndarray) -> None:
        """The edges P (node index pairs) are gone: every node below one that is a tree edge has lost its tree path."""
        from app.checking import kernels

        kernels.cut_tree(P, self.pred, self._first, self._kids, self.dead)


def pair_key(a, b):
    """One integer for the unordered node pair (a, b), of ints or int arrays: the smaller in the high bits."""
    if isinstance(a, np.ndarray):
        return np.minimum(a, b).astype(np.int64) << 32 | np.maximum(a, b)
    a, b = int(a), int(b)
    return min(a, b) << 32 | max(a, b)


def labels_by_least(groups: np.ndarray) -> np.ndarray:
    """Per node, the least node of its group (groups: a non-negative int per node): component labels as `joined_labels`
    keeps them."""
    least = np.full(int(groups.max()) + 1 if len(groups) else 0, len(groups))
    np.minimum.at(least, groups, np.arange(len(groups)))
    return least[groups]


def joined_labels(labels: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Component labels (one per node, each the index of one of its component's nodes) after the edges P (node
    index pairs) join their components: each joined group under the least of its labels."""
    if not len(P):
        return labels
    values, inverse = np.unique(labels[P], return_inverse=True)
    inverse = inverse.reshape(P.shape)
    joins = csr_matrix((np.ones(len(P), bool), (inverse[:, 0], inverse[:, 1])), shape=(len(values),) * 2)
    count, group = connected_components(joins, directed=False)
    least = np.full(count, len(labels))
    np.minimum.at(least, group, values)
    if (least[group] == values).all():
        return labels
    relabel = np.arange(len(labels))
    relabel[values] = least[group]
    return relabel[labels]
