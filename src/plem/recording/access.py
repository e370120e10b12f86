"""Who may read a robot's recordings: its owner only, or also the group named by `shm_group:=`.

Bags, keep marks and the event log get the same access as the robot's shared memory: files 0600 and
directories 0700 by default, 0640 and 0750 with the group when one is given. rosbags creates the bag
files itself, so the recorder process narrows its umask to owner-only first (nothing is ever readable
by others, not even for a moment) and then widens to the group what it created.
"""

from __future__ import annotations

import errno
import os
import stat
from dataclasses import dataclass
from pathlib import Path


def restrict_umask() -> None:
    """Make every file this process creates owner-only from its first moment; never loosens the umask."""
    os.umask(os.umask(0o077) | 0o077)


@dataclass(frozen=True)
class FileAccess:
    """The mode and group of recorded files and directories."""

    group: int | None = None

    @property
    def file_mode(self) -> int:
        """Permission bits of a recorded file: 0600, or 0640 with a group."""
        return 0o600 if self.group is None else 0o640

    @property
    def directory_mode(self) -> int:
        """Permission bits of a recording directory: 0700, or 0750 with a group."""
        return 0o700 if self.group is None else 0o750

    @classmethod
    def like(cls, directory: Path) -> FileAccess:
        """The access a directory already has: its group when the group may read it, else owner only."""
        status = directory.stat()
        return cls(status.st_gid if status.st_mode & stat.S_IRGRP else None)

    def apply_fd(self, fd: int) -> None:
        """Give an open file or directory this access (when it differs), without going through its name again."""
        status = os.fstat(fd)
        mode = self.directory_mode if stat.S_ISDIR(status.st_mode) else self.file_mode
        if stat.S_IMODE(status.st_mode) != mode:
            os.fchmod(fd, mode)
        if self.group is not None and status.st_gid != self.group:
            os.fchown(fd, -1, self.group)

    def apply(self, path: Path) -> None:
        """Give one file or directory this access; a symbolic link, or a file already gone, is left alone."""
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
        except FileNotFoundError:
            return
        except OSError as error:
            if error.errno == errno.ELOOP:
                return
            raise
        try:
            self.apply_fd(fd)
        finally:
            os.close(fd)

    def apply_tree(self, directory: Path) -> None:
        """A directory and everything in it (a bag: its storage file, metadata.yaml)."""
        self.apply(directory)
        for path in directory.rglob("*"):
            self.apply(path)


#: The default access: owner only, no group.
OWNER_ONLY = FileAccess()
