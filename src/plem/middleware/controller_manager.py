"""ros2_control's controller manager services for one plem robot, under `/{robot_id}/controller_manager/`.

The controllers are those of the package's controllers.yaml (`plem.description.controllers`); their states
follow the robot's mode. The trajectory controller is active while the arm holds or moves (HOLD,
TRAJECTORY) unless `switch_controller` deactivated it; free drive is active in FREE_DRIVE; the joint state
broadcaster always runs. Switching and the hardware component's lifecycle become mode changes of the RT
driver, through the same client every script uses:

- activating the trajectory controller holds the arm (enabling the drives when they are off);
- activating free drive switches to free drive;
- deactivating a controller leaves the arm holding where it is, with no controller active;
- the hardware component `active` enables the drives (resetting a fault), `inactive` disables them.

Strictness follows ros2_control: STRICT refuses the whole switch when a name is unknown or a controller is
already in the asked state; BEST_EFFORT (and 0, AUTO, FORCE_AUTO) skips those. Activating two controllers
that claim the same joints' commands is refused either way, unless one of them is deactivated in the same
request.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from plem.bridge.client import DriverGone, RemoteHandle, RobotClient
from plem.control.modes import Mode
from plem.description.controllers import Controller, ControllerSet
from plem.errors import PlemError
from plem.ipc.requests import error_from_json
from plem.middleware.node import Node, ServiceServer

_log = logging.getLogger("plem.bridge.controller_manager")

STRICT = 2
#: lifecycle_msgs/State ids and labels, as ros2_control reports hardware components in.
UNCONFIGURED, INACTIVE, ACTIVE, FINALIZED = 1, 2, 3, 4
LABELS = {UNCONFIGURED: "unconfigured", INACTIVE: "inactive", ACTIVE: "active", FINALIZED: "finalized"}
#: The hardware's interfaces per joint: plem commands position, velocity and acceleration (and effort in free
#: drive) and reads position, velocity and effort.
COMMAND_INTERFACES = ("position", "velocity", "acceleration", "effort")
STATE_INTERFACES = ("position", "velocity", "effort")
SERVICES = {"list_controllers": "ListControllers", "list_hardware_components": "ListHardwareComponents",
            "list_hardware_interfaces": "ListHardwareInterfaces", "switch_controller": "SwitchController",
            "set_hardware_component_state": "SetHardwareComponentState"}


@dataclass(frozen=True)
class Hardware:
    """The arm's hardware component: the name and plugin of the URDF's <ros2_control> block."""

    name: str
    plugin: str


@dataclass
class _Pending:
    """A request whose reply waits for the driver to finish a mode change."""

    server: ServiceServer
    request: Any
    handle: RemoteHandle
    reply: Callable[[str | None], dict[str, Any]]  # the reply's fields, given the driver's error (None: done)


@dataclass
class ControllerManager:
    """Serves the controller manager's services from the robot's mode and the bridge's own switch record."""

    node: Node
    namespace: str
    client: RobotClient
    controllers: ControllerSet
    hardware: Hardware
    deactivated: set[str] = field(default_factory=set)
    _pending: list[_Pending] = field(default_factory=list)

    def __post_init__(self) -> None:
        base = f"{self.namespace}/controller_manager"
        self.servers = {name: self.node.service(f"{base}/{name}", f"controller_manager_msgs/srv/{kind}")
                        for name, kind in SERVICES.items()}
        self._handlers: dict[str, Callable[[ServiceServer, Any], None]] = {
            "list_controllers": self._list_controllers, "list_hardware_components": self._list_components,
            "list_hardware_interfaces": self._list_interfaces, "switch_controller": self._switch,
            "set_hardware_component_state": self._set_hardware_state}

    @property
    def services(self) -> tuple[ServiceServer, ...]:
        """The service servers, for the bridge's wait set."""
        return tuple(self.servers.values())

    def spin_once(self) -> None:
        """Answer waiting requests and the requests whose mode change finished."""
        for name, server in self.servers.items():
            for request in server.take():
                self._handlers[name](server, request)
            server.flush()
        for pending in list(self._pending):
            if pending.handle.done:
                reply = pending.handle.reply or {}
                error = reply.get("error")
                problem = error_from_json(error).render() if error is not None else None
                pending.server.reply(pending.request, **pending.reply(problem))
                self._pending.remove(pending)

    # -- states ---------------------------------------------------------------------------------------
    def mode(self) -> Mode | None:
        """The robot's mode now, or None when its state cannot be read."""
        try:
            state = self.client.state()
        except DriverGone:
            return None
        return None if state is None else state.mode

    def state_of(self, controller: Controller, mode: Mode | None) -> str:
        """'active', 'inactive' or, for a type plem does not run, 'unconfigured'."""
        role = controller.role
        if role is None:
            return "unconfigured"
        active = {"broadcaster": mode is not None,
                  "trajectory": mode in (Mode.HOLD, Mode.TRAJECTORY) and controller.name not in self.deactivated,
                  "free_drive": mode is Mode.FREE_DRIVE}[role]
        return "active" if active else "inactive"

    def accepts_trajectories(self) -> PlemError | None:
        """None when the trajectory controller takes goals; else why not, naming the ROS-side fix."""
        trajectory = self.controllers.trajectory
        mode = self.mode()
        base = f"{self.namespace}/controller_manager"
        enable = (f"ros2 service call {base}/set_hardware_component_state "
                  f"controller_manager_msgs/srv/SetHardwareComponentState "
                  f"\"{{name: {self.hardware.name}, target_state: {{id: 3, label: active}}}}\"")
        activate = (f"ros2 control switch_controllers -c {base} --activate {trajectory.name}"
                    + (" --deactivate " + free.name if (free := self.controllers.by_role("free_drive")) else ""))
        if mode is Mode.IDLE:
            return PlemError(f"{trajectory.name} cannot move the arm: its drives are disabled",
                             what="the drives enabled and the trajectory controller active",
                             why="the hardware component is inactive (mode IDLE)",
                             how=f"enable the drives: {enable}; or launch with start_enabled:=true")
        if mode is Mode.FAULT:
            return PlemError(f"{trajectory.name} cannot move the arm: the robot is in fault",
                             what="the fault cleared", why="mode FAULT (see /rt_events for the reason)",
                             how=f"clear the fault and hold: {enable}")
        if self.state_of(trajectory, mode) != "active":
            return PlemError(f"{trajectory.name} is not active", what="the trajectory controller active",
                             why=f"it is {self.state_of(trajectory, mode)} (mode {mode.name if mode else 'unknown'})",
                             how=f"activate it: {activate}")
        return None

    # -- listing --------------------------------------------------------------------------------------
    def _list_controllers(self, server: ServiceServer, request: Any) -> None:
        mode, new = self.mode(), self.node.library.new
        rate = self.controllers.rate(self.client.cycle_time_s)
        states = []
        for controller in self.controllers.controllers:
            state = self.state_of(controller, mode)
            states.append(new(
                "controller_manager_msgs/msg/ControllerState", name=controller.name, state=state,
                type=controller.type, update_rate=min(rate, 65535),
                claimed_interfaces=list(controller.claimed()) if state == "active" else [],
                required_command_interfaces=list(controller.claimed()),
                required_state_interfaces=[f"{joint}/{interface}" for joint in controller.joints
                                           for interface in controller.state_interfaces]))
        server.reply(request, controller=states)

    def _interfaces(self, kind: str, mode: Mode | None) -> list[Any]:
        names = COMMAND_INTERFACES if kind == "command" else STATE_INTERFACES
        claimed = {name for c in self.controllers.controllers if self.state_of(c, mode) == "active"
                   for name in c.claimed()} if kind == "command" else set()
        return [self.node.library.new("controller_manager_msgs/msg/HardwareInterface", name=f"{joint}/{interface}",
                                      data_type="double", is_available=mode is not None,
                                      is_claimed=f"{joint}/{interface}" in claimed)
                for joint in self.client.joint_names for interface in names]

    def _hardware_state(self, mode: Mode | None) -> Any:
        state_id = UNCONFIGURED if mode is None else INACTIVE if mode is Mode.IDLE else ACTIVE
        return self.node.library.new("lifecycle_msgs/msg/State", id=state_id, label=LABELS[state_id])

    def _list_components(self, server: ServiceServer, request: Any) -> None:
        mode = self.mode()
        rate = round(1.0 / self.client.cycle_time_s)
        component = self.node.library.new(
            "controller_manager_msgs/msg/HardwareComponentState", name=self.hardware.name, type="system",
            rw_rate=min(rate, 65535), plugin_name=self.hardware.plugin, state=self._hardware_state(mode),
            command_interfaces=self._interfaces("command", mode), state_interfaces=self._interfaces("state", mode))
        server.reply(request, component=[component])

    def _list_interfaces(self, server: ServiceServer, request: Any) -> None:
        mode = self.mode()
        server.reply(request, command_interfaces=self._interfaces("command", mode),
                     state_interfaces=self._interfaces("state", mode))

    # -- switching ------------------------------------------------------------------------------------
    def _switch(self, server: ServiceServer, request: Any) -> None:
        try:
            target = self._switch_target(list(request.activate_controllers), list(request.deactivate_controllers),
                                         request.strictness == STRICT)
        except ValueError as refused:
            _log.warning("switch_controller refused: %s", refused)
            server.reply(request, ok=False, message=str(refused))
            return
        self._run(server, request, target,
                  lambda problem: {"ok": problem is None, "message": problem or "switched"})

    def _switch_target(self, activate: list[str], deactivate: list[str], strict: bool
                       ) -> tuple[Mode | None, set[str]]:
        """The mode the switch needs (None: keep it) and the controllers that end deactivated; ValueError when
        the switch is refused."""
        mode = self.mode()
        if mode is None:
            raise ValueError("the RT driver is not running")
        known = {c.name: c for c in self.controllers.controllers}
        skipped = []
        for name in [*activate, *deactivate]:
            if name not in known:
                if strict:
                    raise ValueError(f"unknown controller {name!r}; known: {', '.join(known)}")
                skipped.append(name)
        wanted = {name: "active" for name in activate if name in known}
        wanted.update({name: "inactive" for name in deactivate if name in known and name not in wanted})
        for name, state in list(wanted.items()):
            controller = known[name]
            if controller.role is None:
                raise ValueError(f"{name} is of type {controller.type}, which plem does not run")
            if controller.role == "broadcaster" and state == "inactive":
                raise ValueError(f"{name} always runs: plem's joint states are published whatever is active")
            if self.state_of(controller, mode) == state:
                if strict:
                    raise ValueError(f"{name} is already {state}")
                del wanted[name]
        after = {c.name: wanted.get(c.name, self.state_of(c, mode)) for c in self.controllers.controllers}
        commanding = [name for name, state in after.items() if state == "active"
                      and known[name].role in ("trajectory", "free_drive")]
        if len(commanding) > 1:
            raise ValueError(f"{' and '.join(commanding)} would both command the joints; deactivate one of them in "
                             "the same request")
        if mode is Mode.FAULT and any(state == "active" for state in wanted.values()):
            raise ValueError("the robot is in fault: set the hardware component active first "
                             "(set_hardware_component_state)")
        roles = {known[name].role: state for name, state in wanted.items()}
        deactivated = set(self.deactivated)
        trajectory = self.controllers.trajectory.name
        if roles.get("trajectory") == "active":
            deactivated.discard(trajectory)
        elif roles.get("trajectory") == "inactive" or (roles.get("free_drive") == "inactive"
                                                       and "active" not in roles.values()):
            deactivated.add(trajectory)  # no controller commands the joints: the arm holds where it is
        goal = (Mode.FREE_DRIVE if roles.get("free_drive") == "active" else
                Mode.HOLD if "active" in roles.values() or mode in (Mode.TRAJECTORY, Mode.FREE_DRIVE) and roles
                else None)
        if skipped:
            _log.warning("switch_controller skipped unknown controllers: %s", ", ".join(skipped))
        return (goal if goal is not mode else None), deactivated

    def _run(self, server: ServiceServer, request: Any, target: tuple[Mode | None, set[str]],
             reply: Callable[[str | None], dict[str, Any]]) -> None:
        """Apply a switch: record the deactivated controllers, then change mode (replying when it is done)."""
        goal, deactivated = target
        self.deactivated = deactivated
        if goal is None:
            server.reply(request, **reply(None))
            return
        try:
            handle = self.client.request_mode(goal)
        except PlemError as error:
            server.reply(request, **reply(error.render()))
            return
        self._pending.append(_Pending(server, request, handle, reply))

    # -- the hardware component -----------------------------------------------------------------------
    def _set_hardware_state(self, server: ServiceServer, request: Any) -> None:
        target = request.target_state
        wanted = target.id if target.id else next((i for i, label in LABELS.items() if label == target.label), 0)

        def answer(problem: str | None) -> dict[str, Any]:
            if problem is not None:
                _log.warning("set_hardware_component_state failed: %s", problem)
            return {"ok": problem is None, "state": self._hardware_state(self.mode())}

        if request.name != self.hardware.name or wanted not in (ACTIVE, INACTIVE):
            why = (f"unknown hardware component {request.name!r} (this robot has {self.hardware.name!r})"
                   if request.name != self.hardware.name else
                   f"target state {target.id} {target.label!r}: plem's hardware is either active (3) or inactive (2)")
            server.reply(request, **answer(why))
            return
        mode = self.mode()
        if mode is None:
            server.reply(request, **answer("the RT driver is not running"))
            return
        if wanted == INACTIVE:
            handle = self.client.request_mode(Mode.IDLE) if mode is not Mode.IDLE else None
        elif mode is Mode.FAULT:
            handle = self.client.request_reset()
        else:
            handle = self.client.request_mode(Mode.HOLD) if mode is Mode.IDLE else None
        if handle is None:
            server.reply(request, **answer(None))
        else:
            self._pending.append(_Pending(server, request, handle, answer))
