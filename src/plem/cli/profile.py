"""`plem profile create|show|list`: per-unit calibration files in ~/.plem/profiles.

The profile model (pydantic) is imported inside the commands so other commands start fast.
"""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Annotated

import typer
from pathlib import Path
from typing import TYPE_CHECKING

from plem.cli.output import new_table, print_json, stdout
from plem.core.config.settings import parse_int_list
from plem.errors import PlemError, ProfileError, UsageError
from plem.robot.config import SUPPORTED_DOF

if TYPE_CHECKING:
    from plem.robot.profile import RobotProfile

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
    force: Annotated[bool, typer.Option("--force", help="Replace an existing, different profile.")] = False,
) -> None:
    """Create (atomically) the profile of one robot unit."""
    from plem.robot.profile import RobotProfile

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
    stamp = date or datetime.now(timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")
    profile = RobotProfile(robot_serial=serial, joint_offsets=values, profile_date=stamp)
    path = RobotProfile.default_path(serial)
    if path.exists() and not force:
        existing = _load_or_none(path)
        if existing is None or existing.joint_offsets != profile.joint_offsets:
            raise ProfileError(
                f"Profile {serial} already exists with different offsets",
                what="a new profile, or --force to replace a calibration",
                why=f"{path} exists" + (f" with offsets {existing.joint_offsets}" if existing else " (unreadable)"),
                how=f"rerun with --force to replace it, or inspect it with `plem profile show {serial}`",
            )
    profile.save(path)
    stdout.print(f"Saved profile {serial} ({len(values)} joints) to {path}", markup=False)


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
                 f"path:          {path}", markup=False)


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
