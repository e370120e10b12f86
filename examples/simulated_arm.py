"""Run the simulated Indy7 v2 in real time: enable, move, follow a trajectory, free-drive, stop.

    .venv/bin/python examples/simulated_arm.py [robot_type]

Prints each event as it happens and the loop's timing at the end.
"""

from __future__ import annotations

import sys

from plem.control.trajectory import JointTrajectory
from plem.errors import PlemError
from plem.fieldbus import MockBus
from plem.robot import Robot, model_for


def main(robot_type: str = "indy7_v2") -> None:
    config = model_for(robot_type)()
    config.custom_bus = MockBus(config.dof)
    robot = Robot.builder(config).with_robot_id("indy").build()
    robot.events.subscribe(lambda event: print("  event:", event.describe()))
    dof = config.dof
    with robot:
        robot.set_mode("hold")
        print("move_joints to a pose at full speed, back home at half speed")
        print("  ", robot.move_joints([0.4, -0.3, 0.6, 0.2, 0.5, -0.3, 0.1][:dof]).wait(30))
        print("  ", robot.move_joints([0.0] * dof, speed_scale=0.5).wait(30))
        print("a three-point trajectory with velocities and accelerations (quintic splines)")
        zeros = [0.0] * dof
        trajectory = JointTrajectory.from_lists(config.MODEL.joint_names, [
            {"positions": [0.2] * dof, "velocities": [0.1] * dof, "accelerations": zeros, "time_from_start": 2.0},
            {"positions": [0.3] * dof, "velocities": zeros, "accelerations": zeros, "time_from_start": 3.5},
        ])
        print("  ", robot.execute_trajectory(trajectory).wait(30))
        print("free drive for one second, then hold")
        robot.set_mode("free_drive")
        robot.wait_for_state(1.0, after_cycle=robot.state().cycle + 1000)
        robot.set_mode("hold")
        timing = robot.timing()
        report = robot.loop.report
    print(f"loop: {report.policy} priority {report.priority}, memory locked {report.memory_locked}, "
          f"cpu_dma_latency held {report.dma_latency_held}")
    for warning in report.warnings:
        print("  warning:", warning)
    latency, compute = timing["latency"], timing["compute"]
    print(f"{timing['cycles']} cycles, {timing['overruns']} overruns, {timing['missed_periods']} missed periods")
    print(f"wake-up latency µs: p50 {latency.p50_us:.0f}  p99 {latency.p99_us:.0f}  max {latency.max_us:.0f}")
    print(f"compute µs:         p50 {compute.p50_us:.0f}  p99 {compute.p99_us:.0f}  max {compute.max_us:.0f}")


if __name__ == "__main__":
    try:
        main(*sys.argv[1:2])
    except PlemError as error:
        sys.exit(error.render())
