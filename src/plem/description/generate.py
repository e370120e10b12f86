"""Auto-generation of missing config files, into a temp directory `wim_launch_<time>` (never into the package).

`controllers.yaml` is generated from joint_limits.yaml; `kinematics.yaml` only when an SRDF exists.
The same text builders serve `plem create-description`, so generated and scaffolded files agree.

The directories stay after the launch, for the user to copy the files from, but do not pile up: a launch
whose files are exactly those of an earlier directory reuses it, and only the newest KEPT_GENERATED_DIRS
of the user's directories are kept. A launch holds a shared lock (flock) on the directory it uses for as
long as it runs, and a directory is removed only under an exclusive lock, so never while a launch uses it.
"""

from __future__ import annotations

import fcntl
import logging
import os
import shutil
import stat
import tempfile
import time
import weakref
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from plem.core.files import write_atomic
from plem.description.parameter_ranges import SOLVER_DEFAULTS as SOLVER_DEFAULTS  # re-exported for the planner
from plem.description.validate import Stage, ValidationReport, require_valid
from plem.errors import ConfigError

log = logging.getLogger("plem.launch")

DEFAULT_SOLVER = "kdl_kinematics_plugin/KDLKinematicsPlugin"
STOPPED_VELOCITY_TOLERANCE = 0.01
GOAL_TOLERANCE = 0.01
GENERATED_DIR_PREFIX = "wim_launch_"
#: The user's generated directories kept in the temp directory; older ones no running launch uses are removed.
KEPT_GENERATED_DIRS = 8


def _dump(data: dict[str, Any], header: str) -> str:
    body = yaml.safe_dump(data, sort_keys=False, default_flow_style=False)
    return "".join(f"# {line}\n" for line in header.splitlines()) + body


#: ros2_control types of the controllers plem runs.
TRAJECTORY_TYPE = "joint_trajectory_controller/JointTrajectoryController"
BROADCASTER_TYPE = "joint_state_broadcaster/JointStateBroadcaster"
FREE_DRIVE_TYPE = "wim_controller/FreeDriveController"
#: The trajectory controller's name in a generated controllers.yaml, as the Description Package Protocol gives it
#: (the built-in arms ship the configuration reference's file, which names it joint_trajectory_controller).
GENERATED_TRAJECTORY = "arm_controller"


def controllers_yaml(joints: list[str], cycle_time_us: int = 1000) -> str:
    """A joint_trajectory_controller for `joints`, a state broadcaster and free drive, at the loop's rate."""
    data = {
        "controller_manager": {"ros__parameters": {
            "update_rate": round(1_000_000 / cycle_time_us),
            "joint_state_broadcaster": {"type": BROADCASTER_TYPE},
            GENERATED_TRAJECTORY: {"type": TRAJECTORY_TYPE},
            "free_drive_controller": {"type": FREE_DRIVE_TYPE},
        }},
        GENERATED_TRAJECTORY: {"ros__parameters": {
            "type": TRAJECTORY_TYPE,
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
    return _dump(data, "Controllers: a joint trajectory controller over every joint in joint_limits.yaml, the joint\n"
                       "state broadcaster and free drive (gravity-compensated, damped).\n"
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


def _fresh_directory(root: Path) -> Path:
    base = root / f"{GENERATED_DIR_PREFIX}{time.strftime('%Y%m%d_%H%M%S')}"
    path, attempt = base, 0
    while True:
        try:
            path.mkdir(parents=True, mode=0o700)  # owner-only, as everything else plem writes for a robot
            return path
        except FileExistsError:
            attempt += 1
            path = base.with_name(f"{base.name}_{attempt}")


def _lock(path: Path, operation: int) -> int | None:
    """An open descriptor of the directory `path` holding the flock `operation` (LOCK_SH or LOCK_EX); None when
    the directory is gone, is not a directory, or another process holds a conflicting lock."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        fcntl.flock(fd, operation | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def generated_directories(root: Path) -> list[Path]:
    """This user's generated directories in `root` (real directories, never links), newest first."""
    found: list[tuple[int, Path]] = []
    for path in root.glob(f"{GENERATED_DIR_PREFIX}*"):
        try:
            status = path.lstat()
        except OSError:
            continue
        if stat.S_ISDIR(status.st_mode) and status.st_uid == os.geteuid():
            found.append((status.st_mtime_ns, path))
    return [path for _, path in sorted(found, reverse=True)]


def _holds(directory: Path, files: Mapping[str, str]) -> bool:
    """Whether `directory` holds exactly `files` (name → text) as regular files, and nothing else."""
    try:
        entries = {path.name: path for path in directory.iterdir()}
        return entries.keys() == files.keys() and all(
            stat.S_ISREG(entries[name].lstat().st_mode) and entries[name].read_text(encoding="utf-8") == text
            for name, text in files.items())
    except (OSError, UnicodeDecodeError):
        return False


def _directory_for(files: Mapping[str, str], root: Path) -> tuple[Path, int]:
    """The directory holding `files`, reused or newly written, and the descriptor holding its shared lock."""
    for path in generated_directories(root):
        fd = _lock(path, fcntl.LOCK_SH)
        if fd is None:
            continue
        if _holds(path, files):
            os.utime(path)  # now the newest: kept the longest
            return path, fd
        os.close(fd)
    while True:
        path = _fresh_directory(root)
        fd = _lock(path, fcntl.LOCK_SH)
        if fd is not None:  # None: another launch removed it as the oldest before the lock (a flood of launches)
            break
    for name, text in files.items():
        write_atomic(path / name, text, mode=0o600)
    return path, fd


def _prune(root: Path) -> None:
    """Remove the user's generated directories beyond the newest KEPT_GENERATED_DIRS that no launch uses."""
    for path in generated_directories(root)[KEPT_GENERATED_DIRS:]:
        fd = _lock(path, fcntl.LOCK_EX)
        if fd is None:
            continue  # a running launch holds it
        try:
            shutil.rmtree(path, ignore_errors=True)
        finally:
            os.close(fd)


def resolve_description(package: str | os.PathLike[str], *, urdf_file: str | os.PathLike[str] | None = None,
                        srdf_file: str | os.PathLike[str] | None = None, cycle_time_us: int = 1000,
                        stage: Stage = Stage.STARTUP, temp_root: Path | None = None) -> ResolvedDescription:
    """Validate for `stage`, then generate the missing optional files; the package is never written."""
    report = require_valid(package, stage=stage, urdf_file=urdf_file, srdf_file=srdf_file)
    return complete_description(report, cycle_time_us=cycle_time_us, temp_root=temp_root)


def complete_description(report: ValidationReport, *, cycle_time_us: int = 1000,
                         temp_root: Path | None = None) -> ResolvedDescription:
    """The files a launch uses for a package that passed start-up validation: its own, and the optional files it
    lacks generated into a `wim_launch_*` directory under `temp_root` (the system's temp directory by default).

    The directory stays locked as in use until the returned description is garbage-collected or the process ends.
    """
    files, urdf, srdf = report.files, report.urdf, report.srdf
    if urdf is None or files.urdf is None or files.joint_limits is None:
        raise ValueError("complete_description needs a report of start-up validation (require_valid)")
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
    generated_dir, fd = None, None
    if pending:
        root = Path(temp_root or tempfile.gettempdir())
        try:
            root.mkdir(parents=True, exist_ok=True)
            generated_dir, fd = _directory_for(pending, root)
        except OSError as error:
            raise ConfigError(f"cannot write the generated {' and '.join(pending)} into {root}",
                              what="a temp directory plem may create directories in",
                              why=f"{error.filename or root}: {error.strerror or error}",
                              how=f"set TMPDIR to a writable directory, or add {' and '.join(pending)} to "
                                  f"{files.root / 'config'} (see `plem create-description`)") from None
        _prune(root)
        _say(log_lines, f"Generated files are in {generated_dir}; copy them into config/ to keep them")
    written = {name: generated_dir / name for name in pending} if generated_dir is not None else {}
    resolved = ResolvedDescription(report=report, urdf=files.urdf, srdf=files.srdf, joint_limits=files.joint_limits,
                                   controllers=files.controllers or written["controllers.yaml"],
                                   kinematics=files.kinematics or written.get("kinematics.yaml"),
                                   generated_dir=generated_dir, generated=list(written.values()), log_lines=log_lines)
    if fd is not None:
        weakref.finalize(resolved, os.close, fd)  # the lock that keeps other launches from removing the directory
    return resolved


def _say(log_lines: list[str], line: str) -> None:
    log_lines.append(line)
    log.info(line)
