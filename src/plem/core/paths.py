"""The package search path: find packages by name and resolve `pkg/relative/path` without ROS.

Search order: `PLEM_PACKAGE_PATH` entries, then `share/` of every `AMENT_PREFIX_PATH` prefix, then the
description packages shipped inside plem. A package is a directory holding `package.xml`; its name is
the directory name. A `PLEM_PACKAGE_PATH` entry may be a package itself or a folder of packages.
"""

from __future__ import annotations

import contextlib
import io
import os
import stat
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import IO, Any, Self

from plem.errors import ConfigError, PackageNotFoundError, PlemError

BUILTIN_PACKAGES_DIR = Path(__file__).resolve().parent.parent / "description" / "builtin"
PACKAGE_MARKER = "package.xml"


_pinned: ContextVar[Mapping[str, Path]] = ContextVar("pinned_packages", default=MappingProxyType({}))


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


def find_package(name: str, environ: Mapping[str, str] | None = None,
                 exists: Callable[[Path], bool] = is_file) -> Path:
    """The directory of package `name`, or a PackageNotFoundError that says where plem looked.

    `exists` answers whether a package.xml is there (a PackageReader's, when reading through one)."""
    pinned = _pinned.get().get(name)
    if pinned is not None:
        return pinned
    for root in search_roots(environ):
        candidate = root if root.name == name else root / name
        if _plain_name(name) and exists(candidate / PACKAGE_MARKER):
            return candidate
    raise PackageNotFoundError(
        f"Package '{name}' not found",
        what=f"a directory named '{name}' holding {PACKAGE_MARKER} on the package search path",
        why=f"no such package in: {_search_path_description(environ)}",
        how=f"export PLEM_PACKAGE_PATH=/path/to/folder/containing/{name} (or give the package by path)",
    )


def _plain_name(name: str) -> bool:
    """A name that stays inside the folder it is looked up in (no separator, not . or ..)."""
    return bool(name) and "/" not in name and name not in (".", "..")


class PackageAccessError(PlemError):
    """A description tried to read a file outside the packages it may read."""


@dataclass(frozen=True)
class _Root:
    folder: Path  # as the search path names it
    real: Path  # with symbolic links resolved
    handle: int
    is_package: bool  # a package itself, rather than a folder of packages


class PackageReader:
    """Reads files only from inside packages: the pinned ones, the ones given and those on the search path.

    Each folder is opened once, up front, and files are opened beneath those handles, so a process that later
    loses the right to walk to the folders (a render running as another user) can still read the packages and
    nothing else. Symbolic links are followed only to files that are themselves inside a package.
    """

    def __init__(self, packages: Iterable[Path], environ: Mapping[str, str] | None = None) -> None:
        given = [Path(os.path.abspath(folder)) for folder in [*_pinned.get().values(), *packages]]
        self._roots: list[_Root] = []
        for folder in [*given, *(Path(os.path.abspath(root)) for root in search_roots(environ))]:
            try:
                handle = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
            except (OSError, ValueError):
                continue
            self._roots.append(_Root(folder, Path(os.path.realpath(folder)), handle,
                                     folder in given or _exists_at(handle, PACKAGE_MARKER)))

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        for root in self._roots:
            os.close(root.handle)
        self._roots.clear()

    @property
    def handles(self) -> list[int]:
        """The open folder handles (a child process must keep them to read through this reader)."""
        return [root.handle for root in self._roots]

    def is_file(self, path: str | os.PathLike[str]) -> bool:
        """Whether `path` is a regular file inside a readable package."""
        located = self._locate(Path(os.path.abspath(path)), real=False)
        if located is None:
            return False
        try:
            return stat.S_ISREG(os.stat(located[1], dir_fd=located[0]).st_mode)
        except OSError:
            return False

    def open(self, path: str | os.PathLike[str], mode: str = "r") -> IO[Any]:
        """`open(path, mode)` for reading a file inside a package; anything else is a PackageAccessError."""
        located = self._locate(Path(os.path.abspath(path)), real=False)
        if located is None or not set(mode) <= set("rbt"):
            raise _refused(path, "it is not inside the package being read or a package on the search path")
        try:
            descriptor = os.open(located[1], os.O_RDONLY | os.O_CLOEXEC, dir_fd=located[0])
        except PermissionError:
            raise PackageAccessError(
                f"Cannot read {path}", what="package files readable by the user that renders them",
                why=f"{path} is not readable by user id {os.geteuid()} (a render started as root runs as the "
                    "package folder's owner, or as nobody when root owns it)",
                how="make the package readable (chmod -R a+rX PACKAGE_DIR), or chown it to the user it belongs to",
            ) from None
        real = Path(os.readlink(f"/proc/self/fd/{descriptor}"))
        if self._locate(real, real=True) is None and not any(is_file(up / PACKAGE_MARKER) for up in real.parents):
            os.close(descriptor)
            raise _refused(path, f"it is a link to {real}, which is not inside a package")
        raw = io.FileIO(descriptor, "r")
        return raw if "b" in mode else io.TextIOWrapper(io.BufferedReader(raw))

    def _locate(self, target: Path, real: bool) -> tuple[int, str] | None:
        """(folder handle, path beneath it) when `target` lies inside a package this reader may read."""
        for root in self._roots:
            try:
                parts = target.relative_to(root.real if real else root.folder).parts
            except ValueError:
                continue
            inside = bool(parts) if root.is_package else (
                len(parts) > 1 and _exists_at(root.handle, os.path.join(parts[0], PACKAGE_MARKER)))
            if inside:
                return root.handle, os.path.join(*parts)
        return None


def _refused(path: str | os.PathLike[str], reason: str) -> PackageAccessError:
    return PackageAccessError(
        f"Reading {path} is not allowed",
        what="xacro:include, xacro.load_yaml and $(find) reading files of the package being rendered or of packages "
             "on the package search path",
        why=f"the description asks for {path}, and {reason}",
        how="copy the file into the package, or add the folder of the package holding it to PLEM_PACKAGE_PATH",
    )


def _exists_at(handle: int, relative: str) -> bool:
    try:
        os.stat(relative, dir_fd=handle)
        return True
    except OSError:
        return False


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
        raise _not_found(str(spec), [local],
                         f"no package named '{package}' ({_search_path_description(environ)})") from None
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
