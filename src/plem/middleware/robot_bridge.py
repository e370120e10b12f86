"""One robot on ROS 2: its shared memory published as topics, ROS commands passed to its RT driver.

It publishes the arm's frames on /tf and /tf_static as robot_state_publisher would (names prefixed with
`{robot_id}/` unless `frame_prefix` says otherwise, so several robots never share a frame). Under
`/{robot_id}/` it publishes joint_states and dynamic_joint_states, robot_description and
robot_description_semantic (latched; the latter when the package has an SRDF), rt_raw (every cycle),
rt_events and rt_monitor_stats (10 Hz) and the trajectory controller's controller_state. It serves the
controller manager's services, the trajectory controller's topic and action under the name controllers.yaml
gives it, the wim_rt_driver/set_mode action, moveit_servo's joint jog and twist topics and UR's speed slider
service (`plem.middleware.servo`), and publishes the speed override as UR's speed_scaling. A read-only bridge
(`commands=False`) creates none of these command endpoints (nor the controller manager), so nothing on the
network can command the arm through it.
It only reads shared memory and sends commands to the robot's command service through `RobotClient`, so
nothing it does (or a slow subscriber does to it) can delay the loop; what it could not keep up with is
counted in rt_monitor_stats.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from functools import partial
from typing import Any

from cyclonedds.util import duration

from plem.bridge.client import DriverGone, RobotClient
from plem.control.events import Event, EventKind
from plem.control.trajectory import ErrorCode
from plem.description.controllers import ControllerSet
from plem.errors import PlemError
from plem.middleware.action import ABORTED, ActionServer, Execution
from plem.middleware.controller_manager import ControllerManager, Hardware
from plem.middleware.goals import (
    FJT,
    rejected_trajectory,
    start_mode_change,
    start_trajectory,
    trajectory_bytes,
    trajectory_from_message,
)
from plem.middleware.monitor_feed import DESCRIPTION_TOPIC, DESCRIPTION_TYPE, MONITOR_TOPICS, MonitorFeed, QueueCount
from plem.middleware.node import Node, Subscription
from plem.middleware.node_graph import NodeGraph, RosoutHandler
from plem.middleware.parameters import ParameterServices, ParameterValue
from plem.middleware.qos import DEFAULT, EVENTS, LATCHED, RT_RAW, TF, TF_STATIC
from plem.middleware.servo import (
    SCALING_NODE,
    SERVO_NODE,
    SLIDER_NODE,
    ServoEndpoints,
    SpeedScalingPublisher,
    TwistFrames,
)
from plem.middleware.transforms import TreeTransforms, tf_message
from plem.recording.status import read_status

_log = logging.getLogger("plem.bridge")
_trajectory_log = logging.getLogger("plem.bridge.trajectory")
_manager_log = logging.getLogger("plem.bridge.controller_manager")
_servo_log = logging.getLogger("plem.bridge.servo_node")
#: FollowJointTrajectory codes of goals refused before they ran (the driver reports aborts of running ones).
REFUSAL_CODES = (int(ErrorCode.INVALID_GOAL), int(ErrorCode.INVALID_JOINTS))
#: Where a parameter is changed, said when `ros2 param set` is refused.
PARAMETERS_HOW = "change it in the description package (controllers.yaml, the URDF) or the launch arguments and " \
                 "restart the robot with plem launch"
#: The largest request any command endpoint but a trajectory's accepts (names of controllers, parameters, modes).
REQUEST_BYTES = 64 * 1024
#: Longest reason of an rt_events entry the bridge writes, as the driver's event records allow.
EVENT_REASON_CHARACTERS = 600


def _guarded(handle: Callable[..., None], *args: Any) -> None:
    """Run one command handler; a bug in it is logged, and serving goes on for every other command."""
    try:
        handle(*args)
    except Exception:  # noqa: BLE001 - one bad request must not end command service for everyone
        _log.exception("a ROS command could not be handled; serving goes on")


def sample_bound(dof: int, description: str, semantic: str | None) -> int:
    """The largest sample the bridge's participant lets Cyclone DDS reassemble, sent or received: a trajectory of
    the most points plem runs, or what it publishes of the description (robot_description, tf_static, the
    parameters), whichever is larger. A larger sample is dropped before the bridge holds it in memory."""
    published = len(description.encode()) + len((semantic or "").encode())
    return max(trajectory_bytes(dof), 2 * published + REQUEST_BYTES)


class _Reported:
    """A trajectory goal whose refusal is also logged (to /rosout) and published on rt_events."""

    def __init__(self, execution: Execution, bridge: RobotBridge) -> None:
        self.execution = execution
        self.bridge = bridge
        self._reported = False

    def poll(self) -> tuple[Any | None, tuple[int, Any] | None]:
        """The execution's feedback and end, reporting a refusal once."""
        feedback, end = self.execution.poll()
        if end is not None and not self._reported:
            self._reported = True
            status, result = end
            if status == ABORTED and result["error_code"] in REFUSAL_CODES:
                self.bridge.report_refusal("follow_joint_trajectory", result["error_string"])
        return feedback, end

    def cancel(self) -> bool:
        """Cancel the execution."""
        return self.execution.cancel()


class RobotBridge:
    """Publishes one robot's shared memory on ROS 2 and, unless read-only, serves its ROS 2 commands."""

    trajectories: Subscription[Any]
    follow: ActionServer
    set_mode: ActionServer
    manager: ControllerManager
    servo: ServoEndpoints
    parameter_services: list[ParameterServices]

    def __init__(self, client: RobotClient, node: Node, description: str, joint_state_rate: float,
                 controllers: ControllerSet, hardware: Hardware, commands: bool = True,
                 semantic: str | None = None, frame_prefix: str | None = None) -> None:
        self.client = client
        self.node = node
        self.library = node.library
        self.namespace = f"/{client.robot_id}"
        self.commands = commands
        self.controllers = controllers
        ns = self.namespace
        profiles = {"rt_raw": RT_RAW, "rt_events": EVENTS, "rt_monitor_stats": DEFAULT, "joint_states": DEFAULT}
        self.publishers = {name: node.publisher(f"{ns}/{name}", ros_type, profiles[name])
                           for name, ros_type in MONITOR_TOPICS.items()}
        trajectory = f"{ns}/{controllers.trajectory.name}"
        self.controller_state = node.publisher(f"{trajectory}/controller_state",
                                               "control_msgs/msg/JointTrajectoryControllerState", DEFAULT)
        self.dynamic_joint_states = node.publisher(f"{ns}/dynamic_joint_states", "control_msgs/msg/DynamicJointState",
                                                   DEFAULT)
        self.description = node.publisher(f"{ns}/{DESCRIPTION_TOPIC}", DESCRIPTION_TYPE, LATCHED)
        self.frames = TreeTransforms(description, f"{client.robot_id}/" if frame_prefix is None else frame_prefix)
        self.tf = node.publisher("/tf", "tf2_msgs/msg/TFMessage", TF)
        self.tf_static = node.publisher("/tf_static", "tf2_msgs/msg/TFMessage", TF_STATIC)
        self.tf_static.publish(tf_message(self.library, self.frames.static(), time.time_ns()))
        self.speed_scaling = SpeedScalingPublisher(node, ns, client)
        self.speed_scaling.publish(self.speed_scaling.factor())   # maps the stream block before commands are served
        for controller in controllers.unsupported:
            _log.warning("controllers.yaml declares %s of type %s, which plem does not run; it is listed as "
                         "unconfigured", controller.name, controller.type)
        slower = controllers.rate_warning(client.cycle_time_s)
        if slower is not None:
            _log.warning("%s", slower.render().removeprefix("ERROR: "))
        if commands:
            self._command_endpoints(hardware, TwistFrames(description, client.joint_names, self.frames.frame_prefix))
        self.description.publish(self.description.message(data=description))
        if semantic is not None:
            self.semantic = node.publisher(f"{ns}/robot_description_semantic", "std_msgs/msg/String", LATCHED)
            self.semantic.publish(self.semantic.message(data=semantic))
        self.feed = MonitorFeed(client, self.library, joint_state_rate)
        self._profiles = profiles
        publisher: dict[str, ParameterValue] = {"robot_description": description,
                                                "frame_prefix": self.frames.frame_prefix,
                                                "publish_frequency": float(joint_state_rate)}
        driver: dict[str, ParameterValue] = {"robot_id": client.robot_id,
                                             "cycle_time_us": round(client.cycle_time_s * 1e6)}
        self._parameters = {"robot_state_publisher": publisher, "wim_rt_driver": driver}
        self.graph = self._announce_nodes(semantic is not None)

    def _announce_nodes(self, semantic: bool) -> NodeGraph:
        """Present the endpoints as the nodes of a ros2_control robot (docs/ros2.md lists them) and send each
        node's log to /rosout."""
        graph, ns, controllers = NodeGraph(self.node), self.namespace, self.controllers
        self._handlers: list[tuple[logging.Logger, logging.Handler]] = []
        broadcaster = controllers.by_role("broadcaster")
        graph.add(ns, broadcaster.name if broadcaster else "joint_state_broadcaster",
                  self.publishers["joint_states"], self.dynamic_joint_states)
        graph.add(ns, "robot_state_publisher", self.description, self.tf, self.tf_static,
                  *([self.semantic] if semantic else []))
        driver = graph.add(ns, "wim_rt_driver", *(self.publishers[name] for name in ("rt_raw", "rt_events",
                                                                                 "rt_monitor_stats")))
        trajectory = graph.add(ns, controllers.trajectory.name, self.controller_state)
        free_drive = controllers.by_role("free_drive")
        if free_drive is not None:
            graph.add(ns, free_drive.name)
        graph.add(ns, SCALING_NODE, self.speed_scaling.publisher)
        if self.commands:
            manager = graph.add(ns, "controller_manager", *self.manager.services)
            servo = graph.add(ns, SERVO_NODE, self.servo.joint_jog, self.servo.twist)
            graph.add(ns, SLIDER_NODE, self.servo.speed_slider)
            trajectory.endpoints += [self.trajectories, self.follow]
            driver.endpoints.append(self.set_mode)
            self.parameter_services = [ParameterServices(self.node, f"{ns}/{graph_node.name}",
                                                         self._node_parameters(graph_node.name), PARAMETERS_HOW)
                                       for graph_node in graph.nodes]
            for graph_node, parameters in zip(graph.nodes, self.parameter_services, strict=True):
                graph_node.endpoints.append(parameters)
                for server in parameters.services:
                    server.requests.max_bytes = REQUEST_BYTES
            for logger, graph_node in ((_manager_log, manager), (_trajectory_log, trajectory), (_servo_log, servo)):
                handler = RosoutHandler(graph, graph_node)
                logger.addHandler(handler)
                self._handlers.append((logger, handler))
        graph.announce()
        return graph

    def _node_parameters(self, name: str) -> dict[str, ParameterValue]:
        """The read-only parameters `ros2 param` shows for one of the bridge's nodes."""
        controllers = self.controllers
        if name == "controller_manager":
            return {"update_rate": controllers.rate(self.client.cycle_time_s),
                    **{f"{c.name}.type": c.type for c in controllers.controllers}}
        controller = controllers.named(name)
        if controller is not None:
            return {"joints": list(controller.joints), "command_interfaces": list(controller.command_interfaces),
                    "state_interfaces": list(controller.state_interfaces)}
        return dict(self._parameters.get(name, {}))

    def _command_endpoints(self, hardware: Hardware, frames: TwistFrames) -> None:
        """The controller manager's services, the trajectory controller's topic and action and the set_mode action,
        as ROS 2 names them."""
        client, node, ns = self.client, self.node, self.namespace
        self.manager = ControllerManager(node, ns, client, self.controllers, hardware)
        trajectory = f"{ns}/{self.controllers.trajectory.name}"
        self.trajectories = node.subscription(f"{trajectory}/joint_trajectory", "trajectory_msgs/msg/JointTrajectory",
                                              DEFAULT)
        self.follow = ActionServer(node, f"{trajectory}/follow_joint_trajectory", FJT, self._on_goal)
        self.set_mode = ActionServer(node, f"{ns}/wim_rt_driver/set_mode", "plem_msgs/action/SetMode",
                                     lambda goal: start_mode_change(client, goal))
        self.servo = ServoEndpoints(node, ns, client, partial(self.report_refusal, logger=_servo_log),
                                    self.manager.accepts_trajectories, frames)
        for server in (*self.follow.services, *self.set_mode.services, *self.manager.services,
                       self.servo.speed_slider):
            server.requests.max_bytes = REQUEST_BYTES
        self.servo.joint_jog.max_bytes = self.servo.twist.max_bytes = REQUEST_BYTES
        self.trajectories.max_bytes = self.follow.send_goal.requests.max_bytes = trajectory_bytes(client.dof)

    def close(self) -> None:
        """Stop sending log records to /rosout (before the node closes)."""
        for logger, handler in self._handlers:
            logger.removeHandler(handler)
        self._handlers.clear()

    # -- shared memory → topics -----------------------------------------------------------------------
    def pump(self) -> int:
        """Publish everything new in shared memory; the number of rt_raw samples published."""
        return self.feed.pump(self)

    def rt_raw(self, cdr: bytes, wall_ns: int) -> None:
        """Publish one rt_raw sample as it is, in CDR."""
        self.publishers["rt_raw"].publish_cdr(cdr)

    def joint_state(self, message: Any, wall_ns: int) -> None:
        """Publish on joint_states, and from the same sample dynamic_joint_states and controller_state."""
        self.publishers["joint_states"].publish(message)
        new = self.library.new
        values = [new("control_msgs/msg/InterfaceValue", interface_names=["position", "velocity", "effort"],
                      values=[p, v, e]) for p, v, e in zip(message.position, message.velocity, message.effort,
                                                           strict=True)]
        self.dynamic_joint_states.publish(new("control_msgs/msg/DynamicJointState", header=message.header,
                                              joint_names=message.name, interface_values=values))
        moving = self.frames.moving(dict(zip(message.name, message.position, strict=True)))
        self.tf.publish(tf_message(self.library, moving, wall_ns))
        factor = self.speed_scaling.factor()
        self.speed_scaling.publish(factor)
        self._controller_state(message, factor)

    def _controller_state(self, message: Any, speed_scaling: float) -> None:
        """control_msgs/JointTrajectoryControllerState: the command as reference and output, the measurement as
        feedback, their difference, and the speed override in force as the speed scaling factor."""
        try:
            state = self.client.state()
        except DriverGone:
            return
        if state is None:
            return
        new = self.library.new
        point = "trajectory_msgs/msg/JointTrajectoryPoint"
        reference = new(point, positions=state.command_position.tolist(), velocities=state.command_velocity.tolist(),
                        accelerations=state.command_acceleration.tolist())
        feedback = new(point, positions=state.position.tolist(), velocities=state.velocity.tolist(),
                       effort=state.effort.tolist())
        error = new(point, positions=(state.command_position - state.position).tolist(),
                    velocities=(state.command_velocity - state.velocity).tolist())
        self.controller_state.publish(new(
            "control_msgs/msg/JointTrajectoryControllerState", header=message.header, joint_names=message.name,
            reference=reference, feedback=feedback, error=error,
            output=new(point, positions=state.command_position.tolist()), speed_scaling_factor=speed_scaling))

    def rt_event(self, message: Any, event: Event, wall_ns: int) -> None:
        """Publish on rt_events."""
        self.publishers["rt_events"].publish(message)

    def rt_monitor_stats(self, message: Any, wall_ns: int) -> None:
        """Publish on rt_monitor_stats."""
        self.publishers["rt_monitor_stats"].publish(message)

    def queues(self) -> list[QueueCount]:
        """The DDS publishers that could refuse a write (fill is not exposed by Cyclone DDS), then the recorder's."""
        publishers = [QueueCount(f"dds:{name}", self._profiles[name].depth, 0, self.publishers[name].published,
                                 self.publishers[name].dropped) for name in ("rt_raw", "joint_states", "rt_events")]
        return [*publishers, *read_status(self.client.robot_id)]

    # -- ROS commands → command service ---------------------------------------------------------------
    def serve_commands(self, stop: threading.Event, period: float = 0.01) -> None:
        """Take trajectories, action and service requests until `stop`; runs in its own thread (not when
        read-only), so nothing a command costs delays what the main thread publishes."""
        parameters = [server for node in self.parameter_services for server in node.services]
        waitset = self.node.waitset([self.trajectories, *self.follow.services, *self.set_mode.services,
                                     *self.manager.services, *self.servo.waitables, *parameters])
        handlers = [self._take_trajectories, self.follow.spin_once, self.set_mode.spin_once, self.manager.spin_once,
                    self.servo.spin_once, *(node.spin_once for node in self.parameter_services)]
        timeout = duration(seconds=period)
        _guarded(self.servo.prepare)
        while not stop.is_set():
            waitset.wait(timeout)
            for handle in handlers:   # each on its own: one failing endpoint never starves the others
                _guarded(handle)

    def _take_trajectories(self) -> None:
        """Handle each trajectory waiting on the topic, each on its own."""
        for message in self.trajectories.take():
            _guarded(self._on_trajectory, message)

    def _on_goal(self, goal: Any) -> Execution:
        """A FollowJointTrajectory goal: run it, or end it at once when the trajectory controller is not active."""
        refused = self.manager.accepts_trajectories()
        return _Reported(rejected_trajectory(refused) if refused else
                         start_trajectory(self.client, self.library, goal), self)

    def report_refusal(self, source: str, text: str, logger: logging.Logger = _trajectory_log) -> None:
        """A ROS command refused: a WARNING on /rosout (under the node of `logger`, by default the trajectory
        controller's) and a command_rejected entry on rt_events."""
        logger.warning("%s refused: %s", source, text)
        header = self.library.new("std_msgs/msg/Header", stamp=self.library.stamp())
        state = self._mode_name()
        self.publishers["rt_events"].publish(self.library.new(
            MONITOR_TOPICS["rt_events"], header=header, kind=EventKind.COMMAND_REJECTED.value, cause=source,
            reason=text.splitlines()[0].removeprefix("ERROR: ")[:EVENT_REASON_CHARACTERS], mode=state,
            previous_mode=""))

    def _mode_name(self) -> str:
        try:
            state = self.client.state()
        except DriverGone:
            return ""
        return "" if state is None else str(state.mode)

    def _on_trajectory(self, message: Any) -> None:
        """The trajectory controller's topic: a trajectory replaces the running one; an empty one stops."""
        try:
            if not message.points:
                self.client.stop()
                return
            refused = self.manager.accepts_trajectories()
            if refused:
                raise refused
            self.client.execute_trajectory(trajectory_from_message(message))
        except PlemError as error:
            self.report_refusal("joint_trajectory", error.render())
