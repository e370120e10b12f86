"""The robot's bag directory held open by a handle: reached one name at a time, and never another user's.

bag_dir is often shared (/data/bags, /tmp), and plem often records as root, so other local users must not be
able to steer where the recordings go. The walk to `bag_dir/{robot_id}` opens each directory with
O_NOFOLLOW relative to the one before (openat) and creates what is missing with the recorder's access:
- a symbolic link on the way is followed only when root or this user owns it;
- a directory on the way that every user may write into without the sticky bit is refused: anyone could
  rename the robot's directory and put a link in its place (the sticky bit, as on /tmp, is what stops it);
- the robot's own directory is created by this process (mkdir never reuses what exists), or, when it
  exists, must be a real directory of this user; a link, or another user's directory, is refused. An
  existing one of ours gets the recorder's access again, so nobody can put anything into it any more.
Everything the recorder writes is then reached through the handle: `dir_fd` for its own opens, and
`/proc/self/fd/N/...` for rosbags, which takes paths; renaming or replacing anything above the robot's
directory redirects nothing. `intact` tells when the robot's directory was deleted or replaced, and
`reopen` walks again to recreate it.
"""

from __future__ import annotations

import errno
import os
import pwd
import stat
import weakref
from pathlib import Path

from plem.core.files import file_kind, trusted_owners, user_name
from plem.recording.access import FileAccess
from plem.recording.problems import MOVE_BAG_DIR, UnsafeDirectory

#: Symbolic links followed on the way before the walk gives up, as the kernel does (ELOOP).
MAX_LINKS = 40
_OPEN_DIRECTORY = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC
#: A directory on the way is only passed through: its handle needs no read permission (a home of mode 0711).
_PASS_THROUGH = os.O_PATH | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC


def open_directory(directory: Path, access: FileAccess, robot: bool = True) -> int:
    """A handle (fd) on `directory`, created with its missing parents under `access`, checked as the module says.

    `robot` False checks `directory` itself as a directory on the way (bag_dir when no robot_id is known).

    Raises UnsafeDirectory (an OSError carrying the WHAT/WHY/HOW) for a link, owner or mode that would let
    another user steer the recordings, and OSError naming the full path for anything else.
    """
    path = Path(os.path.abspath(directory))
    parts = list(path.parts[1:])
    shown = Path("/")
    fd = os.open("/", _PASS_THROUGH)
    links = 0
    try:
        while parts:
            name = parts.pop(0)
            last = robot and not parts
            if name == "..":
                fd, shown = _replace(fd, os.open("..", _PASS_THROUGH, dir_fd=fd)), shown.parent
                continue
            here = shown / name
            child, created = _open_or_create(fd, name, here, access, last)
            if child is None:                              # a symbolic link we may follow
                links += 1
                if links > MAX_LINKS:
                    raise OSError(errno.ELOOP, os.strerror(errno.ELOOP), str(here))
                target = Path(os.readlink(name, dir_fd=fd))
                parts = [*target.parts[1:], *parts] if target.is_absolute() else [*target.parts, *parts]
                if target.is_absolute():
                    fd, shown = _replace(fd, os.open("/", _PASS_THROUGH)), Path("/")
                continue
            fd = _replace(fd, child)
            shown = here
            _check(fd, here, directory, last, created, access)
    except BaseException:
        os.close(fd)
        raise
    return fd


def make_directory(directory: Path, access: FileAccess, robot: bool = True) -> None:
    """Create (or check) `directory` as the recorder will, without keeping a handle: `open_directory`'s checks."""
    os.close(open_directory(directory, access, robot))


def _replace(old: int, new: int) -> int:
    os.close(old)
    return new


def _open_or_create(parent: int, name: str, here: Path, access: FileAccess, last: bool) -> tuple[int | None, bool]:
    """(fd of `name` in `parent`, whether this call created it); (None, False) for a link root or we own.

    The robot's directory, and one created here, are opened for reading (their access is set through the
    handle); a directory on the way only to pass through."""
    for _ in range(2):                                    # a directory created by another process meanwhile
        try:
            return os.open(name, _OPEN_DIRECTORY if last else _PASS_THROUGH, dir_fd=parent), False
        except FileNotFoundError:
            try:
                os.mkdir(name, access.directory_mode, dir_fd=parent)
            except FileExistsError:
                continue
            except OSError as error:
                raise OSError(error.errno, error.strerror, str(here)) from None
            return os.open(name, _OPEN_DIRECTORY, dir_fd=parent), True
        except OSError as error:
            if error.errno not in (errno.ELOOP, errno.ENOTDIR):
                raise OSError(error.errno, error.strerror, str(here)) from None
            status = os.lstat(name, dir_fd=parent)
            if not stat.S_ISLNK(status.st_mode):
                raise OSError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(here)) from None
            if last or status.st_uid not in trusted_owners():
                raise _link_problem(parent, name, here, status, last) from None
            return None, False
    raise OSError(errno.EEXIST, "appears and disappears while it is opened", str(here))


def _check(fd: int, here: Path, directory: Path, last: bool, created: bool, access: FileAccess) -> None:
    """Refuse a directory on the way that anyone may rename things in, and a robot directory not of this user;
    one created here, and the robot's own, get the recorder's access."""
    status = os.fstat(fd)
    if last and status.st_uid != os.geteuid():
        raise _owner_problem(here, status)
    if last or created:
        access.apply_fd(fd)
    elif status.st_mode & stat.S_IWOTH and not status.st_mode & stat.S_ISVTX:
        raise _open_problem(here, status, directory)


def _mode(status: os.stat_result) -> str:
    return f"{stat.S_IMODE(status.st_mode):04o}"


def _link_problem(parent: int, name: str, here: Path, status: os.stat_result, last: bool) -> UnsafeDirectory:
    try:
        target = os.readlink(name, dir_fd=parent)
    except OSError:
        target = "?"
    owner, user = user_name(status.st_uid), user_name(os.geteuid())
    if last:
        why = (f"{here} is a symbolic link owned by {owner}, pointing to {target}; recording through it would put "
               f"the bags and the event log wherever the link's owner chose")
        what = f"a robot directory that the recorder creates itself, or a real directory of {user}"
    else:
        why = (f"{here} is a symbolic link owned by {owner}, pointing to {target}; only links of root or {user} "
               "are followed on the way to the bags")
        what = f"a path to the bags whose symbolic links belong to root or {user}"
    return UnsafeDirectory(here, f"{here} is a symbolic link of {owner}", what=what, why=why,
                           how=f"remove the link (`rm {here}`) if you did not make it, name the real directory in "
                               f"bag_dir:=, or {MOVE_BAG_DIR}")


def _owner_problem(here: Path, status: os.stat_result) -> UnsafeDirectory:
    owner, user = user_name(status.st_uid), user_name(os.geteuid())
    return UnsafeDirectory(
        here, f"{here} belongs to {owner}, not to {user}",
        what=f"a robot directory of the recorder's user, {user}, which it creates itself when missing",
        why=f"{here} is a {file_kind(status.st_mode)} owned by {owner} (mode {_mode(status)}); its owner could "
            f"move, replace or read the recordings of {user}",
        how=f"move it aside (`mv {here} {here}.untrusted`) so the recorder creates its own, `chown -R "
            f"{_login(os.geteuid())} {here}` if you trust what is in it, or {MOVE_BAG_DIR}")


def _login(uid: int) -> str:
    """A user as `chown` takes it: the login name, or the uid without a passwd entry."""
    try:
        return pwd.getpwuid(uid).pw_name
    except KeyError:
        return str(uid)


def _open_problem(here: Path, status: os.stat_result, directory: Path) -> UnsafeDirectory:
    return UnsafeDirectory(
        here, f"{here} is writable by every user and has no sticky bit",
        what=f"directories on the way to {directory} that other users cannot rename things in",
        why=f"{here} (owner {user_name(status.st_uid)}, mode {_mode(status)}) lets any local user rename or "
            "replace what is in it, the robot's directory included (a link in its place would take the bags "
            "elsewhere)",
        how=f"`chmod +t {here}` (as /tmp is), or `chmod o-w {here}`, or {MOVE_BAG_DIR}")


class RobotDirectory:
    """The handle on one robot's bag directory; `root` names it for code that takes paths."""

    def __init__(self, directory: Path, access: FileAccess) -> None:
        self.directory = directory                        # as the user named it, for messages
        self.access = access
        self.fd = open_directory(directory, access)
        self._closer = weakref.finalize(self, os.close, self.fd)

    @property
    def root(self) -> Path:
        """The held directory as a path (`/proc/self/fd/N`): what is under it is reached through the handle."""
        return Path(f"/proc/self/fd/{self.fd}")

    def intact(self) -> bool:
        """Whether `directory` still names the held directory (not deleted, moved or replaced)."""
        try:
            named = os.stat(self.directory, follow_symlinks=False)
            held = os.fstat(self.fd)
        except OSError:
            return False
        return (named.st_dev, named.st_ino) == (held.st_dev, held.st_ino) and held.st_nlink > 0

    def reopen(self) -> None:
        """Walk to `directory` again, creating it as at start; the old handle is closed. Raises as at start."""
        fd = open_directory(self.directory, self.access)
        self.close()
        self.fd = fd
        self._closer = weakref.finalize(self, os.close, fd)

    def close(self) -> None:
        """Close the handle (once)."""
        self._closer()
