"""Which closed bag segments to delete: older than the retention window, or oldest first while the disk is too full.

The segment being written is never deleted, nor one the flight recorder protected (it holds the seconds
before a fault), nor the newest closed one, nor any to make room that files plem did not write took. Every deletion
comes with its reason, for the log. Time and disk usage are passed in, so tests inject them.
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


def deletable(closed: Sequence[Segment]) -> list[Segment]:
    """The segments the guard may ever delete, oldest first: neither protected nor the newest."""
    newest = max(closed, key=lambda s: s.start_ns, default=None)
    return sorted((s for s in closed if not s.protected and s is not newest), key=lambda s: s.start_ns)


def choose_deletions(closed: Sequence[Segment], now_ns: int, retention_ns: int, threshold_percent: float,
                     disk_percent: Callable[[int], float]) -> list[Deletion]:
    """Segments to delete, oldest first.

    First those that ended more than `retention_ns` ago; then, while `disk_percent(bytes_freed)` (the usage
    once that many bytes are gone) is above `threshold_percent`, the oldest remaining ones, but only when
    deleting all of them would bring the disk below the threshold: the room is then room plem took. When
    it would not, other files fill the disk and no segment is deleted for it (the recorder stops instead).
    Protected segments and the newest one (what came last, before any stop) are skipped by both rules.
    """
    candidates = deletable(closed)
    deletions: list[Deletion] = []
    rest: list[Segment] = []
    for segment in candidates:
        if now_ns - segment.end_ns > retention_ns:
            reason = (f"older than the retention window ({(now_ns - segment.end_ns) / 1e9:.0f} s > "
                      f"{retention_ns / 1e9:.0f} s)")
            deletions.append(Deletion(segment, reason))
        else:
            rest.append(segment)
    freed = sum(deletion.segment.size for deletion in deletions)
    if disk_percent(freed + sum(segment.size for segment in rest)) > threshold_percent:
        return deletions
    for segment in rest:
        if disk_percent(freed) <= threshold_percent:
            break
        deletions.append(Deletion(segment, f"disk {disk_percent(freed):.1f} % full, above disk_threshold "
                                           f"{threshold_percent:g} %; oldest segment first"))
        freed += segment.size
    return deletions
