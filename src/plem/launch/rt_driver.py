"""The RT driver process: owns one robot's bus and loop and serves it through shared memory.

`plem launch` starts it as `python -m plem.launch.rt_driver '<launch arguments as JSON>'`. It prints one
JSON line on stdout once the loop runs (or why it could not start), then nothing else there. SIGTERM or
SIGINT stops any motion smoothly, disables the drives, stops the loop and removes the shared memory;
when the launching process dies the kernel sends SIGTERM, so the arm never runs unsupervised.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from plem.control import compiled
from plem.control.limits import ArmLimits
from plem.control.modes import Mode
from plem.control.realtime import keep_threads_scheduled
from plem.control.state import StateBlock
from plem.control.streaming import StreamBlock
from plem.errors import PlemError
from plem.fieldbus.bus import IBus
from plem.ipc.channels import RobotChannels
from plem.ipc.command_socket import socket_path
from plem.ipc.motion_slab import MotionSlab
from plem.launch.command_process import CommandServiceProcess
from plem.launch.component import announce, run_component
from plem.launch.driver_service import DriverService
from plem.launch.plan import RobotPlan, plan_robot
from plem.robot.robot import Robot

_log = logging.getLogger("plem.rt_driver")


def _bus(plan: RobotPlan) -> IBus | None:
    if plan.bus == "mock":
        from plem.fieldbus.mock import MockBus

        return MockBus(plan.config.dof, initial_positions=plan.initial_positions)
    return None  # the builder opens the EtherCAT master (bus:=ethercat, or the virtual network's)


def build(plan: RobotPlan, warn: Callable[[str], None] = _log.warning) -> tuple[Robot, RobotChannels]:
    """The robot of `plan`, publishing into freshly created shared memory (removed again if building fails)."""
    channels: list[RobotChannels] = []

    def state_block(limits: ArmLimits) -> StateBlock:
        mode = 0o640 if plan.shm_group is not None else 0o600
        channels.append(RobotChannels.create(plan.robot_id, limits, plan.config.cycle_time * 1000,
                                             poses=plan.poses(limits.joint_names), mode=mode, group=plan.shm_group,
                                             warn=warn))
        return channels[0].state.block

    try:
        robot = (Robot.builder(plan.config).with_bus(_bus(plan)).with_description(str(plan.package), plan.urdf_file)
                 .with_loop_settings(max_consecutive_overruns=plan.max_consecutive_overruns).with_payload(plan.payload)
                 .with_runtime_settings(contact_share=plan.contact_share)
                 .with_state_block(state_block).with_motion_slab(lambda: _slab(channels[0]))
                 .with_raw_ring(lambda: channels[0].rings["rt_raw"])
                 .with_stream_block(lambda: _stream(channels[0]))
                 .build())
    except BaseException as error:
        for created in channels:
            created.remove()
        if isinstance(error, Exception) and not isinstance(error, PlemError):
            _log.debug("building the robot failed", exc_info=error)  # the user gets the error below, not a traceback
            raise _build_failed(plan, error) from error
        raise
    channels[0].publish_events(robot.events)
    return robot, channels[0]


def _build_failed(plan: RobotPlan, error: Exception) -> PlemError:
    """An unexpected error while building the robot from its validated description (the model, the bus, the
    loop), said as what it is: a start-up failure of this package, which `plem validate` is the first tool for."""
    package = plan.report.files.name
    return PlemError(f"the RT driver could not build robot {plan.robot_id} from description package '{package}'",
                     what=f"a robot built from {plan.package} (URDF {plan.report.files.urdf})",
                     why=" ".join(str(error).split()) or type(error).__name__,
                     how=f"run `plem validate {plan.package} --strict` and fix what it reports; if it reports "
                         "nothing, this is a defect of plem: report it with this message")


def _slab(channels: RobotChannels) -> MotionSlab:
    if channels.motions is None:
        raise ValueError("the driver's channels have no motion slab (RobotChannels.create makes one)")
    return channels.motions


def _stream(channels: RobotChannels) -> StreamBlock:
    if channels.stream is None:
        raise ValueError("the driver's channels have no stream block (RobotChannels.create makes one)")
    return channels.stream


@dataclass
class Driver:
    """A running driver: the robot and its loop, its shared memory, its service thread and command service."""

    robot: Robot
    channels: RobotChannels
    service: DriverService
    commands: CommandServiceProcess


def _stop_service(service: DriverService) -> None:
    service.stop.set()
    if service.thread.is_alive():
        service.thread.join(2.0)


@contextlib.contextmanager
def driving(plan: RobotPlan, *, realtime_helpers: bool = False) -> Iterator[Driver]:
    """Build the robot, start its loop, service thread and command service; stop them all smoothly at the end.

    Whatever fails on the way, everything started so far is stopped and the shared memory is removed.
    `realtime_helpers` puts the calling thread, and the service thread, on SCHED_FIFO 1 once the robot is
    built (`keep_threads_scheduled`): building (description, model, bus) runs at normal priority, so a robot
    that starts never holds up the helper threads, and through them the loops, of robots already running.
    """
    robot, channels = build(plan)
    with contextlib.ExitStack() as cleanup:  # undone in reverse: command service, robot, service thread, memory
        cleanup.callback(channels.remove)
        service = DriverService(robot, channels)
        cleanup.callback(_stop_service, service)
        cleanup.callback(robot.shutdown)
        commands = CommandServiceProcess(plan.robot_id)
        cleanup.callback(commands.stop)
        refused = keep_threads_scheduled() if realtime_helpers else None
        if refused:
            _log.warning(refused)
        robot.start()
        service.start()
        commands.start()
        yield Driver(robot, channels, service, commands)


def serve(plan: RobotPlan, stop: threading.Event, announce: Callable[[dict[str, Any]], None], *,
          realtime_helpers: bool = False) -> None:
    """Run the robot of `plan` until `stop`, after announcing readiness (`realtime_helpers` as for `driving`).

    The loop runs on when the command service dies (it is restarted); when the service thread dies, the
    arm is stopped smoothly and the driver ends with an error, which `plem launch` reports.
    """
    with driving(plan, realtime_helpers=realtime_helpers) as driver:
        robot = driver.robot
        if plan.start_enabled:
            _enable(robot)
        report = robot.loop.report
        announce({"ready": True, "pid": os.getpid(), "robot_id": plan.robot_id, "dof": plan.config.dof,
                  "joint_names": list(robot.joint_names), "cycle_time_us": plan.config.cycle_time,
                  "policy": report.policy, "priority": report.priority, "memory_locked": report.memory_locked,
                  "core": compiled.describe(), "loop": "python" if robot.runtime.python_bus else "core",
                  "warnings": report.warnings, "shared_memory": driver.channels.names,
                  "command_socket": str(socket_path(plan.robot_id)), "command_service_pid": driver.commands.pid})
        while not stop.wait(0.2):
            if not robot.running:
                _log.error("the control loop stopped: %r", robot.loop.error)
                break
            if not driver.service.thread.is_alive():
                raise PlemError("the RT driver's service thread stopped", what="the service thread to run",
                                why="it ended unexpectedly; the arm was stopped smoothly",
                                how="restart the robot with `plem launch`, and report this with its output")
            driver.commands.keep_running()


def _enable(robot: Robot) -> None:
    """Enable the drives and hold (start_enabled); when they do not enable, say why and stay disabled."""
    try:
        robot.set_mode(Mode.HOLD)
    except PlemError as error:
        _log.warning("the drives did not enable at start (start_enabled); the arm stays disabled:\n%s",
                     error.render())


def _serve_launched(arguments: dict[str, str], stop: threading.Event) -> None:
    serve(plan_robot(arguments), stop, announce, realtime_helpers=True)


def main(argv: list[str] | None = None) -> int:
    """Run the RT driver of the robot whose launch arguments (JSON) are `argv[0]`; the process's exit code."""
    return run_component("rt_driver", _serve_launched, argv)


if __name__ == "__main__":
    sys.exit(main())
