"""What the recorder tells when it cannot write its bags: one WHAT/WHY/HOW naming the real cause.

A full disk (or quota), a directory the recorder's user may not write into, a read-only file system, and a
bag_dir that cannot exist at all (under /proc, a NUL byte, too long a path) each get their own wording;
the HOW names the launch argument that moves the recordings (`bag_dir:=`).
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

from plem.core.files import size_text, user_name
from plem.errors import PlemError

#: Errors that mean the disk (or the user's quota) has no room left: recording resumes once there is.
SPACE_ERRORS = frozenset({errno.ENOSPC, errno.EDQUOT})
#: Linux's limits on a path and on one file name in it, in bytes.
PATH_MAX, NAME_MAX = 4096, 255
MOVE_BAG_DIR = "pass bag_dir:=DIR to plem launch with a DIR the recorder can write into, or record:=false"


class RecordingError(PlemError):
    """The recorder cannot write its bags where bag_dir points."""


class UnsafeDirectory(OSError):
    """A directory on the way to the bags that would let another user steer them; carries its WHAT/WHY/HOW."""

    def __init__(self, path: Path, summary: str, *, what: str, why: str, how: str) -> None:
        super().__init__(errno.EPERM, summary, str(path))
        self.problem = RecordingError(summary, what=what, why=why, how=how)


def unusable_path(path: Path) -> str | None:
    """Why no file system can hold `path` (a NUL byte, too long a path or name); None when it could."""
    text = str(path)
    if "\0" in text:
        return "the path holds a NUL byte, which no file name may contain"
    size = len(os.fsencode(text))
    if size >= PATH_MAX:
        return f"the path is {size} bytes long; Linux allows {PATH_MAX - 1}"
    name = next((part for part in path.parts if len(os.fsencode(part)) > NAME_MAX), None)
    if name is not None:
        return f"'{name[:40]}...' is {len(os.fsencode(name))} bytes long; a file name may have {NAME_MAX}"
    return None


def refuse_unusable(path: Path) -> None:
    """Raise the RecordingError of a bag directory no file system can hold."""
    why = unusable_path(path)
    if why is not None:
        raise RecordingError(f"bag_dir cannot be created: {why}", what="a bag directory the recorder can create",
                             why=why, how=MOVE_BAG_DIR)


def write_problem(directory: Path, error: OSError | ValueError, disk_threshold: float | None = None,
                  detail: str = "") -> RecordingError:
    """The WHAT/WHY/HOW of a write into `directory` that failed with `error`.

    `disk_threshold` is given while recording runs: the summary then says recording stopped, and the HOW
    when it resumes by itself. `detail` ends the WHY (what became of the open segment).
    """
    if isinstance(error, ValueError):
        why = unusable_path(directory) or str(error)
        return RecordingError(f"bag_dir cannot be created: {why}", what="a bag directory the recorder can create",
                              why=why, how=MOVE_BAG_DIR)
    running = disk_threshold is not None
    if isinstance(error, UnsafeDirectory):
        unsafe = error.problem
        return RecordingError(f"recording stopped: {unsafe.summary}" if running else unsafe.summary,
                              what=unsafe.what, why="; ".join(part for part in (unsafe.why, detail) if part),
                              how=unsafe.how + ("; recording resumes by itself once the directory is safe to "
                                                "create" if running else ""))
    cause = error.strerror or str(error)
    why = "; ".join(part for part in (f"{error.filename or directory}: {cause}", detail) if part)
    user = user_name(os.geteuid())
    resumes = "; the robot runs on and recording resumes by itself once it can write" if running else ""
    if error.errno in SPACE_ERRORS:
        full = f"the quota of {user} on the disk" if error.errno == errno.EDQUOT else "the disk"
        summary = f"{full} holding {directory} is full"
        what = f"room on the disk holding {directory} for the bags"
        how = f"free space there, lower retention_minutes:= or disk_threshold:=, or {MOVE_BAG_DIR}"
        if running:
            resumes = (f"; the robot runs on, messages are counted as not recorded, and recording resumes in a new "
                       f"segment once the disk is below disk_threshold {disk_threshold:g} %")
    elif error.errno in (errno.EACCES, errno.EPERM):
        summary = f"cannot write into {directory}: permission denied"
        what = f"a bag directory the recorder's user, {user}, may create files in"
        how = f"give {user} write access to {directory}, or {MOVE_BAG_DIR}"
    elif error.errno == errno.EROFS:
        summary = f"cannot write into {directory}: read-only file system"
        what, how = "a bag directory on a writable file system", MOVE_BAG_DIR
    else:
        summary = f"cannot write into {directory}: {cause[:1].lower()}{cause[1:]}"
        what, how = "a bag directory the recorder can create and write into", MOVE_BAG_DIR
    return RecordingError(f"recording stopped: {summary}" if running else summary, what=what, why=why,
                          how=how + resumes)


def room_problem(directory: Path, percent: float, disk_threshold: float, own_bytes: int, deletable_bytes: int,
                 detail: str = "") -> RecordingError:
    """The WHAT/WHY/HOW of a disk above `disk_threshold` that deleting plem's own segments cannot bring below it."""
    why = "; ".join(part for part in (
        f"the disk is {percent:.1f} % full; plem's segments in {directory} take {size_text(own_bytes)}, of which "
        f"it may delete {size_text(deletable_bytes)} (never the newest, nor those kept for faults), not enough to "
        "bring the disk below the threshold, and it deletes none to make room other files took", detail) if part)
    return RecordingError(
        f"recording stopped: the disk holding {directory} is above disk_threshold {disk_threshold:g} %",
        what=f"the disk holding {directory} below disk_threshold {disk_threshold:g} %, or room plem may free by "
             "deleting its own older segments",
        why=why,
        how=f"free space there, raise disk_threshold:=, or {MOVE_BAG_DIR}; the robot runs on, messages are counted "
            f"as not recorded, and recording resumes in a new segment once the disk is below disk_threshold "
            f"{disk_threshold:g} %")
