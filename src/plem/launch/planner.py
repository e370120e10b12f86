"""The planner process: IK, collision checking, OMPL planning and time parameterisation for one robot.

`plem launch` starts it after the RT driver (and bridge) when the description package has an SRDF, as
`python -m plem.launch.planner '<launch arguments as JSON>'`. It reads the arm's state from shared memory
and serves plans on the robot's planner socket (see `plem.planning.service`) and, unless the launch wants no
DDS (bridge:=false), MoveIt's services and execute_trajectory action under `/{robot_id}/` (see
`plem.middleware.moveit`). Plans never move the arm; execute_trajectory sends its trajectory through the
robot's command path as any client does, so the planner's death or slowness never moves or stalls the arm.
It exits when the driver's heartbeat stops.
"""

from __future__ import annotations

import sys
import threading
from pathlib import Path

from plem.bridge.client import RobotClient, connect
from plem.control.limits import ArmLimits
from plem.ipc.command_socket import listen, remove_own_socket, socket_path
from plem.launch.component import announce, run_component
from plem.launch.plan import RobotPlan, plan_robot
from plem.middleware.moveit import MoveItServices
from plem.middleware.node import Node
from plem.planning.planner import Planner
from plem.planning.scene import read_scene_file
from plem.planning.service import PlannerService

LIVENESS_PERIOD_S = 0.5


def build_planner(plan: RobotPlan, limits: ArmLimits) -> Planner:
    """The planner of a launched robot: its URDF, SRDF and kinematics.yaml, the driver's limits and cycle, and the
    objects of the scene:= file."""
    planner = Planner.for_package(plan.report, plan.joint_names, limits, plan.config.cycle_time / 1e6,
                                  plan.frame_prefix)
    scene = plan.arguments.get("scene")
    if scene:
        for item in read_scene_file(Path(scene)):
            planner.scene.add(item)
    return planner


def moveit_services(plan: RobotPlan, service: PlannerService, client: RobotClient) -> MoveItServices:
    """MoveIt's services and action for a launched robot, on a DDS participant of their own."""
    robot_model = plan.report.urdf.name if plan.report.urdf is not None else plan.robot_name
    return MoveItServices(Node(), service, client, f"/{plan.robot_id}",
                          trajectory_controller=plan.controllers.trajectory.name, robot_model=robot_model)


def serve(arguments: dict[str, str], stop: threading.Event) -> None:
    """Serve plans until `stop` or until the RT driver is gone."""
    plan = plan_robot(arguments, generate=False)
    client = connect(plan.robot_id, plan.config.dof)
    planner = build_planner(plan, client.limits)
    service = PlannerService(planner, client)
    moveit = moveit_services(plan, service, client) if plan.bridge else None
    server = listen(plan.robot_id, service="planner")
    threads = [threading.Thread(target=service.serve, args=(server, stop), name="plem-planner", daemon=True)]
    if moveit is not None:
        threads += [threading.Thread(target=spin, args=(stop,), name=f"plem-moveit-{part}", daemon=True)
                    for part, spin in (("services", moveit.spin_services), ("execution", moveit.spin_execution))]
    for thread in threads:
        thread.start()
    announce({"ready": True, "socket": str(socket_path(plan.robot_id, "planner")),
              "groups": list(planner.groups), "objects": len(planner.scene.objects()),
              "warnings": planner.warnings, "namespace": moveit.namespace if moveit else None,
              "domain": moveit.node.settings.describe() if moveit else None})
    try:
        while not stop.is_set():
            client.live_state()
            stop.wait(LIVENESS_PERIOD_S)
    finally:
        stop.set()
        for thread in threads:
            thread.join(1.0)
        if moveit is not None:
            moveit.close()
            if not any(thread.is_alive() for thread in threads):  # else a plan still runs: the exit ends it
                moveit.node.close()
        server.close()
        remove_own_socket(plan.robot_id, "planner")
        client.close()


def main(argv: list[str] | None = None) -> int:
    """Run the planner of the robot whose launch arguments (JSON) are `argv[0]`; the process's exit code."""
    return run_component("planner", serve, argv)


if __name__ == "__main__":
    sys.exit(main())
