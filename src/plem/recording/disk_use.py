"""How much disk one robot's recording takes: bytes per hour at its rates, and the most its retention keeps.

The figure is computed from the payload sizes the recorder writes (RtRaw and JointState have a fixed size per
robot; rt_monitor_stats is measured on a message naming the queues it reports) plus what MCAP adds per message
(its record header and message index entry); segments' schemas, chunk indexes and summaries add well under 1 %.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from plem.middleware.monitor_feed import MONITOR_TOPICS
from plem.middleware.raw_cdr import raw_dtype
from plem.middleware.types import InterfaceLibrary
from plem.recording.bulk_cdr import JointStateEncoder
from plem.recording.mcap_records import MESSAGE_FIELDS, RECORD_HEADER
from plem.recording.settings import RecordingSettings

#: What MCAP adds to a message's payload: its record header and fields, and its (time, offset) index entry.
MESSAGE_OVERHEAD = RECORD_HEADER + MESSAGE_FIELDS + 16
#: How often the RT driver writes its loop statistics (one rt_monitor_stats each).
STATS_RATE_HZ = 10.0
#: The queues an rt_monitor_stats reports (the recorder's rings, the command intake and the bag).
STATS_QUEUES = ("rt_raw", "events", "stats", "commands", "bag")


@dataclass(frozen=True)
class DiskUse:
    """Estimated bytes per hour of one robot's recording, and the most its retention keeps on disk."""

    bytes_per_hour: float
    retained_bytes: float
    rate_hz: float
    settings: RecordingSettings

    def describe(self) -> str:
        """For the launch summary: 'about 1.6 GB an hour at 1000 Hz; retention 60 min keeps at most about 1.6 GB'."""
        return (f"about {size(self.bytes_per_hour)} an hour at {self.rate_hz:g} Hz; retention "
                f"{self.settings.retention_s / 60:g} min keeps at most about {size(self.retained_bytes)} "
                f"(plus segments kept for faults, and less once the disk is {self.settings.disk_threshold:g} % full)")


def size(count: float) -> str:
    """Bytes in kB, MB or GB (powers of 1000, as disks are sold)."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= scale:
            return f"{count / scale:.1f} {unit}"
    return f"{count:.0f} B"


def disk_use(settings: RecordingSettings, joint_names: Sequence[str], cycle_time_s: float, joint_state_rate: float,
             library: InterfaceLibrary) -> DiskUse:
    """The recording's bytes per hour at one rt_raw per cycle, joint_states at their rate and stats at 10 Hz; what
    retention keeps is its window plus the open segment."""
    new = library.new
    stats = new(MONITOR_TOPICS["rt_monitor_stats"],
                queues=[new("plem_msgs/msg/QueueStats", name=name) for name in STATS_QUEUES]).serialize()
    rate_hz = 1.0 / cycle_time_s
    per_second = (rate_hz * (raw_dtype(len(joint_names)).itemsize + MESSAGE_OVERHEAD)
                  + joint_state_rate * (JointStateEncoder(joint_names).template.size + MESSAGE_OVERHEAD)
                  + STATS_RATE_HZ * (len(stats) + MESSAGE_OVERHEAD))
    return DiskUse(per_second * 3600, per_second * (settings.retention_s + settings.segment_s), rate_hz, settings)
