"""`plem validate` and `plem create-description`: check and scaffold description packages.

The description machinery (numpy, xacro) is imported inside the commands so other commands start fast.
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path
from typing import Annotated

import typer

from plem.cli.output import OutputFormat, print_json, stderr, stdout
from plem.core.config.launch_args import parse_launch_arguments
from plem.errors import UsageError

#: Overrides `plem validate` also takes as `name:=value`, the form `plem launch` and validation hints use.
VALIDATE_ARGUMENTS = ("urdf_file", "srdf_file")


def validate(
    package: Annotated[str, typer.Argument(help="Package directory, or package name on the search path.")],
    overrides: Annotated[list[str] | None, typer.Argument(
        help="urdf_file:=PATH or srdf_file:=PATH, as `plem launch` takes them (same as --urdf-file, --srdf-file).",
        metavar="NAME:=VALUE", show_default=False)] = None,
    output_format: Annotated[OutputFormat, typer.Option("--format", help="Output format.")] = OutputFormat.text,
    strict: Annotated[bool, typer.Option("--strict", help="Fail on warnings too.")] = False,
    urdf_file: Annotated[str | None, typer.Option(
        "--urdf-file", help="URDF override (absolute or package-relative).")] = None,
    srdf_file: Annotated[str | None, typer.Option(
        "--srdf-file", help="SRDF override (absolute or package-relative).")] = None,
) -> None:
    """Check a description package against every rule of the protocol; all problems are listed at once."""
    options = [f"{name}:={value}" for name, value in zip(VALIDATE_ARGUMENTS, (urdf_file, srdf_file), strict=True)
               if value is not None]
    given = parse_launch_arguments([*(overrides or []), *options], VALIDATE_ARGUMENTS)
    from plem.description.validate import validate_package

    report = validate_package(package, urdf_file=given.get("urdf_file"), srdf_file=given.get("srdf_file"))
    errors, warnings = report.findings.errors, report.findings.warnings
    passed = report.passed(strict)
    if output_format is OutputFormat.json:
        print_json({"package": report.files.name, "path": str(report.files.root), "dof": report.dof,
                    "passed": passed, "strict": strict, "errors": [p.to_dict() for p in errors],
                    "warnings": [p.to_dict() for p in warnings], "notes": report.notes})
    else:
        for problem in errors + warnings:
            stderr.print(problem.render() + "\n", markup=False)
        for note in report.notes:
            stdout.print(f"INFO: {note}", markup=False)
        verdict = "OK" if passed else "FAILED"
        stdout.print(f"{verdict}: {report.files.name} ({report.files.root}): {len(errors)} error(s), "
                     f"{len(warnings)} warning(s), DOF {report.dof if report.dof is not None else '?'}"
                     + (" [strict]" if strict else ""), markup=False)
    if not passed:
        raise typer.Exit(1)


def create_description(
    name: Annotated[str | None, typer.Option("--name", help="Robot name; the package is NAME_description.")] = None,
    dof: Annotated[int | None, typer.Option("--dof", help="Number of joints: 6 or 7.")] = None,
    with_moveit: Annotated[bool, typer.Option("--with-moveit", help="Also an SRDF and kinematics.yaml.")] = False,
    no_launch: Annotated[bool, typer.Option("--no-launch", help="Skip launch/bringup.launch.py.")] = False,
    force: Annotated[bool, typer.Option("--force", help="Overwrite files that differ.")] = False,
    output: Annotated[Path, typer.Option("--output", help="Folder to create the package in.")] = Path("."),
) -> None:
    """Create a description package for a generic 6- or 7-axis arm (asks for missing options on a terminal)."""
    from plem.description.scaffold import create_package

    if name is None or dof is None:
        if not sys.stdin.isatty():
            missing = [flag for flag, value in (("--name", name), ("--dof", dof)) if value is None]
            raise UsageError(
                f"Missing {' and '.join(missing)}",
                what="--name NAME --dof 6|7, or a terminal to answer questions interactively",
                why=f"{', '.join(missing)} not given and standard input is not a terminal",
                how="e.g. plem create-description --name my_robot --dof 6",
            )
        name = name or typer.prompt("Robot name (lowercase, e.g. my_robot)")
        dof = dof or typer.prompt("Number of joints (6 or 7)", type=int, default=6)
        with_moveit = with_moveit or typer.confirm("Add an SRDF and kinematics.yaml for planning?", default=False)
        no_launch = no_launch or not typer.confirm("Generate launch/bringup.launch.py?", default=True)
    result = create_package(output, name, dof, with_moveit=with_moveit, launch=not no_launch, force=force)
    for label, items in (("created", result.created), ("identical, skipped", result.identical),
                         ("overwritten", result.overwritten)):
        for relative in items:
            stdout.print(f"  {label:<18} {relative}", markup=False)
    stdout.print(f"Package ready: {result.root}\nNext: plem validate {_path_argument(result.root)} --strict",
                 markup=False)


def _path_argument(path: Path) -> str:
    """`path` written so that plem reads it as a path, never as a package name (./ before a bare relative
    path), quoted for the shell."""
    from plem.description.discover import PATH_PREFIXES

    text = str(path)
    return shlex.quote(text if text.startswith(PATH_PREFIXES) or text in (".", "..") else f"./{text}")
