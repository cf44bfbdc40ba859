"""How much a query may spend: wall-clock seconds and/or collision checks, whichever runs out first."""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass

# The time limit a query keeps unless told otherwise: beside a check limit, a safety net for a machine so slow (or a
# robot's meshes so heavy) that the checks would take hours. PlanSettings' default budget has it, and the command line
# adds it to a budget given in checks alone (`--budget 300kchecks`); `--budget 300kchecks,nolimit` leaves it out.
SAFETY_NET_SECONDS = 600.0
# The largest budgets taken: a day (a longer one, 1e308 s, is no limit at all, and a query that cannot be solved would
# run until killed) and a billion checks.
MAX_SECONDS = 86_400.0
MAX_CHECKS = 10**9


@dataclass(frozen=True)
class Budget:
    """A limit on seconds and/or collision checks (None: no limit of that kind). `str(budget)` writes it as
    `--budget` takes it ("30s,200000checks"; "none" for no limit).

    Attributes:
        seconds: Wall-clock seconds.
        checks: Collision checks.
    """

    seconds: float | None = None
    checks: int | None = None

    def spent(self, seconds: float, checks: int) -> bool:
        """Whether `seconds` and `checks` spent reach either limit."""
        return (self.seconds is not None and seconds >= self.seconds) or (
            self.checks is not None and checks >= self.checks
        )

    def __str__(self) -> str:
        parts = []
        if self.seconds is not None:
            parts.append(f"{self.seconds:g}s")
        if self.checks is not None:
            parts.append(f"{self.checks}checks")
        return ",".join(parts) or "none"

    def larger(self, seconds_spent: float, factor: int = 10) -> str:
        """A budget as `--budget` takes it with `factor` times this one's checks ("2000kchecks"), for a query that
        spent them in `seconds_spent`: with a time limit too ("2000kchecks,1500s") when that many checks would take
        longer at the same pace than this budget's time limit (or, without one, the command line's
        SAFETY_NET_SECONDS, which a check limit alone keeps there)."""
        checks = min(MAX_CHECKS, factor * (self.checks or 1))
        limit = SAFETY_NET_SECONDS if self.seconds is None else self.seconds
        needed = 1.5 * seconds_spent * checks / (self.checks or 1)  # with a margin: later rounds cost more a check
        if needed <= limit:
            return spell_checks(checks)
        return f"{spell_checks(checks)},{min(MAX_SECONDS, 100 * math.ceil(needed / 100)):g}s"


def spell_checks(checks: int) -> str:
    """A check limit as `--budget` takes it: 2000kchecks, 2500checks."""
    return f"{checks // 1000}kchecks" if checks % 1000 == 0 else f"{checks}checks"


def poll(stop: Stop | None) -> None:
    """BudgetSpent if `stop` is spent (None: never): for loops that may go round without asking for a check."""
    if stop is not None:
        stop.allow(0)


class BudgetSpent(Exception):
    """Raised by a query context when its Stop runs out; the query that set the stop catches it."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason  # "time", "checks" or "cancelled"


class Stop:
    """A Budget running against the clock and a query context's check counter, from the moment it is made.

    Like OMPL's PlannerTerminationCondition it travels down to where the work is: the query's context
    (app.checking.context) polls it before every collision batch (`allow`), so sampling, edge checks and smoothing all
    stop within one batch of the limit, and a check limit is never overrun. `cancel` (a threading.Event, or anything
    with `is_set()`) stops it from outside: another thread that no longer wants the answer (a newer request, a
    shutdown)."""

    def __init__(self, budget: Budget, checker, cancel=None):
        self.budget, self._checker, self._cancel = budget, checker, cancel
        self._t0, self._c0 = time.perf_counter(), checker.checks

    def seconds(self) -> float:
        return time.perf_counter() - self._t0

    def checks(self) -> int:
        return self._checker.checks - self._c0

    def reason(self) -> str | None:
        """'cancelled', 'time' or 'checks' once the query must stop, else None."""
        if self._cancel is not None and self._cancel.is_set():
            return "cancelled"
        b = self.budget
        if b.seconds is not None and self.seconds() >= b.seconds:
            return "time"
        if b.checks is not None and self.checks() >= b.checks:
            return "checks"
        return None

    def allow(self, n: int) -> int:
        """How many of the next n checks may run (all of them, or what the check limit leaves); BudgetSpent when
        none may."""
        reason = self.reason()
        if reason is not None:
            raise BudgetSpent(reason)
        if self.budget.checks is None:
            return n
        return min(n, self.budget.checks - self.checks())

    def within(self, checks: int) -> Stop:
        """A stop for part of the work: what is left of this budget, and at most `checks` more checks."""
        left = None if self.budget.checks is None else max(0, self.budget.checks - self.checks())
        seconds = None if self.budget.seconds is None else max(0.0, self.budget.seconds - self.seconds())
        budget = Budget(seconds=seconds, checks=checks if left is None else min(left, checks))
        return Stop(budget, self._checker, self._cancel)

    def without_check_limit(self) -> Stop:
        """This stop on the same clock and cancel flag, without its check limit: for proving and timing a path
        already found, which ask for distances rather than the collision checks a budget counts, but must keep to
        the query's time limit."""
        stop = copy.copy(self)
        stop.budget = Budget(seconds=self.budget.seconds)
        return stop
