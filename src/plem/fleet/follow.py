"""Continuous export: a recorder's closed segments into the fleet dataset as they close (`export_dir:=DEST`).

The recorder starts this as a child process of its own (`python -m plem.fleet.follow ROBOT_DIR DEST THRESHOLD`)
at the lowest priority the system has (SCHED_IDLE, nice 19): it runs on CPU time nothing else wants, never in
the real-time driver, and never holds up the recorder (another process, so no interpreter lock in common). It
looks for newly closed segments every `PERIOD_S` and exports each once, as `plem bag export` does. It obeys the
recorder's disk rules: a local dataset is never written past `disk_threshold` (the export waits for room,
said once), retention deletes bags whether or not they were exported, and a segment deleted before its export
is reported once, then forgotten. On SIGTERM (the recorder is ending) it makes one last pass and exits.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import threading
from pathlib import Path

from plem.errors import PlemError
from plem.fleet.destination import Destination, open_destination
from plem.fleet.export import ExportReport, disk_room, export_segments, still_open
from plem.launch.component import begin
from plem.recording.segment import bag_file

_log = logging.getLogger("plem.export")
#: How often the robot's directory is looked at for closed segments.
PERIOD_S = 2.0
#: How long a destination that failed (unreachable store, no room) is left before it is tried again.
RETRY_S = 30.0


def lower_priority() -> None:
    """Run only on CPU time nothing else wants: SCHED_IDLE where the system has it, and nice 19."""
    with contextlib.suppress(AttributeError, OSError):
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
    os.setpriority(os.PRIO_PROCESS, 0, 19)


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
    """Export the robot's closed segments until `stop`, then one last pass."""
    follower: Follower | None = None
    while True:
        stopping = stop.is_set()
        try:
            if follower is None:
                follower = Follower(robot_dir, open_destination(text, "export_dir:="), threshold)
            wait = PERIOD_S if follower.step() else RETRY_S
        except PlemError as error:
            _log.warning("%s", error.log_text())
            wait = RETRY_S
        if stopping:
            return
        stop.wait(wait)


def main(argv: list[str] | None = None) -> int:
    """The export process of one recorder: ROBOT_DIR DEST DISK_THRESHOLD."""
    robot_dir, text, threshold = (sys.argv[1:] if argv is None else argv)[:3]
    stop = begin("export")
    lower_priority()
    follow(Path(robot_dir), text, float(threshold), stop)
    return 0


if __name__ == "__main__":
    sys.exit(main())
