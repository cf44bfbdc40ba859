"""A Checker on boxes in the plane, numpy alone (no Drake): a point robot (x, y) in [0, 100]^2 among axis-aligned boxes.

It is a real QueryContext on a toy oracle, so its counting, budgets and coarse-to-fine edge checks are the project's
own; only the collision answers are the toy's. The fast tests (`make test-fast`) run the samplers, the roadmap,
shortcut smoothing and budgets on it, in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.checking.context import QueryContext
from app.scene.cspace import ConfigurationSpace

# A wall across the plane with a gap of 4 at y 48..52 (a narrow passage), and a block to go round.
WALL = [((45.0, 0.0), (55.0, 48.0)), ((45.0, 52.0), (55.0, 100.0))]
BLOCK = [((20.0, 20.0), (30.0, 80.0))]


@dataclass
class ToyScene:
    """The facts of a toy scene (app.checking.protocol.SceneFacts)."""

    boxes: list
    name: str = "toy"
    start: np.ndarray = field(default_factory=lambda: np.array([10.0, 50.0]))
    goal: np.ndarray = field(default_factory=lambda: np.array([90.0, 50.0]))
    step: float | None = 5.0
    lower: np.ndarray = field(default_factory=lambda: np.zeros(2))
    upper: np.ndarray = field(default_factory=lambda: np.full(2, 100.0))
    angular: np.ndarray = field(default_factory=lambda: np.zeros(2, bool))
    weights: np.ndarray = field(default_factory=lambda: np.ones(2))
    self_collisions: bool = False
    velocity_limits: np.ndarray = field(default_factory=lambda: np.full(2, 20.0))
    acceleration_limits: np.ndarray = field(default_factory=lambda: np.full(2, 20.0))
    position_map: None = None


class ToyOracle:
    """Collision answers of a point among boxes: what a QueryContext asks of a CollisionOracle (`free_batch`,
    `first_hits`, `free`), and its counters."""

    def __init__(self, boxes=WALL, resolution: float = 0.5):
        self.scene = ToyScene(boxes=[(np.array(lo), np.array(hi)) for lo, hi in boxes])
        self.space = ConfigurationSpace(
            lower=self.scene.lower,
            upper=self.scene.upper,
            weights=self.scene.weights,
            angular=self.scene.angular,
            continuous=np.zeros(2, bool),
            resolution=resolution,
            names=["x", "y"],
        )
        self.threads = 1
        self.answered = 0

    def collides(self, Q: np.ndarray) -> np.ndarray:
        Q = np.atleast_2d(Q)
        hit = np.zeros(len(Q), bool)
        for lo, hi in self.scene.boxes:
            hit |= np.all((Q >= lo) & (Q <= hi), axis=1)
        return hit

    def free(self, q: np.ndarray) -> bool:
        self.answered += 1
        return not bool(self.collides(q)[0])

    def free_batch(self, Q: np.ndarray) -> np.ndarray:
        self.answered += len(Q)
        return ~self.collides(Q)

    def first_hits(self, Q: np.ndarray, owner: np.ndarray, hit: list, until_one: bool) -> tuple[int, int]:
        checked = 0
        for i, edge in enumerate(owner.tolist()):
            if hit[edge]:
                continue
            checked += 1
            if self.collides(Q[i])[0]:
                hit[edge] = True
                if until_one:
                    self.answered += checked
                    return i + 1, checked
        self.answered += checked
        return len(owner), checked


def toy_checker(boxes=WALL, resolution: float = 0.5) -> QueryContext:
    """A fresh checker (its own counters) on a toy oracle of these boxes."""
    return QueryContext(ToyOracle(boxes, resolution))
