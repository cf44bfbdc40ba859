"""The interface every stage after collision checking sees: a `Checker` (in practice a QueryContext).

Samplers, the roadmap, path shortcuts, timing and the certificate ask it for counted collision answers and a few
uncounted measurements, and never touch Drake objects themselves; this Protocol makes that dependency visible and
lets a stand-in (a test's toy checker) take its place.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from app.checking.budget import Stop


class Checker(Protocol):
    """Counted, bounded collision answers for one query on a shared oracle (see app.checking.context)."""

    oracle: object  # the shared CollisionOracle behind it (uncounted measurements, the Drake model)
    space: object  # the ConfigurationSpace (bounds, metric, interpolation)
    scene: object  # the Scene
    checks: int  # configurations handed to Drake for a collision answer
    distance_queries: int  # signed-distance queries (the certificate's)
    point_queries: int  # workspace points asked for their distances to obstacles
    stop: Stop | None  # the budget every counted answer polls
    threads: int  # the cores the shared oracle may use (a large k-nearest query is spread over them)

    def poll(self) -> None: ...

    def is_free(self, q: np.ndarray) -> bool: ...

    def are_free(self, Q: np.ndarray) -> np.ndarray: ...

    def edges_free(
        self, Q1: np.ndarray, Q2: np.ndarray, resolution: float | None = None, ends_free: bool = False
    ) -> np.ndarray: ...

    def edges_status(
        self,
        Q1: np.ndarray,
        Q2: np.ndarray,
        resolution: float | None = None,
        ends_free: bool = False,
        until_one_collides: bool = False,
        progress: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]: ...

    def signed_distances(self, q: np.ndarray, max_distance: float) -> list: ...

    def in_contact(self, q: np.ndarray) -> bool: ...

    def pair_distances(self, q: np.ndarray, pairs: list) -> list: ...

    def count_bounded(self, n: int) -> None: ...

    def environment_gaps(self, P: np.ndarray, width: float) -> np.ndarray: ...
