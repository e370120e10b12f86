"""Talking to a robot's command service byte by byte, as a buggy or hostile client would."""

from __future__ import annotations

import json
import socket
import time
from typing import Any

from plem.ipc.command_socket import FrameReader, frame, socket_path


class RawConnection:
    """One connection to a command service, sending any bytes and reading whole answers."""

    def __init__(self, robot_id: str) -> None:
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.connect(str(socket_path(robot_id)))
        self._frames = FrameReader()
        self._answers: list[dict[str, Any]] = []

    def send(self, payload: bytes | dict[str, Any]) -> None:
        """One frame around `payload` (a dict is sent as JSON, bytes as they are)."""
        data = json.dumps(payload).encode() if isinstance(payload, dict) else payload
        self.sock.sendall(frame(data))

    def answers(self, count: int, timeout: float = 10.0) -> list[dict[str, Any]]:
        """The next `count` answers; fewer if the service closes the connection or the time runs out."""
        deadline = time.monotonic() + timeout
        while len(self._answers) < count and (remaining := deadline - time.monotonic()) > 0:
            self.sock.settimeout(remaining)
            try:
                data = self.sock.recv(1 << 16)
            except TimeoutError:
                break
            if not data:
                break
            self._answers += [json.loads(record) for record in self._frames.feed(data)]
        taken, self._answers = self._answers[:count], self._answers[count:]
        return taken

    def close(self) -> None:
        self.sock.close()
