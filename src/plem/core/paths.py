"""The package search path: find packages by name and resolve `pkg/relative/path` without ROS.

Search order: `PLEM_PACKAGE_PATH` entries, then `share/` of every `AMENT_PREFIX_PATH` prefix, then the
description packages shipped inside plem. A package is a directory holding `package.xml`; its name is
the directory name. A `PLEM_PACKAGE_PATH` entry may be a package itself or a folder of packages.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Mapping
from contextvars import ContextVar
from pathlib import Path

from plem.errors import ConfigError, PackageNotFoundError

BUILTIN_PACKAGES_DIR = Path(__file__).resolve().parent.parent / "description" / "builtin"
PACKAGE_MARKER = "package.xml"


_pinned: ContextVar[Mapping[str, Path]] = ContextVar("pinned_packages", default={})


@contextlib.contextmanager
def pinned_packages(packages: Mapping[str, Path]) -> Iterator[None]:
    """Within the block, these names resolve to these directories before any search (a package given by path
    must find itself through `$(find its_name)` even when it is not on the search path)."""
    token = _pinned.set({**_pinned.get(), **packages})
    try:
        yield
    finally:
        _pinned.reset(token)


def _environ(environ: Mapping[str, str] | None) -> Mapping[str, str]:
    return os.environ if environ is None else environ


def search_roots(environ: Mapping[str, str] | None = None) -> list[Path]:
    """Folders searched for packages, highest priority first."""
    env = _environ(environ)
    roots: list[Path] = []
    for entry in env.get("PLEM_PACKAGE_PATH", "").split(os.pathsep):
        if entry:
            roots.append(Path(entry).expanduser())
    for prefix in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            roots.append(Path(prefix).expanduser() / "share")
    roots.append(BUILTIN_PACKAGES_DIR)
    return roots


def is_file(path: Path) -> bool:
    """`path.is_file()` that answers False for names the OS rejects (too long, NUL bytes)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


def is_dir(path: Path) -> bool:
    """`path.is_dir()` that answers False for names the OS rejects."""
    try:
        return path.is_dir()
    except (OSError, ValueError):
        return False


def _search_path_description(environ: Mapping[str, str] | None) -> str:
    env = _environ(environ)
    return (
        f"PLEM_PACKAGE_PATH={env.get('PLEM_PACKAGE_PATH', '') or '(unset)'}, "
        f"AMENT_PREFIX_PATH={env.get('AMENT_PREFIX_PATH', '') or '(unset)'}, "
        f"built-in packages in {BUILTIN_PACKAGES_DIR}"
    )


def find_package(name: str, environ: Mapping[str, str] | None = None) -> Path:
    """The directory of package `name`, or a PackageNotFoundError that says where plem looked."""
    pinned = _pinned.get().get(name)
    if pinned is not None:
        return pinned
    for root in search_roots(environ):
        candidate = root if root.name == name else root / name
        if name and is_file(candidate / PACKAGE_MARKER):
            return candidate
    raise PackageNotFoundError(
        f"Package '{name}' not found",
        what=f"a directory named '{name}' holding {PACKAGE_MARKER} on the package search path",
        why=f"no such package in: {_search_path_description(environ)}",
        how=f"export PLEM_PACKAGE_PATH=/path/to/folder/containing/{name} (or give the package by path)",
    )


def resolve_resource(spec: str | os.PathLike[str], environ: Mapping[str, str] | None = None) -> Path:
    """Resolve an absolute path, a path relative to the working directory, or `package_name/relative/path`.

    A relative path that exists under the working directory wins over a package of the same first name.
    """
    path = Path(spec).expanduser()
    if path.is_absolute():
        if path.exists():
            return path
        raise _not_found(str(spec), [path], None)
    local = Path.cwd() / path
    if local.exists():
        return local
    package, _, rest = path.as_posix().partition("/")
    try:
        package_dir = find_package(package, environ)
    except PackageNotFoundError:
        raise _not_found(str(spec), [local], f"no package named '{package}' ({_search_path_description(environ)})")
    in_package = package_dir / rest
    if in_package.exists():
        return in_package
    raise _not_found(str(spec), [local, in_package], None)


def _not_found(spec: str, tried: list[Path], extra: str | None) -> ConfigError:
    why = "tried " + ", ".join(str(p) for p in tried) + "; none exists"
    if extra:
        why += f"; {extra}"
    return ConfigError(
        f"File not found: {spec}",
        what="an absolute path, a path relative to the working directory, or package_name/relative/path",
        why=why,
        how="check the spelling, or add the package's folder to PLEM_PACKAGE_PATH",
    )


def resolve_package_uri(uri: str, base: Path | None = None, environ: Mapping[str, str] | None = None) -> Path:
    """The file behind a URDF resource reference: `package://pkg/rel`, `file:///abs`, or a path relative to `base`."""
    if uri.startswith("package://"):
        package, _, rest = uri.removeprefix("package://").partition("/")
        path = find_package(package, environ) / rest
    elif uri.startswith("file://"):
        path = Path(uri.removeprefix("file://"))
    else:
        path = (base or Path.cwd()) / uri
    if not is_file(path):
        raise ConfigError(
            f"Resource not found: {uri}",
            what="a mesh or resource file that exists",
            why=f"{uri} resolves to {path}, which does not exist",
            how="fix the file name, or add the file to the package",
        )
    return path
