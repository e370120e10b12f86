"""POSIX shared-memory segments (/dev/shm) created owner-only, exclusively, and mapped into the process.

Python's `multiprocessing.shared_memory` registers every segment with a resource tracker that may unlink
it when any attaching process exits, so plem opens `/dev/shm/<name>` itself: the creator alone decides
when a segment goes away.
"""

from __future__ import annotations

import mmap
import os
import re
from pathlib import Path

from plem.errors import ConfigError, PlemError

SHM_DIRECTORY = Path("/dev/shm")
_NAME = re.compile(r"/[A-Za-z0-9_.-]{1,250}")


class SegmentError(PlemError):
    """A shared-memory segment is missing, foreign, already owned or cannot be created."""


def segment_path(name: str) -> Path:
    """The file behind a POSIX shared-memory name such as '/indy_joint_actual_values'."""
    if not _NAME.fullmatch(name):
        raise ConfigError(f"invalid shared-memory name {name!r}",
                          what="'/' followed by letters, digits, '_', '.' or '-'",
                          why=f"got {name!r}", how="use a robot_id made of letters, digits and '_'")
    return SHM_DIRECTORY / name[1:]


class SharedSegment:
    """One mapped segment; `buffer` is a memoryview over the whole mapping."""

    def __init__(self, name: str, fd: int, size: int, writable: bool) -> None:
        self.name = name
        self.size = size
        self.writable = writable
        self._mmap = mmap.mmap(fd, size, prot=mmap.PROT_READ | (mmap.PROT_WRITE if writable else 0))
        os.close(fd)
        self.buffer = memoryview(self._mmap)

    @classmethod
    def create(cls, name: str, size: int, mode: int = 0o600, group: int | None = None) -> SharedSegment:
        """Create a new segment of `size` bytes, failing with FileExistsError when the name is taken."""
        path = segment_path(name)
        fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_RDWR, mode)
        try:
            os.fchmod(fd, mode)  # not narrowed by the umask
            if group is not None:
                os.fchown(fd, -1, group)
            os.ftruncate(fd, size)
        except OSError:
            os.close(fd)
            path.unlink(missing_ok=True)
            raise
        return cls(name, fd, size, writable=True)

    @classmethod
    def open(cls, name: str, writable: bool = False) -> SharedSegment:
        """Map an existing segment; SegmentError when there is none."""
        path = segment_path(name)
        try:
            fd = os.open(path, os.O_RDWR if writable else os.O_RDONLY)
        except FileNotFoundError:
            raise SegmentError(f"shared memory {name} does not exist",
                               what=f"{path}, created by the RT driver of this robot",
                               why="no such segment: the driver is not running, or uses another robot_id",
                               how="start the robot with `plem launch` (bus:=mock for the simulated arm) "
                                   "and check robot_id / PLEM_ROBOT_ID") from None
        except PermissionError:
            raise SegmentError(f"no permission to open shared memory {name}",
                               what="read access to the robot's shared memory",
                               why=f"{path} belongs to another user (segments are owner-only by default)",
                               how="run as the user that launched the robot, or launch it with a group") from None
        size = os.fstat(fd).st_size
        if size == 0:
            os.close(fd)
            raise SegmentError(f"shared memory {name} is empty", what="a segment initialised by the driver",
                               why=f"{path} has size 0 (a driver is starting or crashed while starting)",
                               how="wait a moment and retry, or restart the robot")
        return cls(name, fd, size, writable)

    @staticmethod
    def exists(name: str) -> bool:
        return segment_path(name).exists()

    @staticmethod
    def unlink(name: str) -> None:
        """Remove the name; processes that mapped it keep their mapping until they close it."""
        segment_path(name).unlink(missing_ok=True)

    def close(self) -> None:
        """Unmap (the name stays until `unlink`)."""
        self.buffer.release()
        self._mmap.close()
