"""`plem state`, `plem move`, `plem mode`, `plem reset`: watch and command a launched robot."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Annotated

import typer

from plem.cli.output import OutputFormat, new_table, print_json, stdout
from plem.errors import UsageError

if TYPE_CHECKING:
    from rich.table import Table

    from plem.bridge.client import RobotClient
    from plem.control.state import JointState

RobotId = Annotated[str | None, typer.Option(
    "--robot-id", help="Robot to talk to (default: $PLEM_ROBOT_ID, else indy).", show_default=False)]
WATCH_PERIOD_S = 0.1


def _connect(robot_id: str | None) -> RobotClient:
    from plem.bridge.client import connect

    return connect(robot_id)


def _state_table(client: RobotClient, state: JointState) -> Table:
    table = new_table(f"{client.robot_id}: {state.mode.name}{' (FAULT)' if state.faulted else ''}, cycle "
                      f"{state.cycle}, drives {'enabled' if state.drives_enabled else 'disabled'}",
                      "joint", "position rad", "position °", "velocity rad/s", "effort N·m", "command rad")
    for i, name in enumerate(client.joint_names):
        table.add_row(name, f"{state.position[i]:+.4f}", f"{math.degrees(state.position[i]):+.2f}",
                      f"{state.velocity[i]:+.4f}", f"{state.effort[i]:+.3f}", f"{state.command_position[i]:+.4f}")
    return table


def _state_json(client: RobotClient, state: JointState) -> dict[str, object]:
    return {"robot_id": client.robot_id, "cycle": state.cycle, "mode": state.mode.name.lower(),
            "faulted": state.faulted, "drives_enabled": state.drives_enabled, "joint_names": list(client.joint_names),
            **{row: getattr(state, row).tolist() for row in ("position", "velocity", "effort", "command_position",
                                                            "command_velocity", "command_acceleration")}}


def state(
    watch: Annotated[bool, typer.Option("--watch", "-w", help="Refresh ten times a second until Ctrl-C.")] = False,
    robot_id: RobotId = None,
    output_format: Annotated[OutputFormat, typer.Option("--format", help="Output format.")] = OutputFormat.text,
) -> None:
    """Print the robot's joint state (from shared memory; never disturbs the loop)."""
    with _connect(robot_id) as client:
        current = client.live_state()
        if output_format is OutputFormat.json:
            print_json(_state_json(client, current))
            return
        if not watch:
            stdout.print(_state_table(client, current))
            return
        from rich.live import Live

        with Live(_state_table(client, current), console=stdout, auto_refresh=False) as live:
            try:
                while True:
                    time.sleep(WATCH_PERIOD_S)
                    live.update(_state_table(client, client.live_state()), refresh=True)
            except KeyboardInterrupt:
                pass


def _target(client: RobotClient, text: str) -> list[float]:
    poses = client.channels.state.poses
    if text in poses:
        return poses[text]
    try:
        return [float(value) for value in text.split(",")]
    except ValueError:
        raise UsageError(f"cannot read target {text!r}", what=f"a named pose ({', '.join(poses)}) or "
                         f"{client.dof} joint positions in rad, comma-separated",
                         why=f"{text!r} is neither", how="e.g. --to home or --to 0,0,-1.57,0,-1.57,0") from None


def move(
    to: Annotated[str, typer.Option("--to", help="A named pose (home, or the SRDF's group states) or q1,q2,... rad.")],
    speed_scale: Annotated[float, typer.Option("--speed-scale", help="Fraction of full speed, (0, 1].")] = 0.5,
    robot_id: RobotId = None,
    timeout: Annotated[float, typer.Option("--timeout", help="Seconds to wait for the motion.")] = 60.0,
) -> None:
    """Move the arm to a pose (enables the drives first if they are off) and wait until it arrives."""
    from plem.control.modes import Mode

    with _connect(robot_id) as client:
        target = _target(client, to)
        if client.live_state().mode in (Mode.IDLE, Mode.FREE_DRIVE):
            client.set_mode("hold")
        result = client.move_joints(target, speed_scale).wait(timeout)
        stdout.print(f"{client.robot_id}: {result.message}", markup=False)


def mode(
    name: Annotated[str, typer.Argument(help="free_drive, hold or idle.")],
    robot_id: RobotId = None,
) -> None:
    """Change the robot's mode and wait until it took effect."""
    with _connect(robot_id) as client:
        reached = client.set_mode(name)
        stdout.print(f"{client.robot_id}: mode {reached.name.lower()}", markup=False)


def reset(robot_id: RobotId = None) -> None:
    """Clear a fault: reset the drives, enable them and hold where the arm is."""
    with _connect(robot_id) as client:
        reached = client.reset_fault()
        stdout.print(f"{client.robot_id}: fault cleared, mode {reached.name.lower()}", markup=False)
