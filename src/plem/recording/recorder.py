"""The flight recorder of one robot: monitoring messages into bounded bag segments, with a disk guard.

A `Recorder` is the sink of a `RecordingFeed` (whole batches, `record`) or of a `MonitorFeed` (message by
message, as batches of one). It writes every message into the open segment and starts a new one every
`segment_s` of message time; a segment opens with its first message and is named by that message's stamp,
so a recorder that runs behind still names every segment by what it holds. Given the robot's URDF text, it
records it as robot_description at the start of every segment, so a bag directory alone is enough to replay
the arm.
`maintain()` (about once a second) deletes closed segments past the retention window or while the disk is
fuller than the threshold, never the open one, the newest closed one, nor one kept for a fault. When deleting
what it may would not bring the disk below the threshold (files plem did not write fill it), it deletes nothing
for it: it finishes the open segment and stops recording with a WHAT/WHY/HOW until the disk is below the
threshold again. On a fault it puts the open segment
on disk at once, keeps every segment holding the `flight_window_s` before it, and logs where in the bags the
fault is.

A write the disk refuses stops recording: the open segment is finished with everything written to it
(`SegmentWriter.salvage`), the cause is logged once as WHAT/WHY/HOW, and what follows is counted as not
recorded. That segment stays out of the guard's reach while recording is stopped. Recording resumes in a
new segment, opened by the next message, once the disk is below its threshold again (a full disk) or at the
next guard pass (any other cause); the resume is logged with the messages not recorded meanwhile.

The robot's directory is held open (`Archive`): when it is deleted, moved or replaced while recording, the
next guard pass gives up the segment that went with it, creates the directory again as at start (and with
the same checks: a link or another user's directory put in its place stops recording instead), and says
what was lost; recording goes on in a new segment.
"""

from __future__ import annotations

import errno
import logging
import shutil
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.typesys.store import Typestore

from plem.control.events import Event, EventKind
from plem.errors import PlemError
from plem.middleware.monitor_feed import DESCRIPTION_TOPIC, DESCRIPTION_TYPE, QueueCount
from plem.recording.access import FileAccess
from plem.recording.archive import Archive, directory_size, iso_time
from plem.recording.problems import SPACE_ERRORS, room_problem, write_problem
from plem.recording.repair import repair
from plem.recording.retention import Segment, choose_deletions, deletable
from plem.recording.segment import SegmentWriter, being_written
from plem.recording.settings import RecordingSettings

Clock = Callable[[], int]
DiskUsage = Callable[[Path], tuple[int, int, int]]


#: Events whose flight window the recorder keeps, and the word its log uses for each.
_KEPT_KINDS = {EventKind.FAULT: "fault", EventKind.REACTION: "reaction"}


@dataclass(frozen=True)
class Messages:
    """Messages of one topic (its short name, rt_raw): stamps (ns, ascending) and equal-size payloads (messages ×
    bytes); an rt_event comes alone, with its event."""

    name: str
    stamps: np.ndarray
    payloads: np.ndarray
    event: Event | None = None

    @classmethod
    def one(cls, name: str, wall_ns: int, payload: bytes, event: Event | None = None) -> Messages:
        """A single message."""
        return cls(name, np.array([wall_ns], np.int64), np.frombuffer(payload, np.uint8)[None, :], event)

    def split(self, cut: int) -> tuple[Messages, Messages]:
        """The messages before index `cut` and those from it on."""
        return (Messages(self.name, self.stamps[:cut], self.payloads[:cut], self.event),
                Messages(self.name, self.stamps[cut:], self.payloads[cut:], self.event))


@dataclass
class Stopped:
    """Why recording stopped, since when (wall-clock ns), and what was not recorded since, per topic."""

    problem: PlemError
    errno: int | None
    cause: str                                 # the system's words for it: 'No space left on device'
    since_ns: int
    interrupted: str | None                    # the segment that was open, kept from the guard until recording resumes
    unfinished: bool                           # that segment could not be finished: rebuilt when recording resumes
    lost: Counter[str] = field(default_factory=Counter)

    def describe(self, now_ns: int) -> str:
        """'1794 messages not recorded in 12.3 s (rt_raw 1790, rt_monitor_stats 4)'."""
        topics = ", ".join(f"{name} {count}" for name, count in self.lost.most_common())
        return (f"{self.lost.total()} messages not recorded in {(now_ns - self.since_ns) / 1e9:.1f} s"
                + (f" ({topics})" if topics else ""))

    def fields(self, now_ns: int) -> dict[str, Any]:
        """The event log's fields of a stop that ended: its cause, length and the messages not recorded."""
        return {"reason": self.cause, "not_recorded": self.lost.total(), "not_recorded_topics": dict(self.lost),
                "stopped_s": round((now_ns - self.since_ns) / 1e9, 3)}


class Recorder:
    """Writes one robot's monitoring messages into segments under `settings.directory`.

    `description`: the robot's URDF text, recorded at the start of every segment (None: not recorded).
    `identity`: who records (plem.recording.identity), written into every segment's metadata.yaml.
    Raises RecordingError (WHAT/WHY/HOW) when the directory cannot be created or written into.
    """

    def __init__(self, settings: RecordingSettings, robot_id: str, topics: dict[str, str], store: Typestore,
                 clock: Clock = time.time_ns, disk_usage: DiskUsage = shutil.disk_usage,
                 description: str | None = None, identity: Mapping[str, str] | None = None) -> None:
        self.settings = settings
        self.identity = dict(identity or {})
        self.topics = topics                       # short name (rt_raw) → ROS type
        self._description = None
        if description is not None:
            self.topics = {**topics, DESCRIPTION_TOPIC: DESCRIPTION_TYPE}
            self._description = bytes(store.serialize_cdr(store.types[DESCRIPTION_TYPE](data=description),
                                                          DESCRIPTION_TYPE))
        self.namespace = f"/{robot_id}"
        self.store = store
        self.clock = clock
        self.disk_usage = disk_usage
        self.access = FileAccess(settings.group)
        self.written = 0
        self.unrecorded = 0
        self.closed: list[Segment] = []
        self.segment: SegmentWriter | None = None
        self.stopped: Stopped | None = None
        self._resume_due = False                 # a guard pass found the disk usable: the next message resumes
        self._segment_ns = round(settings.segment_s * 1e9)
        self._segment_start = 0
        self._next_guard = 0
        try:
            self.archive = Archive(settings.directory, robot_id, self.access)
            with tempfile.TemporaryFile(dir=self.archive.root):
                pass                               # the directory takes new files
            self._adopt_previous_segments()
        except (OSError, ValueError) as error:
            raise write_problem(settings.directory, error) from None

    # -- MonitorSink -----------------------------------------------------------------------------------
    def rt_raw(self, cdr: bytes, wall_ns: int) -> None:
        """Record one cycle's RtRaw, already in CDR."""
        self.record([Messages.one("rt_raw", wall_ns, cdr)])

    def joint_state(self, message: Any, wall_ns: int) -> None:
        """Record a sensor_msgs/JointState."""
        self.record([Messages.one("joint_states", wall_ns, message.serialize())])

    def rt_event(self, message: Any, event: Event, wall_ns: int) -> None:
        """Record an RtEvent; a fault or a reaction also keeps the segments of the flight window before it."""
        self.record([Messages.one("rt_events", wall_ns, message.serialize(), event)])

    def rt_monitor_stats(self, message: Any, wall_ns: int) -> None:
        """Record an RtMonitorStats."""
        self.record([Messages.one("rt_monitor_stats", wall_ns, message.serialize())])

    def record(self, batch: list[Messages]) -> None:
        """Write a batch of messages in stamp order, each into the segment its stamp belongs to."""
        batch = [messages for messages in batch if len(messages.stamps)]
        while batch:
            try:
                segment = self._segment_for(min(int(messages.stamps[0]) for messages in batch))
            except OSError as error:
                self._stop(error)
                segment = None
            if segment is None:
                self._not_recorded(batch)
                return
            parts = [messages.split(int(np.searchsorted(messages.stamps, self._segment_start + self._segment_ns)))
                     for messages in batch]
            here = [part for part, _ in parts if len(part.stamps)]
            batch = [rest for _, rest in parts if len(rest.stamps)]
            try:
                self._append(segment, here)
            except OSError as error:
                self._stop(error)
                self._not_recorded(here)
                continue
            try:                                      # a flush refused here is written again by `_stop`
                segment.flush_due()
            except OSError as error:
                self._stop(error)
            for part in here:
                if part.event is not None and part.event.kind in _KEPT_KINDS:
                    self._keep_window(part.event, int(part.stamps[0]))

    def _append(self, segment: SegmentWriter, batch: list[Messages]) -> None:
        segment.append_groups([(f"{self.namespace}/{messages.name}", messages.stamps, messages.payloads)
                               for messages in batch])
        self.written += sum(len(messages.stamps) for messages in batch)

    def _not_recorded(self, batch: list[Messages]) -> None:
        for messages in batch:
            self.unrecorded += len(messages.stamps)
            if self.stopped is not None:
                self.stopped.lost[messages.name] += len(messages.stamps)

    def queues(self) -> list[QueueCount]:
        """The bag itself: messages written, and messages not recorded (recording stopped or a write failed)."""
        return [QueueCount("bag", 0, 0, self.written, self.unrecorded)]

    # -- segments --------------------------------------------------------------------------------------
    def _segment_for(self, wall_ns: int) -> SegmentWriter | None:
        """The segment for a message stamped `wall_ns`: the open one until it is `segment_s` long, else a new one
        opened with (and named by) this message; None while recording is stopped and no guard pass let it resume.
        OSError when a segment cannot be closed or opened."""
        if self.stopped is not None and not self._resume_due:
            return None
        if self.segment is not None and wall_ns - self._segment_start >= self._segment_ns:
            if not self.archive.intact() and not self._recreate():   # checked once a segment too
                return None
            if self.segment is not None:
                self._close()
        if self.segment is None:
            self._resume_due = False
            self._open(wall_ns)
            if self.stopped is not None:
                stopped, self.stopped = self.stopped, None
                self._log_resume(stopped)
        return self.segment

    def _open(self, wall_ns: int) -> None:
        path = self.archive.new_segment_path(wall_ns)
        topics = [(f"{self.namespace}/{name}", ros_type) for name, ros_type in self.topics.items()]
        self.segment = SegmentWriter(path, topics, self.store, self.settings.storage, self.settings.flush_period_s,
                                     self.access, self.identity)
        self._segment_start = wall_ns
        if self._description is not None:
            self._append(self.segment, [Messages.one(DESCRIPTION_TOPIC, wall_ns, self._description)])
        self.archive.log("segment_opened", f"recording into {self.archive.shown(path)}", segment=path.name,
                         storage=self.settings.storage)

    def _close(self) -> None:
        """Finish the open segment (metadata.yaml) and hand it to the guard; OSError leaves it open for `_stop`."""
        segment = self.segment
        if segment is None:
            return
        segment.close()
        self.segment = None
        self._hand_over(segment.directory)
        self.archive.log("segment_closed", f"segment {segment.name} closed: {segment.messages} messages",
                         segment=segment.name, messages=segment.messages)

    def _hand_over(self, path: Path) -> None:
        """Put a segment that ended under the guard: as its metadata tells, or from its start until now."""
        self.closed.append(self.archive.closed_segment(path)
                           or Segment(str(path), self._segment_start, self.clock(), directory_size(path),
                                      self.archive.is_kept(path)))

    def close(self) -> None:
        """Finish the open segment; called once when recording ends. A stop still on is logged with its count."""
        try:
            self._close()
        except OSError as error:
            self._stop(error)
        if self.stopped is not None:
            now = self.clock()
            self.archive.log("recording_ended", f"recording ended while stopped ({self.stopped.cause}): "
                             f"{self.stopped.describe(now)}", logging.WARNING, **self.stopped.fields(now))
        self.archive.close()

    # -- the disk --------------------------------------------------------------------------------------
    def _stop(self, error: OSError) -> None:
        """A write failed: finish the open segment with what it holds, stop recording, and say why once."""
        segment, self.segment = self.segment, None
        outcome, complete = "no new segment could be opened", True
        if segment is not None:
            complete = segment.salvage()
            self.written -= segment.lost           # a transaction sqlite3 rolled back
            self.unrecorded += segment.lost
            self._hand_over(segment.directory)
            outcome = (f"segment {segment.name} finished with its {segment.messages} messages" if complete else
                       f"segment {segment.name} left unfinished with {segment.messages} messages, "
                       f"{segment.lost} more lost with its last transaction (rebuilt once recording resumes, "
                       "or by `plem bag repair`)")
        problem = write_problem(self.settings.directory, error, self.settings.disk_threshold, outcome)
        if self.stopped is None:
            self.stopped = Stopped(problem, error.errno, error.strerror or str(error), self.clock(),
                                   None if segment is None else str(segment.directory), not complete)
        elif self.stopped.errno == error.errno:
            return                                 # a resume that failed for the same reason: said already
        else:
            self.stopped = replace(self.stopped, problem=problem, errno=error.errno,
                                   cause=error.strerror or str(error))
        self.archive.log("recording_stopped", problem.render(), logging.ERROR, reason=problem.why,
                         errno=error.errno, segment=None if segment is None else segment.name)

    def maintain(self) -> None:
        """Apply retention and the disk guard (at most once per guard period); recreate a deleted robot directory;
        resume a stopped recording."""
        now = self.clock()
        if now < self._next_guard:
            return
        self._next_guard = now + round(self.settings.guard_period_s * 1e9)
        if not self.archive.intact() and not self._recreate():
            return
        try:
            total, used, _ = self.disk_usage(self.archive.root)
        except OSError:
            return                                 # the directory is gone: writing says why
        interrupted = self.stopped.interrupted if self.stopped is not None else None

        def percent(freed: int) -> float:
            return 100.0 * (used - freed) / total

        deletions = choose_deletions([segment for segment in self.closed if segment.path != interrupted], now,
                                     round(self.settings.retention_s * 1e9), self.settings.disk_threshold, percent)
        freed = 0
        for deletion in deletions:
            try:
                self.archive.delete(deletion)
            except OSError as error:
                self.archive.log("delete_failed", f"segment {Path(deletion.segment.path).name} not deleted: "
                                 f"{error}", logging.WARNING, segment=Path(deletion.segment.path).name)
                continue
            freed += deletion.segment.size
            self.closed.remove(deletion.segment)
        if percent(freed) > self.settings.disk_threshold:
            self._stop_for_room(percent(freed))
        elif self.stopped is not None:
            self._resume_due = True                              # the next message opens a segment

    def _stop_for_room(self, percent: float) -> None:
        """The disk is above disk_threshold and nothing plem may delete brings it below: finish the open segment
        (it is then the newest, which the guard keeps) and stop recording until the disk is below it again."""
        if self.stopped is not None and self.stopped.errno in SPACE_ERRORS:
            return                                               # stopped for room already: said once
        detail = ""
        if self.segment is not None:
            name, count = self.segment.name, self.segment.messages
            try:
                self._close()
            except OSError as error:
                self._stop(error)
                return
            detail = f"segment {name} finished with its {count} messages"
        threshold = self.settings.disk_threshold
        problem = room_problem(self.archive.directory, percent, threshold,
                               sum(segment.size for segment in self.closed),
                               sum(segment.size for segment in deletable(self.closed)), detail)
        cause = f"disk {percent:.1f} % full, above disk_threshold {threshold:g} %"
        if self.stopped is None:
            self.stopped = Stopped(problem, errno.ENOSPC, cause, self.clock(), None, False)
        else:
            self.stopped = replace(self.stopped, problem=problem, errno=errno.ENOSPC, cause=cause)
        self.archive.log("recording_stopped", problem.render(), logging.ERROR, reason=problem.why,
                         errno=None, percent=round(percent, 1), segment=None)

    def _recreate(self) -> bool:
        """The robot's directory was deleted, moved or replaced: finish the open segment where it is (or give it up
        with a deleted directory) and create the directory again, as at start; False (recording stopped, said why)
        when that is refused or fails."""
        segment, self.segment = self.segment, None
        went, lost = "no segment was open", 0
        if segment is not None:
            try:
                segment.close()                                  # moved: it is finished where it went
                went = f"segment {segment.name} finished where the directory went, {segment.messages} messages"
            except OSError:                                      # deleted: it went with the directory
                went, lost = f"segment {segment.name} went with it, {segment.messages} messages", segment.messages
        closed, self.closed = len(self.closed), []
        try:
            self.archive.recreate()
        except OSError as error:
            self._stop(error)
            return False
        self.archive.log("directory_recreated", f"{self.archive.directory} was deleted, moved or replaced while "
                         f"recording ({went}; {closed} closed segments no longer under the guard): created it "
                         "again, recording goes on in a new segment", logging.WARNING,
                         lost_with_directory=lost,
                         segment=None if segment is None else segment.name)
        if self.stopped is not None and self.stopped.interrupted is not None:
            self.stopped = replace(self.stopped, interrupted=None, unfinished=False)   # gone with the directory
        return True

    def _log_resume(self, stopped: Stopped) -> None:
        """A new segment opened after a stop: say so; the segment the stop interrupted is rebuilt if unfinished."""
        now = self.clock()
        name = self.segment.name if self.segment is not None else ""
        self.archive.log("recording_resumed", f"recording resumed in segment {name} after a stop "
                         f"({stopped.cause}): {stopped.describe(now)}", logging.WARNING, **stopped.fields(now))
        if stopped.interrupted is not None and stopped.unfinished:
            self.closed = [segment for segment in self.closed if segment.path != stopped.interrupted]
            self._repair(Path(stopped.interrupted))

    # -- the flight recorder ---------------------------------------------------------------------------
    def _keep_window(self, event: Event, wall_ns: int) -> None:
        """Put the seconds before a fault (or a reaction) on disk, keep their segments, and log its bag position."""
        kind = _KEPT_KINDS[event.kind]
        reason = f"{kind} at {iso_time(wall_ns)}: {event.reason}"
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
        self.archive.log(kind, f"{kind} at cycle {event.cycle} ({event.reason}): {where}; kept {', '.join(kept)}",
                         logging.WARNING, cycle=event.cycle, reason=event.reason, **{f"{kind}_time_ns": wall_ns},
                         time_in_bag=iso_time(wall_ns), **position, kept=kept,
                         window_s=self.settings.flight_window_s)

    # -- start-up --------------------------------------------------------------------------------------
    def _adopt_previous_segments(self) -> None:
        """Closed segments of earlier runs come under the guard; unfinished ones (a killed recorder) are repaired.

        A segment another recorder holds open is left alone.
        """
        for path in self.archive.segment_paths():
            if being_written(path):
                continue
            try:
                segment = self.archive.closed_segment(path)
            except PlemError as error:
                self.archive.log("segment_unreadable", f"segment {path.name} left alone: {error.summary}: "
                                 f"{error.why}", logging.WARNING, segment=path.name)
                continue
            if segment is None:
                self._repair(path)
            else:
                self.closed.append(segment)

    def _repair(self, path: Path) -> None:
        """Rebuild an unfinished segment (a killed recorder's, or one a full disk interrupted); it joins the guard."""
        try:
            report = repair(path)
            segment = self.archive.closed_segment(path)
        except PlemError as error:
            self.archive.log("repair_failed", f"unfinished segment {path.name} could not be repaired: "
                             f"{error.summary}: {error.why}", logging.WARNING, segment=path.name)
            return
        self.archive.log("repaired", f"unfinished segment {path.name} repaired: {report.messages} messages",
                         segment=path.name, messages=report.messages)
        if segment is not None:
            self.closed.append(segment)
