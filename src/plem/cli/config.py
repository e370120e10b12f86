"""`plem config show`: every effective configuration field and the layer it came from."""

from __future__ import annotations

import os
from typing import Annotated

import typer

from plem.cli.output import OutputFormat, new_table, print_json, print_warnings, stdout
from plem.core.config.environment import middleware_environment, plem_home
from plem.core.config.launch_args import parse_launch_arguments
from plem.robot.config import ARM_SETTINGS
from plem.robot.models import DEFAULT_ROBOT_TYPE

app = typer.Typer(help="Show the effective configuration.", no_args_is_help=True)

CONFIG_ARGUMENTS = ("robot_type", *(setting.launch for setting in ARM_SETTINGS if setting.launch))
EXTRA_ARGS = {"allow_extra_args": True, "ignore_unknown_options": True}
HIDDEN_FIELDS = ("custom_bus",)


@app.command("show", context_settings=EXTRA_ARGS)
def show(
    arguments: Annotated[list[str] | None, typer.Argument(
        help=f"Launch arguments as name:=value ({', '.join(CONFIG_ARGUMENTS)}); "
             f"robot_type defaults to {DEFAULT_ROBOT_TYPE}.", show_default=False)] = None,
    output_format: Annotated[OutputFormat, typer.Option("--format", help="Output format.")] = OutputFormat.text,
) -> None:
    """Print every effective field with its value and source, as `plem launch` would resolve them."""
    from plem.robot.resolution import LAUNCH_DEFAULTS, resolve_arm_config  # deferred: pulls in pydantic

    launch = parse_launch_arguments(arguments or [], CONFIG_ARGUMENTS)
    resolved = resolve_arm_config(launch_args=launch, launch_defaults=LAUNCH_DEFAULTS)
    middleware = middleware_environment()
    config = resolved.config
    rows = [(name, value, str(resolved.sources[name]))
            for name, value in config.field_values().items() if name not in HIDDEN_FIELDS]
    rows += [
        ("ros_domain_id", middleware.ros_domain_id, middleware.ros_domain_source),
        ("rmw_implementation", middleware.rmw_implementation, middleware.rmw_source),
        ("plem_home", str(plem_home()), "environment PLEM_HOME" if os.environ.get("PLEM_HOME") else "default ~/.plem"),
    ]
    warnings = resolved.warnings + middleware.warnings
    robot_type = config.MODEL.robot_type if config.MODEL else "custom"
    if output_format is OutputFormat.json:
        print_json({
            "robot_type": robot_type,
            "model": config.model_name(),
            "fields": {name: {"value": value, "source": source} for name, value, source in rows},
            "warnings": warnings,
        })
        return
    table = new_table(f"Effective configuration: {config.model_name()} ({robot_type})", "field", "value", "source")
    for name, value, source in rows:
        table.add_row(name, str(value), source)
    stdout.print(table)
    print_warnings(warnings)
