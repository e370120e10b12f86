"""The continuous export's work: one robot's closed segments into the fleet dataset as they close.

`plem.fleet.follow` runs it in the recorder's idle-priority child process (`export_dir:=`). Every `PERIOD_S` it
looks for segments closed since (their metadata.yaml written, no recorder's lock) and exports each once, as
`plem bag export` does. A local dataset is never written past `disk_threshold` (the export waits for room, said
once); retention deletes bags whether or not they were exported, and a segment deleted before its export is
reported once, then forgotten.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path

from plem.errors import PlemError
from plem.fleet.destination import Destination, open_destination
from plem.fleet.export import ExportReport, disk_room, export_segments, still_open
from plem.recording.segment import bag_file

_log = logging.getLogger("plem.export")
#: How often the robot's directory is looked at for closed segments.
PERIOD_S = 2.0
#: How long a destination that failed (unreachable store, no room) is left before it is tried again.
RETRY_S = 30.0


def segment_names(robot_dir: Path) -> set[str]:
    """The names of the robot's segment directories (and anything else not hidden in its directory)."""
    try:
        return {child.name for child in robot_dir.iterdir() if not child.name.startswith(".")}
    except OSError:
        return set()                                 # recreated by the recorder meanwhile: looked at next time


def closed(segment: Path) -> bool:
    """Whether a segment is closed: its metadata.yaml (the recorder writes it when it closes one) is there and no
    recorder holds it."""
    return (segment / "metadata.yaml").is_file() and bag_file(segment) is not None and not still_open(segment)


class Follower:
    """Exports one robot's segments as they close; `handled` holds those exported or reported once (names still in
    the robot's directory, so it stays as small as the directory)."""

    def __init__(self, robot_dir: Path, destination: Destination, threshold: float) -> None:
        self.robot_dir = robot_dir
        self.destination = destination
        self.room = disk_room(destination, threshold)
        self.handled: set[str] = set()
        self.seen: set[str] = set()                  # found closed once: its deletion before export is reported
        self.held_back: str | None = None            # why the destination refused last time (said once)

    def step(self) -> bool:
        """One pass: export what closed; False when the destination refused (try again after `RETRY_S`)."""
        present = segment_names(self.robot_dir)
        gone = [self.robot_dir / name for name in sorted(self.seen - self.handled - present)]
        self.handled &= present
        self.seen &= present
        candidates = [self.robot_dir / name for name in sorted(present - self.handled) if closed(self.robot_dir / name)]
        if not candidates and not gone:
            return True
        self.seen.update(path.name for path in candidates)
        report = ExportReport()
        try:
            export_segments(self.robot_dir.name, [*gone, *candidates], self.destination, report, self.room)
        except PlemError as error:
            if error.summary != self.held_back:
                _log.warning("%s", error.log_text())
                self.held_back = error.summary
            self.handled.update(name.split("/", 1)[1] for name in [*report.exported, *report.already])
            return False
        self.held_back = None
        for name in report.exported:
            _log.info("exported %s to %s", name, self.destination.text)
        for problem in report.problems:
            _log.warning("%s", problem.log_text())
        self.handled.update(path.name for path in candidates)
        return True


def follow(robot_dir: Path, text: str, threshold: float, stop: threading.Event) -> None:
    """Export the robot's closed segments until `stop`, then one last pass; a destination that cannot be opened is
    said once and tried again every `RETRY_S`."""
    follower: Follower | None = None
    said: str | None = None
    while True:
        stopping = stop.is_set()
        try:
            if follower is None:
                follower = Follower(robot_dir, open_destination(text, "export_dir:="), threshold)
            wait = PERIOD_S if follower.step() else RETRY_S
        except PlemError as error:
            if error.summary != said:
                _log.warning("%s", error.log_text())
                said = error.summary
            wait = RETRY_S
        if stopping:
            return
        stop.wait(wait)
