"""Rendering xacro files of description packages, which are untrusted input, without ROS installed.

`render_xacro` is the one entry point: xacro runs in a limited child process, without root when plem has it
(plem.description.sandbox) and reads files only through a PackageReader. xacro's hooks are replaced so that
`$(find pkg)` uses plem's package search path, `${...}` and `$(eval ...)` cannot reach Python internals,
`$(eval ...)` has a handful of builtins, `$(env VAR)` is refused and `$(optenv VAR DEFAULT)` gives DEFAULT.
"""

from __future__ import annotations

import ast
import builtins
import contextlib
import io
import os
from contextvars import ContextVar
from functools import lru_cache, partial
from pathlib import Path
from types import CodeType
from typing import IO, Any
from xml.dom import expatbuilder  # noqa: F401 - imported here: the sandboxed child may not read Python's library
from xml.dom.minidom import Document
from xml.parsers.expat import ExpatError

import xacro
from xacro import substitution_args

from plem.core.paths import (
    PACKAGE_MARKER,
    PackageAccessError,
    PackageReader,
    find_package,
    is_file,
    package_name,
    pinned_packages,
)
from plem.description.model import MAX_XML_BYTES, dtd_refused, too_large
from plem.description.problems import DescriptionError
from plem.description.sandbox import run_sandboxed
from plem.errors import PlemError


class XacroArgumentsError(DescriptionError):
    """The xacro file only renders when given arguments, which the protocol does not allow."""


WRAPPER_EXAMPLE = (
    "<!-- my_robot.urdf.xacro -->\n"
    '<xacro:include filename="base_robot.urdf.xacro"/>\n'
    '<xacro:base_robot name="my_robot" prefix="" eye="false"/>'
)
# Attribute names that lead from a value to Python internals: dunders and private names, the frames and code of
# generators and coroutines, a class's bases, and str.format (its format string reads attributes by itself).
UNSAFE_ATTRIBUTE_PREFIXES = ("_", "gi_", "cr_", "ag_", "f_", "tb_", "co_")
UNSAFE_ATTRIBUTES = frozenset({"mro", "format", "format_map"})
# xacro offers these as python.type and python.vars; both hand out any object's internals by name.
REMOVED_SYMBOLS = ("type", "vars")
EVAL_BUILTINS = {name: getattr(builtins, name) for name in
                 ("list", "dict", "map", "str", "float", "int", "bool", "len", "min", "max", "abs", "round")}

_reader: ContextVar[PackageReader | None] = ContextVar("package_reader", default=None)
_xacro_parse = xacro.parse


def render_xacro(path: Path, mappings: dict[str, str] | None = None) -> str:
    """The XML that `xacro PATH [name:=value ...]` prints; failures are DescriptionErrors with the fix.

    Rendering happens in the sandbox, a child process within memory, CPU-time and wall-clock limits, whoever
    runs plem; run as root, the child also gives up root.
    """
    path = Path(path)
    owner = _owning_package(path)
    package = next(iter(owner.values()), path.resolve().parent)
    with pinned_packages(owner), PackageReader([package]) as reader:
        work = partial(_render, path, dict(mappings or {}), reader)
        return run_sandboxed(work, task=f"rendering {path.name}", owner=package, keep_fds=reader.handles,
                             error_types=(DescriptionError, XacroArgumentsError, PackageAccessError))


def _render(path: Path, mappings: dict[str, str], reader: PackageReader) -> str:
    """xacro's output for `path`, reading through `reader`."""
    token = _reader.set(reader)
    try:
        with contextlib.redirect_stderr(io.StringIO()):
            document: Document = xacro.process_file(os.fspath(path), mappings=mappings)
            return document.toxml()
    except PlemError as error:
        raise error from None
    except xacro.XacroException as error:
        if isinstance(error.exc, MemoryError):
            raise error.exc from None  # the sandbox reports the memory limit
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
        _reader.reset(token)


def _owning_package(path: Path) -> dict[str, Path]:
    """The package a file lives in (nearest folder with package.xml), so `$(find` itself`)` always works."""
    for folder in Path(path).resolve().parents:
        if (folder / PACKAGE_MARKER).is_file():
            return {package_name(folder): folder}
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


# xacro's hooks. They are module globals of xacro, replaced once when plem renders anything.

def _find_share(package: str) -> str:
    """`$(find package)`: plem's package search path (xacro would ask ament_index, which needs ROS)."""
    reader = _reader.get()
    return str(find_package(package, exists=reader.is_file if reader is not None else is_file))


def _open(file: str | os.PathLike[str], mode: str = "r") -> IO[Any]:
    """The `open` xacro uses for the file it renders, includes and xacro.load_yaml: while plem renders, through
    the package reader and refused for a file above MAX_XML_BYTES (xacro would take minutes over it)."""
    reader = _reader.get()
    if reader is None:
        return builtins.open(file, mode)
    handle = reader.open(file, mode)
    size = os.fstat(handle.fileno()).st_size
    if size > MAX_XML_BYTES:
        handle.close()
        raise too_large(Path(file), size, rendered=False)
    return handle


def _parse(inp: Any, filename: str | None = None) -> Any:
    """xacro's parse of a file it renders or includes, refused when the file declares a DTD: its entities would
    reach robot_description, where another parser may read files or expand them without end."""
    document = _xacro_parse(inp, filename)
    if isinstance(document, Document) and document.doctype is not None:
        doctype = document.doctype
        raise dtd_refused(filename or _current_file(Path("the xacro file")),
                          f"<!DOCTYPE {doctype.name} [{doctype.internalSubset or ''}]>")
    return document


@lru_cache(maxsize=4096)
def _compiled(expression: str) -> CodeType:
    """The compiled expression, or a DescriptionError when it names a way into Python internals (macros repeat
    the same expressions, hence the cache)."""
    tree = ast.parse(expression.strip(), "<expression>", "eval")
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and (node.attr.startswith(UNSAFE_ATTRIBUTE_PREFIXES)
                                                or node.attr in UNSAFE_ATTRIBUTES):
            raise _refused_expression(expression, f".{node.attr}")
        if isinstance(node, ast.Name) and node.id.startswith("__"):
            raise _refused_expression(expression, node.id)
    return compile(tree, "<expression>", "eval")


def _refused_expression(expression: str, name: str) -> DescriptionError:
    return DescriptionError(
        f"xacro expression refused: {name}",
        what="${...} and $(eval ...) expressions that compute values: arithmetic, math functions, properties, "
             "xacro.load_yaml and indexing",
        why=f"'{expression.strip()}' uses {name}, which reaches Python internals",
        how="compute the value without it (for text, '%' formatting instead of str.format)",
    )


def _safe_eval(expression: str, symbols: dict[str, Any], local_symbols: dict[str, Any] | None = None) -> Any:
    """`${...}`: xacro's evaluation (no builtins, only its symbols) after the internals check."""
    code = _compiled(expression)
    symbols.update(__builtins__={})
    return eval(code, symbols, local_symbols)  # checked expression, no builtins


def _eval_substitution(expression: str, context: dict[str, Any]) -> str:
    """`$(eval ...)`: xacro's names (arg, dirname, math, find, optenv) and EVAL_BUILTINS, after the internals check."""
    arguments = context.setdefault("arg", {})
    functions = {
        **substitution_args._eval_dict,
        "arg": lambda name: substitution_args.convert_value(substitution_args._eval_arg(name, arguments), "auto"),
        "dirname": lambda: substitution_args._eval_dirname(context.get("filename")),
    }
    return str(eval(_compiled(expression), {"__builtins__": EVAL_BUILTINS},
                    substitution_args._DictWrapper(arguments, functions)))


def _refuse_env(name: str) -> str:
    """`$(env VAR)`: refused, so no environment value ends up in robot_description."""
    raise DescriptionError(
        f"$(env {name}) is not allowed in a description",
        what="a description that renders the same wherever it runs, without reading the environment",
        why=f"$(env {name}) would copy the variable {name} into robot_description, which every reader on the "
            "network sees",
        how=f"put the value in the package (a xacro:property), or use $(optenv {name} DEFAULT), which plem renders "
            "as DEFAULT",
    )


def _optenv_default(name: str, default: str = "") -> str:
    """`$(optenv VAR DEFAULT)`: always DEFAULT, so no environment value ends up in robot_description."""
    return default


def _install_hooks() -> None:
    """Replace xacro's lookups with the ones above, once, when this module is first imported."""
    substitution_args._eval_find = _find_share
    substitution_args._eval_env = _refuse_env
    substitution_args._eval_optenv = _optenv_default
    substitution_args._eval = _eval_substitution
    substitution_args._eval_dict.update(find=_find_share, env=_refuse_env, optenv=_optenv_default)
    xacro.safe_eval = _safe_eval
    xacro.open = _open
    xacro.parse = _parse
    for name in REMOVED_SYMBOLS:
        xacro._global_symbols["python"].pop(name, None)


_install_hooks()
