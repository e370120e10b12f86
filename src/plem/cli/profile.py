"""`plem profile create|calibrate|show|list`: per-unit calibration files in ~/.plem/profiles.

The profile model (pydantic) is imported inside the commands so other commands start fast.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from plem.cli.output import new_table, print_json, print_warnings, stdout
from plem.core.config.settings import parse_int_list
from plem.errors import PlemError, ProfileError, UsageError
from plem.robot.config import SUPPORTED_DOF

if TYPE_CHECKING:
    from plem.robot.profile import ProfilePayload, RobotProfile

app = typer.Typer(help="Create and inspect robot profiles (calibration offsets).", no_args_is_help=True)


def _parse_offsets(text: str) -> list[int]:
    try:
        return parse_int_list(text)
    except ValueError:
        raise UsageError(
            "--offsets must be whole numbers separated by commas",
            what="--offsets a,b,c,... with one int32 encoder offset per joint",
            why=f"found {text!r}",
            how="e.g. --offsets=-535768,195386,191634,34542,24035,21232",
        ) from None


@app.command("create")
def create(
    serial: Annotated[str, typer.Option("--serial", help="Robot serial, e.g. PE07I7E0E001.")],
    offsets: Annotated[str, typer.Option("--offsets", help="Comma-separated encoder offsets, one per joint.")],
    dof: Annotated[int | None, typer.Option("--dof", help="Expected number of joints (6 or 7).")] = None,
    date: Annotated[str | None, typer.Option("--date", help="ISO 8601 time; default now (UTC).")] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing, different profile (the old file is "
                                        "kept beside it as a .bak).")] = False,
) -> None:
    """Create (atomically) the profile of one robot unit."""
    from plem.robot.profile import ProfileExists, RobotProfile

    values = _parse_offsets(offsets)
    if dof is not None and dof not in SUPPORTED_DOF:
        raise UsageError(
            f"--dof {dof} is not supported",
            what="--dof 6 or --dof 7",
            why=f"--dof is {dof}",
            how="omit --dof, or give the arm's number of joints",
        )
    if dof is not None and len(values) != dof:
        raise ProfileError(
            f"joint_offsets must have exactly {dof} elements",
            what=f"{dof} offsets for a {dof}-joint arm",
            why=f"--offsets has {len(values)} values",
            how=f"give one offset per joint ({dof} values)",
        )
    path = RobotProfile.default_path(serial)
    kept = _load_or_none(path) if force and path.exists() else None
    profile = RobotProfile(robot_serial=serial, joint_offsets=values, profile_date=date or _now(),
                           payload=kept.payload if kept is not None else None)
    if force:
        _replace(profile, path)
    else:
        try:
            profile.save(path, exclusive=True)
        except ProfileExists as exists:
            existing = _load_or_none(path)
            if existing is None or existing.joint_offsets != profile.joint_offsets:
                raise ProfileError(
                    f"Profile {serial} already exists with different offsets",
                    what="a new profile, or --force to replace a calibration",
                    why=exists.why + (f"; its offsets are {existing.joint_offsets}" if existing
                                      else "; it cannot be read"),
                    how=f"rerun with --force to replace it, or inspect it with `plem profile show {serial}`",
                ) from None
            stdout.print(f"Profile {serial} already holds these offsets: {path} (unchanged)", markup=False)
            return
    stdout.print(f"Saved profile {serial} ({len(values)} joints) to {path}", markup=False)


def _now() -> str:
    """This moment in ISO 8601 UTC, as profiles record it."""
    return datetime.now(UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")


#: Joint speed (rad/s) above which calibration refuses: the encoders must be read at rest.
CALIBRATION_STANDSTILL = 1e-3
#: How long calibration waits for the driver's next statistics record (published at 10 Hz).
CALIBRATION_WAIT_S = 2.0


@app.command("calibrate")
def calibrate(
    serial: Annotated[str, typer.Option("--serial", help="Serial of the robot unit, e.g. PE07I7E0E001.")],
    robot_id: Annotated[str | None, typer.Option("--robot-id", help="Running robot to read (default: "
                                                 "$PLEM_ROBOT_ID, else indy).", show_default=False)] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing profile (the old file is kept beside "
                                        "it as a .bak).")] = False,
) -> None:
    """Read the raw encoders of a running arm standing at its zero pose (every joint on its zero mark, where it
    must read 0 rad; not the SRDF's home) and save their negation as the unit's offsets."""
    from plem.robot.profile import RobotProfile

    path = RobotProfile.default_path(serial)
    old = _load_or_none(path) if path.exists() else None
    if path.exists() and not force:
        raise ProfileError(
            f"Profile {serial} already exists",
            what="a new profile, or --force to replace a calibration (the old file is then kept as a backup)",
            why=f"{path} exists" + (f" with offsets {old.joint_offsets}" if old else " (it cannot be read)"),
            how=f"inspect it with `plem profile show {serial}`; rerun with --force to calibrate again")
    reading = _read_encoders(robot_id)
    offsets = [-raw for raw in reading.raw]
    stdout.print(f"Calibrating {serial} from robot {reading.robot_id}. It assumes the arm stands at its zero pose: "
                 "every joint on its zero mark, the pose that must read 0 rad (the configuration reference's "
                 "\"known zero position\"; not the SRDF's home).", markup=False)
    near = _named_state_near(reading)
    if near:
        print_warnings([f"by its current offsets the arm stands at the SRDF's {near!r}, not at 0 rad: these "
                        f"offsets make that pose read 0 rad. If it is not on its zero marks, move every joint "
                        f"there (e.g. in free drive: `plem mode free_drive --robot-id {reading.robot_id}`) and "
                        f"calibrate again with --force"])
    table = new_table("Encoders now and the offsets that make this pose read 0 rad", "joint", "raw counts",
                      "reads now rad", "old offset", "new offset")
    before = old.joint_offsets if old is not None and len(old.joint_offsets) == len(offsets) else reading.offsets
    for name, raw, position, earlier, new in zip(reading.joint_names, reading.raw, reading.position, before,
                                                 offsets, strict=True):
        table.add_row(name, str(raw), f"{position:+.4f}", str(earlier), str(new))
    stdout.print(table)
    profile = RobotProfile(robot_serial=serial, joint_offsets=offsets, profile_date=_now(),
                           payload=old.payload if old is not None else None)
    if old is not None or path.exists():
        _replace(profile, path)
    else:
        profile.save(path, exclusive=True)
    stdout.print(f"Saved {path}. Launch with robot_serial:={serial} to use these offsets.", markup=False)


def _replace(profile: RobotProfile, path: Path) -> None:
    """Save `profile` over `path`, keeping the old file as a backup, and say where the backup is."""
    backup = profile.replace(path)
    if backup is not None:
        stdout.print(f"Kept the previous profile as {backup}", markup=False)


@dataclass(frozen=True)
class _Encoders:
    """One reading of a resting arm: its raw counts, the offsets it runs with and the positions they give."""

    robot_id: str
    joint_names: tuple[str, ...]
    raw: list[int]
    offsets: list[int]
    position: list[float]
    poses: dict[str, list[float]]


def _read_encoders(robot_id: str | None) -> _Encoders:
    """The raw encoder counts of a running arm at rest (from the driver's next statistics record)."""
    import time

    from plem.bridge.client import connect

    with connect(robot_id) as client:
        state = client.live_state()
        moving = [name for name, v in zip(client.joint_names, state.velocity, strict=True)
                  if abs(v) > CALIBRATION_STANDSTILL]
        if moving or state.mode.name == "TRAJECTORY":
            raise ProfileError(
                f"robot {client.robot_id} is moving: calibration needs the arm at rest",
                what="the arm standing still at its zero pose (every joint on its zero mark)",
                why=f"mode {state.mode.name.lower()}" + (f", moving: {', '.join(moving)}" if moving else ""),
                how=f"wait for the motion to end (`plem state --robot-id {client.robot_id}`), then calibrate again")
        since = time.monotonic_ns()
        deadline = time.monotonic() + CALIBRATION_WAIT_S
        stats = client.stats()
        while (stats is None or stats["monotonic_ns"] < since) and time.monotonic() < deadline:
            time.sleep(0.02)
            stats = client.stats()
        if stats is None or "encoders" not in stats:
            raise ProfileError(f"robot {client.robot_id} does not report its encoders",
                               what="the RT driver's statistics with raw encoder counts",
                               why="no statistics record arrived within "
                                   f"{CALIBRATION_WAIT_S:g} s", how="check that its `plem launch` runs")
        return _Encoders(client.robot_id, client.joint_names, [int(raw) for raw in stats["encoders"]],
                         [int(x) for x in stats["joint_offsets"]], client.live_state().position.tolist(),
                         {name: list(values) for name, values in client.channels.state.poses.items()})


#: How close (rad, every joint) the arm must be to a named state of the SRDF for calibration to warn about it.
NAMED_STATE_NEAR_RAD = 0.01


def _named_state_near(reading: _Encoders) -> str | None:
    """The SRDF state other than all zeros that the arm stands at by its current offsets, if any."""
    for name, values in reading.poses.items():
        if any(abs(v) > NAMED_STATE_NEAR_RAD for v in values) and all(
                abs(v - q) <= NAMED_STATE_NEAR_RAD for v, q in zip(values, reading.position, strict=False)):
            return name
    return None


def _load_or_none(path: Path) -> RobotProfile | None:
    from plem.robot.profile import RobotProfile

    try:
        return RobotProfile.load(path)
    except PlemError:
        return None


@app.command("show")
def show(
    serial: Annotated[str, typer.Argument(help="Robot serial.")],
    output_format: Annotated[str, typer.Option("--format", help="text or json.")] = "text",
) -> None:
    """Print one profile."""
    from plem.robot.profile import RobotProfile

    path = RobotProfile.default_path(serial)
    profile = RobotProfile.load_from_serial(serial)
    if output_format == "json":
        print_json({"path": str(path), **profile.model_dump()})
        return
    stdout.print(f"robot_serial:  {profile.robot_serial}\n"
                 f"joint_offsets: {profile.joint_offsets}\n"
                 f"profile_date:  {profile.profile_date or '(not set)'}\n"
                 f"payload:       {_payload_text(profile.payload)}\n"
                 f"path:          {path}", markup=False)


def _payload_text(payload: ProfilePayload | None) -> str:
    """A profile's payload on one line, as `plem profile show` prints it."""
    if payload is None:
        return "(none)"
    inertia = "" if payload.inertia is None else f", inertia {payload.inertia} kg·m²"
    return f"{payload.mass:g} kg at {payload.center_of_mass} m in the flange frame{inertia}"


@app.command("list")
def list_profiles() -> None:
    """List every profile in the profiles folder; unreadable files are listed with their problem."""
    from plem.robot.profile import PROFILE_SUFFIX, RobotProfile

    directory = RobotProfile.default_directory()
    files = sorted(directory.glob(f"*{PROFILE_SUFFIX}")) if directory.is_dir() else []
    if not files:
        stdout.print(f"No profiles in {directory}. Create one with `plem profile create --serial S --offsets ...`.",
                     markup=False)
        return
    table = new_table(f"Profiles in {directory}", "serial", "joints", "profile_date", "status")
    for path in files:
        try:
            profile = RobotProfile.load(path)
            table.add_row(profile.robot_serial, str(len(profile.joint_offsets)), profile.profile_date or "", "ok")
        except PlemError as error:
            table.add_row(path.stem, "?", "", f"invalid: {error.why}")
    stdout.print(table)
