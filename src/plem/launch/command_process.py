"""The RT driver's side of its command service: start it, restart it when it dies, stop it."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import time

from plem.errors import PlemError
from plem.ipc.command_socket import remove_own_socket, socket_path
from plem.launch.startup import first_line

STOP_TIMEOUT_S = 3.0
#: Restarts allowed within RESTART_WINDOW_S before the driver gives up on commands.
MAX_RESTARTS = 5
RESTART_WINDOW_S = 60.0
_log = logging.getLogger("plem.rt_driver")


class CommandServiceFailed(PlemError):
    """The robot's command service could not be started."""


class CommandServiceProcess:
    """`python -m plem.launch.command_service <robot_id>`, a child that dies with the driver."""

    def __init__(self, robot_id: str) -> None:
        self.robot_id = robot_id
        self._process: subprocess.Popen[str] | None = None
        self._restarts: list[float] = []

    @property
    def pid(self) -> int | None:
        """The running service's process id, None while none is started."""
        return None if self._process is None else self._process.pid

    def start(self) -> None:
        """Start the service and wait until it listens on the robot's command socket."""
        env = {**os.environ, "PLEM_LAUNCH_PID": str(os.getpid())}
        process = subprocess.Popen([sys.executable, "-m", "plem.launch.command_service", self.robot_id],
                                   stdout=subprocess.PIPE, text=True, env=env)
        self._process = process
        first = first_line(process, f"the command service of robot '{self.robot_id}'", _log.warning)
        announcement = json.loads(first.line) if first.line.startswith("{") else {}
        if not announcement.get("ready"):
            self.stop()
            error = announcement.get("error", {})
            raise CommandServiceFailed(
                f"the command service of robot '{self.robot_id}' did not start: {error.get('summary', 'no answer')}",
                what=error.get("what", f"a command service listening on {socket_path(self.robot_id)}"),
                why=error.get("why", first.why or f"it printed {first.line.strip()!r}"),
                how=error.get("how", "see the messages above"))

    def keep_running(self) -> None:
        """Restart a dead service (the loop and any motion run on meanwhile); give up after too many restarts."""
        process = self._process
        if process is None or process.poll() is None:
            return
        now = time.monotonic()
        self._restarts = [t for t in self._restarts if now - t < RESTART_WINDOW_S] + [now]
        if len(self._restarts) > MAX_RESTARTS:
            raise CommandServiceFailed("the command service keeps dying", what="a command service that stays up",
                                       why=f"it ended {len(self._restarts)} times within {RESTART_WINDOW_S:g} s "
                                           f"(last exit code {process.returncode})",
                                       how="see its messages above; restart the robot with `plem launch`")
        _log.warning("the command service ended (exit code %s); starting it again", process.returncode)
        self.start()

    def stop(self) -> None:
        """Terminate the service (it removes its socket); kill it if it does not end in time."""
        process, self._process = self._process, None
        if process is None:
            return
        if process.poll() is None:
            process.terminate()
            try:
                process.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        if process.stdout is not None:
            process.stdout.close()
        remove_own_socket(self.robot_id)
