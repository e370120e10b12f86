"""RobotProfile: per-unit calibration (encoder offsets) and the payload it carries, stored as JSON in
~/.plem/profiles/<serial>.json."""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, ConfigDict, Field, StrictFloat, StrictInt, StrictStr, ValidationError, model_validator

from plem.core.config.environment import plem_home
from plem.core.files import read_regular_text, write_atomic, write_new
from plem.errors import ConfigError, ProfileError
from plem.robot.config import SUPPORTED_DOF, offsets_problem
from plem.robot.serial import serial_problem

if TYPE_CHECKING:
    from plem.control.payload import Payload

PROFILE_SUFFIX = ".json"
PROFILE_MODE = 0o600
#: A profile holds a serial, seven offsets and a date: a few hundred bytes. Nothing valid comes near this.
MAX_PROFILE_BYTES = 64 * 1024


def _create_hint(serial: str, replace: bool = False) -> str:
    return (f"plem profile create --serial {serial} --offsets {','.join(['0'] * 6)}"
            + (" --force" if replace else "") + "  (one offset per joint)")


class ProfileExists(ProfileError):
    """A profile was to be created where one already is; nothing was written."""

    def __init__(self, path: Path) -> None:
        super().__init__(
            f"Profile {path.stem} already exists",
            what=f"no profile at {path} yet",
            why=f"{path} exists (created before, or by another command at the same time)",
            how=f"keep it (`plem profile show {path.stem}`), or replace it: {_create_hint(path.stem, replace=True)}",
        )
        self.path = path


def _parse_json(text: str, path: Path, serial_hint: str) -> Any:
    """The JSON value in a profile's text; malformed, too deeply nested or overlong numbers are a ProfileError."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        problem = f"{path}:{exc.lineno}:{exc.colno}: {exc.msg}"
    except RecursionError:
        problem = f"{path}: lists or objects nest too deeply to read (a profile nests two levels)"
    except ValueError:
        problem = (f"{path}: a number has more than {sys.get_int_max_str_digits()} digits "
                   "(a joint offset is an int32: at most 10 digits)")
    raise ProfileError(
        f"Profile file is not valid JSON: {path}",
        what='a JSON object such as {"robot_serial": "...", "joint_offsets": [...]}',
        why=problem,
        how=f"fix the JSON at that place, or recreate it: {_create_hint(serial_hint, replace=True)}",
    )


class ProfilePayload(BaseModel):
    """The payload a unit carries: mass (kg), centre of mass (m, flange frame), and optionally its inertia about
    that centre as six numbers in the URDF's order (ixx, ixy, ixz, iyy, iyz, izz; kg·m²)."""

    model_config = ConfigDict(extra="forbid")

    mass: StrictFloat
    center_of_mass: list[StrictFloat] = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    inertia: list[StrictFloat] | None = None

    def problems(self) -> list[str]:
        """Every reason this is not a payload plem accepts (plem.control.payload's rules), empty when it is."""
        from plem.control.payload import inertia_matrix, payload_problems  # numpy only for profiles with one
        if self.inertia is not None and len(self.inertia) != 6:
            return [f"payload inertia has {len(self.inertia)} values, not 6 (ixx, ixy, ixz, iyy, iyz, izz)"]
        inertia = None if self.inertia is None else inertia_matrix(*self.inertia)
        return [f"payload: {problem}" for problem in payload_problems(self.mass, self.center_of_mass, inertia)]

    def to_payload(self) -> Payload:
        """The checked Payload (a ConfigError when `problems` is not empty)."""
        from plem.control.payload import Payload
        return Payload.from_numbers([self.mass, *self.center_of_mass, *(self.inertia or [])])


class RobotProfile(BaseModel):
    """Calibration of one robot unit: its serial, one encoder offset per joint, when it was made, and optionally
    the payload it carries (used by gravity compensation and the external-torque estimate when no `payload:=`
    launch argument or `robot.set_payload` says otherwise)."""

    model_config = ConfigDict(extra="ignore")

    robot_serial: StrictStr = ""
    joint_offsets: list[StrictInt] = Field(default_factory=list)
    profile_date: StrictStr | None = None
    payload: ProfilePayload | None = None

    @model_validator(mode="before")
    @classmethod
    def _migrate_calibration_date(cls, data: Any) -> Any:
        """Old profiles said `calibration_date`; they load as `profile_date`."""
        if isinstance(data, dict) and "calibration_date" in data and "profile_date" not in data:
            data = dict(data)
            data["profile_date"] = data.pop("calibration_date")
        return data

    def problems(self, dof: int | None = None) -> list[str]:
        """Every reason this profile is unusable (for `dof` joints when given), empty when valid."""
        found: list[str] = []
        serial = serial_problem(self.robot_serial)
        if serial:
            found.append(f"robot_serial {self.robot_serial!r}: {serial}")
        if dof is not None:
            offsets = offsets_problem(self.joint_offsets, dof)
        elif len(self.joint_offsets) in SUPPORTED_DOF:
            offsets = offsets_problem(self.joint_offsets, len(self.joint_offsets))
        else:
            offsets = f"joint_offsets has {len(self.joint_offsets)} elements; an arm has 6 or 7 joints"
        if offsets:
            found.append(offsets)
        if self.profile_date is not None:
            try:
                datetime.fromisoformat(self.profile_date)
            except (TypeError, ValueError):
                found.append(f"profile_date {self.profile_date!r} is not an ISO 8601 time such as 2026-01-22T10:30:00Z")
        if self.payload is not None:
            found.extend(self.payload.problems())
        return found

    def is_valid(self, dof: int | None = None) -> bool:
        """True when the profile can be used (with `dof` joints when given)."""
        return not self.problems(dof)

    def save(self, path: str | os.PathLike[str], *, exclusive: bool = False) -> None:
        """Write atomically (temp file, fsync, rename); an invalid profile is refused, not written.

        With `exclusive`, only create: a ProfileExists error, and nothing written, when the file is already there.
        """
        problems = self.problems()
        if problems:
            raise ProfileError(
                "Refusing to save an invalid profile",
                what="a profile with a safe robot_serial, 6 or 7 int32 joint_offsets, an optional ISO 8601 date and an "
                     "optional payload the arm can carry",
                why="; ".join(problems),
                how="fix the listed fields and save again",
            )
        target = Path(path).expanduser()
        text = json.dumps(self.model_dump(exclude_none=True), indent=2) + "\n"
        try:
            if exclusive:
                try:
                    write_new(target, text, mode=PROFILE_MODE)
                except FileExistsError:
                    raise ProfileExists(target) from None
            else:
                write_atomic(target, text, mode=PROFILE_MODE)
        except OSError as error:
            raise ProfileError(
                f"Cannot write profile file {target}",
                what=f"a folder where plem can write robot profiles ({target.parent})",
                why=f"{error.filename or target}: {error.strerror or error}",
                how=f"make {target.parent} a folder you can write to, or export PLEM_HOME=/path/to/a/writable/folder",
            ) from None

    def replace(self, path: str | os.PathLike[str]) -> Path | None:
        """Save over the profile at `path`, keeping the file that was there beside it as
        `<serial>.json.<UTC time>.bak` (not a profile to `plem profile list`); the backup's path, None when
        there was no file to keep."""
        target = Path(path).expanduser()
        backup = None
        if target.exists():
            stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S.%fZ")
            backup = target.with_name(f"{target.name}.{stamp}.bak")
            try:
                write_new(backup, target.read_bytes(), mode=PROFILE_MODE)
            except OSError as error:
                raise ProfileError(
                    f"Cannot keep a backup of profile {target}",
                    what=f"a copy of the old profile beside it ({backup.name}) before it is replaced",
                    why=f"{error.filename or backup}: {error.strerror or error}",
                    how=f"make {target.parent} a folder you can write to, or move {target} away yourself",
                ) from None
        self.save(target)
        return backup

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> RobotProfile:
        """Read and check a profile file; every failure is a ProfileError naming the path."""
        path = Path(path).expanduser()
        serial_hint = path.stem or "<serial>"
        try:
            text = read_regular_text(path, MAX_PROFILE_BYTES, "robot profile (JSON)")
        except ConfigError as error:
            fix = (f"create it: {_create_hint(serial_hint)}" if not path.exists()
                   else f"{error.how}; or recreate it: {_create_hint(serial_hint, replace=True)}")
            raise ProfileError(f"Failed to open profile file: {path}", what=error.what, why=error.why,
                               how=fix) from None
        data = _parse_json(text, path, serial_hint)
        if not isinstance(data, dict):
            raise ProfileError(
                f"Profile file has the wrong shape: {path}",
                what="a JSON object with robot_serial and joint_offsets",
                why=f"the file holds a JSON {type(data).__name__}",
                how=f"recreate it: {_create_hint(serial_hint, replace=True)}",
            )
        missing = [name for name in ("robot_serial", "joint_offsets") if name not in data]
        try:
            profile = cls.model_validate(data)
        except ValidationError as exc:
            details = "; ".join(
                f"{'.'.join(str(p) for p in error['loc'])}: {error['msg'].lower()} (found {error.get('input')!r})"
                for error in exc.errors()
            )
            raise ProfileError(
                f"Invalid profile file: {path}",
                what="robot_serial as text, joint_offsets as a list of whole numbers, profile_date as text, payload as "
                     '{"mass": kg, "center_of_mass": [x, y, z], "inertia": [ixx, ixy, ixz, iyy, iyz, izz]} '
                     "(inertia optional)",
                why=f"{path}: {details}",
                how="correct those fields in the file",
            ) from None
        problems = ([f"missing required field '{name}'" for name in missing]
                    + (profile.problems() if not missing else []))
        if problems:
            raise ProfileError(
                f"Invalid profile file: {path}",
                what="a safe robot_serial, 6 or 7 int32 joint_offsets, optional ISO 8601 profile_date, optional "
                     "payload the arm can carry",
                why=f"{path}: " + "; ".join(problems),
                how="correct those fields in the file, or recreate it with `plem profile create`",
            )
        return profile

    @classmethod
    def load_from_serial(cls, serial: str, environ: Mapping[str, str] | None = None) -> RobotProfile:
        """Load `<profiles dir>/<serial>.json` and check it belongs to `serial`."""
        path = cls.default_path(serial, environ)
        profile = cls.load(path)
        if profile.robot_serial != serial:
            raise ProfileError(
                f"Profile file {path.name} belongs to another robot",
                what=f"a profile whose robot_serial is {serial!r}",
                why=f"{path} says robot_serial is {profile.robot_serial!r}",
                how=f"rename the file to {profile.robot_serial}{PROFILE_SUFFIX}, or fix robot_serial inside it",
            )
        return profile

    @staticmethod
    def default_directory(environ: Mapping[str, str] | None = None) -> Path:
        """`$PLEM_HOME/profiles`, normally `~/.plem/profiles`."""
        return plem_home(environ) / "profiles"

    @staticmethod
    def default_path(serial: str, environ: Mapping[str, str] | None = None) -> Path:
        """Where the profile of `serial` lives; a serial that is not a safe file name is refused."""
        problem = serial_problem(serial)
        if problem:
            raise ProfileError(
                f"Invalid robot serial {serial!r}",
                what="a serial usable as a file name: letters, digits, '.', '_' or '-' (e.g. PE07I7E0E001)",
                why=f"{serial!r}: {problem}",
                how="use the serial printed on the robot's label",
            )
        return RobotProfile.default_directory(environ) / f"{serial}{PROFILE_SUFFIX}"
