"""Files written atomically, files read only when they are regular and of a sane size, and files opened
only when they are what and whose they should be.

A reader or a crash sees the old file or the new one, never a torn one. A file a user names is read only
when it is a regular file below a size cap, so a FIFO cannot hang a command and /dev/zero cannot eat the
memory. A file in a directory every user may write into (/dev/shm) is opened without following a symbolic
link or waiting on a FIFO, and only when it is a regular file of a user the reader trusts.
"""

from __future__ import annotations

import errno
import os
import pwd
import secrets
import stat
import tempfile
from collections.abc import Collection
from pathlib import Path

from plem.errors import ConfigError

_KINDS = {stat.S_IFREG: "regular file", stat.S_IFDIR: "directory", stat.S_IFLNK: "symbolic link",
          stat.S_IFIFO: "FIFO", stat.S_IFSOCK: "socket", stat.S_IFCHR: "character device",
          stat.S_IFBLK: "block device"}


def write_atomic(path: Path, data: str | bytes, mode: int = 0o644, group: int | None = None) -> None:
    """Write `data` to a temporary file beside `path`, fsync it, rename it over `path`, fsync the folder.

    The file gets exactly `mode` (and `group`, when given) before it appears under its name, whatever
    the process's umask.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    fd, temp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            os.fchmod(handle.fileno(), mode)
            if group is not None:
                os.fchown(handle.fileno(), -1, group)
            handle.write(payload)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temp_name, path)
    except BaseException:
        Path(temp_name).unlink(missing_ok=True)
        raise
    _sync_folder(path.parent)


def write_shared(path: Path, data: str | bytes, group: int | None = None) -> None:
    """`write_atomic` for a file beside a robot's shared memory: owner-only, or 0640 readable by `group`."""
    write_atomic(path, data, mode=0o600 if group is None else 0o640, group=group)


def remove_own(path: Path) -> None:
    """Remove `path` if this user owns it: what another user put in a shared directory is not ours to remove."""
    try:
        if os.lstat(path).st_uid == os.geteuid():
            os.unlink(path)
    except FileNotFoundError:
        pass


def write_new(path: Path, data: str | bytes, mode: int = 0o644) -> None:
    """Create `path` holding `data`, complete or not at all; FileExistsError when `path` is already there.

    The file is written and synced under a temporary name, then hard-linked to `path`: the link fails when
    `path` exists, so of several processes creating the same file exactly one succeeds.
    """
    path = Path(path)
    temp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.new")
    write_atomic(temp, data, mode=mode)
    try:
        os.link(temp, path)
    finally:
        temp.unlink()
    _sync_folder(path.parent)


def _sync_folder(folder: Path) -> None:
    """Make a rename or link in `folder` durable."""
    directory = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(directory)
    finally:
        os.close(directory)


def size_text(size: int) -> str:
    """A byte count as people read it: '512 bytes', '3.0 KiB', '16.0 MiB'."""
    if size < 1024:
        return f"{size} bytes"
    return f"{size / 1024:.1f} KiB" if size < 1024 * 1024 else f"{size / (1024 * 1024):.1f} MiB"


def read_regular(path: Path, max_bytes: int, role: str) -> bytes:
    """The bytes of `path` when it is a regular file (symbolic links followed) of at most `max_bytes`.

    Anything else is a ConfigError saying what the file is (a FIFO, a device, a folder, too large): such
    a file would hang the reader or fill its memory. `role` names the file in the message ("profile").
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise ConfigError(f"File not found: {path}", what=f"a {role} at {path}", why="the file does not exist",
                          how="check the path, or create the file") from None
    except (OSError, ValueError) as error:
        raise ConfigError(f"Cannot read {path}", what=f"a readable {role} at {path}",
                          why=getattr(error, "strerror", None) or str(error),
                          how="check the path and the file's permissions") from None
    status = os.fstat(fd)
    if not stat.S_ISREG(status.st_mode):
        os.close(fd)
        raise ConfigError(
            f"Not a regular file: {path}", what=f"a {role} that is a regular file",
            why=f"{path} is a {file_kind(status.st_mode)}" + (
                "" if stat.S_ISDIR(status.st_mode) else "; reading one can block forever or never end"),
            how=f"point to the {role} itself, not to a device, FIFO, socket or folder")
    with os.fdopen(fd, "rb") as handle:
        try:
            data = handle.read(max_bytes + 1) if status.st_size <= max_bytes else b""
        except OSError as error:  # /proc/self/mem and its kind: regular by its type, unreadable as a file
            raise ConfigError(f"Cannot read {path}", what=f"a readable {role} at {path}",
                              why=f"reading it fails: {error.strerror or error}",
                              how=f"point to the {role} itself, a file on disk") from None
        if status.st_size > max_bytes or len(data) > max_bytes:
            raise ConfigError(
                f"File too large: {path}", what=f"a {role} of at most {size_text(max_bytes)}",
                why=f"{path} holds {size_text(max(status.st_size, len(data)))}",
                how=f"check that {path} is the {role} you meant; no valid one is that large")
    return data


def read_regular_text(path: Path, max_bytes: int, role: str) -> str:
    """`read_regular` decoded as UTF-8; a file in another encoding is a ConfigError naming the byte offset."""
    data = read_regular(path, max_bytes, role)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ConfigError(f"Not UTF-8: {path}", what=f"a {role} encoded as UTF-8",
                          why=f"byte {error.start} of {path} ({data[error.start:error.start + 1]!r}) is not UTF-8",
                          how=f"save {path} as UTF-8") from None


def user_name(uid: int) -> str:
    """A user as messages name it: 'nobody (uid 65534)', or 'uid 1234' for a user without a passwd entry."""
    try:
        return f"{pwd.getpwuid(uid).pw_name} (uid {uid})"
    except KeyError:
        return f"uid {uid}"


def file_kind(mode: int) -> str:
    """'regular file', 'FIFO', 'symbolic link', ... for an `st_mode`."""
    return _KINDS.get(stat.S_IFMT(mode), "special file")


def trusted_owners() -> frozenset[int]:
    """The users whose files this process trusts in a shared directory: itself and root."""
    return frozenset({os.geteuid(), 0})


class UntrustedFile(Exception):
    """A file refused by `open_trusted`: not a regular file, or owned by a user the reader does not trust."""

    def __init__(self, path: Path, status: os.stat_result) -> None:
        self.path = path
        self.kind = file_kind(status.st_mode)
        self.owner_uid = status.st_uid
        self.owner = user_name(status.st_uid)
        super().__init__(f"{path} is a {self.kind} owned by {self.owner}")


def open_trusted(path: Path, flags: int, owners: Collection[int]) -> tuple[int, os.stat_result]:
    """Open `path` only if it is a regular file owned by one of `owners`; the descriptor and its status.

    Never follows a symbolic link and never waits (a FIFO would block `open` until someone writes), so
    a file planted by another user cannot redirect, hang or feed the caller. Raises UntrustedFile for
    such a file, OSError (FileNotFoundError, PermissionError) as `os.open` does otherwise.
    """
    try:
        fd = os.open(path, flags | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as error:
        if error.errno not in (errno.ELOOP, errno.ENXIO, errno.EISDIR):   # a link, a socket, a directory
            raise
        raise UntrustedFile(path, os.lstat(path)) from None
    status = os.fstat(fd)
    if not stat.S_ISREG(status.st_mode) or status.st_uid not in owners:
        os.close(fd)
        raise UntrustedFile(path, status)
    return fd, status


def read_trusted(path: Path, max_bytes: int) -> bytes | None:
    """The bytes of `path` opened as `open_trusted` does for this user and root; None when it holds more than
    `max_bytes`. Raises as `open_trusted` does."""
    fd, status = open_trusted(path, os.O_RDONLY, trusted_owners())
    with os.fdopen(fd, "rb") as handle:
        data = handle.read(max_bytes + 1) if status.st_size <= max_bytes else b""
    return None if status.st_size > max_bytes or len(data) > max_bytes else data
