"""The probabilistic roadmap: nodes with provenance, k-nearest connections, batched edge checks, search.

Nearest neighbours use the scene's own configuration metric, exactly: coordinates are scaled by their weights, and
every continuous angle becomes a periodic axis of length 2*pi*w in scipy's toroidal k-d tree (`cKDTree(boxsize=...)`;
a box size of 0 leaves an axis flat). The tree's distance is then sqrt(sum (w_i * d_i)^2) with d_i the short way
round on continuous angles -- the very number `ConfigurationSpace.distance` gives -- so no neighbour is missed or
misranked across the +-pi seam (embedding an angle as (w cos, w sin) would rank by chord length instead of arc
length, which is not the metric the edges are checked and weighed in).

Edges are checked by the checker's `edges_free`, coarse-to-fine and batched, at the scene's resolution, in one of two
ways: - eager (a multi-query roadmap, the paper's PRM): every k-nearest edge is checked as nodes are connected (one call
  per chunk of 32 new nodes). A pair is tried at most once, and by default not at all when both nodes already share
  a component (Kavraki's PRM rule: such an edge adds no connectivity, and skipping it saves most checks).
- lazy (a single query; Bohlin and Kavraki's Lazy PRM, ICRA 2000): k-nearest edges go into the graph unchecked, and
  `shortest_path` checks only the edges of the current shortest candidate path, drops those that collide and
  searches again. Most edges of a roadmap are never on a candidate path (`bench plan --roadmap both` and
  `bench jobs` measure the query mode, lazy and stopping when connected, against the full roadmap).
Shortcut smoothing (app/motion/path.py) then recovers the path quality a denser graph would have given.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from app.checking.budget import Stop
from app.checking.protocol import Checker
from app.planning.graph import SearchTree, joined_labels, labels_by_least, pair_key

START, GOAL, UNIFORM, NARROW, WORKSPACE = "start", "goal", "uniform", "narrow", "workspace"

# Candidate paths a lazy search tries per pair of shortest-path trees (see Roadmap.shortest_path).
CANDIDATES = 16
# Query points x tree nodes from which a k-nearest query is spread over the oracle's threads: a smaller one does not
# pay for starting them.
_THREADED_QUERY = 100_000


def prm_star_k(n: int, dim: int) -> int:
    """k-PRM*'s neighbour count, ceil(e (1 + 1/d) ln n) (Karaman and Frazzoli, IJRR 2011): enough for the roadmap
    to stay connected and its paths to converge to optimal as n grows. 17 for 127 nodes in 4 dimensions."""
    return max(1, math.ceil(math.e * (1.0 + 1.0 / dim) * math.log(max(n, 2))))


# ---- the roadmap ----------------------------------------------------------------------------------------------------
class Roadmap:
    """An undirected PRM graph over configurations, each node remembering where it came from (its `kind`)."""

    def __init__(
        self,
        checker: Checker,
        k: int | None = 10,
        resolution: float | None = None,
        skip_connected: bool = True,
        chunk: int = 32,
        lazy: bool = False,
    ):
        if k is not None and k < 1:
            raise ValueError("k must be positive")
        self.checker = checker  # the current query's (a persistent roadmap is handed each query's in turn)
        self.space = checker.space
        self.k = k  # None: k-PRM*'s, growing with the roadmap (`prm_star_k`)
        self.k_used = k or 0
        self.lazy = lazy
        # Kavraki's rule: an edge between two nodes already in one component adds no connectivity, so it is not
        # checked (components are refreshed every `chunk` new nodes, between batched edge checks). Off: every
        # k-nearest edge is checked, a denser graph with shorter raw paths for many more collision checks.
        self.skip_connected = skip_connected
        self.chunk = max(1, int(chunk))
        # That rule's components: a label per node, shared by the nodes edges decided free join (see `joined_labels`).
        self._free = np.empty(0, np.int64)
        self.resolution = resolution or checker.space.resolution
        self.Q = np.empty((0, checker.space.dim))
        self.kinds: list[str] = []
        # The edges, as arrays (the search builds its sparse matrix from them, in C): rows in insertion order, every
        # pair ever decided or proposed, (a, b) with a < b; `_rows` finds a pair's row by its `pair_key(a, b)`. A row
        # stays when its edge is found to collide. Columns per row: `_ends` (a, b); `_lengths`; `_alive`, not known
        # to collide; `_checked`, decided free (or known to collide); `_progress`, of an edge not yet decided, how
        # many of its points (coarse to fine) a check found free before it stopped at another edge's collision (its
        # next check starts after them). Each is a view of the first rows of a larger array (`_set_rows`), so that
        # adding a round's edges does not copy every edge before them.
        empty = np.empty(0)
        self._set_rows(np.empty((0, 2), int), empty, empty.astype(bool), empty.astype(bool), empty.astype(np.int64))
        self.edges_tried = 0  # decided: checked in full, or found to collide
        self.edges_proposed = 0  # lazy candidates ever added
        self._tried: set[int] = set()  # `pair_key`s of the pairs ever proposed
        # Edges the certificate proved, (smaller, larger) -> the clearance they were proved to keep.
        self.proved: dict[tuple[int, int], float] = {}
        # Where set, which node pairs were checked free elsewhere: the search takes those edges as checked (a
        # query's fresh roadmap beside a stored one, app.planning.query.FreshShadow). Only free verdicts: a
        # collision known in advance would steer the search off the candidate paths it would otherwise check.
        self.free_elsewhere = None
        self._labelled = None  # (graph sizes, connected components) of the last `_labels`
        self._nodes: dict[bytes, int] = {}  # a configuration's bytes -> its node, so a repeated one is not added twice
        # Neighbour search (`_trees`): a k-d tree over the first `_tree_size` nodes, and one over the nodes since.
        self._tree: cKDTree | None = None
        self._tree_size = 0
        self._recent: cKDTree | None = None
        # The search's graph, kept from one search to the next so that a search only merges in the edges added
        # (sorting every edge again cost more than the search on large roadmaps): each edge in both directions,
        # ordered by (from, to) as a sorted CSR matrix wants them. Per entry: from << 32 | to (the order), `to` (the
        # matrix's column), the edge's length, infinite once the edge is known to collide (the search's matrix
        # shares the lengths, so that what it finds colliding stays out), and its row; entries of edges known to
        # collide are dropped when they are many.
        self._search = (np.empty(0, np.int64), np.empty(0, np.int32), np.empty(0), np.empty(0, np.int64))
        self._search_synced = 0  # edge rows merged in so far
        self._search_dead = 0  # entries of edges known to collide still in `_search`
        # A label per node such that nodes joined by edges not known to collide share it (`joined_labels`): different
        # labels are certainly apart, so a search between them is not run. Edges that die later are not undone here
        # (they would need the components counted again), but each search's tree from the start sets its
        # component's labels exactly.
        self._reach = np.empty(0, np.int64)
        # Periodic axes for continuous angles, flat (0) elsewhere; the scaled embedding lives in [0, box).
        w = checker.space.weights
        self._box = np.where(checker.space.continuous, 2 * np.pi * w, 0.0)
        self._embedded = np.empty((0, checker.space.dim))

    def __len__(self) -> int:
        return len(self.Q)

    # ---- metric embedding ---------------------------------------------------------------------------------------
    def embed(self, Q: np.ndarray) -> np.ndarray:
        """Weighted coordinates for the k-d tree: continuous angles mapped into [0, 2*pi*w), others (q - lower)*w."""
        space = self.space
        Q = np.atleast_2d(np.asarray(Q, float))
        angle = np.mod(Q + np.pi, 2 * np.pi)
        X = np.where(space.continuous, angle, Q - space.lower) * space.weights
        # mod can return exactly 2*pi*w after scaling by rounding; the periodic tree wants [0, box).
        periodic = space.continuous
        X[:, periodic] = np.where(X[:, periodic] >= self._box[periodic], 0.0, X[:, periodic])
        return X

    def neighbours(self, Q: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(distances, indices) of the k nearest roadmap nodes to each row of Q (fewer columns if the map is small)."""
        k = min(k, len(self))
        X = self.embed(Q)
        threads = self.checker.threads  # scipy spreads a large query over threads (it releases the GIL)
        found = [
            _query(tree, X, k, first, threads if len(X) * tree.n >= _THREADED_QUERY else 1)
            for tree, first in self._trees()
        ]
        if len(found) == 1:
            return found[0]
        d, i = np.hstack([f[0] for f in found]), np.hstack([f[1] for f in found])
        nearest = np.argsort(d, axis=1, kind="stable")[:, :k]
        return np.take_along_axis(d, nearest, axis=1), np.take_along_axis(i, nearest, axis=1)

    def _trees(self) -> list[tuple[cKDTree, int]]:
        """k-d trees over all the nodes, each with its first node: one over the nodes up to `_tree_size`, and one
        over the nodes added since, rebuilt as they come. A round's few new nodes then cost a small tree, not the
        whole roadmap's (a hard query grows a cell roadmap tenfold in a hundred rounds); the large tree is rebuilt
        once the newer nodes are more than half as many as it holds, so each node is built into it a few times."""
        n, size = len(self), self._tree_size
        if self._tree is None or n - size > size // 2:
            self._tree, self._tree_size, self._recent = cKDTree(self._embedded, boxsize=self._box), n, None
        elif n > size and (self._recent is None or self._recent.n != n - size):
            self._recent = cKDTree(self._embedded[size:], boxsize=self._box)
        trees = [(self._tree, 0)]
        if n > self._tree_size:
            trees.append((self._recent, self._tree_size))
        return trees

    # ---- building -----------------------------------------------------------------------------------------------
    def add(self, Q: np.ndarray, kind: str, connect: bool = True) -> np.ndarray:
        """Add configurations (assumed free) as nodes of one kind; connect each to its k nearest nodes.

        Returns the new node indices.
        """
        Q = np.atleast_2d(np.asarray(Q, float)).reshape(-1, self.space.dim)
        first = len(self.Q)
        new = np.arange(first, first + len(Q))
        if len(Q) == 0:
            return new
        wrapped = self.space.wrap(Q)
        self.Q = np.vstack([self.Q, wrapped])
        self.kinds.extend([kind] * len(Q))
        self._nodes.update((q.tobytes(), int(i)) for q, i in zip(wrapped, new))
        self._free = np.concatenate([self._free, new])
        self._embedded = np.vstack([self._embedded, self.embed(Q)])
        self._reach = np.concatenate([self._reach, new])
        if connect:
            self.connect(new)
        return new

    def unseen(self, Q: np.ndarray) -> np.ndarray:
        """Which of the configurations Q (rows) are not nodes yet (a mask)."""
        wrapped = self.space.wrap(np.atleast_2d(np.asarray(Q, float)).reshape(-1, self.space.dim))
        return np.array([q.tobytes() not in self._nodes for q in wrapped], bool)

    def indices(self, Q: np.ndarray) -> np.ndarray:
        """The node at each configuration of Q (rows; each must be a node)."""
        wrapped = self.space.wrap(np.atleast_2d(np.asarray(Q, float)).reshape(-1, self.space.dim))
        return np.array([self._nodes[q.tobytes()] for q in wrapped], np.int64)

    def node(self, q: np.ndarray, kind: str) -> int:
        """The node at configuration q (free), added unconnected if the roadmap has none there: a persistent roadmap
        asked for the same start or goal again reuses the node and every edge decided from it."""
        found = self._nodes.get(self.space.wrap(np.asarray(q, float)).tobytes())
        return found if found is not None else int(self.add(q, kind, connect=False)[0])

    def connect(self, nodes: np.ndarray, stop: Stop | None = None) -> int:
        """Try the edges from `nodes` to their k nearest neighbours not tried before; return how many were free.

        Nodes go in chunks; each chunk's candidate edges are one `edges_free` batch, bounded by `stop`.
        """
        nodes = np.asarray(nodes, int)
        if len(self) < 2 or len(nodes) == 0:
            return 0
        step = self.chunk if self.skip_connected and not self.lazy else len(nodes)
        added = 0
        for begin in range(0, len(nodes), step):
            added += self._connect_chunk(nodes[begin : begin + step], stop)
        return added

    def candidates(self, nodes: np.ndarray) -> np.ndarray:
        """The edges (node index pairs, smaller first) from `nodes` to their k nearest neighbours that were never
        tried, now marked tried: each pair is decided at most once in the roadmap's life."""
        self.k_used = self.k or prm_star_k(len(self), self.space.dim)
        _, idx = self.neighbours(self.Q[nodes], self.k_used + 1)  # +1: a node is its own nearest neighbour
        a, b = np.repeat(np.asarray(nodes, np.int64), idx.shape[1]), idx.ravel().astype(np.int64)
        real = (a != b) & (b < len(self))  # (a missing neighbour of a small map is numbered len(self))
        P = np.column_stack([np.minimum(a, b), np.maximum(a, b)])[real]
        keys = pair_key(P[:, 0], P[:, 1])
        first = np.sort(np.unique(keys, return_index=True)[1])  # each pair once, where it first comes
        P, keys = P[first], keys[first].tolist()
        new = np.array([key not in self._tried for key in keys], bool)
        if self.skip_connected and not self.lazy:
            new &= self._free[P[:, 0]] != self._free[P[:, 1]]
        self._tried.update(itertools.compress(keys, new))
        return P[new].reshape(-1, 2)

    def extend(self, near: int, q: np.ndarray, kind: str) -> int:
        """Node q joined to node `near` by an edge the caller has checked free (a motion grown from `near`, as RRT
        grows one): the edge is in the graph checked, and the pair is never proposed again. Returns the new node."""
        new = int(self.add(q, kind, connect=False)[0])
        self._tried.add(pair_key(near, new))
        self.edges_tried += 1
        self._add_edges(np.array([[min(near, new), max(near, new)]]), checked=True)
        return new

    def record(self, P: np.ndarray, free: np.ndarray) -> None:
        """Verdicts decided elsewhere (another process, for the same roadmap) for candidate edges P: the free ones
        join the graph checked, the colliding ones are kept as known to collide, so neither is checked again."""
        P, free = np.asarray(P, int).reshape(-1, 2), np.asarray(free, bool)
        self.edges_tried += len(P)
        self._add_edges(P[free], checked=True)
        self._add_dead(P[~free])

    def propose(self, P: np.ndarray) -> None:
        """Candidate edges P (node index pairs) decided elsewhere to be worth a try, added unchecked as a lazy
        roadmap adds its own; pairs tried before are left out."""
        P = np.sort(np.asarray(P, np.int64).reshape(-1, 2), axis=1)
        keys = pair_key(P[:, 0], P[:, 1]).tolist()
        new = np.array([key not in self._tried for key in keys], bool)
        self._tried.update(itertools.compress(keys, new))
        if new.any():
            self._add_edges(P[new], checked=False)
            self.edges_proposed += int(new.sum())

    def learn(self, P: np.ndarray, free: np.ndarray) -> None:
        """Verdicts reached elsewhere on edges P (node index pairs) this roadmap holds undecided: the free ones are
        checked, the colliding ones leave the graph. Edges it has decided, or does not hold, are left as they are."""
        rows, free = self._rows_of(P), np.asarray(free, bool)
        take = rows >= 0
        take[take] = self._alive[rows[take]] & ~self._checked[rows[take]]
        ok, bad = rows[take & free], rows[take & ~free]
        self._checked[ok] = True
        self._free = joined_labels(self._free, self._ends[ok])
        # (an edge not checked joined no components of `_free`: killing one leaves them as they are)
        self._kill(bad)

    def known(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per pair of P (node index pairs): (whether this roadmap has decided that edge, whether it is free)."""
        rows = self._rows_of(P)
        held = rows >= 0
        alive, checked = np.zeros(len(rows), bool), np.zeros(len(rows), bool)
        alive[held], checked[held] = self._alive[rows[held]], self._checked[rows[held]]
        return held & (checked | ~alive), alive

    def _rows_of(self, P: np.ndarray) -> np.ndarray:
        """The edge row of each pair of P (node index pairs, either order), -1 where there is none."""
        P = np.sort(np.asarray(P, np.int64).reshape(-1, 2), axis=1)
        return np.array([self._rows.get(key, -1) for key in pair_key(P[:, 0], P[:, 1]).tolist()], np.int64)

    def pairs(self, first: int = 0) -> np.ndarray:
        """Every pair proposed or decided (smaller index first), in the order they came, from the `first`th on."""
        return self._ends[first:]

    def verdicts(self) -> tuple[np.ndarray, np.ndarray]:
        """Per pair of `pairs()`: (whether it is decided -- checked free, or known to collide --, whether it is not
        known to collide)."""
        return self._checked | ~self._alive, self._alive.copy()

    def _add_dead(self, P: np.ndarray) -> None:
        """Rows for edges known to collide: out of the graph, remembered (and saved) so they are never tried again."""
        if not len(P):
            return
        self._append_rows(P, self.space.distance(self.Q[P[:, 0]], self.Q[P[:, 1]]), alive=False, checked=True)

    def _connect_chunk(self, nodes: np.ndarray, stop: Stop | None) -> int:
        P = self.candidates(nodes)
        if not len(P):
            return 0
        if self.lazy:
            # Candidates, checked when a shortest path uses them. No check up front: screening every candidate at
            # its midpoint cost 1 check per edge and, on the maze and the UR3, more than the searches it saved.
            self._add_edges(P, checked=False)
            self.edges_proposed += len(P)
            return len(P)
        free = self._check(P, stop)
        self._add_edges(P[free], checked=True)
        self._add_dead(P[~free])
        return int(free.sum())

    def _check(self, P: np.ndarray, stop: Stop | None) -> np.ndarray:
        """Free flags of the edges (node index pairs) P, checked in one batch."""
        self.edges_tried += len(P)
        return self.checker.edges_free(self.Q[P[:, 0]], self.Q[P[:, 1]], self.resolution, ends_free=True, stop=stop)

    def _add_edges(self, P: np.ndarray, checked: bool) -> None:
        """Add edges (node index pairs, smaller index first) of the given state, to the graph and the arrays."""
        lengths = self.space.distance(self.Q[P[:, 0]], self.Q[P[:, 1]]) if len(P) else np.empty(0)
        self._append_rows(P, lengths, alive=True, checked=checked)
        self._reach = joined_labels(self._reach, P)
        if checked:
            self._free = joined_labels(self._free, P)

    def _set_rows(self, ends, lengths, alive, checked, progress) -> None:
        """The edge rows, whole (as `keep_nodes` leaves them), and `_rows` to find them."""
        self._columns = [ends, lengths, alive, checked, progress]
        self._ends, self._lengths, self._alive, self._checked, self._progress = self._columns
        self._rows = dict(zip(pair_key(ends[:, 0], ends[:, 1]).tolist(), range(len(ends))))

    def _append_rows(self, P: np.ndarray, lengths: np.ndarray, alive: bool, checked: bool) -> None:
        """New edge rows after the others, in arrays that double when full."""
        first, last = len(self._ends), len(self._ends) + len(P)
        if last > len(self._columns[0]):
            size = max(2 * last, 1024)
            self._columns = [np.resize(column, (size, *column.shape[1:])) for column in self._columns]
        for column, new in zip(self._columns, (P, lengths, alive, checked, 0)):
            column[first:last] = new
        self._ends, self._lengths, self._alive, self._checked, self._progress = (c[:last] for c in self._columns)
        self._rows.update(zip(pair_key(P[:, 0], P[:, 1]).tolist(), range(first, last)))

    # ---- queries ------------------------------------------------------------------------------------------------
    def edges(self, checked: bool | None = None) -> np.ndarray:
        """The edges not known to collide, (m, 2) node pairs (smaller first); with `checked`, only those decided free
        (True) or only those not yet checked (False)."""
        rows = self._alive if checked is None else self._alive & (self._checked if checked else ~self._checked)
        return self._ends[rows]

    def _labels(self) -> tuple[int, np.ndarray]:
        """Connected components of the graph of edges not known to collide: (count, label per node), from the edge
        arrays in C (a persistent roadmap asks this of tens of thousands of edges after every query)."""
        # Edges are only ever added or killed, so the sizes name the graph: kept until they change. The search's
        # graph holds each edge both ways, so its strong components are the components, found without the
        # transposed copy an undirected count makes.
        state = (len(self), len(self._ends), int(self._alive.sum()))
        if self._labelled is None or self._labelled[0] != state:
            graph = self._search_graph(compact=True)
            self._labelled = (state, connected_components(graph, directed=True, connection="strong"))
        return self._labelled[1]

    def labels(self) -> np.ndarray:
        """A component label per node, of the graph of edges not known to collide."""
        return self._labels()[1]

    def components(self) -> int:
        return int(self._labels()[0])

    def component_sizes(self, *nodes: int) -> list[int]:
        labels = self._labels()[1]
        return [int(np.sum(labels == labels[n])) for n in nodes]

    def shortest_path(self, a: int, b, stop: Stop | None = None) -> list[int] | None:
        """Node indices of a short path by metric length from a to b (a node, or a list of nodes: to the nearest
        that can be reached) whose every edge is checked free, or None; its edge checks bounded by `stop`.

        Lazy PRM's search: the unchecked edges of a candidate path are checked together, coarse to fine, until one
        collides; those decided free are marked checked, those that collide are removed. Candidates come from two
        shortest-path trees (scipy's Dijkstra, in C), from a and from b: the path through a node m is a's tree path
        to m and b's from m, of length dist_a[m] + dist_b[m]; the least such is the shortest path, the next ones are
        the shortest detours. Up to CANDIDATES of them are tried, in that order, before the trees are grown again
        (skipping those that lost an edge, and nodes of paths already tried): a narrow passage's roadmap disproves
        hundreds of candidate paths per round, and one Dijkstra per disproved path cost more than their checks.
        The first free candidate is the shortest free path in the trees' graph, or a near-shortest one after
        removals (smoothing shortens it).
        """
        targets = [int(t) for t in np.atleast_1d(b)]
        if not 0 <= a < len(self) or not any(0 <= t < len(self) for t in targets):
            return None
        if not (self._reach[targets] == self._reach[a]).any():
            return None
        from app.checking import kernels

        matrix = self._search_graph()
        nodes, rows = np.empty(len(self), np.int64), np.empty(len(self), np.int64)
        while True:
            dist_a, pred_a = dijkstra(matrix, indices=a, return_predecessors=True)
            reached = np.isfinite(dist_a)
            self._label_component(a, reached)
            if not reached[targets].any():  # apart: the second tree is not needed
                return None
            # The tree from the targets is a forest, one tree per target (min_only: each node under its nearest).
            dist_b, pred_b, _ = dijkstra(matrix, indices=targets, return_predecessors=True, min_only=True)
            through = dist_a + dist_b
            reachable = np.flatnonzero(np.isfinite(through))
            order = reachable[np.argsort(through[reachable], kind="stable")]
            trees = SearchTree(pred_a), SearchTree(pred_b)
            taken = np.zeros(len(self), bool)  # nodes of the candidate paths tried on these trees
            at = 0
            for _ in range(CANDIDATES):
                # The next candidate, found in a compiled scan of `order` from just past the last one.
                at, count, unchecked = kernels.next_candidate(
                    order, at, taken, pred_a, pred_b, trees[0].dead, trees[1].dead, matrix.indptr, matrix.indices,
                    self._search[3], self._checked, nodes, rows,
                )  # fmt: skip
                if at < 0:
                    break  # no candidate left on these trees: grow them again
                if self._check_path(rows[:unchecked].copy(), trees, stop):
                    return nodes[:count].tolist()

    def _label_component(self, a: int, reached: np.ndarray) -> None:
        """Node a's component is exactly `reached` (a mask): it gets a label of its own, and the rest of its label's
        nodes another."""
        label = self._reach[a]
        rest = (self._reach == label) & ~reached
        self._reach[reached] = np.argmax(reached)
        if rest.any():
            self._reach[rest] = np.argmax(rest)

    def _search_graph(self, compact: bool = False) -> csr_matrix:
        """The edges not known to collide as a symmetric CSR matrix of their lengths, with sorted indices (the search
        looks an edge's row up by bisection): the kept graph with the edges added since merged in, in C. Its lengths
        are the kept ones, shared: an edge the search drops (`_kill`) stays dropped. compact: without entries of
        edges known to collide (a structural count, such as components, needs that)."""
        n, search = len(self), self._search
        if self._search_dead > (0 if compact else len(search[0]) // 8):
            search = tuple(column[np.isfinite(search[2])] for column in search)
            self._search_dead = 0
        fresh = np.arange(self._search_synced, len(self._ends))
        fresh = fresh[self._alive[fresh]]
        if len(fresh):
            U, V = self._ends[fresh, 0].astype(np.int64), self._ends[fresh, 1].astype(np.int64)
            keys = np.concatenate([U << 32 | V, V << 32 | U])
            order = np.argsort(keys)
            keys = keys[order]
            rows = np.concatenate([fresh, fresh])[order]
            added = (keys, (keys & 0xFFFFFFFF).astype(np.int32), self._lengths[rows], rows)
            at = np.searchsorted(search[0], keys)
            search = tuple(np.insert(column, at, new) for column, new in zip(search, added))
        self._search, self._search_synced = search, len(self._ends)
        indptr = np.searchsorted(search[0], np.arange(n + 1, dtype=np.int64) << 32).astype(np.int32)
        matrix = csr_matrix((search[2], search[1], indptr), shape=(n, n), copy=False)
        matrix.has_sorted_indices = True
        return matrix

    def _check_path(self, rows: np.ndarray, trees, stop: Stop | None) -> bool:
        """Check a candidate path's unchecked edges (rows) until one collides; whether all are free. A colliding
        edge leaves the graph, the search's matrix and the trees."""
        if not len(rows):
            return True
        if self.free_elsewhere is not None:
            known = self.free_elsewhere(self._ends[rows])
            self._checked[rows[known]] = True
            rows = rows[~known]
            if not len(rows):
                return True
        P, progress = self._ends[rows], self._progress[rows]
        free, decided = self.checker.edges_status(
            self.Q[P[:, 0]],
            self.Q[P[:, 1]],
            self.resolution,
            ends_free=True,
            until_one_collides=True,
            progress=progress,
            stop=stop,
        )
        self._progress[rows] = progress
        self.edges_tried += int(np.count_nonzero(decided))
        self._checked[rows[decided & free]] = True
        gone = decided & ~free
        if gone.any():
            self._kill(rows[gone])
            for tree in trees:
                tree.cut(P[gone])
            return False
        return bool(decided.all())

    def _kill(self, rows: np.ndarray) -> None:
        """Edge rows found to collide: not alive, and out of the search's graph where merged into it (their lengths
        infinite, in the arrays the search's matrix shares)."""
        from app.checking import kernels

        keys, lengths = self._search[0], self._search[2]
        self._search_dead += 2 * kernels.kill_edges(rows, self._ends, self._alive, keys, lengths, self._search_synced)

    def remove_edge(self, a: int, b: int) -> None:
        """Drop an edge found bad later (e.g. by a finer check). Components are rebuilt from the graph."""
        row = self._rows.get(pair_key(a, b))
        if row is not None and self._alive[row]:
            self._kill(np.array([row]))
            self._recount_components()

    def truncate(self, n: int) -> None:
        """Drop the nodes from index n on (see `keep_nodes`)."""
        self.keep_nodes(np.arange(len(self)) < n)

    def keep_nodes(self, keep: np.ndarray) -> np.ndarray:
        """Keep only the nodes where `keep` (a mask over the nodes), numbered again in their order, and drop every
        edge that touches another; what was decided between the nodes kept stays (verdicts, proofs, pairs tried).
        Returns each node's new index (-1: dropped)."""
        keep = np.asarray(keep, bool)
        index = np.where(keep, np.cumsum(keep) - 1, -1)
        if keep.all():
            return index
        rows = keep[self._ends].all(axis=1)
        self.Q, self._embedded, self._tree = self.Q[keep], self._embedded[keep], None  # (`_trees` builds anew)
        self.kinds = list(itertools.compress(self.kinds, keep.tolist()))
        self._nodes = {key: int(index[i]) for key, i in self._nodes.items() if keep[i]}
        ends = index[self._ends[rows]]
        self._set_rows(ends, self._lengths[rows], self._alive[rows], self._checked[rows], self._progress[rows])
        tried = np.fromiter(self._tried, np.int64, len(self._tried))
        a, b = tried >> 32, tried & 0xFFFFFFFF
        kept = keep[a] & keep[b]
        self._tried = set(pair_key(index[a[kept]], index[b[kept]]).tolist())
        self.proved = {(int(index[u]), int(index[v])): c for (u, v), c in self.proved.items() if keep[u] and keep[v]}
        self._search, self._search_synced, self._search_dead = tuple(column[:0] for column in self._search), 0, 0
        # Each label's nodes kept stay together, under the least of them (labels may only join more than is true).
        self._reach = labels_by_least(self._reach[keep])
        self._labelled = None
        self._recount_components()
        return index

    def joined_nodes(self) -> np.ndarray:
        """Which nodes have an edge decided free (a mask over the nodes)."""
        joined = np.zeros(len(self), bool)
        joined[self._ends[self._alive & self._checked].ravel()] = True
        return joined

    def _recount_components(self) -> None:
        """The skip-connected rule's components from scratch, from the edges decided free: after edges or nodes
        left, which joining labels cannot undo."""
        n, ends = len(self.Q), self._ends[self._alive & self._checked]
        graph = csr_matrix((np.ones(len(ends), bool), (ends[:, 0], ends[:, 1])), shape=(n, n))
        self._free = labels_by_least(connected_components(graph, directed=False)[1])  # as `joined_labels` keeps them

    def edge_pairs(self, P: np.ndarray) -> list[tuple[int, int] | None]:
        """For each straight segment of the polyline P, the roadmap edge (node pair, smaller first) not known to
        collide that joins the very same two configurations, or None."""
        nodes = [self._nodes.get(np.asarray(q, float).tobytes()) for q in P]
        pairs = []
        for a, b in itertools.pairwise(nodes):
            row = None if a is None or b is None else self._rows.get(pair_key(a, b))
            pairs.append((min(a, b), max(a, b)) if row is not None and self._alive[row] else None)
        return pairs

    def proved_with(self, pairs: list, clearance: float) -> np.ndarray:
        """Per entry of `pairs` (edge_pairs' answer), whether that edge was proved to keep at least `clearance`."""
        return np.array([pair is not None and self.proved.get(pair, -1.0) >= clearance for pair in pairs], bool)

    def mark_proved(self, pairs: list, clearance: float) -> None:
        """The edges of `pairs` (None entries skipped) proved to keep `clearance` (the larger proof is kept)."""
        for pair in pairs:
            if pair is not None:
                self.proved[pair] = max(clearance, self.proved.get(pair, -1.0))

    # ---- persistence ------------------------------------------------------------------------------------------------
    def arrays(self) -> dict[str, np.ndarray]:
        """The whole roadmap as arrays: nodes, their kinds, every decided or proposed edge with its verdict flags
        (alive: not known to collide; checked: decided free at the resolution, or known to collide; proved: the
        certificate proved it), and the settings that shape later connections."""
        names = sorted(set(self.kinds)) or [UNIFORM]
        proved = np.array([(int(a), int(b)) in self.proved for a, b in self._ends.tolist()], bool)
        return {
            "Q": self.Q,
            "kind_names": np.array(names),
            "kinds": np.array([names.index(kind) for kind in self.kinds], np.int16),
            "ends": self._ends.astype(np.int64),
            "alive": self._alive,
            "checked": self._checked,
            "progress": self._progress,
            "proved": proved,
            "k": np.array(self.k or 0),
            "resolution": np.array(self.resolution),
            "counters": np.array([self.edges_tried, self.edges_proposed], np.int64),
        }

    @classmethod
    def from_arrays(cls, checker, data) -> Roadmap:
        """The roadmap `arrays()` described, on `checker`'s space (lazy: later edges are checked when used), with no
        edge proved."""
        k = int(data["k"])
        graph = cls(checker, k=k or None, resolution=float(data["resolution"]), skip_connected=False, lazy=True)
        names = [str(n) for n in data["kind_names"]]
        kinds = np.asarray(data["kinds"], int)
        Q = np.asarray(data["Q"], float).reshape(-1, checker.space.dim)
        graph.Q = checker.space.wrap(Q)
        graph._reach = np.arange(len(Q))
        graph.kinds = [names[c] for c in kinds]
        graph._nodes = {q.tobytes(): i for i, q in enumerate(graph.Q)}
        graph._embedded = graph.embed(graph.Q) if len(Q) else np.empty((0, checker.space.dim))
        ends = np.asarray(data["ends"], int).reshape(-1, 2)
        alive, checked = (np.asarray(data[key], bool) for key in ("alive", "checked"))
        graph._add_edges(ends[alive], checked=False)
        graph._checked[:] = checked[alive]
        graph._progress[: int(alive.sum())] = np.asarray(data["progress"], np.int64)[alive]
        graph._add_dead(ends[~alive])
        graph._recount_components()
        graph._tried = set(pair_key(ends[:, 0], ends[:, 1]).tolist())
        # The file's `proved` flags are not read: a certified answer rests only on proofs made in this process
        # (anyone can write a file; its checked verdicts only steer the search, which the certificate then decides).
        graph.edges_tried, graph.edges_proposed = (int(c) for c in data["counters"])
        return graph

    def stats(self) -> RoadmapStats:
        """Sizes and counters (see RoadmapStats)."""
        counts = {kind: self.kinds.count(kind) for kind in (UNIFORM, NARROW, WORKSPACE)}
        return RoadmapStats(
            nodes=len(self),
            edges=int(self._alive.sum()),
            edges_unchecked=int((self._alive & ~self._checked).sum()),
            components=self.components(),
            edges_tried=self.edges_tried,
            edges_proposed=self.edges_proposed,
            uniform_nodes=counts[UNIFORM],
            narrow_nodes=counts[NARROW],
            workspace_nodes=counts[WORKSPACE],
            k=self.k_used,
            lazy=self.lazy,
            skip_connected=self.skip_connected and not self.lazy,
        )


@dataclass(frozen=True)
class RoadmapStats:
    """A roadmap's sizes and counters. Lazy: `edges` and `components` are of the candidate graph (edges not known
    to collide), `edges_tried` counts edges checked in full, `edges_proposed` the candidates added unchecked."""

    nodes: int
    edges: int
    edges_unchecked: int
    components: int
    edges_tried: int
    edges_proposed: int
    uniform_nodes: int
    narrow_nodes: int
    workspace_nodes: int
    k: int | None
    lazy: bool
    skip_connected: bool

    def to_json(self) -> dict:
        return asdict(self)


def _query(tree: cKDTree, X: np.ndarray, k: int, first: int, workers: int) -> tuple[np.ndarray, np.ndarray]:
    """(distances, node indices) of the k nearest of a tree's points (fewer if it holds fewer), its first point
    being node `first`; on `workers` threads."""
    k = min(k, tree.n)
    d, i = tree.query(X, k=k, workers=workers)
    return np.asarray(d).reshape(len(X), k), np.asarray(i).reshape(len(X), k) + first
