"""What the recorder tells when it cannot write its bags: one WHAT/WHY/HOW naming the real cause.

A full disk (or quota), a directory the recorder's user may not write into, a read-only file system, and a
bag_dir that cannot exist at all (under /proc, a NUL byte, too long a path) each get their own wording;
the HOW names the launch argument that moves the recordings (`bag_dir:=`).
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

from plem.core.files import user_name
from plem.errors import PlemError

#: Errors that mean the disk (or the user's quota) has no room left: recording resumes once there is.
SPACE_ERRORS = frozenset({errno.ENOSPC, errno.EDQUOT})
#: Linux's limits on a path and on one file name in it, in bytes.
PATH_MAX, NAME_MAX = 4096, 255
_MOVE = "pass bag_dir:=DIR to plem launch with a DIR the recorder can write into, or record:=false"


class RecordingError(PlemError):
    """The recorder cannot write its bags where bag_dir points."""


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
                             why=why, how=_MOVE)


def write_problem(directory: Path, error: OSError | ValueError, disk_threshold: float | None = None,
                  detail: str = "") -> RecordingError:
    """The WHAT/WHY/HOW of a write into `directory` that failed with `error`.

    `disk_threshold` is given while recording runs: the summary then says recording stopped, and the HOW
    when it resumes by itself. `detail` ends the WHY (what became of the open segment).
    """
    if isinstance(error, ValueError):
        why = unusable_path(directory) or str(error)
        return RecordingError(f"bag_dir cannot be created: {why}", what="a bag directory the recorder can create",
                              why=why, how=_MOVE)
    running = disk_threshold is not None
    cause = error.strerror or str(error)
    why = "; ".join(part for part in (f"{error.filename or directory}: {cause}", detail) if part)
    user = user_name(os.geteuid())
    resumes = "; the robot runs on and recording resumes by itself once it can write" if running else ""
    if error.errno in SPACE_ERRORS:
        full = f"the quota of {user} on the disk" if error.errno == errno.EDQUOT else "the disk"
        summary = f"{full} holding {directory} is full"
        what = f"room on the disk holding {directory} for the bags"
        how = f"free space there, lower retention_minutes:= or disk_threshold:=, or {_MOVE}"
        if running:
            resumes = (f"; the robot runs on, messages are counted as not recorded, and recording resumes in a new "
                       f"segment once the disk is below disk_threshold {disk_threshold:g} %")
    elif error.errno in (errno.EACCES, errno.EPERM):
        summary = f"cannot write into {directory}: permission denied"
        what = f"a bag directory the recorder's user, {user}, may create files in"
        how = f"give {user} write access to {directory}, or {_MOVE}"
    elif error.errno == errno.EROFS:
        summary = f"cannot write into {directory}: read-only file system"
        what, how = "a bag directory on a writable file system", _MOVE
    else:
        summary = f"cannot write into {directory}: {cause[:1].lower()}{cause[1:]}"
        what, how = "a bag directory the recorder can create and write into", _MOVE
    return RecordingError(f"recording stopped: {summary}" if running else summary, what=what, why=why,
                          how=how + resumes)
