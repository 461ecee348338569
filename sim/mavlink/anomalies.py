"""Counting what a peer got wrong, and reporting it at most once per period.

Every anomaly is counted by kind (:attr:`AnomalyCounter.stats`, for the lifetime of the link).
Reports are one line per ``period_s`` of wall time at most, whatever the traffic: the first
anomaly after a quiet period is reported at once, later ones are summed into the next line
(``"3 anomalies in 1.0 s: garbage 2, bad_crc 1; last: ..."``) at the most severe level seen.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable

EventFn = Callable[[str, str], None]  # (text, level in "debug" | "info" | "warning" | "error")
_LEVELS = ("debug", "info", "warning", "error")


class AnomalyCounter:
    def __init__(self, emit: EventFn, clock: Callable[[], float], period_s: float = 1.0):
        self._emit = emit
        self._clock = clock
        self.period_s = period_s
        self.stats: Counter[str] = Counter()
        self._pending: Counter[str] = Counter()
        self._level = 0
        self._last_detail = ""
        self._since = 0.0
        self._next_report = -float("inf")

    def count(self, kind: str, detail: str, level: str = "warning") -> None:
        """One anomaly of ``kind``; ``detail`` says what (kept for the report of its period)."""
        self.stats[kind] += 1
        now = self._clock()
        if not self._pending:
            self._since = now
        self._pending[kind] += 1
        self._level = max(self._level, _LEVELS.index(level))
        self._last_detail = f"{kind}: {detail}"
        self.flush(now)

    def flush(self, now: float | None = None, force: bool = False) -> None:
        """Report what is pending if the period since the last report has passed (or ``force``)."""
        if not self._pending:
            return
        now = self._clock() if now is None else now
        if now < self._next_report and not force:
            return
        n = sum(self._pending.values())
        if n == 1:
            text = self._last_detail
        else:
            kinds = ", ".join(f"{k} {c}" for k, c in self._pending.most_common())
            text = f"{n} anomalies in {now - self._since:.1f} s: {kinds}; last: {self._last_detail}"
        self._emit(text, _LEVELS[self._level])
        self._pending.clear()
        self._level = 0
        self._next_report = now + self.period_s
