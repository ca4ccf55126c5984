"""When things happen in the optimisation loop: subdivision events, the displacement-only
phase, and the time limit (ours) that compresses the schedule."""
from __future__ import annotations

import math
import time

from ..settings.fields import ConstructSettings

# The share of the time limit by which the loop and the fit's later passes are done (the
# bounds, metrics and files come after them).
END_SHARE = 0.9


class Schedule:
    """Subdivision events (absolute iterations), the iteration that freezes the base, and the
    time limit: the whole construction, the base building and what follows the loop (the
    fit, bounds, metrics: ``finish_s``, the estimate's seconds for them) included, within
    ``time_limit_s``. The loop's own share ends at 90 % of the limit less ``finish_s``; once
    two thirds of that are spent the next subdivision is pulled forward (at most every 10
    iterations), and the loop ends at it once the subdivisions are done. Where the finish
    alone takes the whole limit (millions of faces), the loop only subdivides."""

    def __init__(self, s: ConstructSettings, t_start: float, fixed_levels: bool,
                 finish_s: float = 0.0):
        self.events = sorted(set(int(i) for i in s.subdivide_at)) if s.progressive else []
        self.freeze_at = s.base_freeze_iteration
        if fixed_levels:
            self.events, self.freeze_at = [], 0   # displacements only from the first iteration
        self.limit = s.time_limit_s
        self.loop_end = END_SHARE * self.limit - max(0.0, finish_s)
        self.t_start = t_start
        self.last_event = -10
        self.stopped_early = False

    @property
    def deadline(self) -> float:
        """``perf_counter()`` at ``END_SHARE`` of the time limit (inf without one)."""
        return self.t_start + END_SHARE * self.limit if self.limit > 0 else math.inf

    def out_of_time(self, it: int) -> bool:
        """True when the loop must end now; may pull the next event forward."""
        if self.limit <= 0:
            return False
        el = time.perf_counter() - self.t_start
        if el > self.loop_end and not self.events:
            self.stopped_early = True
            return True
        if el > self.loop_end * 2 / 3 and self.events and self.events[0] > it \
                and it - self.last_event >= 10:
            self.events[0] = it
        return False

    def bounded_eta(self, eta: float) -> float:
        """``eta`` (the loop's remaining iterations at its pace so far) bounded by the time
        limit, at whose loop share the loop ends once the subdivisions are done."""
        if self.limit <= 0:
            return eta
        return min(eta, max(0.0, self.loop_end - (time.perf_counter() - self.t_start)))

    def events_due(self, it: int) -> int:
        """How many subdivision events fall due at ``it`` (removed from the list)."""
        n = 0
        while self.events and it >= self.events[0]:
            self.events.pop(0)
            self.last_event = it
            n += 1
        return n

    def frozen(self, it: int) -> bool:
        return it >= self.freeze_at
