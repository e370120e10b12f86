"""`plem jog` and `plem speed`: stream one joint's velocity, and set or read the speed override of a launched arm."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Annotated, Any

import typer

from plem.cli.interrupt import MotionGuard, wait_until_at_rest
from plem.cli.motion import hold_drives
from plem.cli.output import stdout
from plem.cli.robot import RobotId, connect_robot
from plem.errors import UsageError

if TYPE_CHECKING:
    from plem.bridge.client import RobotClient
    from plem.control.streaming import StreamStatus

#: How often `plem jog` sends its sample; the stream's timeout (0.1 s) covers several missed ones.
JOG_RATE_HZ = 100.0
#: Longest `plem jog --duration`: a jog is a short nudge, a longer motion is planned.
MAX_JOG_S = 60.0
#: How long `plem speed F` waits for the factor in force to reach F before it prints both.
SETTLE_S = 2.0
#: Factors closer than this are the same to the user (both print alike).
SAME = 1e-6
#: `plem jog -0.2` must read -0.2 as a value, not as an option.
JOG_SETTINGS: dict[str, Any] = {"context_settings": {"ignore_unknown_options": True}}


def speed(
    factor: Annotated[float | None, typer.Argument(
        help="Speed override from 0 (every motion stopped on its path) to 1 (as planned); without it, print the "
             "factor in force.", show_default=False)] = None,
    robot_id: RobotId = None,
) -> None:
    """Set the speed override, which re-times every motion on its own path, or print it (the factor in force now and
    the one asked for)."""
    if factor is not None and not 0.0 <= factor <= 1.0:   # NaN fails too
        raise UsageError(f"the speed override must be from 0 to 1, not {factor:g}",
                         what="a fraction of the planned speed: 0 stops every motion on its path, 1 runs it as "
                              "planned", why=f"got {factor:g}", how="e.g. plem speed 0.3")
    with connect_robot(robot_id) as client:
        if factor is None:
            status = client.stream_status()
            said = f"{status.speed_override:.4g} in force, {status.override_target:.4g} asked"
        else:
            client.set_speed_override(factor)
            status = _settled(client)
            said = f"{status.override_target:.4g} asked, {status.speed_override:.4g} in force"
        stdout.print(f"{client.robot_id}: speed override {said}{_following(status)}", markup=False)


def _settled(client: RobotClient) -> StreamStatus:
    """The core's report once the factor in force reached the one asked for, or after SETTLE_S if it has not."""
    deadline = time.monotonic() + SETTLE_S
    while abs((status := client.stream_status()).speed_override - status.override_target) >= SAME \
            and time.monotonic() < deadline:
        time.sleep(0.01)
    return status


def _following(status: StreamStatus) -> str:
    """What the user reads when the factor in force has not reached the one asked for yet."""
    if abs(status.speed_override - status.override_target) < SAME:
        return ""
    return " (it follows as fast as the running motion's limits allow)"


def jog(
    joint: Annotated[str, typer.Argument(help="Joint name (as the robot's joint_names) or index from 0.",
                                         show_default=False)],
    velocity: Annotated[float, typer.Argument(help="Velocity in rad/s, within the joint's limit.",
                                              show_default=False)],
    duration: Annotated[float, typer.Option("--duration", help=f"Seconds to jog, at most {MAX_JOG_S:g}.")] = 1.0,
    robot_id: RobotId = None,
) -> None:
    """Move one joint at a velocity for --duration s (enables the drives first if they are off), then let it come to
    rest within its limits; Ctrl-C stops the arm at once, smoothly."""
    if not 0.0 < duration <= MAX_JOG_S:
        raise UsageError(f"--duration must be in (0, {MAX_JOG_S:g}] s", what=f"seconds to jog, at most {MAX_JOG_S:g}",
                         why=f"--duration {duration:g}", how="e.g. --duration 1")
    with connect_robot(robot_id) as client, MotionGuard(client) as guard:
        index = _joint(client, joint)
        _check_velocity(client, index, velocity)
        hold_drives(client)
        guard.stream(lambda: client.jog(index, velocity), 1.0 / JOG_RATE_HZ, duration)
        wait_until_at_rest(client)
        position = ", ".join(f"{value:+.3f}" for value in client.live_state().position)
        stdout.print(f"{client.robot_id}: jogged {client.joint_names[index]} at {velocity:g} rad/s for {duration:g} s; "
                     f"the arm came to rest at [{position}] rad", markup=False)


def _joint(client: RobotClient, text: str) -> int:
    """The index of the joint `text` names, by name or by index."""
    names = client.joint_names
    if text in names:
        return names.index(text)
    if text.isdigit() and int(text) < len(names):
        return int(text)
    raise UsageError(f"no joint {text!r}", what=f"a joint name ({', '.join(names)}) or an index from 0 to "
                                                f"{len(names) - 1}",
                     why=f"{client.robot_id} has no joint {text!r}", how=f"e.g. plem jog {names[0]} 0.1")


def _check_velocity(client: RobotClient, index: int, velocity: float) -> None:
    limit = float(client.limits.maximum("velocity")[index])
    if not math.isfinite(velocity) or abs(velocity) > limit:
        name = client.joint_names[index]
        raise UsageError(f"{velocity:g} rad/s is beyond {name}'s velocity limit",
                         what=f"a velocity from {-limit:g} to {limit:g} rad/s for {name}",
                         why=f"got {velocity:g} rad/s", how=f"e.g. plem jog {name} {min(0.1, limit):g}")
