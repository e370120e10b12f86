"""The controllers a package's controllers.yaml declares, as plem runs them under the names the file gives.

plem runs three kinds of controller, recognised by their ros2_control type: the trajectory controller
(joint_trajectory_controller, one for the whole arm), the joint state broadcaster and the free drive
controller. A type is declared as ros2_control reads it, under `controller_manager.ros__parameters.<name>.type`
or under `<name>.ros__parameters.type`. A package without controllers.yaml runs the controllers plem
generates for it; the built-in arms ship the configuration reference's file.

`controller_manager.ros__parameters.update_rate` is the controller manager's rate as ROS 2 tools see it
(list_controllers, the `update_rate` parameter). The controllers themselves run inside plem's loop, every
cycle_time, so a rate above the loop's cannot be honoured: it is reported as the loop's rate, with a warning.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from plem.description.generate import BROADCASTER_TYPE, FREE_DRIVE_TYPE, TRAJECTORY_TYPE, controllers_yaml
from plem.description.package_yaml import read_package_yaml
from plem.description.parameter_ranges import update_rate_error
from plem.errors import ConfigError, PlemError
from plem.robot.config import CYCLE_TIME_RANGE_US

#: The role of each controller type plem runs.
ROLES = {TRAJECTORY_TYPE: "trajectory", BROADCASTER_TYPE: "broadcaster", FREE_DRIVE_TYPE: "free_drive"}
#: Interfaces each role uses when controllers.yaml names none.
DEFAULT_INTERFACES = {"trajectory": (("position",), ("position", "velocity")),
                      "broadcaster": ((), ("position", "velocity", "effort")),
                      "free_drive": (("effort",), ("position", "velocity"))}


@dataclass(frozen=True)
class Controller:
    """One controller: its name, ros2_control type, joints and the interfaces it commands and reads."""

    name: str
    type: str
    joints: tuple[str, ...]
    command_interfaces: tuple[str, ...]
    state_interfaces: tuple[str, ...]

    @property
    def role(self) -> str | None:
        """'trajectory', 'broadcaster' or 'free_drive'; None for a type plem does not run."""
        return ROLES.get(self.type)

    def claimed(self) -> tuple[str, ...]:
        """The command interfaces it owns while active, as ros2_control names them (`joint/interface`)."""
        return tuple(f"{joint}/{interface}" for joint in self.joints for interface in self.command_interfaces)


@dataclass(frozen=True)
class ControllerSet:
    """The controllers of one robot: the file's update rate, the controllers in the file's order, the file."""

    update_rate: float | None
    controllers: tuple[Controller, ...]
    source: str = "controllers.yaml"

    def rate(self, cycle_time_s: float) -> int:
        """The controller manager's update rate in Hz as ROS 2 reports it: the file's, at most the loop's
        (1/cycle_time); the loop's when the file gives none."""
        loop = round(1.0 / cycle_time_s)
        return loop if self.update_rate is None else max(1, min(round(self.update_rate), loop))

    def rate_warning(self, cycle_time_s: float) -> PlemError | None:
        """Why the file's update_rate is not the rate reported (it is above the loop's), or None."""
        loop = round(1.0 / cycle_time_s)
        if self.update_rate is None or self.update_rate <= loop:
            return None
        faster = math.floor(1e6 / self.update_rate)  # the cycle_time (µs) whose loop runs at the file's rate
        return ConfigError(f"update_rate {self.update_rate:g} Hz is above the loop's {loop} Hz; "
                           f"the controllers run and are reported at {loop} Hz",
                           what="controller_manager.ros__parameters.update_rate at or below the loop's rate "
                                "(1 / cycle_time)",
                           why=f"{self.source} asks {self.update_rate:g} Hz, and cycle_time "
                               f"{round(cycle_time_s * 1e6)} µs runs the loop at {loop} Hz: every controller "
                               "runs inside the loop, never faster",
                           how=f"set update_rate: {loop} (or less) in {self.source}"
                               + (f", or launch with cycle_time:={faster}" if faster >= CYCLE_TIME_RANGE_US[0] else ""))

    def by_role(self, role: str) -> Controller | None:
        """The controller of `role`, or None when the file declares none."""
        return next((c for c in self.controllers if c.role == role), None)

    @property
    def trajectory(self) -> Controller:
        """The trajectory controller (always present: plem adds one when the file declares none)."""
        found = self.by_role("trajectory")
        assert found is not None  # read_controllers guarantees it
        return found

    @property
    def unsupported(self) -> tuple[Controller, ...]:
        """Controllers of types plem does not run."""
        return tuple(c for c in self.controllers if c.role is None)

    def named(self, name: str) -> Controller | None:
        """The controller called `name`, or None."""
        return next((c for c in self.controllers if c.name == name), None)


def _strings(value: Any) -> tuple[str, ...] | None:
    return tuple(value) if isinstance(value, list) and all(isinstance(v, str) for v in value) else None


def _parameters(document: Mapping[str, Any], name: str) -> Mapping[str, Any]:
    body = document.get(name)
    params = body.get("ros__parameters") if isinstance(body, dict) else None
    return params if isinstance(params, dict) else {}


def controllers_from(document: Any, joints: Sequence[str], source: str) -> ControllerSet:
    """The controllers of a parsed controllers.yaml; `joints` are the arm's, in order."""
    document = document if isinstance(document, dict) else {}
    manager = _parameters(document, "controller_manager")
    rate = manager.get("update_rate")
    if rate is not None and (error := update_rate_error(rate, source)) is not None:
        raise error
    update_rate = None if rate is None else float(rate)
    declared: dict[str, str] = {}
    for name, body in manager.items():
        if isinstance(body, dict) and isinstance(body.get("type"), str):
            declared[name] = body["type"]
    for name in document:
        kind = _parameters(document, name).get("type")
        if name != "controller_manager" and isinstance(kind, str):
            declared.setdefault(name, kind)
    controllers = []
    for name, kind in declared.items():
        params = _parameters(document, name)
        commands, states = DEFAULT_INTERFACES.get(ROLES.get(kind, ""), ((), ()))
        controllers.append(Controller(name, kind, _strings(params.get("joints")) or tuple(joints),
                                      _strings(params.get("command_interfaces")) or commands,
                                      _strings(params.get("state_interfaces")) or states))
    trajectories = [c for c in controllers if c.role == "trajectory"]
    if len(trajectories) > 1:
        raise ConfigError(f"{source} declares {len(trajectories)} trajectory controllers",
                          what="one joint_trajectory_controller for the whole arm",
                          why=f"found {', '.join(c.name for c in trajectories)}",
                          how="keep one and remove the others from controllers.yaml")
    for controller in trajectories:
        if sorted(controller.joints) != sorted(joints):
            raise ConfigError(f"trajectory controller {controller.name} does not cover the arm",
                              what=f"its joints: each of {', '.join(joints)} exactly once",
                              why=f"{source} lists {', '.join(controller.joints)}",
                              how=f"list every arm joint under {controller.name}.ros__parameters.joints")
    if not trajectories:
        commands, states = DEFAULT_INTERFACES["trajectory"]
        controllers.insert(0, Controller("joint_trajectory_controller", TRAJECTORY_TYPE, tuple(joints), commands,
                                         states))
    return ControllerSet(update_rate, tuple(controllers), source)


def read_controllers(path: Path | None, joints: Sequence[str], cycle_time_us: int) -> ControllerSet:
    """The controllers of controllers.yaml at `path`; without one, those plem generates for the arm."""
    if path is None:
        return controllers_from(yaml.safe_load(controllers_yaml(list(joints), cycle_time_us)), joints,
                                "the generated controllers.yaml")
    return controllers_from(read_package_yaml(path, "controllers.yaml").root, joints, str(path))
