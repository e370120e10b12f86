"""Ctrl-C during a command that moves the arm: cancel the motion, let the arm stop smoothly, exit 130 saying so.

Every `plem` command that starts a motion runs it inside `MotionGuard`: SIGINT (Ctrl-C) or SIGTERM while the
motion runs sends the driver a stop for that motion (the core's jerk-limited stop, within every limit), waits
until the arm stands still and ends with 128 + the signal's number (130 for Ctrl-C). A command that streams
(`plem jog`) stops sending at the signal and asks for the same stop of the stream. The guard installs its
handlers even where the shell left SIGINT ignored (a background job of a script): `kill -INT` on a command that
moves the arm is a request to stop it.
"""

from __future__ import annotations

import signal
import time
from types import FrameType, TracebackType
from typing import TYPE_CHECKING, Any

import typer

from plem.cli.output import stderr
from plem.errors import PlemError

if TYPE_CHECKING:
    from collections.abc import Callable

    from plem.bridge.client import RemoteHandle, RobotClient

#: The signals that cancel a running motion.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: Seconds to wait for the driver to confirm the stop and for the arm to stand still.
STOP_TIMEOUT_S = 30.0
#: How often the wait for a motion's end looks for a signal.
SLICE_S = 0.05


def wait_until_at_rest(client: RobotClient, timeout: float = STOP_TIMEOUT_S) -> None:
    """Block until no motion runs and the command stands still (a stop's ramp runs on after the mode is HOLD)."""
    from plem.control.modes import Mode

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        state = client.live_state()
        if state.mode is not Mode.TRAJECTORY and not state.command_velocity.any():
            return
        time.sleep(SLICE_S / 10)
    raise PlemError("the arm is still moving", what=f"the arm at rest within {timeout:g} s",
                    why=f"mode {state.mode.name}, commanded velocity {abs(state.command_velocity).max():.3g} rad/s",
                    how="watch it with `plem state --watch`; stop it with `plem mode hold`")


class MotionGuard:
    """Turns SIGINT and SIGTERM during a motion command into a smooth stop of its motion and exit 128 + signal."""

    def __init__(self, client: RobotClient) -> None:
        self.client = client
        self.handle: RemoteHandle | None = None
        self.streamed = False
        self.signum: int | None = None
        self._deferred = False
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> MotionGuard:
        for signum in STOP_SIGNALS:
            self._previous[signum] = signal.signal(signum, self._on_signal)
        return self

    def _on_signal(self, signum: int, _frame: FrameType | None) -> None:
        self.signum = self.signum or signum
        if not self._deferred:
            raise KeyboardInterrupt

    def run(self, send: Callable[[], RemoteHandle], timeout: float) -> Any:
        """Send a motion with `send` and wait up to `timeout` s for its result (as RemoteHandle.wait returns it).

        From the moment the motion is sent, a signal is only noted, and the wait looks for it between answers: a
        signal that arrives while the driver accepts the motion stops it as soon as its handle is known.
        """
        from plem.control.commands import CommandTimeout

        self._deferred = True
        self.handle = send()
        deadline = time.monotonic() + timeout
        while self.signum is None:
            remaining = deadline - time.monotonic()
            try:
                return self.handle.wait(max(0.0, min(SLICE_S, remaining)))
            except CommandTimeout:
                if remaining <= SLICE_S:
                    raise CommandTimeout(f"{self.handle.description} did not finish in {timeout} s",
                                         what=f"the motion to end within --timeout {timeout} s",
                                         why="it still runs, and goes on after this command ends",
                                         how="wait longer with --timeout; watch the arm with `plem state --watch`"
                                         ) from None
        raise KeyboardInterrupt

    def stream(self, send: Callable[[], object], period: float, duration: float) -> None:
        """Call `send` every `period` s for `duration` s; a signal meanwhile ends the stream with a stop.

        Signals are only noted while a sample is written, and looked for before each one, so a stop follows a
        signal within one period.
        """
        self._deferred = True
        began = time.monotonic()
        ticks = 0
        while self.signum is None:
            now = time.monotonic()
            if now - began >= duration:
                return
            send()
            self.streamed = True
            ticks += 1
            time.sleep(max(0.0, min(began + ticks * period, began + duration) - time.monotonic()))
        raise KeyboardInterrupt

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self._deferred = True   # a second Ctrl-C does not cut the stop short
        try:
            if exc_type is KeyboardInterrupt:
                self._stop()
        finally:
            for signum, handler in self._previous.items():
                signal.signal(signum, handler)

    def _stop(self) -> None:
        """Cancel the motion, wait until the arm stands still, say so and end with 128 + the signal."""
        signum = self.signum or signal.SIGINT
        name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        robot = self.client.robot_id
        if self.streamed:
            self.client.stop().wait(STOP_TIMEOUT_S)
            wait_until_at_rest(self.client)
            stderr.print(f"{robot}: interrupted ({name}): stream stopped, the arm stopped smoothly within its limits "
                         f"at [{self._position()}] rad", markup=False)
        elif self.handle is None:
            stderr.print(f"{robot}: interrupted ({name}) before the motion started; the arm did not move",
                         markup=False)
        elif self.handle.done:
            stderr.print(f"{robot}: interrupted ({name}); the motion had already ended", markup=False)
        else:
            self.handle.cancel().wait(STOP_TIMEOUT_S)
            self.client.wait_until_idle(STOP_TIMEOUT_S)
            stderr.print(f"{robot}: interrupted ({name}): motion canceled, the arm stopped smoothly within its "
                         f"limits at [{self._position()}] rad", markup=False)
        raise typer.Exit(128 + signum)

    def _position(self) -> str:
        """Where the arm is, as the messages print it."""
        return ", ".join(f"{value:+.3f}" for value in self.client.live_state().position)
