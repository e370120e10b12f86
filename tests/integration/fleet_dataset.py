"""A small synthetic fleet dataset of two robots whose report answers are known by construction.

arm_a: a 6-axis arm, 8 s on 2026-11-02 (overruns 3, missed periods 1, lost frames 2; rt_raw second 2.0–3.0 lost;
a tracking fault at 2.5 s) and 8 s on 2026-11-03 (counters restarted: overruns 5, missed periods 1).
arm_b: a 7-axis arm, 8 s on each day, wake-up latency base 20 µs then 30 µs; a limit fault at 6 s of the second day.
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

from plem.fleet.synthetic import Fault, Run, write_runs

DAY_1, DAY_2 = datetime(2026, 11, 2, 8, tzinfo=UTC), datetime(2026, 11, 3, 8, tzinfo=UTC)
RUNS = [
    Run("arm_a", 6, DAY_1, 8, segment_seconds=4, overruns=3, missed_periods=1, lost_frames=2,
        faults=(Fault(2.5),), gaps=((2.0, 3.0),)),
    Run("arm_a", 6, DAY_2, 8, segment_seconds=4, overruns=5, missed_periods=1),
    Run("arm_b", 7, DAY_1, 8, segment_seconds=4, latency_base_us=20),
    Run("arm_b", 7, DAY_2, 8, segment_seconds=4, latency_base_us=30,
        faults=(Fault(6.0, "joint_limit", "joint7 reached its position limit"),)),
]


def write_fleet(directory: Path) -> Path:
    """The two robots' dataset under `directory`."""
    write_runs(directory, RUNS)
    return directory
