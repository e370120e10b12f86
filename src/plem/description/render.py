"""Rendering xacro files with no ROS installed: `$(find pkg)` goes through plem's package search path."""

from __future__ import annotations

import contextlib
import io
import os
from collections.abc import Callable
from pathlib import Path
from xml.dom.minidom import Document
from xml.parsers.expat import ExpatError

import xacro
from xacro import substitution_args

from plem.core.paths import PACKAGE_MARKER, find_package, pinned_packages
from plem.description.problems import DescriptionError
from plem.errors import PlemError

class XacroArgumentsError(DescriptionError):
    """The xacro file only renders when given arguments, which the protocol does not allow."""


WRAPPER_EXAMPLE = (
    "<!-- my_robot.urdf.xacro -->\n"
    '<xacro:include filename="base_robot.urdf.xacro"/>\n'
    '<xacro:base_robot name="my_robot" prefix="" eye="false"/>'
)


def _find_share(package: str) -> str:
    return str(find_package(package))


# xacro resolves $(find pkg) through ament_index, which needs a ROS install; plem answers it instead.
substitution_args._eval_find = _find_share


def render_xacro(path: Path, mappings: dict[str, str] | None = None) -> str:
    """The XML that `xacro PATH [name:=value ...]` prints; failures are DescriptionErrors with the fix."""
    return _render(path, lambda: xacro.process_file(os.fspath(path), mappings=dict(mappings or {})))


def _render(path: Path, process: Callable[[], Document]) -> str:
    stack_before = list(xacro.filestack or [])
    try:
        with contextlib.redirect_stderr(io.StringIO()), pinned_packages(_owning_package(path)):
            return process().toxml()
    except PlemError as error:
        raise error from None
    except xacro.XacroException as error:
        raise _xacro_error(path, error) from None
    except substitution_args.SubstitutionException as error:
        raise _xacro_error(path, error) from None
    except ExpatError as error:
        raise DescriptionError(
            f"Invalid XML in {path.name}",
            what=f"well-formed XML in {path} and the files it includes",
            why=f"{_current_file(path)}: {error}",
            how="fix the XML at that line (unclosed or mismatched tags, bad characters)",
        ) from None
    except RuntimeError as error:
        if "xacro:arg" in str(error) and "default" in str(error):
            raise _needs_arguments(path, str(error)) from None
        raise _xacro_error(path, error) from None
    except (OSError, ValueError, TypeError, KeyError, IndexError, AttributeError) as error:
        raise _xacro_error(path, error) from None
    finally:
        xacro.filestack = stack_before


def _owning_package(path: Path) -> dict[str, Path]:
    """The package a file lives in (nearest folder with package.xml), so `$(find` itself`)` always works."""
    for folder in Path(path).resolve().parents:
        if (folder / PACKAGE_MARKER).is_file():
            return {folder.name: folder}
    return {}


def _current_file(default: Path) -> str:
    stack = [f for f in (xacro.filestack or []) if f]
    return str(stack[-1]) if stack else str(default)


def _needs_arguments(path: Path, detail: str) -> XacroArgumentsError:
    return XacroArgumentsError(
        f"{path.name} needs arguments to render",
        what="a xacro file that renders with no arguments (`xacro FILE`), as UR, Franka and MoveIt 2 packages do",
        why=f"{_current_file(path)}: {detail}",
        how="give every xacro:arg a default, or make a wrapper xacro that supplies them:\n" + WRAPPER_EXAMPLE,
    )


def _xacro_error(path: Path, error: BaseException) -> DescriptionError:
    cause = getattr(error, "exc", None)
    if isinstance(cause, PlemError):
        return DescriptionError(cause.summary, what=cause.what, why=f"while rendering {path}: {cause.why}",
                                how=cause.how)
    if isinstance(error, substitution_args.ArgException) or isinstance(cause, substitution_args.ArgException):
        return _needs_arguments(path, f"Undefined substitution argument {cause or error}")
    message = " ".join(str(error).split())
    return DescriptionError(
        f"xacro failed on {path.name}",
        what=f"{path} to render with xacro",
        why=f"{_current_file(path)}: {message}",
        how="fix the xacro expression or include named there (render it alone with `xacro FILE` to see the context)",
    )
