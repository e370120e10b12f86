"""`plem state`, `plem mode`, `plem reset`: watch a launched robot and change its mode."""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Annotated, Any

import typer

from plem.cli.output import OutputFormat, new_table, print_json, stdout

if TYPE_CHECKING:
    from rich.console import RenderableType

    from plem.bridge.client import RobotClient
    from plem.control.events import Event
    from plem.control.state import JointState

RobotId = Annotated[str | None, typer.Option(
    "--robot-id", help="Robot to talk to (default: $PLEM_ROBOT_ID, else indy).", show_default=False)]
WATCH_PERIOD_S = 0.1


def connect_robot(robot_id: str | None) -> RobotClient:
    """A client of the robot `--robot-id` names (default: $PLEM_ROBOT_ID, else indy)."""
    from plem.bridge.client import connect

    return connect(robot_id)


def _headline(client: RobotClient, state: JointState) -> str:
    return (f"{client.robot_id}: {state.mode.name.lower()}, cycle {state.cycle}, "
            f"drives {'enabled' if state.drives_enabled else 'disabled'}")


def _fault_line(state: JointState, fault: Event | None) -> str | None:
    """The fault the robot is in, or the last one it had if that was cleared since; None if it never faulted."""
    if fault is None:
        return None
    label = "fault" if state.faulted else "last fault (cleared)"
    return f"{label} at cycle {fault.cycle} ({fault.cause}): {fault.reason}"


def _state_view(client: RobotClient, state: JointState) -> RenderableType:
    from rich.console import Group
    from rich.text import Text

    table = new_table(_headline(client, state), "joint", "position rad", "position °", "velocity rad/s",
                      "effort N·m", "command rad")
    for i, name in enumerate(client.joint_names):
        table.add_row(name, f"{state.position[i]:+.4f}", f"{math.degrees(state.position[i]):+.2f}",
                      f"{state.velocity[i]:+.4f}", f"{state.effort[i]:+.3f}", f"{state.command_position[i]:+.4f}")
    fault = _fault_line(state, client.last_fault())
    return table if fault is None else Group(table, Text(fault, style="bold red" if state.faulted else ""))


def _state_line(client: RobotClient, state: JointState) -> str:
    """One frame as one plain line, for a pipe or a file."""
    position = " ".join(f"{value:+.4f}" for value in state.position)
    fault = _fault_line(state, client.last_fault())
    return f"{_headline(client, state)}, position rad {position}" + ("" if fault is None else f"; {fault}")


def _state_json(client: RobotClient, state: JointState) -> dict[str, Any]:
    fault = client.last_fault()
    return {"robot_id": client.robot_id, "cycle": state.cycle, "mode": state.mode.name.lower(),
            "faulted": state.faulted, "drives_enabled": state.drives_enabled, "joint_names": list(client.joint_names),
            **{row: getattr(state, row).tolist() for row in ("position", "velocity", "effort", "command_position",
                                                            "command_velocity", "command_acceleration")},
            "last_fault": None if fault is None else {"active": state.faulted, "cycle": fault.cycle,
                                                      "cause": fault.cause, "reason": fault.reason,
                                                      "wall_time": fault.wall_time}}


@contextlib.contextmanager
def _quiet_when_stdout_closes() -> Iterator[None]:
    """End quietly when the reader of stdout has gone (`plem state --watch | head`): no traceback, exit 0."""
    try:
        yield
    except BrokenPipeError:
        # Python flushes stdout once more at exit; aim it at /dev/null, where that flush cannot fail.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def _watch_lines(client: RobotClient, current: JointState, output_format: OutputFormat) -> None:
    """One line per frame: plain text, or a JSON object per line with --format json."""
    while True:
        line = json.dumps(_state_json(client, current)) if output_format is OutputFormat.json \
            else _state_line(client, current)
        sys.stdout.write(line + "\n")
        sys.stdout.flush()
        time.sleep(WATCH_PERIOD_S)
        current = client.live_state()


def _watch_live(client: RobotClient, current: JointState) -> None:
    """The table, redrawn in place on the terminal."""
    from rich.live import Live

    with Live(_state_view(client, current), console=stdout, auto_refresh=False) as live:
        while True:
            time.sleep(WATCH_PERIOD_S)
            live.update(_state_view(client, client.live_state()), refresh=True)


def state(
    watch: Annotated[bool, typer.Option("--watch", "-w", help="Refresh ten times a second until Ctrl-C; to a pipe "
                                        "or file (or with --format json), one line per refresh.")] = False,
    robot_id: RobotId = None,
    output_format: Annotated[OutputFormat, typer.Option("--format", help="Output format.")] = OutputFormat.text,
) -> None:
    """Print the robot's joint state and its fault (from shared memory; never disturbs the loop)."""
    with connect_robot(robot_id) as client, _quiet_when_stdout_closes():
        current = client.live_state()
        if not watch:
            if output_format is OutputFormat.json:
                print_json(_state_json(client, current))
            else:
                stdout.print(_state_view(client, current))
            return
        with contextlib.suppress(KeyboardInterrupt):  # Ctrl-C is how a watch ends
            if output_format is OutputFormat.json or not stdout.is_terminal:
                _watch_lines(client, current, output_format)
            else:
                _watch_live(client, current)


def mode(
    name: Annotated[str, typer.Argument(help="free_drive, hold or idle.")],
    robot_id: RobotId = None,
) -> None:
    """Change the robot's mode and wait until it took effect."""
    with connect_robot(robot_id) as client:
        reached = client.set_mode(name)
        stdout.print(f"{client.robot_id}: mode {reached.name.lower()}", markup=False)


def reset(robot_id: RobotId = None) -> None:
    """Clear a fault: reset the drives, enable them and hold where the arm is (without a fault: nothing to do)."""
    with connect_robot(robot_id) as client:
        current = client.live_state()
        if not current.faulted:
            stdout.print(f"{client.robot_id}: no fault to clear; mode {current.mode.name.lower()}", markup=False)
            return
        fault = client.last_fault()
        reached = client.reset_fault()
        cleared = "" if fault is None else f" ({fault.cause}: {fault.reason})"
        stdout.print(f"{client.robot_id}: fault cleared{cleared}, mode {reached.name.lower()}", markup=False)
