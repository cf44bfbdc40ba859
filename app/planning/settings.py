"""What a query may be told (PlanSettings), and the limits and defaults behind it.

What a budget covers is said once, here. A query's budget (`PlanSettings.budget`) runs as one `Stop` from the moment
the query is made (app.checking.budget), handed to every counted call as its argument: its check limit bounds the
search for a path -- samples, roadmap edge checks, the easy route -- and smoothing, which may spend SMOOTHING_SHARE of
the checks finding the path took (`Stop.within`); its time limit and cancel flag bound all of it, the certificate
and timing of the path found included, which ask Drake for distances rather than checks (`Stop.without_check_limit`):
a check budget's answer must not depend on how fast the machine proves it. Two other limits are not a query's: a
cell roadmap's build has its own (`BuildSettings.budget`, looked at between rounds), and a sampler's `max_checks` is
a guard on one call of it that finds nothing, not a budget.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from app.checking.budget import SAFETY_NET_SECONDS, Budget
from app.checking.certify import CLEARANCE
from app.errors import UserError

# What a query may spend unless told otherwise: every query ends, and says so when this is why. Collision checks
# decide, so the same seed gives the same answer on any machine at any load; the seconds are a safety net for a
# machine so slow that the checks would take hours, and a query they stop says that its answer depends on the machine.
DEFAULT_BUDGET = Budget(seconds=SAFETY_NET_SECONDS, checks=200_000)
# Smoothing may spend this share of the checks that finding the path took (at least SMOOTHING_MIN), and all its passes
# together (a path the certificate refused is shortened again, fine-only) SMOOTHING_CAP.
SMOOTHING_SHARE, SMOOTHING_CAP, SMOOTHING_MIN = 0.2, 0.3, 200
# How many times a smoothed path the certificate refused is smoothed again without the shortcuts that carried the
# refused edges, before the query goes careful: each repair costs a certificate, and a refused edge is bisected deep
# (the measurements behind one are on the benchmark pages, "Tuning notes").
SMOOTHING_REPAIRS = 4
# The shortest trajectory sample period: a 1 kHz controller; finer would only make files of gigabytes.
MIN_DT = 1e-3
# The smallest clearance a query may ask for (PlanSettings.clearance, CLEARANCE by default): the samples a controller
# needs for the straight lines between them to keep half of it grow as 1/sqrt(clearance).
MIN_CLEARANCE = 1e-6
# Narrow-passage samples per round once they are on: narrow/NARROW_RAMP at first, doubling every round up to
# narrow/4 -- few while a few may do, and never more than twice what the query needed.
NARROW_RAMP = 16
# The most rounds of uniform samples alone while start or goal is shut in a pocket (Query). On the 70 MotionBenchMaker
# Panda problems, 15 pockets opened to uniform rounds alone in 2 to 4 rounds, for a third to a half of the checks
# the narrow-passage rounds had spent on them; in a pocket that needs narrow-passage samples (cage, window, welding)
# each round of waiting costs one uniform round, a few hundred checks (window and welding: 5 % more).
POCKET_ROUNDS = 4


def default_step(scene) -> float:
    """A scene's default sampler step: its file's `step` if set; else a tenth of its largest linear extent (10 for
    the 100-unit scenes); with no linear coordinate, a tenth of the weighted diagonal of the bounds."""
    if scene.step:
        return scene.step
    extent = np.asarray(scene.upper) - np.asarray(scene.lower)
    linear = ~np.asarray(scene.angular)
    if linear.any():
        return 0.1 * float(np.max(extent[linear]))
    return 0.1 * float(np.linalg.norm(extent * scene.weights))


@dataclass(frozen=True)
class PlanSettings:
    """Everything a query may be told, validated once when built (a bad value raises UserError).

    Attributes:
        sampler: Where the narrow-passage samples come from: a sampler's registered name (one of `app.SAMPLERS`),
            with `workspace` of them placements, or "adaptive": placements and the narrow-passage samplers in
            shares learned while the query runs (app.planning.sources.Mixture).
        narrow: Narrow-passage samples that size a query's rounds (see Query); with `full_roadmap`, the whole
            roadmap's.
        uniform: Uniform samples, as `narrow`.
        step: The sampler's base step a in the weighted metric (None: the scene's default).
        seed: The random seed (on a check budget, the same seed gives the same answer on any machine).
        budget: What the query may spend (seconds and/or collision checks; `Budget()` has no limit). The default,
            DEFAULT_BUDGET, stops on checks with SAFETY_NET_SECONDS as a safety net; a budget built here as
            `Budget(checks=N)` has no time limit unless it says `seconds=...` (the command line's `--budget Nchecks`
            keeps the safety net). Its time limit bounds the whole query, the proof (the certificate) and timing of
            the path found included; its check limit bounds the search and smoothing, as proving and timing ask for
            distances, not checks.
        k: Neighbours per node (None: k-PRM*'s).
        smooth_rounds: Random shortcut rounds.
        dt: Trajectory sample period (s).
        sampler_params: Extra keyword arguments of the sampler (e.g. `alpha_angle`).
        skip_connected: Kavraki's rule for a full roadmap.
        full_roadmap: The paper's protocol: every sample drawn, every edge checked, then the query.
        workspace: The share of a query's narrow-passage samples placed in narrow gaps of the workspace
            (app.samplers.workspace; 0: the sampler alone; a full roadmap draws none).
        timing: Time the path with Toppra (False: the result's trajectory is None, for a caller that times several
            paths as one motion, as a job does through its pass-through poses).
        velocity_scale: The fraction in (0, 1] of the scene's velocity limits that the trajectory keeps to
            (MoveIt's scaling factor).
        acceleration_scale: The same for the acceleration limits.
        clearance: The distance (scene length units) the certified motion keeps from everything the scene counts
            (CLEARANCE; at least MIN_CLEARANCE), of which the straight lines between its samples and the path
            polyline keep at least half: start and goal must be that far off too.
    """

    sampler: str = "lfbs"
    narrow: int = 200
    uniform: int = 300
    step: float | None = None
    seed: int = 0
    budget: Budget = DEFAULT_BUDGET
    k: int | None = None
    smooth_rounds: int = 50
    dt: float = 0.02
    sampler_params: dict = field(default_factory=dict)
    skip_connected: bool = True
    full_roadmap: bool = False
    workspace: float = 0.75
    timing: bool = True
    velocity_scale: float = 1.0
    acceleration_scale: float = 1.0
    clearance: float = CLEARANCE

    def __post_init__(self):
        from app.planning.sources import ADAPTIVE, check_source_name

        check_source_name(self.sampler)
        if self.sampler == ADAPTIVE and self.sampler_params:
            names = ", ".join(self.sampler_params)
            raise UserError(f"sampler parameters ({names}) need a named sampler, not {ADAPTIVE}")
        for name in ("narrow", "uniform", "smooth_rounds", "seed"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise UserError(f"{name} must be a non-negative whole number, got {value!r}")
        if self.k is not None and (isinstance(self.k, bool) or not isinstance(self.k, (int, np.integer)) or self.k < 1):
            raise UserError(f"k must be a positive whole number, got {self.k!r}")
        if isinstance(self.dt, (int, float)) and self.dt < MIN_DT:
            raise UserError(f"dt must be at least {MIN_DT:g} s (a {1 / MIN_DT:g} Hz controller), got {self.dt!r}")
        for name in ("dt", "step"):
            value = getattr(self, name)
            if value is None and name == "step":
                continue
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float, np.floating, np.integer))
                or not math.isfinite(value)
                or value <= 0
            ):
                raise UserError(f"{name} must be a positive finite number, got {value!r}")
        share = self.workspace
        if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0 <= share <= 1:
            raise UserError(f"workspace must be a share from 0 to 1, got {self.workspace!r}")
        if not isinstance(self.budget, Budget):
            raise UserError(f"budget must be a Budget, got {self.budget!r}")
        for name in ("velocity_scale", "acceleration_scale"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= 1:
                raise UserError(f"{name} must be a fraction in (0, 1], got {value!r}")
        c = self.clearance
        if isinstance(c, bool) or not isinstance(c, (int, float)) or not MIN_CLEARANCE <= c < math.inf:
            raise UserError(f"clearance must be a finite distance of at least {MIN_CLEARANCE:g}, got {c!r}")
