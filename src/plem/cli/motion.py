"""`plem move` and `plem plan`: move a launched arm to a named state, joint positions or a pose.

With a planner running (the description package has an SRDF), motions are planned around the robot itself
and the scene's objects, timed within every limit and checked before they run. Without one, `plem move` to
a named state or joint positions moves straight there in joint space, as before planning existed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from plem.cli.interrupt import MotionGuard
from plem.cli.output import stdout
from plem.cli.robot import RobotId, connect_robot
from plem.errors import UsageError

if TYPE_CHECKING:
    from plem.bridge.client import RobotClient
    from plem.planning.goals import Goal, Plan, PlanOptions

Pose7 = tuple[float, float, float, float, float, float, float]
ToOption = Annotated[str | None, typer.Option(
    "--to", help="A named state (the SRDF's group states such as home, any case; zero: all joints at 0 rad) or "
    "q1,q2,... rad.", show_default=False)]
ToPoseOption = Annotated[Pose7 | None, typer.Option(
    "--to-pose", help="Tool pose: x y z qx qy qz qw (m, unit quaternion) in --frame.", show_default=False)]
FrameOption = Annotated[str, typer.Option("--frame", help="Frame of --to-pose: a URDF link (default: the root).")]
LinkOption = Annotated[str, typer.Option("--link", help="Link to bring to --to-pose (default: the group's tip).")]
GroupOption = Annotated[str, typer.Option("--group", help="Planning group of the SRDF (default: its first).")]
PlannerOption = Annotated[str, typer.Option("--planner", help="OMPL planner, e.g. RRTConnect (the default), RRTstar.")]
CartesianOption = Annotated[bool, typer.Option(
    "--cartesian", help="Move the tool along a straight line to --to-pose, as far as it can go (MoveIt's "
    "compute_cartesian_path).")]
LinearOption = Annotated[bool, typer.Option(
    "--linear", help="Move the tool along a straight line to --to-pose, all the way or not at all, within the tool's "
    "speed limits (Pilz's LIN).")]
SpeedOption = Annotated[float, typer.Option("--speed-scale", help="Fraction of full speed, from 0.001 to 1.")]
PlanningTimeOption = Annotated[float, typer.Option("--planning-time", help="Seconds the planner may take, at most 60.")]
TimeoutOption = Annotated[float, typer.Option("--timeout", help="Seconds to wait for the motion.")]


def move(to: ToOption = None, to_pose: ToPoseOption = None, frame: FrameOption = "", link: LinkOption = "",
         group: GroupOption = "", planner: PlannerOption = "", cartesian: CartesianOption = False,
         linear: LinearOption = False, speed_scale: SpeedOption = 0.5, planning_time: PlanningTimeOption = 5.0,
         robot_id: RobotId = None, timeout: TimeoutOption = 60.0) -> None:
    """Move the arm to a named state, joint positions or a tool pose (enables the drives first if they are off);
    planned around obstacles when a planner runs. Waits until the arm arrives; Ctrl-C stops the arm smoothly."""
    with connect_robot(robot_id) as client, MotionGuard(client) as guard:
        options = _options(group, planner, speed_scale, planning_time)
        if to_pose is None and not _planner_runs(client):
            if to is None:
                raise _no_target()
            hold_drives(client)
            target = _joint_target(client, to)
            result = guard.run(lambda: client.move_joints(target, speed_scale), timeout)
            stdout.print(f"{client.robot_id}: {result.message} (no planner runs: moved straight in joint space, "
                         "without collision checks)", markup=False)
            return
        plan = _plan(client, to, to_pose, frame, link, _path_kind(cartesian, linear), options)
        stdout.print(f"{client.robot_id}: {plan.summary()}", markup=False)
        _run(guard, plan, timeout)


def plan(to: ToOption = None, to_pose: ToPoseOption = None, frame: FrameOption = "", link: LinkOption = "",
         group: GroupOption = "", planner: PlannerOption = "", cartesian: CartesianOption = False,
         linear: LinearOption = False, speed_scale: SpeedOption = 0.5, planning_time: PlanningTimeOption = 5.0,
         dry_run: Annotated[bool, typer.Option("--dry-run", help="Print the plan and checks; do not move.")] = False,
         robot_id: RobotId = None, timeout: TimeoutOption = 60.0) -> None:
    """Plan a motion with the robot's planner and print its duration and checks, then run it (not with --dry-run);
    Ctrl-C stops the arm smoothly."""
    with connect_robot(robot_id) as client, MotionGuard(client) as guard:
        found = _plan(client, to, to_pose, frame, link, _path_kind(cartesian, linear),
                      _options(group, planner, speed_scale, planning_time))
        stdout.print(f"{client.robot_id}: {found.summary()}", markup=False)
        points = found.trajectory.points
        stdout.print(f"  {len(points)} trajectory points, first {_positions(points[0].positions)}, "
                     f"last {_positions(points[-1].positions)} rad", markup=False)
        if dry_run:
            stdout.print("  --dry-run: nothing moved", markup=False)
            return
        _run(guard, found, timeout)


def _options(group: str, planner: str, speed_scale: float, planning_time: float) -> PlanOptions:
    from plem.ipc.request_bounds import MIN_SPEED_SCALE
    from plem.planning.goals import MAX_PLANNING_TIME_S, PlanOptions

    if not MIN_SPEED_SCALE <= speed_scale <= 1.0:
        raise UsageError(f"--speed-scale must be from {MIN_SPEED_SCALE:g} to 1",
                         what=f"a fraction of full speed, at least {MIN_SPEED_SCALE:g} (a motion then takes "
                              f"{1 / MIN_SPEED_SCALE:g} times as long), at most 1",
                         why=f"--speed-scale {speed_scale:g}", how="e.g. --speed-scale 0.5")
    if not 0.0 < planning_time <= MAX_PLANNING_TIME_S:
        raise UsageError(f"--planning-time must be in (0, {MAX_PLANNING_TIME_S:g}] s",
                         what=f"seconds the planner may take, at most {MAX_PLANNING_TIME_S:g}",
                         why=f"--planning-time {planning_time:g}", how="e.g. --planning-time 5")
    return PlanOptions(group, planner, planning_time, speed_scale, speed_scale)


def _planner_runs(client: RobotClient) -> bool:
    """Whether the robot's planner answers."""
    from plem.errors import PlanningError

    try:
        client.planning_scene()
    except PlanningError:
        return False
    return True


def _path_kind(cartesian: bool, linear: bool) -> str:
    """'cartesian', 'linear' or '' (a planned path), from the flags; both at once is a usage error."""
    if cartesian and linear:
        raise UsageError("--cartesian and --linear exclude each other",
                         what="one way to move along a straight line",
                         why="both were given", how="--linear for the whole line within the tool's speed limits, "
                         "--cartesian for as far as the arm can follow it")
    return "cartesian" if cartesian else "linear" if linear else ""


def _plan(client: RobotClient, to: str | None, to_pose: Pose7 | None, frame: str, link: str, path: str,
          options: PlanOptions) -> Plan:
    from plem.planning.goals import PoseGoal
    from plem.planning.poses import Pose
    from plem.planning.sequence import Linear

    if (to is None) == (to_pose is None):
        raise _no_target()
    if path and to_pose is None:
        raise UsageError(f"--{path} needs --to-pose", what="a tool pose to move to along a straight line",
                         why=f"--{path} was given with --to", how="give --to-pose x y z qx qy qz qw")
    hold_drives(client)
    if to_pose is not None:
        pose = Pose.of(list(to_pose))
        if path == "cartesian":
            return client.cartesian_path([pose], frame=frame, link=link, options=options)
        if path == "linear":
            return client.plan_sequence([Linear(pose, frame=frame)], link=link, options=options)
        goal: Goal = PoseGoal(pose, frame, link)
        return client.plan(goal, options=options)
    assert to is not None
    named = to in client.channels.state.poses or "," not in to
    return client.plan(to if named else _joint_target(client, to), options=options)


def hold_drives(client: RobotClient) -> None:
    """Enable the drives and hold when they are off (idle or free drive), as moving needs."""
    from plem.control.modes import Mode

    if client.live_state().mode in (Mode.IDLE, Mode.FREE_DRIVE):
        client.set_mode("hold")


def _run(guard: MotionGuard, found: Plan, timeout: float) -> None:
    client = guard.client
    result = guard.run(lambda: client.execute_trajectory(found.trajectory), timeout)
    stdout.print(f"{client.robot_id}: {result.message}", markup=False)


def _joint_target(client: RobotClient, text: str) -> list[float]:
    from plem.planning.named_states import resolve_state

    poses = client.channels.state.poses
    if "," not in text:
        return poses[resolve_state(text, poses)]
    try:
        return [float(value) for value in text.split(",")]
    except ValueError:
        raise UsageError(f"cannot read target {text!r}", what=f"a named pose ({', '.join(poses)}) or "
                         f"{client.dof} joint positions in rad, comma-separated",
                         why=f"{text!r} is neither", how="e.g. --to home or --to 0,0,-1.57,0,-1.57,0") from None


def _no_target() -> UsageError:
    return UsageError("give one target", what="--to NAME|q1,q2,... or --to-pose x y z qx qy qz qw",
                      why="none or both were given", how="e.g. plem move --to home, or plem move --to-pose "
                      "0.4 0 0.5 0 1 0 0")


def _positions(values: tuple[float, ...]) -> str:
    return "[" + ", ".join(f"{v:+.3f}" for v in values) + "]"
