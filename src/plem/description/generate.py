"""Auto-generation of missing config files, into a fresh temp directory (never into the package).

`controllers.yaml` is generated from joint_limits.yaml; `kinematics.yaml` only when an SRDF exists.
The same text builders serve `plem create-description`, so generated and scaffolded files agree.
"""

from __future__ import annotations

import logging
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from plem.core.files import write_atomic
from plem.description.validate import Stage, ValidationReport, require_valid

log = logging.getLogger("plem.launch")

DEFAULT_SOLVER = "kdl_kinematics_plugin/KDLKinematicsPlugin"
SOLVER_DEFAULTS = {"kinematics_solver_search_resolution": 0.005, "kinematics_solver_timeout": 0.05,
                   "kinematics_solver_attempts": 3}
STOPPED_VELOCITY_TOLERANCE = 0.01
GOAL_TOLERANCE = 0.01
GENERATED_DIR_PREFIX = "wim_launch_"


def _dump(data: dict[str, Any], header: str) -> str:
    body = yaml.safe_dump(data, sort_keys=False, default_flow_style=False)
    return "".join(f"# {line}\n" for line in header.splitlines()) + body


def controllers_yaml(joints: list[str], cycle_time_us: int = 1000) -> str:
    """A joint_trajectory_controller for `joints` and a state broadcaster, at the loop's rate."""
    data = {
        "controller_manager": {"ros__parameters": {
            "update_rate": round(1_000_000 / cycle_time_us),
            "joint_state_broadcaster": {"type": "joint_state_broadcaster/JointStateBroadcaster"},
            "arm_controller": {"type": "joint_trajectory_controller/JointTrajectoryController"},
        }},
        "arm_controller": {"ros__parameters": {
            "type": "joint_trajectory_controller/JointTrajectoryController",
            "joints": list(joints),
            "command_interfaces": ["position"],
            "state_interfaces": ["position", "velocity"],
            "constraints": {
                "stopped_velocity_tolerance": STOPPED_VELOCITY_TOLERANCE,
                "goal_time": 0.0,
                **{joint: {"trajectory": 0.0, "goal": GOAL_TOLERANCE} for joint in joints},
            },
        }},
    }
    return _dump(data, "Controllers: a joint trajectory controller over every joint in joint_limits.yaml.\n"
                       "Tolerances in rad; 0.0 disables a check (ros2_control semantics).")


def kinematics_yaml(groups: list[str]) -> str:
    """The KDL solver with conservative defaults for each planning group."""
    return _dump({group: {"kinematics_solver": DEFAULT_SOLVER, **SOLVER_DEFAULTS} for group in groups},
                 "Inverse kinematics per planning group (KDL solver, conservative defaults).")


@dataclass
class ResolvedDescription:
    """The files launch uses, each from the package or generated, and whether planning can start."""

    report: ValidationReport
    urdf: Path
    srdf: Path | None
    joint_limits: Path
    controllers: Path
    kinematics: Path | None
    generated_dir: Path | None = None
    generated: list[Path] = field(default_factory=list)
    log_lines: list[str] = field(default_factory=list)

    @property
    def planner_enabled(self) -> bool:
        """Whether MoveIt starts: only with an SRDF."""
        return self.srdf is not None


def _fresh_directory(temp_root: Path | None) -> Path:
    root = Path(temp_root or tempfile.gettempdir())
    base = root / f"{GENERATED_DIR_PREFIX}{time.strftime('%Y%m%d_%H%M%S')}"
    path, attempt = base, 0
    while True:
        try:
            path.mkdir(parents=True, mode=0o700)  # owner-only, as everything else plem writes for a robot
            return path
        except FileExistsError:
            attempt += 1
            path = base.with_name(f"{base.name}_{attempt}")


def resolve_description(package: str | os.PathLike[str], *, urdf_file: str | os.PathLike[str] | None = None,
                        srdf_file: str | os.PathLike[str] | None = None, cycle_time_us: int = 1000,
                        stage: Stage = Stage.STARTUP, temp_root: Path | None = None) -> ResolvedDescription:
    """Validate for `stage`, then generate the missing optional files; the package is never written."""
    report = require_valid(package, stage=stage, urdf_file=urdf_file, srdf_file=srdf_file)
    files, urdf, srdf = report.files, report.urdf, report.srdf
    # require_valid raised unless the URDF rendered and joint_limits.yaml exists; an SRDF that exists has parsed
    assert urdf is not None and files.urdf is not None and files.joint_limits is not None
    log_lines: list[str] = []
    pending: dict[str, str] = {}
    if srdf is None:
        _say(log_lines, "SRDF not found - MoveIt will not be started")
    elif files.kinematics is None:
        _say(log_lines, "Auto-generating kinematics.yaml (KDL solver)")
        pending["kinematics.yaml"] = kinematics_yaml([g for g, body in srdf.groups.items() if body.chains])
    if files.controllers is None:
        _say(log_lines, "Auto-generating controllers.yaml from joint_limits.yaml")
        actuated = [j.name for j in urdf.actuated_joints]
        pending["controllers.yaml"] = controllers_yaml([j for j in actuated if j in report.limits] or actuated,
                                                       cycle_time_us)
    generated_dir = _fresh_directory(temp_root) if pending else None
    written: dict[str, Path] = {}
    if generated_dir is not None:
        for name, text in pending.items():
            written[name] = generated_dir / name
            write_atomic(written[name], text, mode=0o600)
        _say(log_lines, f"Generated files are in {generated_dir}; copy them into config/ to keep them")
    return ResolvedDescription(report=report, urdf=files.urdf, srdf=files.srdf, joint_limits=files.joint_limits,
                               controllers=files.controllers or written["controllers.yaml"],
                               kinematics=files.kinematics or written.get("kinematics.yaml"),
                               generated_dir=generated_dir, generated=list(written.values()), log_lines=log_lines)


def _say(log_lines: list[str], line: str) -> None:
    log_lines.append(line)
    log.info(line)
