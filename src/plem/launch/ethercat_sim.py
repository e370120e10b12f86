"""The virtual EtherCAT network as a launch component (`bus:=ethercat_sim`): the arm's emulated drives.

`plem launch bus:=ethercat_sim` starts it before the RT driver and points the driver's EtherCAT master
at the network's master end, so the whole real master path runs without hardware. It announces the
interface it serves, and stops (removing the network) after the RT driver has disabled the drives.
"""

from __future__ import annotations

import threading

from plem.description.drives import drive_parameters
from plem.errors import ConfigError
from plem.fieldbus.ethercat.virtual.emulator import Arm, VirtualNetwork
from plem.launch.component import announce, run_component
from plem.launch.plan import RobotPlan, plan_robot
from plem.robot.robot import arm_joint_names, home_position, startup_urdf


def arm_of_plan(plan: RobotPlan, encoder_zero: tuple[int, ...] | None = None,
                missing_objects: frozenset[int] = frozenset(), start: tuple[float, ...] | None = None) -> Arm:
    """The arm the emulated drives move: the plan's joints, URDF, drive parameters, cycle time and limits (and the
    objects its drives lack); it starts at `start` when given, else at zero, home or mid-range within the limits."""
    urdf, urdf_xml = startup_urdf(plan.report)
    joint_names = arm_joint_names(plan.config, urdf)
    drives = drive_parameters(urdf, joint_names)
    if not drives:
        raise ConfigError(f"{plan.package.name} has no drive parameters for the virtual EtherCAT network",
                          what="encoder_resolution, gear_ratio and direction <param> tags for every joint",
                          why=f"no <joint> of {plan.package.name}'s ros2_control block declares them",
                          how="add them to the ros2_control block (docs/ethercat.md), or use bus:=mock")
    if encoder_zero is not None and len(encoder_zero) != len(joint_names):
        raise ConfigError("wrong number of encoder zeros for the virtual network",
                          what=f"one raw encoder reading at home per joint ({len(joint_names)})",
                          why=f"got {len(encoder_zero)}", how=f"give {len(joint_names)} whole numbers")
    limits = plan.limits()
    return Arm(joint_names, urdf_xml, drives, plan.config.cycle_time * 1e-6, encoder_zero,
               home_position(plan.report, joint_names), start,
               (tuple(limits.min_position), tuple(limits.max_position)), missing_objects)


def serve(arguments: dict[str, str], stop: threading.Event) -> None:
    """Run the robot's virtual network (numbered by its master_index) until `stop`."""
    plan = plan_robot(arguments, generate=False)
    network = VirtualNetwork(arm_of_plan(plan, start=plan.initial_positions), index=plan.config.master_index)
    network.stop = stop
    network.run(ready=lambda running: announce({"ready": True, "interface": running.master_interface,
                                                "slaves": len(running.identities)}))


if __name__ == "__main__":
    raise SystemExit(run_component("ethercat_sim", serve))
