"""The bridge process: one robot's shared memory on ROS 2 over Cyclone DDS (see `plem.middleware.robot_bridge`).

`plem launch` starts it after the robot's RT driver announced itself, as
`python -m plem.launch.ros_bridge '<launch arguments as JSON>'`. It runs at normal priority: it only
reads shared memory and sends commands to the robot's command service, so its death or slowness never
moves or stalls the arm. With `bridge_commands:=false` it only publishes: it creates no command
endpoints and sends no command. It exits when the driver's heartbeat stops: with an error when the driver
went away on its own, quietly when the launch is stopping (`plem launch` signals every component at once, and
the driver may end before the bridge has seen its own signal).
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import replace

from plem.bridge.client import DriverGone, connect
from plem.description.hardware import driven_block
from plem.launch.component import announce, run_component
from plem.launch.plan import plan_robot
from plem.middleware.controller_manager import Hardware
from plem.middleware.discovery import DiscoverySettings
from plem.middleware.node import Node
from plem.middleware.robot_bridge import RobotBridge, sample_bound

#: The hardware plugin reported for a package whose <ros2_control> block names none.
HARDWARE_PLUGIN = "hardware/HardwareInterface"
#: How often the bridge looks for new cycles; rt_raw is published in order, in batches of about this much.
PUMP_PERIOD_S = 0.001
LIVENESS_PERIOD_S = 0.5
#: How long a bridge whose driver is gone waits for its own stop signal before it calls the driver's end an error.
SHUTDOWN_GRACE_S = 5.0


def serve(arguments: dict[str, str], stop: threading.Event) -> None:
    """Publish and serve until `stop` or until the RT driver is gone."""
    plan = plan_robot(arguments, generate=False)
    bound = sample_bound(plan.config.dof, plan.robot_description, plan.report.srdf_xml)
    node = Node(replace(DiscoverySettings.from_environment(), max_sample_bytes=bound))
    client = connect(plan.robot_id, plan.config.dof)
    rate = plan.joint_state_rate()
    block = driven_block(plan.report.urdf) if plan.report.urdf else None
    hardware = Hardware(block.name if block else plan.robot_name, (block.plugin if block else None) or HARDWARE_PLUGIN)
    bridge = RobotBridge(client, node, plan.robot_description, rate, plan.controllers, hardware,
                         commands=plan.bridge_commands, semantic=plan.report.srdf_xml, frame_prefix=plan.frame_prefix)
    commands = _command_thread(bridge, stop) if bridge.commands else None
    announce({"ready": True, "namespace": bridge.namespace, "domain": node.settings.describe(),
              "joint_state_rate": rate, "commands": bridge.commands})
    next_check = time.monotonic()
    try:
        while not stop.is_set():
            bridge.pump()
            if time.monotonic() >= next_check:
                client.live_state()
                next_check = time.monotonic() + LIVENESS_PERIOD_S
            time.sleep(PUMP_PERIOD_S)
    except DriverGone:
        if not stop.wait(SHUTDOWN_GRACE_S):   # not the launch stopping: the driver ended on its own
            raise
    finally:
        stop.set()
        if commands is not None:
            commands.join(1.0)
        bridge.close()
        client.close()
        node.close()


def _command_thread(bridge: RobotBridge, stop: threading.Event) -> threading.Thread:
    """The started thread that serves the bridge's ROS 2 commands until `stop`."""
    thread = threading.Thread(target=bridge.serve_commands, args=(stop,), name="plem-bridge-commands", daemon=True)
    thread.start()
    return thread


def main(argv: list[str] | None = None) -> int:
    """Run the bridge of the robot whose launch arguments (JSON) are `argv[0]`; the process's exit code."""
    return run_component("bridge", serve, argv)


if __name__ == "__main__":
    sys.exit(main())
