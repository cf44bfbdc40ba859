"""How much a query may spend: wall-clock seconds and/or collision checks, whichever runs out first."""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass


@dataclass(frozen=True)
class Budget:
    """A limit on seconds and/or collision checks (None: no limit of that kind)."""

    seconds: float | None = None
    checks: int | None = None

    def spent(self, seconds: float, checks: int) -> bool:
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
