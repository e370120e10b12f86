"""How one robot is recorded, as the launch arguments set it (kept free of heavy imports for the planner)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class RecordingSettings:
    """Where and how one robot's monitoring topics are recorded (durations in seconds).

    `group` (a gid, from `shm_group:=`) may read the recordings too; without it they are owner-only.
    """

    directory: Path
    storage: str = "mcap"
    segment_s: float = 60.0
    retention_s: float = 3600.0
    disk_threshold: float = 70.0
    flight_window_s: float = 10.0
    flush_period_s: float = 1.0
    guard_period_s: float = 1.0
    group: int | None = None

    def describe(self) -> str:
        """One line for the launch summary: storage, segment length, retention, disk threshold, flight window."""
        return (f"{self.storage}, segments of {self.segment_s:g} s, retention {self.retention_s / 60:g} min, "
                f"disk_threshold {self.disk_threshold:g} %, {self.flight_window_s:g} s kept before a fault")
