"""`plem launch`: bring up one robot (or several with robots:=FILE.yaml), optionally from a bring-up file."""

from __future__ import annotations

import os
from pathlib import Path

import typer

from plem.errors import UsageError

USAGE = """Usage: plem launch [LAUNCH_FILE | PACKAGE [FILE]] [name:=value ...]

Start a robot: the RT driver (shared memory /{robot_id}_joint_actual_values and its rings), then the
components that are part of this version. Ctrl-C stops the arm smoothly and exits.

  plem launch bus:=mock                                  the simulated Indy7 v2
  plem launch bus:=mock robot_type:=indy12_v2 rt_priority:=80
  plem launch description_package:=./my_robot_description bus:=mock
  plem launch my_robot_description/launch/bringup.launch.py bus:=mock
  plem launch my_robot_description bringup.launch.py     (package found on PLEM_PACKAGE_PATH)
  plem launch robots:=robots.yaml                        several robots, each with its own robot_id

Arguments (name:=value, or --name value):
"""
EXTRA_ARGS = {"allow_extra_args": True, "ignore_unknown_options": True, "help_option_names": []}


def _split_positional(tokens: list[str]) -> tuple[list[str], list[str]]:
    """Leading words that are neither name:=value nor --options name the launch file."""
    count = 0
    while count < len(tokens) and ":=" not in tokens[count] and not tokens[count].startswith("-"):
        count += 1
    return tokens[:count], tokens[count:]


def _launch_file(positional: list[str]) -> Path:
    from plem.core.config.launch_args import check_home
    from plem.description.discover import locate_package

    for word in positional:
        check_home(word, word)
    if len(positional) == 1 and positional[0].endswith(".py"):
        return Path(positional[0]).expanduser()
    if len(positional) in (1, 2):
        return locate_package(positional[0]) / "launch" / (positional[1] if len(positional) == 2
                                                           else "bringup.launch.py")
    raise UsageError("too many words before the launch arguments", what="at most a package and a launch file",
                     why=f"got {' '.join(positional)}", how="write the other arguments as name:=value")


def trust_warning(path: Path) -> str:
    """The warning printed before a launch file runs: it is Python, run with the launcher's rights."""
    user = "root's" if os.geteuid() == 0 else "your"
    return (f"{path} is Python and runs now with {user} rights: launching a package's own launch file trusts that "
            "package (plem validate checks a description, never its launch file); to launch a package you do not "
            "trust, use description_package:=PACKAGE instead")


def launch(ctx: typer.Context) -> int:
    """Start a robot and keep it running until Ctrl-C (see `plem launch --help`)."""
    tokens = list(ctx.args)
    if "--help" in tokens or "-h" in tokens:
        from plem.launch.arguments import help_text

        typer.echo(USAGE + help_text())
        return 0
    from plem.cli.output import print_warnings
    from plem.core.config.launch_args import check_home
    from plem.launch.arguments import parse
    from plem.launch.description import COMPONENTS, load_launch_file
    from plem.launch.plan import plan_launch
    from plem.launch.robots_file import load_robots
    from plem.launch.supervisor import Supervisor

    positional, rest = _split_positional(tokens)
    arguments = parse(rest)
    components = dict.fromkeys(COMPONENTS, True)
    if positional:
        path = _launch_file(positional)
        print_warnings([trust_warning(path)])
        described = load_launch_file(path)
        components = described.components
        package = described.description_package
        if path.resolve().parent.parent.name == package:  # the package the bring-up file lives in
            package = str(path.resolve().parent.parent)
        arguments = {**described.arguments, "description_package": package, **arguments}
    if arguments.get("robots"):
        check_home(arguments["robots"], f"robots:={arguments['robots']}")
    robots = load_robots(arguments["robots"], arguments) if arguments.get("robots") else [arguments]
    plans = plan_launch(robots, bridge=components.get("bridge", True))
    return Supervisor(plans, components).run()
