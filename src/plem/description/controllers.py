"""The controllers a package's controllers.yaml declares, as plem runs them under the names the file gives.

plem runs three kinds of controller, recognised by their ros2_control type: the trajectory controller
(joint_trajectory_controller, one for the whole arm), the joint state broadcaster and the free drive
controller. A type is declared as ros2_control reads it, under `controller_manager.ros__parameters.<name>.type`
or under `<name>.ros__parameters.type`. A package without controllers.yaml runs the controllers plem
generates for it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from plem.description.generate import BROADCASTER_TYPE, FREE_DRIVE_TYPE, TRAJECTORY_TYPE, controllers_yaml
from plem.description.package_yaml import read_package_yaml
from plem.errors import ConfigError

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
    """The controllers of one robot: the update rate and the controllers in the file's order."""

    update_rate: float | None
    controllers: tuple[Controller, ...]

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
    update_rate = float(rate) if isinstance(rate, (int, float)) and not isinstance(rate, bool) and rate > 0 else None
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
    return ControllerSet(update_rate, tuple(controllers))


def read_controllers(path: Path | None, joints: Sequence[str], cycle_time_us: int) -> ControllerSet:
    """The controllers of controllers.yaml at `path`; without one, those plem generates for the arm."""
    if path is None:
        return controllers_from(yaml.safe_load(controllers_yaml(list(joints), cycle_time_us)), joints,
                                "the generated controllers.yaml")
    return controllers_from(read_package_yaml(path, "controllers.yaml").root, joints, str(path))
