"""The package search path: find packages by name and resolve `pkg/relative/path` without ROS.

Search order: `PLEM_PACKAGE_PATH` entries, then `share/` of every `AMENT_PREFIX_PATH` prefix, then the
description packages shipped inside plem. A package is a directory holding `package.xml`; its name is the
`<name>` that file declares, as colcon reads it (a clone in `Universal_Robots_ROS2_Description` is the package
`ur_description`). A `PLEM_PACKAGE_PATH` entry may be a package itself or a folder searched for packages as
colcon searches a workspace: recursively (up to SEARCH_DEPTH folders down), not below a package, skipping hidden
folders and those marked COLCON_IGNORE or AMENT_IGNORE. An install's `share/` holds each package under its name.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import stat
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import IO, Any, Self

from plem.core.files import read_regular
from plem.errors import ConfigError, PackageNotFoundError, PlemError

BUILTIN_PACKAGES_DIR = Path(__file__).resolve().parent.parent / "description" / "builtin"
PACKAGE_MARKER = "package.xml"
#: Files that keep colcon (and plem) from looking for packages in a folder.
IGNORE_MARKERS = ("COLCON_IGNORE", "AMENT_IGNORE")
#: How deep below a search path entry packages are looked for (a workspace's src/REPOSITORY/PACKAGE is 2).
SEARCH_DEPTH = 4
#: package.xml is a few KiB; a larger file is not read for its name.
MAX_PACKAGE_XML_BYTES = 1024 * 1024
_PACKAGE_NAME = re.compile(rb"<name>\s*([^<\s]+)\s*</name>")


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


def _plem_package_path(environ: Mapping[str, str] | None) -> list[Path]:
    """The PLEM_PACKAGE_PATH entries: packages, or workspaces searched for packages as colcon searches them."""
    return [Path(entry).expanduser() for entry in _environ(environ).get("PLEM_PACKAGE_PATH", "").split(os.pathsep)
            if entry]


def search_roots(environ: Mapping[str, str] | None = None) -> list[Path]:
    """Folders searched for packages, highest priority first."""
    env = _environ(environ)
    roots = _plem_package_path(environ)
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


def _read_declared_name(package_xml: Path) -> str | None:
    try:
        match = _PACKAGE_NAME.search(read_regular(package_xml, MAX_PACKAGE_XML_BYTES, PACKAGE_MARKER))
    except PlemError:
        return None
    return match.group(1).decode("utf-8", errors="replace") if match else None


_declared: dict[Path, tuple[tuple[int, int, int], str | None]] = {}


def declared_name(folder: Path) -> str | None:
    """The `<name>` the folder's package.xml declares; None without a readable package.xml or name in it."""
    marker = folder / PACKAGE_MARKER
    try:
        status = os.stat(marker)
    except (OSError, ValueError):
        return None
    signature = (status.st_mtime_ns, status.st_size, status.st_ino)
    cached = _declared.get(marker)
    if cached is None or cached[0] != signature:
        cached = _declared[marker] = (signature, _read_declared_name(marker))
    return cached[1]


def package_name(folder: Path) -> str:
    """A package's name: what its package.xml declares, else the folder's name."""
    return declared_name(folder) or folder.name


def _packages_below(root: Path, depth: int = SEARCH_DEPTH) -> Iterator[Path]:
    """The packages in `root` as colcon finds them: `root` itself when it is one, else recursively below it."""
    if is_file(root / PACKAGE_MARKER):
        yield root
        return
    if depth == 0 or any(is_file(root / marker) for marker in IGNORE_MARKERS):
        return
    try:
        folders = sorted(entry.path for entry in os.scandir(root) if entry.is_dir() and not entry.name.startswith("."))
    except OSError:
        return
    for folder in folders:
        yield from _packages_below(Path(folder), depth - 1)


def find_package(name: str, environ: Mapping[str, str] | None = None,
                 exists: Callable[[Path], bool] = is_file) -> Path:
    """The directory of the package package.xml names `name`, or a PackageNotFoundError that says where plem looked.

    In each search path entry a folder carrying the name comes first (the usual layout; an install's share/ names
    its packages so, as ament's index does), then in a PLEM_PACKAGE_PATH entry the packages below it by their
    declared names. `exists` answers whether a package.xml
    is there (a PackageReader's, when reading through one)."""
    pinned = _pinned.get().get(name)
    if pinned is not None:
        return pinned
    roots = search_roots(environ) if _plain_name(name) else []
    workspaces = set(roots[:len(_plem_package_path(environ))])
    for root in roots:
        candidate = root if root.name == name else root / name
        if exists(candidate / PACKAGE_MARKER):  # as ament's index names an install's packages: by folder
            return candidate
        for folder in _packages_below(root) if root in workspaces else ():
            if declared_name(folder) == name:
                return folder
    raise PackageNotFoundError(
        f"Package '{name}' not found",
        what=f"a package whose {PACKAGE_MARKER} declares <name>{name}</name>, on the package search path",
        why=f"no such package in: {_search_path_description(environ)}",
        how=f"export PLEM_PACKAGE_PATH=/path/to/the/folder/holding/{name} (or give the package by path)",
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
            inside = bool(parts) if root.is_package else any(  # a package as deep as find_package looks
                _exists_at(root.handle, os.path.join(*parts[:depth], PACKAGE_MARKER))
                for depth in range(1, min(len(parts) - 1, SEARCH_DEPTH) + 1))
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
