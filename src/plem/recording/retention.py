"""Which closed bag segments to delete: older than the retention window, or oldest first while the disk is too full.

The segment being written is never deleted, nor one the flight recorder protected (it holds the seconds
before a fault). Every deletion comes with its reason, for the log. Time and disk usage are passed in,
so tests inject them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Segment:
    """A closed segment as retention sees it: where, when (wall-clock ns), how big, and whether it is kept."""

    path: str
    start_ns: int
    end_ns: int
    size: int
    protected: bool = False


@dataclass(frozen=True)
class Deletion:
    """A segment the guard deletes, and why (past retention, or the disk above its threshold)."""

    segment: Segment
    reason: str


def choose_deletions(closed: Sequence[Segment], now_ns: int, retention_ns: int, threshold_percent: float,
                     disk_percent: Callable[[int], float]) -> list[Deletion]:
    """Segments to delete, oldest first.

    First those that ended more than `retention_ns` ago; then, while `disk_percent(bytes_freed)` (the
    usage once that many bytes are gone) is above `threshold_percent`, the oldest remaining ones.
    Protected segments are skipped by both rules.
    """
    candidates = sorted((s for s in closed if not s.protected), key=lambda s: s.start_ns)
    deletions: list[Deletion] = []
    freed = 0
    for segment in candidates:
        age_s = (now_ns - segment.end_ns) / 1e9
        if now_ns - segment.end_ns > retention_ns:
            reason = f"older than the retention window ({age_s:.0f} s > {retention_ns / 1e9:.0f} s)"
        elif disk_percent(freed) > threshold_percent:
            reason = (f"disk {disk_percent(freed):.1f} % full, above disk_threshold {threshold_percent:g} %; "
                      "oldest segment first")
        else:
            continue
        deletions.append(Deletion(segment, reason))
        freed += segment.size
    return deletions
