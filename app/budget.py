"""How much a query may spend: wall-clock seconds and/or collision checks, whichever runs out first."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Budget:
    """A limit on seconds and/or collision checks (None: no limit of that kind)."""

    seconds: float | None = None
    checks: int | None = None

    def spent(self, seconds: float, checks: int) -> bool:
        return ((self.seconds is not None and seconds >= self.seconds)
                or (self.checks is not None and checks >= self.checks))

    def __str__(self) -> str:
        parts = []
        if self.seconds is not None:
            parts.append(f"{self.seconds:g}s")
        if self.checks is not None:
            parts.append(f"{self.checks}checks")
        return ",".join(parts) or "none"
