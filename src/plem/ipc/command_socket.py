"""The command socket `/dev/shm/{robot_id}_commands`: how clients reach a robot's command service (and, at
`/dev/shm/{robot_id}_planner`, its planner).

A Unix stream socket, one connection per client, carrying length-prefixed JSON frames. The kernel keeps
clients apart: a client that stops reading or stalls holds up only its own connection, and no lock is
shared. Both ends check who is at the other end (SO_PEERCRED): the service takes commands only from its
own user and root; a client sends commands only to a service run by itself or by root, so a name taken
first by another user is never commanded.
"""

from __future__ import annotations

import errno
import os
import socket
import stat
import struct
from pathlib import Path

from plem.core.files import remove_own, trusted_owners, user_name
from plem.errors import PlemError
from plem.ipc.request_bounds import MAX_REQUEST_BYTES
from plem.ipc.segment import SHM_DIRECTORY

_LENGTH = struct.Struct("<I")
_CREDENTIALS = struct.Struct("3i")  # pid, uid, gid
#: Largest frame either side accepts: one request of the largest size, with room for its framing.
MAX_FRAME_BYTES = MAX_REQUEST_BYTES + 1024
#: The services a robot serves on sockets, by the suffix of their socket's name, with their names in messages.
SERVICES = {"commands": "command service", "planner": "planner"}


class CommandSocketError(PlemError):
    """The command socket is missing, foreign, busy or broken."""


def socket_path(robot_id: str, service: str = "commands") -> Path:
    """The socket of a robot's command service (or another of SERVICES), beside its shared memory."""
    return SHM_DIRECTORY / f"{robot_id}_{service}"


def peer_credentials(connection: socket.socket) -> tuple[int, int, int]:
    """(pid, uid, gid) of the process at the other end."""
    return _CREDENTIALS.unpack(connection.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, _CREDENTIALS.size))


def trusted(uid: int) -> bool:
    """Whether a process of user `uid` may command, or be commanded by, this process: same user or root."""
    return uid in trusted_owners()


def frame(payload: bytes) -> bytes:
    """One frame: the payload's length, then the payload."""
    return _LENGTH.pack(len(payload)) + payload


class FrameReader:
    """Splits a byte stream into frames; a frame longer than `limit` is an error, not a buffer to fill."""

    def __init__(self, limit: int = MAX_FRAME_BYTES) -> None:
        self.limit = limit
        self._buffer = bytearray()

    def feed(self, data: bytes) -> list[bytes]:
        """Add received bytes; the frames now complete. CommandSocketError when a frame announces too much."""
        self._buffer += data
        frames: list[bytes] = []
        while len(self._buffer) >= _LENGTH.size:
            (length,) = _LENGTH.unpack_from(self._buffer)
            if length > self.limit:
                raise CommandSocketError("a command frame is too large", what=f"at most {self.limit} bytes",
                                         why=f"the frame announces {length} bytes",
                                         how="send fewer trajectory points per request")
            end = _LENGTH.size + length
            if len(self._buffer) < end:
                break
            frames.append(bytes(self._buffer[_LENGTH.size:end]))
            del self._buffer[:end]
        return frames


def listen(robot_id: str, backlog: int = 16, service: str = "commands") -> socket.socket:
    """Bind the robot's socket, owner-only and non-blocking; a live one is refused, a stale own one replaced."""
    path = socket_path(robot_id, service)
    title = SERVICES[service]
    _clear_stale(path, robot_id, title)
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    previous = os.umask(0o177)  # the socket file is created 0600: only the owner (and root) may connect
    try:
        server.bind(os.fspath(path))
    except OSError as error:
        server.close()
        raise CommandSocketError(f"cannot create the {title} socket of robot '{robot_id}'",
                                 what=f"{path} free for this robot's {title}",
                                 why=f"{error.strerror}", how=f"remove {path} or use another robot_id:=") from None
    finally:
        os.umask(previous)
    server.listen(backlog)
    server.setblocking(False)
    return server


def _clear_stale(path: Path, robot_id: str, title: str) -> None:
    """Remove a socket left by a dead service of this user; anything else at the name is an error."""
    try:
        info = path.lstat()
    except FileNotFoundError:
        return
    if not stat.S_ISSOCK(info.st_mode) or info.st_uid != os.geteuid():
        kind = "socket" if stat.S_ISSOCK(info.st_mode) else "file that is not a socket"
        raise CommandSocketError(f"the {title} socket name of robot '{robot_id}' is taken",
                                 what=f"{path} free, or a socket of this user",
                                 why=f"it is a {kind} owned by {user_name(info.st_uid)}",
                                 how=f"remove it as its owner or root (rm {path}), or use another robot_id:=")
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        probe.connect(os.fspath(path))
    except OSError as error:
        if error.errno not in (errno.ECONNREFUSED, errno.ENOENT):
            raise
        path.unlink(missing_ok=True)
        return
    finally:
        probe.close()
    raise CommandSocketError(f"robot '{robot_id}' already has a {title}",
                             what=f"one {title} per robot_id; {path} must be free",
                             why=f"a process answers on {path}", how="stop that robot first, or use another robot_id:=")


def remove_own_socket(robot_id: str, service: str = "commands") -> None:
    """Remove the robot's socket if this user created it; another user's is left alone."""
    remove_own(socket_path(robot_id, service))


def connect(robot_id: str, service: str = "commands") -> socket.socket:
    """A non-blocking connection to the robot's command service (or another of SERVICES), checked to be run by
    this user or root."""
    path = socket_path(robot_id, service)
    title = SERVICES[service]
    connection = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        connection.connect(os.fspath(path))
    except OSError as error:
        connection.close()
        denied = error.errno in (errno.EACCES, errno.EPERM)
        raise CommandSocketError(
            f"cannot reach the {title} of robot '{robot_id}'",
            what=f"a {title} listening on {path}",
            why=(f"{path} belongs to another user: commands are taken from the user that launched the robot "
                 "and root" if denied else f"{error.strerror}: the robot is not running or is starting"),
            how="command the robot as the user that launched it" if denied
            else "start the robot with `plem launch` (bus:=mock for the simulated arm) and check robot_id"
            + ("; the planner runs when the description package has an SRDF" if service == "planner" else "")
        ) from None
    pid, uid, _ = peer_credentials(connection)
    if not trusted(uid):
        connection.close()
        raise CommandSocketError(f"robot '{robot_id}' is served by another user's process",
                                 what=f"a {title} run by you or by root",
                                 why=f"process {pid} of {user_name(uid)} answers on {path}",
                                 how=f"stop that process (or remove {path} as root) and launch the robot again, "
                                     "or use another robot_id:=")
    connection.setblocking(False)
    return connection
