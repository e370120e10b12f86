"""Serving a virtual segment on a network interface: a raw EtherCAT socket and one poll loop.

The socket is AF_PACKET/SOCK_RAW bound to the interface with protocol ETH_P_ECAT, so it receives the
master's EtherCAT frames only and never its own answers. `serve` answers each frame at once (or
`segment.delay_s` later), calls `segment.poll` about every millisecond so watchdogs run out when no
frames come, services the caller's extra file descriptors (a control socket, say) in between, and
returns within a millisecond of its stop event being set (from another thread or a signal handler).
"""

from __future__ import annotations

import errno
import gc
import heapq
import itertools
import select
import socket
import threading
import time
from collections.abc import Callable, Mapping

from plem.errors import PlemError
from plem.fieldbus.ethercat.virtual.frames import ETHERTYPE
from plem.fieldbus.ethercat.virtual.segment import Segment

#: How often the segment is polled, and the stop event looked at, when no frame arrives.
POLL_PERIOD_S = 0.001
_MAX_FRAME = 2048
#: What the socket reports while the link is down (a pulled cable): frames are lost, serving goes on.
_LINK_DOWN = (errno.ENETDOWN, errno.ENXIO)


def open_socket(interface: str) -> socket.socket:
    """A non-blocking raw socket on `interface` that receives EtherCAT frames (ethertype 0x88A4) only."""
    sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETHERTYPE))
    try:
        sock.bind((interface, ETHERTYPE))
    except OSError as error:
        sock.close()
        raise PlemError(f"cannot serve EtherCAT frames on {interface!r}",
                        what=f"binding a raw EtherCAT socket to {interface!r} failed: {error.strerror}",
                        why="the virtual segment answers the master on this interface",
                        how="create the virtual network first and open the socket inside its namespace") from error
    sock.setblocking(False)
    return sock


def serve(sock: socket.socket, segment: Segment, *, stop: threading.Event,
          extra: Mapping[int, Callable[[], None]] | None = None) -> None:
    """Answer the frames arriving on `sock` with `segment` until `stop` is set; `extra` maps descriptors to
    the callables that service them when readable. The caller keeps owning `sock`."""
    extra = dict(extra or {})
    gc.freeze()                                    # what exists now is never scanned: no collection stalls an answer
    sock.setblocking(False)
    poller = select.poll()
    for fd in (sock.fileno(), *extra):
        poller.register(fd, select.POLLIN)
    late: list[tuple[float, int, bytes]] = []
    order = itertools.count()
    next_poll = time.monotonic()
    while not stop.is_set():
        deadline = min(next_poll, late[0][0]) if late else next_poll
        for fd, _ in poller.poll(max(0.0, (deadline - time.monotonic()) * 1000.0)):
            if fd in extra:
                extra[fd]()
                continue
            while (frame := _receive(sock)) is not None:
                answer = segment.process(frame)
                if answer is None:
                    continue                       # lost on the way
                if segment.delay_s > 0:
                    heapq.heappush(late, (time.monotonic() + segment.delay_s, next(order), answer))
                else:
                    _send(sock, answer)
                segment.finish_cycle()
        now = time.monotonic()
        while late and late[0][0] <= now:
            _send(sock, heapq.heappop(late)[2])
        if now >= next_poll:
            segment.poll(now)
            next_poll = now + POLL_PERIOD_S


def _receive(sock: socket.socket) -> bytes | None:
    """The next frame waiting on the socket, None when there is none (or the link just went down)."""
    try:
        return sock.recv(_MAX_FRAME)
    except BlockingIOError:
        return None
    except OSError as error:
        if error.errno in _LINK_DOWN:
            return None
        raise


def _send(sock: socket.socket, frame: bytes) -> None:
    """Send an answer; one that does not fit the interface queue, or meets a link that is down, is lost."""
    try:
        sock.send(frame)
    except BlockingIOError:
        pass
    except OSError as error:
        if error.errno not in _LINK_DOWN:
            raise
