"""One robot's bag directory: its segments, the flight recorder's keep marks, and its event log.

Layout under `bag_dir/{robot_id}/`:
- `{robot_id}_YYYY_MM_DD-HH_MM_SS[_N]/`: one rosbag2 bag per segment (names sort in time order);
- `{segment}.keep`: the segment holds seconds before a fault and is never deleted automatically;
- `event_log.jsonl`: one JSON object per line for every segment opened or closed, deletion (with its
  reason), fault (with its bag position), repair, stop and resume of recording.
The robot's directory, the keep marks and the event log get the archive's `FileAccess`. The archive holds
the robot's directory open (`RobotDirectory`) and reaches everything in it through that handle; only real
directories of the recorder's user are taken for segments, and the event log is appended to only when it is a
regular file of that user (anything else in there was put by someone else while the directory was open to
them).
"""

from __future__ import annotations

import errno
import json
import logging
import os
import shutil
import stat
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from plem.core.config.yaml_document import load_yaml
from plem.core.files import file_kind, read_regular_text, user_name, write_atomic
from plem.errors import ConfigError
from plem.recording.access import OWNER_ONLY, FileAccess
from plem.recording.retention import Deletion, Segment
from plem.recording.robot_directory import RobotDirectory

_log = logging.getLogger("plem.recorder")
EVENT_LOG = "event_log.jsonl"
KEEP_SUFFIX = ".keep"
#: The largest event log read back (a recorder appends a few hundred bytes a minute).
MAX_EVENT_LOG_BYTES = 256 * 1024 * 1024


def iso_time(wall_ns: int) -> str:
    """UTC time with milliseconds, e.g. 2026-11-21T10:15:00.123Z."""
    seconds, ns = divmod(wall_ns, 1_000_000_000)
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(seconds)) + f".{ns // 1_000_000:03d}Z"


def directory_size(path: Path) -> int:
    """Bytes of all files under `path`, what deleting it frees."""
    return sum(entry.stat().st_size for entry in path.rglob("*") if entry.is_file())


def bag_metadata(path: Path) -> dict[str, Any] | None:
    """The `rosbag2_bagfile_information` of a bag's metadata.yaml; None without one.

    A metadata.yaml that is not a small regular YAML file of that shape is a ConfigError saying why.
    """
    metadata = path / "metadata.yaml"
    if not metadata.exists():
        return None
    document = load_yaml(metadata, "rosbag2 metadata.yaml")
    info = document.get("rosbag2_bagfile_information") if isinstance(document, dict) else None
    if not isinstance(info, dict):
        raise ConfigError(f"{metadata} is not rosbag2 metadata", what="a mapping rosbag2_bagfile_information",
                          why="the file holds no such mapping", how="restore the file, or delete the segment")
    return info


def extent_of(info: dict[str, Any]) -> tuple[int, int]:
    """(start, end) in ns since the epoch of a bag's metadata; KeyError, TypeError or ValueError if malformed."""
    start = int(info["starting_time"]["nanoseconds_since_epoch"])
    return start, start + int(info["duration"]["nanoseconds"])


def bag_extent(path: Path) -> tuple[int, int] | None:
    """(start, end) in ns since the epoch from a bag's metadata.yaml; None without one, ConfigError if malformed."""
    info = bag_metadata(path)
    if info is None:
        return None
    try:
        return extent_of(info)
    except (KeyError, TypeError, ValueError) as error:
        raise ConfigError(f"{path / 'metadata.yaml'} has no valid start and duration",
                          what="starting_time.nanoseconds_since_epoch and duration.nanoseconds as integers",
                          why=f"{type(error).__name__}: {error}", how="restore the file, or delete the segment") \
            from None


class Archive:
    """The bag directory of one robot, held open: `directory` names it in messages, `root` reaches into it."""

    def __init__(self, directory: Path, robot_id: str, access: FileAccess = OWNER_ONLY) -> None:
        self.directory = directory
        self.robot_id = robot_id
        self.access = access
        self.handle = RobotDirectory(directory, access)

    @property
    def root(self) -> Path:
        """The robot's directory through its handle (`/proc/self/fd/N`), for every path the recorder opens."""
        return self.handle.root

    def segment_paths(self) -> list[Path]:
        """Every segment directory (a real directory of this user), oldest first."""
        prefix, uid = f"{self.robot_id}_", os.geteuid()
        with os.scandir(self.root) as entries:
            return sorted(self.root / entry.name for entry in entries
                          if entry.name.startswith(prefix) and entry.is_dir(follow_symlinks=False)
                          and entry.stat(follow_symlinks=False).st_uid == uid)

    def new_segment_path(self, wall_ns: int) -> Path:
        """A fresh segment directory name for a segment starting at `wall_ns`."""
        stamp = time.strftime("%Y_%m_%d-%H_%M_%S", time.gmtime(wall_ns // 1_000_000_000))
        path = self.root / f"{self.robot_id}_{stamp}"
        number = 1
        while os.path.lexists(path):
            path = self.root / f"{self.robot_id}_{stamp}_{number}"
            number += 1
        return path

    def shown(self, path: Path) -> Path:
        """A path under the handle as the user knows it (`bag_dir/robot_id/name`)."""
        return self.directory / path.name

    def closed_segment(self, path: Path) -> Segment | None:
        """A finished segment as retention sees it; None when it has no metadata.yaml (killed or open)."""
        extent = bag_extent(path)
        if extent is None:
            return None
        return Segment(str(path), *extent, directory_size(path), self.is_kept(path))

    def keep(self, path: Path, reason: str) -> None:
        """Mark a segment as one the guard must never delete."""
        write_atomic(path.with_name(path.name + KEEP_SUFFIX), json.dumps({"reason": reason}) + "\n",
                     mode=self.access.file_mode, group=self.access.group)

    def is_kept(self, path: Path) -> bool:
        """Whether a segment has a keep mark (it holds seconds before a fault)."""
        return path.with_name(path.name + KEEP_SUFFIX).exists()

    def delete(self, deletion: Deletion) -> None:
        """Remove a segment and log why."""
        path = Path(deletion.segment.path)
        shutil.rmtree(path)
        self.log("deleted", f"deleted segment {path.name}: {deletion.reason}", segment=path.name,
                 bytes=deletion.segment.size, reason=deletion.reason)

    def intact(self) -> bool:
        """Whether the robot's directory is still where it was named (not deleted, moved or replaced)."""
        return self.handle.intact()

    def recreate(self) -> None:
        """Create the robot's directory again, as at start; raises OSError (UnsafeDirectory) as at start."""
        self.handle.reopen()

    def close(self) -> None:
        """Let go of the robot's directory."""
        self.handle.close()

    def log(self, kind: str, message: str, level: int = logging.INFO, **fields: Any) -> None:
        """One entry in the event log, also on the recorder's log; a log the disk refuses is reported, not raised."""
        _log.log(level, "%s", message)
        now = time.time_ns()
        entry = {"time": iso_time(now), "time_ns": now, "kind": kind, "message": message, **fields}
        flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
        try:
            with open(os.open(EVENT_LOG, flags, self.access.file_mode, dir_fd=self.handle.fd), "a",
                      encoding="utf-8") as handle:
                status = os.fstat(handle.fileno())
                if not stat.S_ISREG(status.st_mode) or status.st_uid != os.geteuid():
                    raise OSError(errno.EPERM, f"a {file_kind(status.st_mode)} of {user_name(status.st_uid)}, "
                                               "not the recorder's own log")
                self.access.apply_fd(handle.fileno())
                handle.write(json.dumps(entry) + "\n")
        except OSError as error:
            _log.error("event log %s not written: %s", self.directory / EVENT_LOG, error)


def read_event_log(directory: Path) -> Iterator[dict[str, Any]]:
    """The entries of a robot's event log, oldest first; a torn or malformed line is skipped.

    A log that is not a regular UTF-8 file of at most MAX_EVENT_LOG_BYTES is a ConfigError saying why.
    """
    path = directory / EVENT_LOG
    if not path.exists():
        return
    for line in read_regular_text(path, MAX_EVENT_LOG_BYTES, "recorder event log").splitlines():
        try:
            entry = json.loads(line)
        except (json.JSONDecodeError, RecursionError):
            continue
        if isinstance(entry, dict):
            yield entry
