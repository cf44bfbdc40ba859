"""The random-walk family, one class with two switches (see README.md for the choices the paper leaves open):

    step_law   bridge   name
    gaussian   off      rws   (Bera et al.: walk out of an obstacle with Gaussian steps until free)
    levy       off      lfs   (Algorithm 1 of the paper)
    gaussian   on       rwbs  (the paper's RWBS)
    levy       on       lfbs  (Algorithm 2 of the paper)

A walk starts at a uniform configuration that collides. Each step proposes q' from q; a colliding q' becomes the
new q. A free q' ends the walk with q' as the sample; with the bridge switch on it must also pass the bridge test
(extend(q, q') = q' + (q' - q) collides), and when it does not, the walk goes on from the same q (Algorithm 2 only
replaces q when q' collides; `bridge_fail="move"` is the other reading). A walk that has not ended after
`max_steps` steps is abandoned (counted in gave_up).

Many walkers advance in lockstep: one step of all of them is a few numpy operations and one `oracle.are_free`
call (plus one for the bridge ends), which is what makes the samplers fast despite a walk being sequential.
"""

from __future__ import annotations

import numpy as np

from app.errors import UserError
from app.samplers.base import Sampler
from app.samplers.levy import mantegna

# exp() of more than this is clipped: 2*pi*e^30 is still resolved to 0.002 rad, and the angle is random by then.
_EXP_CLIP = 30.0

# Where the paper can be read more than one way (README.md, "Readings"), the choices a Walker accepts:
# alpha_convention: the paper's alpha (1.9 steps, 1.1 angles) is the Lévy law's stability index ("stability"), or
#   the exponent of the density x^-alpha its text writes ("density": stability index alpha - 1);
# angle_law: an angle moves by the paper's law theta' = 2 pi (1 - e^f) of its own Lévy move ("paper"), by the same
#   Lévy step as the length, with no law of its own ("length"), or by a Gaussian step as in rws ("gaussian");
# bridge_fail: when a free q' fails the bridge test the walk stays at q ("stay", Algorithm 2 as written replaces q
#   only when q' collides) or moves on to q' ("move").
READING_CHOICES = {
    "alpha_convention": ("stability", "density"),
    "angle_law": ("paper", "length", "gaussian"),
    "bridge_fail": ("stay", "move"),
}
DEFAULT_READING = {"alpha_convention": "stability", "angle_law": "paper", "bridge_fail": "stay"}


class Walker(Sampler):
    """Random-walk sampler. step_law: 'gaussian' | 'levy'; bridge: off | on."""

    def __init__(
        self,
        checker,
        step: float = 10.0,
        step_law: str = "levy",
        bridge: bool = False,
        alpha: float = 1.9,
        alpha_angle: float = 1.1,
        alpha_convention: str = DEFAULT_READING["alpha_convention"],
        angle_law: str = DEFAULT_READING["angle_law"],
        bridge_fail: str = DEFAULT_READING["bridge_fail"],
        max_steps: int = 500,
        walkers: int | None = None,
        name: str | None = None,
        **kw,
    ):
        super().__init__(checker, step=step, **kw)
        if step_law not in ("gaussian", "levy"):
            raise ValueError(f"step_law must be 'gaussian' or 'levy', not {step_law!r}")
        self.step_law, self.bridge = step_law, bool(bridge)
        for key, value in (
            ("alpha_convention", alpha_convention),
            ("angle_law", angle_law),
            ("bridge_fail", bridge_fail),
        ):
            if value not in READING_CHOICES[key]:
                raise UserError(f"{key} must be one of {', '.join(READING_CHOICES[key])}, not {value!r}")
        self.angle_law, self.bridge_fail = angle_law, bridge_fail
        # Mantegna's draw takes the stability index; the density reading's x^-alpha has stability index alpha - 1.
        shift = 1.0 if alpha_convention == "density" else 0.0
        self.alpha, self.alpha_angle = float(alpha) - shift, float(alpha_angle) - shift
        self.max_steps = int(max_steps)
        self.walkers = walkers  # pool size; None: sized to what is still needed (see _pool_size)
        self.name = (
            name
            or {("gaussian", False): "rws", ("levy", False): "lfs", ("gaussian", True): "rwbs", ("levy", True): "lfbs"}[
                (step_law, self.bridge)
            ]
        )
        self._angular = np.asarray(checker.space.angular, bool)

    # ---- steps ---------------------------------------------------------------------------------------------
    def _draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """n configuration-space displacements for the chosen step law."""
        space, a = self.space, self.step
        if self.step_law == "gaussian":
            return self._offsets(rng, n, a, exact=False)
        # Lévy: a random direction u in the weighted space; every coordinate moves u_i * (a + a|L|) workspace
        # units, with one L ~ S(alpha) per step for the translational coordinates (so they move on a line) and an
        # independent L ~ S(alpha_angle) per angle. An angle's linear move delta (radians) then goes through the
        # paper's law theta' = 2 pi (1 - e^f) with f = -delta / (2 pi), which is delta for small moves.
        dim, ang = space.dim, self._angular
        m = int(ang.sum())
        G = rng.standard_normal((n, dim + 2 + 2 * m))  # direction, (U, V) for the length, (U, V) per angle
        u = G[:, :dim] / np.sqrt(np.einsum("ij,ij->i", G[:, :dim], G[:, :dim]))[:, None]
        length = a * (1.0 + np.abs(mantegna(G[:, dim : dim + 1], G[:, dim + 1 : dim + 2], self.alpha)))
        d = u * length / space.weights
        if m and self.angle_law == "paper":
            L = mantegna(G[:, dim + 2 : dim + 2 + m], G[:, dim + 2 + m :], self.alpha_angle)
            delta = u[:, ang] * a * (1.0 + np.abs(L)) / space.weights[ang]
            d[:, ang] = 2 * np.pi * (1.0 - np.exp(np.minimum(-delta / (2 * np.pi), _EXP_CLIP)))
        elif m and self.angle_law == "gaussian":
            d[:, ang] = self._offsets(rng, n, a, exact=False)[:, ang]
        return d

    # ---- the lockstep walk ---------------------------------------------------------------------------------
    def _begin(self, rng):
        dim = self.space.dim
        self._Q = np.empty((0, dim))  # current (colliding) position of each walker
        self._age = np.empty(0, int)  # steps each walker has taken
        self._reserve = np.empty((0, dim))  # colliding starts found but not yet walking
        self._hit_rate = 0.5  # running estimate of the colliding fraction of uniform draws

    def _pool_size(self, need: int) -> int:
        if self.walkers:
            return min(int(self.walkers), max(1, self._room))
        # Walk lengths are heavy-tailed, so a larger pool finishes its samples with shorter walks, which offsets
        # the unfinished walks it leaves, and its batches are fuller (benchmark pages, "Tuning notes").
        return min(int(np.clip(4 * need, 32, 256)), max(1, self._room))

    def _refill(self, rng, size: int, stop) -> None:
        """Top the pool up to `size` walkers from colliding uniform configurations (checked in one call)."""
        missing = size - len(self._Q)
        if missing <= 0:
            return
        if len(self._reserve) < missing:
            n = int(np.clip(np.ceil(1.2 * (missing - len(self._reserve)) / max(self._hit_rate, 0.02)), 8, 4096))
            n = max(1, min(n, self._room))
            C = self.space.uniform(rng, n)
            hit = self._collides(C, stop)
            self._hit_rate = max(hit.mean(), 0.02)
            self._reserve = np.concatenate([self._reserve, C[hit]])
        take = min(missing, len(self._reserve))
        self._Q = np.concatenate([self._Q, self._reserve[:take]])
        self._age = np.concatenate([self._age, np.zeros(take, int)])
        self._reserve = self._reserve[take:]
        self.stats["attempts"] += take

    def _round(self, rng, need, stop):
        space = self.space
        self._refill(rng, self._pool_size(need), stop)
        Q = self._Q
        if not len(Q):
            return np.empty((0, space.dim)), None
        P, ok = self._propose(rng, Q, self._draw)  # out of bounds after all redraws: the walker stays this step
        free = np.zeros(len(Q), bool)
        free[ok] = self.checker.are_free(P[ok], stop)
        accept, ends = free, None
        if self.bridge:
            # extend(q, q'): q' is the midpoint of q q''. q'' out of bounds is no collision (no obstacle there).
            cand = np.flatnonzero(free)
            R = space.wrap(P[cand] + space.difference(Q[cand], P[cand]))
            hit = self._collides(R, stop)
            accept = np.zeros(len(Q), bool)
            accept[cand[hit]] = True
            ends = np.stack([Q[cand[hit]], R[hit]], axis=1)
        # q' collides: q <- q'. A free q' that failed the bridge test leaves q where it was, or is moved on to.
        moved = ok & (~accept if self.bridge_fail == "move" else ~free)
        Q[moved] = P[moved]
        self._age += 1
        self.stats["steps"] = self.stats.get("steps", 0) + len(Q)
        done = accept | (self._age >= self.max_steps)
        self.stats["gave_up"] += int((~accept & done).sum())
        self._Q, self._age = Q[~done], self._age[~done]
        return P[accept], ends
