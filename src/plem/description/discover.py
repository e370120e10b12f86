"""Finding a description package and its files by the protocol's conventions.

`urdf/` holds exactly one `*.urdf.xacro`, `srdf/` at most one SRDF, `config/` the exact names
`joint_limits.yaml`, `controllers.yaml`, `kinematics.yaml`; `urdf_file`/`srdf_file` override discovery.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from plem.core.config.launch_args import check_home
from plem.core.files import file_kind
from plem.core.paths import PACKAGE_MARKER, find_package, is_dir, is_file, package_name
from plem.description.problems import Findings
from plem.errors import PackageNotFoundError
from plem.robot.models import DEFAULT_ROBOT_TYPE, model_for

URDF_SUFFIX = ".urdf.xacro"
ROS2_CONTROL_SUFFIX = ".ros2_control.xacro"
SRDF_SUFFIXES = (".srdf", ".srdf.xacro")
COMPAT_FILE = "PLEM_COMPAT_VERSION"
CONFIG_NAMES = ("joint_limits.yaml", "controllers.yaml", "kinematics.yaml")
LEGACY_PACKAGE = "wim_description"


@dataclass
class DescriptionFiles:
    """The files of one package as discovery found them; missing ones are None. `name` is the package's name as
    package.xml declares it (the folder's name without one)."""

    name: str
    root: Path
    urdf: Path | None = None
    ros2_control: Path | None = None
    srdf: Path | None = None
    joint_limits: Path | None = None
    controllers: Path | None = None
    kinematics: Path | None = None
    compat_version: Path | None = None
    findings: Findings = field(default_factory=Findings)


PATH_PREFIXES = ("./", "../", "/", "~")


def _is_path(package: str | os.PathLike[str]) -> bool:
    """Whether the user wrote a path (a Path object, or text starting with ./ ../ / or ~) rather than a name."""
    text = os.fspath(package)
    return not isinstance(package, str) or text in (".", "..") or text.startswith(PATH_PREFIXES)


def locate_package(package: str | os.PathLike[str]) -> Path:
    """A package given by path (./, ../, / or ~) or by name through the package search path only.

    A name is never looked up in the working directory: a folder planted there must not replace a package."""
    if _is_path(package):
        check_home(os.fspath(package), os.fspath(package))
        path = Path(package).expanduser()
        if is_dir(path):
            return path.resolve()
        raise PackageNotFoundError(
            f"Package directory not found: {package}",
            what="a description package directory, or a package name on the package search path",
            why=f"{path.absolute()} does not exist or is not a directory",
            how="check the path, or give the package name and add its folder to PLEM_PACKAGE_PATH",
        )
    name = str(package)
    if not name or "/" in name:
        raise PackageNotFoundError(
            f"Not a package name: '{name}'",
            what="a package name (a folder name on the package search path) or a path starting with ./, ../, / or ~",
            why=f"'{name}' is neither" if name else "the name is empty",
            how=f"write the path as ./{name}" if name else "give the package name or its directory",
        )
    try:
        return find_package(name)
    except PackageNotFoundError as error:
        if is_dir(Path(name)):
            raise PackageNotFoundError(
                error.summary, what=error.what,
                why=f"{error.why}; ./{name} exists, but a bare name is only looked up on the package search path",
                how=f"did you mean ./{name}? Give the folder as a path to use it") from None
        raise


def package_for_launch(description_package: str | None, robot_type: str | None) -> str:
    """The package `plem launch` uses: `wim_description` (or none) means the built-in `<robot_type>_description`."""
    if description_package and description_package != LEGACY_PACKAGE:
        return description_package
    return model_for(robot_type or DEFAULT_ROBOT_TYPE).MODEL.description_package


def _override(files: DescriptionFiles, kind: str, given: str | os.PathLike[str]) -> Path | None:
    """The file named by a `urdf_file`/`srdf_file` argument (absolute or package-relative), or a problem."""
    check_home(os.fspath(given), f"{kind}_file:={os.fspath(given)}")
    path = Path(given).expanduser()
    path = path if path.is_absolute() else files.root / path
    if is_file(path):
        return path
    try:
        summary, found = "is not a regular file", f"{path} is a {file_kind(path.stat().st_mode)}, not a regular file"
    except (OSError, ValueError):
        summary, found = "not found", f"{path} does not exist"
    files.findings.error(f"{kind}.override_missing", f"{kind.upper()} override {summary}: {given}",
                         what=f"{kind}_file:= naming an existing file (absolute, or relative to the package)",
                         why=found, how=f"fix the {kind}_file:= path, or drop it to use discovery", file=path)
    return None


def discover(package: str | os.PathLike[str], urdf_file: str | os.PathLike[str] | None = None,
             srdf_file: str | os.PathLike[str] | None = None) -> DescriptionFiles:
    """Find the package's files; problems (none, several, wrong names) are collected, not raised."""
    root = locate_package(package)
    files = DescriptionFiles(name=package_name(root), root=root)
    found = files.findings
    if not (root / PACKAGE_MARKER).is_file():
        found.warning("package.xml_missing", f"No package.xml in '{root.name}'",
                      what="a ROS 2 package with package.xml (so colcon and the package search path see it)",
                      why=f"{root / PACKAGE_MARKER} does not exist", how="create package.xml (ament_cmake)",
                      file=root)
    _discover_urdf(files, urdf_file)
    _discover_srdf(files, srdf_file)
    for name in CONFIG_NAMES:
        path = root / "config" / name
        if path.is_file():
            setattr(files, name.removesuffix(".yaml"), path)
    _near_misses(files)
    compat = root / COMPAT_FILE
    files.compat_version = compat if compat.is_file() else None
    return files


def _discover_urdf(files: DescriptionFiles, urdf_file: str | os.PathLike[str] | None) -> None:
    root, found = files.root, files.findings
    urdf_dir = root / "urdf"
    controls = sorted(urdf_dir.glob(f"*{ROS2_CONTROL_SUFFIX}")) if urdf_dir.is_dir() else []
    files.ros2_control = controls[0] if len(controls) == 1 else None
    if urdf_file:
        files.urdf = _override(files, "urdf", urdf_file)
        return
    candidates = sorted(urdf_dir.glob(f"*{URDF_SUFFIX}")) if urdf_dir.is_dir() else []
    if len(candidates) == 1:
        files.urdf = candidates[0]
        return
    others = sorted(p.name for p in urdf_dir.iterdir()) if urdf_dir.is_dir() else []
    if not candidates:
        found.error("urdf.missing", f"No URDF file found in package '{root.name}'",
                    what=f"Auto-discovery expected exactly one {URDF_SUFFIX} file in urdf/ directory",
                    why="Found 0 matching files" + (f" (urdf/ holds: {', '.join(others)})" if others
                                                   else " (urdf/ is empty)" if urdf_dir.is_dir()
                                                   else " (no urdf/ directory)"),
                    how=f"Create urdf/{_base_name(root)}{URDF_SUFFIX}, or name the URDF with urdf_file:=PATH "
                        "(plem launch or plem validate)",
                    file=urdf_dir)
    else:
        found.error("urdf.multiple", f"Several URDF files found in package '{root.name}'",
                    what=f"Auto-discovery expected exactly one {URDF_SUFFIX} file in urdf/ directory",
                    why=f"Found {len(candidates)} matching files: {', '.join(p.name for p in candidates)}",
                    how="keep one, rename the others (e.g. to .xacro), or pick one with "
                        f"urdf_file:=urdf/{candidates[0].name}",
                    file=urdf_dir)


def _discover_srdf(files: DescriptionFiles, srdf_file: str | os.PathLike[str] | None) -> None:
    root, found = files.root, files.findings
    if srdf_file:
        files.srdf = _override(files, "srdf", srdf_file)
        return
    srdf_dir = root / "srdf"
    candidates = sorted(p for p in srdf_dir.iterdir() if p.name.endswith(SRDF_SUFFIXES)) if srdf_dir.is_dir() else []
    if len(candidates) == 1:
        files.srdf = candidates[0]
    elif len(candidates) > 1:
        found.error("srdf.multiple", f"Several SRDF files found in package '{root.name}'",
                    what="at most one .srdf or .srdf.xacro file in srdf/",
                    why=f"Found {len(candidates)}: {', '.join(p.name for p in candidates)}",
                    how=f"keep one, or pick one with srdf_file:=srdf/{candidates[0].name}", file=srdf_dir)


def _near_misses(files: DescriptionFiles) -> None:
    """Config files with almost the right name are ignored by discovery; say so rather than stay silent."""
    config_dir = files.root / "config"
    if not config_dir.is_dir():
        return
    for path in sorted(config_dir.iterdir()):
        stem = path.name.split(".")[0]
        for expected in CONFIG_NAMES:
            if path.name != expected and stem == expected.split(".")[0]:
                files.findings.warning(
                    "config.misnamed", f"config/{path.name} is ignored",
                    what=f"the exact file name config/{expected}", why=f"found config/{path.name}",
                    how=f"rename it to config/{expected}", file=path)


def _base_name(root: Path) -> str:
    return package_name(root).removesuffix("_description")
