"""Launch descriptions: which components of a robot to start, as written in a bring-up file.

A bring-up file (e.g. the scaffold's `launch/bringup.launch.py`) defines `generate_launch_description()`
returning a `LaunchDescription`; `plem launch FILE` loads it with `load_launch_file`. A bring-up file is Python:
loading it runs it with the rights of whoever launches, so launching a package's own file trusts that package.
"""

from __future__ import annotations

import importlib.util
import os
import sys
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from plem.errors import PlemError

COMPONENTS = ("rt_driver", "bridge", "recorder", "planner")


class LaunchFileError(PlemError):
    """A bring-up file cannot be loaded or does not describe a launch."""


@dataclass(frozen=True)
class LaunchDescription:
    """A robot's bring-up: its description package, component switches and launch arguments."""

    description_package: str
    components: dict[str, bool] = field(default_factory=lambda: dict.fromkeys(COMPONENTS, True))
    arguments: dict[str, str] = field(default_factory=dict)

    @property
    def enabled(self) -> list[str]:
        """The components switched on, in the order of COMPONENTS."""
        return [name for name in COMPONENTS if self.components.get(name)]


def bringup(description_package: str, *, rt_driver: bool = True, bridge: bool = True, recorder: bool = True,
            planner: bool = True, **arguments: object) -> LaunchDescription:
    """Describe a bring-up with per-component switches; extra keywords are launch arguments (`record=False`)."""
    if not rt_driver and (bridge or recorder or planner):
        raise LaunchFileError(
            "Components enabled without the RT driver",
            what="rt_driver=True whenever bridge, recorder or planner is enabled",
            why="every component reads the state the RT driver publishes",
            how="set rt_driver=True, or disable the other components too",
        )
    switches = {"rt_driver": rt_driver, "bridge": bridge, "recorder": recorder, "planner": planner}
    return LaunchDescription(description_package, switches, {k: _text(v) for k, v in arguments.items()})


def _text(value: object) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def load_launch_file(path: str | os.PathLike[str]) -> LaunchDescription:
    """Import a bring-up file and call its `generate_launch_description()`."""
    path = Path(path)
    spec = importlib.util.spec_from_file_location(f"plem_launch_file_{abs(hash(path))}", path)
    if spec is None or spec.loader is None or not path.is_file():
        raise LaunchFileError(f"Cannot load launch file {path}", what="a readable Python launch file",
                              why=f"{path} does not exist or is not a Python file",
                              how="check the path (e.g. my_robot_description/launch/bringup.launch.py)")
    module = importlib.util.module_from_spec(spec)
    writes_bytecode = sys.dont_write_bytecode
    sys.dont_write_bytecode = True  # never write __pycache__ into the user's package
    try:
        spec.loader.exec_module(module)
        generate = module.generate_launch_description
        description = generate()
    except PlemError:
        raise
    except (Exception, SystemExit) as error:  # noqa: BLE001 - user code may raise anything: the user's problem
        where = _raised_at(path, error)
        raise LaunchFileError(f"Launch file {path.name} failed", what="generate_launch_description() to return "
                              "plem.launch.bringup(...)",
                              why=f"{where}: {type(error).__name__}: {' '.join(str(error).split())[:500]}",
                              how=f"fix {where}") from None
    finally:
        sys.dont_write_bytecode = writes_bytecode
    if not isinstance(description, LaunchDescription):
        raise LaunchFileError(f"Launch file {path.name} returned {type(description).__name__}",
                              what="generate_launch_description() returning plem.launch.bringup(...)",
                              why=f"it returned {description!r}", how="return bringup(\"my_robot_description\", ...)")
    return description


def _raised_at(path: Path, error: BaseException) -> str:
    """`file:line` of the launch file where `error` arose (the last of its frames in that file; a syntax error's
    own line), or the file alone when no frame of it is known."""
    if isinstance(error, SyntaxError) and error.lineno:
        return f"{error.filename or path}:{error.lineno}"
    target = os.path.realpath(path)
    lines = [frame.lineno for frame in traceback.extract_tb(error.__traceback__)
             if os.path.realpath(frame.filename) == target and frame.lineno]
    return f"{path}:{lines[-1]}" if lines else str(path)
