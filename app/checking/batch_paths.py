"""Which of the oracle's batch paths answers a batch: the cheapest so far per size class of batch, each tried first and
the others measured again now and then (app.checking.oracle's module doc says what the paths are)."""

from __future__ import annotations

# Batches of at least this many configurations may be split with helper processes; below it the pipe's round trip
# costs more than the half batch saves.
SPLIT_MIN = 16
# Batch calls before the path not in favour is measured again: at first 16; each time it is found dearer still, twice
# as many, up to 1024. Probes back off because the path out of favour can cost several times the other per
# configuration (the checker's batch lists every penetrating pair where HasCollisions stops at the first).
_PROBE_FIRST, _PROBE_MAX = 16, 1024
# Calls each path is given before the cheapest is chosen, its cost the least of them, so that one call slowed by
# another process does not settle the choice.
_TRIES = 2


def splits(size: int) -> bool:
    """Whether batches of a size class (n.bit_length() == size) are large enough to split."""
    return 1 << (size - 1) >= SPLIT_MIN


class BatchPaths:
    """The running cost per configuration of each batch path, for one size class of batch, and which path to take:
    the cheapest so far; each is tried first (_TRIES times), and the others are measured again in turn at the
    probe's calls (see _PROBE_FIRST)."""

    def __init__(self, paths):
        self.cost: dict[str, float | None] = dict.fromkeys(paths)
        self.tries: dict[str, int] = dict.fromkeys(paths, 0)
        self.calls = 0
        self.probes = 0
        self.probe_wait = _PROBE_FIRST  # calls from one probe to the next
        self.next_probe = _PROBE_FIRST  # the call that probes

    @property
    def settled(self) -> bool:
        """Every path has had its tries: calls from now on take the cheapest (but for probes)."""
        return all(self.tries.get(path, 0) >= _TRIES for path in self.cost)

    def choose(self) -> str:
        self.calls += 1
        for path in self.cost:
            if self.tries.get(path, 0) < _TRIES:
                return path
        best = min(self.cost, key=self.cost.get)
        if self.calls == self.next_probe:
            others = [path for path in self.cost if path != best]
            self.probes += 1
            return others[self.probes % len(others)]
        return best

    def measured(self, path: str, cost: float) -> None:
        """A call on `path` cost `cost` seconds per configuration. After a probe: wait twice as long for the next one
        if the probed path is still the dearer, else start probing over."""
        old, tries = self.cost.get(path), self.tries.get(path, 0)
        if old is None:
            self.cost[path] = cost
        else:  # (a slowed call is the usual outlier: the least of the tries)
            self.cost[path] = min(old, cost) if tries < _TRIES else 0.7 * old + 0.3 * cost
        self.tries[path] = tries + 1
        if self.calls == self.next_probe:
            dearer = self.cost[path] > min(self.cost.values())
            self.probe_wait = min(2 * self.probe_wait, _PROBE_MAX) if dearer else _PROBE_FIRST
            self.next_probe = self.calls + self.probe_wait
