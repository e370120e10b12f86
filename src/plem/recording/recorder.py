"""The flight recorder of one robot: monitoring messages into bounded bag segments, with a disk guard.

A `Recorder` is the `MonitorSink` of a `MonitorFeed`. It writes every message into the open segment and
starts a new one every `segment_s`. `maintain()` (about once a second) deletes closed segments past the
retention window or while the disk is fuller than the threshold, never the open one nor one kept for
a fault. On a fault it puts the open segment on disk at once, keeps every segment holding the
`flight_window_s` before it, and logs where in the bags the fault is. A write the disk refuses stops
recording with a logged event (what follows is counted as not recorded) and recording resumes in a
new segment once the guard brought the disk back under its threshold.
"""

from __future__ import annotations

import logging
import shutil
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from rosbags.typesys.store import Typestore

from plem.control.events import Event, EventKind
from plem.errors import PlemError
from plem.middleware.monitor_feed import QueueCount
from plem.recording.access import FileAccess
from plem.recording.archive import Archive, directory_size, iso_time
from plem.recording.repair import repair
from plem.recording.retention import Segment, choose_deletions
from plem.recording.segment import SegmentWriter
from plem.recording.settings import RecordingSettings

Clock = Callable[[], int]
DiskUsage = Callable[[Path], tuple[int, int, int]]


class Recorder:
    """Writes one robot's monitoring messages into segments under `settings.directory`."""

    def __init__(self, settings: RecordingSettings, robot_id: str, topics: dict[str, str], store: Typestore,
                 clock: Clock = time.time_ns, disk_usage: DiskUsage = shutil.disk_usage) -> None:
        self.settings = settings
        self.topics = topics                       # short name (rt_raw) → ROS type
        self.namespace = f"/{robot_id}"
        self.store = store
        self.clock = clock
        self.disk_usage = disk_usage
        self.access = FileAccess(settings.group)
        self.archive = Archive(settings.directory, robot_id, self.access)
        self.written = 0
        self.unrecorded = 0
        self.closed: list[Segment] = []
        self.segment: SegmentWriter | None = None
        self.stopped_because: str | None = None
        self._segment_ns = round(settings.segment_s * 1e9)
        self._segment_start = 0
        self._next_guard = 0
        self._full_warned = False
        self._adopt_previous_segments()

    # -- MonitorSink -----------------------------------------------------------------------------------
    def rt_raw(self, cdr: bytes, wall_ns: int) -> None:
        """Record one cycle's RtRaw, already in CDR."""
        self._write("rt_raw", wall_ns, cdr)

    def joint_state(self, message: Any, wall_ns: int) -> None:
        """Record a sensor_msgs/JointState."""
        self._write("joint_states", wall_ns, message.serialize())

    def rt_event(self, message: Any, event: Event, wall_ns: int) -> None:
        """Record an RtEvent; a fault also keeps the segments of the flight window before it."""
        self._write("rt_events", wall_ns, message.serialize())
        if event.kind == EventKind.FAULT:
            self._keep_fault_window(event, wall_ns)

    def rt_monitor_stats(self, message: Any, wall_ns: int) -> None:
        """Record an RtMonitorStats."""
        self._write("rt_monitor_stats", wall_ns, message.serialize())

    def queues(self) -> list[QueueCount]:
        """The bag itself: messages written, and messages not recorded (recording stopped or a write failed)."""
        return [QueueCount("bag", 0, 0, self.written, self.unrecorded)]

    # -- segments --------------------------------------------------------------------------------------
    def start(self) -> None:
        """Open the first segment."""
        self._open(self.clock())

    def _open(self, wall_ns: int) -> None:
        path = self.archive.new_segment_path(wall_ns)
        topics = [(f"{self.namespace}/{name}", ros_type) for name, ros_type in self.topics.items()]
        self.segment = SegmentWriter(path, topics, self.store, self.settings.storage, self.settings.flush_period_s,
                                     self.access)
        self._segment_start = wall_ns
        self.archive.log("segment_opened", f"recording into {path}", segment=path.name,
                         storage=self.settings.storage)

    def _close(self) -> None:
        """Finish the open segment (metadata.yaml) and hand it to the guard."""
        segment, self.segment = self.segment, None
        if segment is None:
            return
        try:
            segment.close()
        except (OSError, ValueError):
            self._give_up(segment)
            raise
        closed = self.archive.closed_segment(segment.directory)
        if closed is not None:
            self.closed.append(closed)
        self.archive.log("segment_closed", f"segment {segment.name} closed: {segment.messages} messages",
                         segment=segment.name, messages=segment.messages)

    def _write(self, name: str, wall_ns: int, data: bytes) -> None:
        if self.segment is None:
            self.unrecorded += 1
            return
        try:
            if wall_ns - self._segment_start >= self._segment_ns:
                self._close()
                self._open(wall_ns)
            self.segment.write(f"{self.namespace}/{name}", wall_ns, data)
        except OSError as error:
            self.unrecorded += 1
            self._stop(error)
            return
        self.written += 1

    def close(self) -> None:
        """Finish the open segment; called once when recording ends."""
        try:
            self._close()
        except OSError as error:
            self._stop(error)

    # -- the disk --------------------------------------------------------------------------------------
    def _stop(self, error: OSError) -> None:
        """The disk refused a write: give up the open segment (repairable later) and stop recording."""
        segment, self.segment = self.segment, None
        self.stopped_because = f"{error.strerror or error} ({self.settings.directory})"
        if segment is not None:
            try:
                segment.close()
            except (OSError, ValueError):
                self._give_up(segment)
            else:
                self._track(segment)
        self.archive.log("recording_stopped", f"recording stopped: {self.stopped_because}; the robot goes on, "
                         "recording resumes once the disk is below disk_threshold", logging.ERROR,
                         reason=self.stopped_because)

    def _give_up(self, segment: SegmentWriter) -> None:
        """A segment the disk would not let finish: its file closed as a killed segment, still under the guard."""
        segment.abandon()                           # `plem bag repair` (or the next recorder) rebuilds it
        self._track(segment)

    def _track(self, segment: SegmentWriter) -> None:
        """Hand a segment that ended without `_close` to the guard, from its start until now."""
        self.closed.append(Segment(str(segment.directory), self._segment_start, self.clock(),
                                   directory_size(segment.directory), self.archive.is_kept(segment.directory)))

    def maintain(self) -> None:
        """Apply retention and the disk guard (at most once per guard period); resume a stopped recording."""
        now = self.clock()
        if now < self._next_guard:
            return
        self._next_guard = now + round(self.settings.guard_period_s * 1e9)
        total, used, _ = self.disk_usage(self.settings.directory)

        def percent(freed: int) -> float:
            return 100.0 * (used - freed) / total

        deletions = choose_deletions(self.closed, now, round(self.settings.retention_s * 1e9),
                                     self.settings.disk_threshold, percent)
        freed = 0
        for deletion in deletions:
            try:
                self.archive.delete(deletion)
            except OSError as error:
                self.archive.log("delete_failed", f"segment {deletion.segment.path} not deleted: {error}",
                                 logging.WARNING, segment=deletion.segment.path)
                continue
            freed += deletion.segment.size
            self.closed.remove(deletion.segment)
        over = percent(freed) > self.settings.disk_threshold
        if over and not self._full_warned:
            self.archive.log("disk_above_threshold", f"disk {percent(freed):.1f} % full, above disk_threshold "
                             f"{self.settings.disk_threshold:g} %, and no closed segment is left to delete "
                             "(kept fault segments stay)", logging.WARNING, percent=round(percent(freed), 1))
        self._full_warned = over
        if self.segment is None and self.stopped_because is not None and not over:
            self.archive.log("recording_resumed", "recording resumed: the disk is below disk_threshold again")
            self.stopped_because = None
            try:
                self._open(now)
            except OSError as error:
                self._stop(error)

    # -- the flight recorder ---------------------------------------------------------------------------
    def _keep_fault_window(self, event: Event, wall_ns: int) -> None:
        """Put the seconds before a fault on disk, keep their segments, and log the fault's bag position."""
        reason = f"fault at {iso_time(wall_ns)}: {event.reason}"
        window_start = wall_ns - round(self.settings.flight_window_s * 1e9)
        kept = []
        for index, segment in enumerate(self.closed):
            if segment.end_ns >= window_start:
                self.archive.keep(Path(segment.path), reason)
                self.closed[index] = replace(segment, protected=True)
                kept.append(Path(segment.path).name)
        position: dict[str, Any] = {"segment": None}
        if self.segment is not None:
            try:
                self.segment.flush()
            except OSError as error:
                self._stop(error)
        if self.segment is not None:
            self.archive.keep(self.segment.directory, reason)
            kept.append(self.segment.name)
            start = self._segment_start if self.segment.start_ns is None else self.segment.start_ns
            position = {"segment": self.segment.name, "offset_s": round((wall_ns - start) / 1e9, 3)}
        where = (f"segment {position['segment']} at {position['offset_s']:.3f} s" if position["segment"]
                 else "not recorded (recording stopped)")
        self.archive.log("fault", f"fault at cycle {event.cycle} ({event.reason}): {where}; kept {', '.join(kept)}",
                         logging.WARNING, cycle=event.cycle, reason=event.reason, fault_time_ns=wall_ns,
                         time_in_bag=iso_time(wall_ns), **position, kept=kept,
                         window_s=self.settings.flight_window_s)

    # -- start-up --------------------------------------------------------------------------------------
    def _adopt_previous_segments(self) -> None:
        """Closed segments of earlier runs come under the guard; segments of a killed recorder are repaired."""
        for path in self.archive.segment_paths():
            segment = self.archive.closed_segment(path)
            if segment is None:
                try:
                    report = repair(path)
                except (PlemError, OSError) as error:
                    self.archive.log("repair_failed", f"segment {path.name} of a killed recorder could not be "
                                     f"repaired: {error}", logging.WARNING, segment=path.name)
                    continue
                self.archive.log("repaired", f"segment {path.name} of a killed recorder repaired: "
                                 f"{report.messages} messages", segment=path.name, messages=report.messages)
                segment = self.archive.closed_segment(path)
            if segment is not None:
                self.closed.append(segment)
