"""POSIX shared-memory segments (/dev/shm) created owner-only, exclusively, and mapped into the process.

Python's `multiprocessing.shared_memory` registers every segment with a resource tracker that may unlink
it when any attaching process exits, so plem opens `/dev/shm/<name>` itself: the creator alone decides
when a segment goes away.

/dev/shm is writable by every local user, so a name may be taken by someone else first. The rule:
- a creator makes a name only if it is free (O_EXCL, never through a symbolic link); an existing name
  is replaced only when it is a regular file of the creating user, never when it is another user's
  or a FIFO, link or directory;
- a client maps a name only if it is a regular file of its own user or of root (a root driver serving
  `shm_group:=`), opened without following a link or waiting on a FIFO.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import re
import stat
from pathlib import Path

from plem.core.files import UntrustedFile, open_trusted, trusted_owners, user_name
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


def _not_claimable(name: str, found: UntrustedFile) -> SegmentError:
    """A creator finds the name taken by a file it must neither open nor remove."""
    me = user_name(os.geteuid())
    return SegmentError(f"shared memory {name} is taken by a {found.kind} of {found.owner}",
                        what=f"{found.path} free, or a segment of {me} left by an earlier run of this robot",
                        why=f"{found.path} is a {found.kind} owned by {found.owner}; plem creates, replaces "
                            "and removes only regular files of its own user there",
                        how=f"if no robot of {found.owner} uses it, remove it as that user or as root "
                            f"(`rm {found.path}`); or launch this robot with another robot_id:=...")


def _not_trusted(name: str, found: UntrustedFile) -> SegmentError:
    """A client finds a file it must not map: not a regular file, or not its own user's nor root's."""
    if found.kind != "regular file":
        why = f"{found.path} is a {found.kind} owned by {found.owner}, not a segment a driver created"
    else:
        why = (f"{found.path} is owned by {found.owner}; mapping it would read the state of, and send "
               "commands to, a process of that user")
    return SegmentError(f"shared memory {name} is not a segment of your user or root",
                        what=f"a regular file owned by {user_name(os.geteuid())} or by root "
                             "(a robot launched by root with shm_group:=)",
                        why=why,
                        how=f"run as the user that launched the robot; if that is not a robot, remove it as "
                            f"{found.owner} or root (`rm {found.path}`) and start the robot with `plem launch`")


def _give_to_group(fd: int, name: str, group: int) -> None:
    """Make the segment's group `group` (shm_group:=); a group plem may not give it to is a SegmentError."""
    try:
        os.fchown(fd, -1, group)
    except (OSError, OverflowError) as error:
        raise SegmentError(f"shared memory {name} cannot be given to group {group}",
                           what="shm_group:= naming an existing group you are a member of (root: any group)",
                           why=str(error) if isinstance(error, OverflowError) else error.strerror or str(error),
                           how="pass shm_group:= one of the groups `id -Gn` lists, or leave it out for owner-only "
                               "shared memory") from None


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
        """Create a new segment of `size` bytes; SegmentError when the name is taken (it is left alone)."""
        path = segment_path(name)
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_RDWR | os.O_NOFOLLOW | os.O_CLOEXEC, mode)
        except FileExistsError:
            raise _not_claimable(name, UntrustedFile(path, os.lstat(path))) from None
        try:
            os.fchmod(fd, mode)  # not narrowed by the umask
            if group is not None:
                _give_to_group(fd, name, group)
            os.ftruncate(fd, size)
            return cls(name, fd, size, writable=True)
        except BaseException:  # nothing of a segment that could not be made stays behind
            with contextlib.suppress(OSError):
                os.close(fd)
            path.unlink(missing_ok=True)
            raise

    @classmethod
    def open(cls, name: str, writable: bool = False) -> SharedSegment:
        """Map an existing segment of this user or root; SegmentError when there is none or it is foreign."""
        path = segment_path(name)
        try:
            fd, status = open_trusted(path, os.O_RDWR if writable else os.O_RDONLY, trusted_owners())
        except UntrustedFile as found:
            raise _not_trusted(name, found) from None
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
                               how="run as the user that launched the robot, or launch it with "
                                   "shm_group:=<a group of yours>") from None
        if status.st_size == 0:
            os.close(fd)
            raise SegmentError(f"shared memory {name} is empty", what="a segment initialised by the driver",
                               why=f"{path} has size 0 (a driver is starting or crashed while starting)",
                               how="wait a moment and retry, or restart the robot")
        return cls(name, fd, status.st_size, writable)

    @staticmethod
    def exists(name: str) -> bool:
        """Whether anything (of any user, of any kind) has the name."""
        return os.path.lexists(segment_path(name))

    @staticmethod
    def own_leftover(name: str) -> bool:
        """True when the name is a regular file of this user (its creator may replace it), False when free.

        SegmentError when another user's file or a FIFO, link or directory has the name: that is
        neither opened nor removed.
        """
        path = segment_path(name)
        try:
            status = os.lstat(path)
        except FileNotFoundError:
            return False
        if not stat.S_ISREG(status.st_mode) or status.st_uid != os.geteuid():
            raise _not_claimable(name, UntrustedFile(path, status))
        return True

    @staticmethod
    def unlink(name: str) -> None:
        """Remove the name if it is this user's segment; processes that mapped it keep their mapping.

        A name taken by another user (or by something that is not a segment) raises SegmentError and stays.
        """
        if SharedSegment.own_leftover(name):
            segment_path(name).unlink(missing_ok=True)

    def close(self) -> None:
        """Unmap (the name stays until `unlink`)."""
        self.buffer.release()
        self._mmap.close()
