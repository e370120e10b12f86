"""Command-line values converted without pydantic wherever the conversion is plain.

typer converts every parameter value through a pydantic TypeAdapter that it builds on first use; importing
pydantic and building the adapters costs more than most plem commands take to run. For the types plem's
commands declare, a value that already has the parameter's type, a string for a `str`, a choice or a path, and
a plain decimal number are converted here with the same result typer's conversion gives. Everything else, and
every value that does not convert, goes through typer's own conversion, so what is accepted and every error
message stay typer's.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any, get_args, get_origin

import typer.core
from typer._click import Context
from typer._click.exceptions import BadParameter
from typer._coercion import RuntimeParam, TypeDescriptor, build_runtime_param
from typer._param_types import coerce_cli_choice, coerce_cli_path, lenient_issubclass
from typer.models import ParameterInfo

_INTEGER = re.compile(r"-?[0-9]+")
_DECIMAL = re.compile(r"-?[0-9]+(?:\.[0-9]+)?")


class _NotPlain(Exception):
    """The value is not one converted here; typer's conversion decides."""


def _number(annotation: type[Any], info: ParameterInfo, value: Any) -> Any:
    """An int or float value as typer gives it: the number itself, or a plain decimal string's value, in bounds."""
    if type(value) is annotation:
        number = value
    elif isinstance(value, str) and (_INTEGER if annotation is int else _DECIMAL).fullmatch(value):
        number = annotation(value)
    else:
        raise _NotPlain
    if info.clamp or (info.min is not None and number < info.min) or (info.max is not None and number > info.max):
        raise _NotPlain
    return number


def _convert(annotation: Any, info: ParameterInfo, value: Any, param: typer.core._TyperParameter, ctx: Context) -> Any:
    """`value` converted to `annotation` as typer's conversion would, or _NotPlain (or its error) when not plain."""
    if info.parser is not None:
        raise _NotPlain
    if get_origin(annotation) is list and isinstance(value, (list, tuple)):
        (item,) = get_args(annotation)
        return [_convert(item, info, element, param, ctx) for element in value]
    if lenient_issubclass(annotation, Enum):
        return coerce_cli_choice(value, choices=tuple(annotation), case_sensitive=info.case_sensitive, ctx=ctx)
    if annotation in (int, float):
        return _number(annotation, info, value)
    if annotation is str and isinstance(value, str):
        return value
    if annotation is Path and info.path_type is None and isinstance(value, (str, Path)):
        return coerce_cli_path(Path(value), info, path_type=Path, param=param, ctx=ctx)
    raise _NotPlain


@dataclass(frozen=True)
class PlainRuntimeParam(RuntimeParam):
    """typer's runtime conversion of one parameter, done directly for plain values (see the module docstring)."""

    def _coerce_value(self, value: Any, param: typer.core._TyperParameter, ctx: Context) -> Any:
        try:
            return _convert(self.annotation, self.parameter_info, value, param, ctx)
        except (_NotPlain, ValueError, BadParameter):
            return build_runtime_param(param.type_descriptor)._coerce_value(value, param=param, ctx=ctx)


def plain_runtime_param(descriptor: TypeDescriptor) -> RuntimeParam:
    """A parameter's runtime conversion: the direct one for plain values, typer's for the rest."""
    return PlainRuntimeParam(annotation=descriptor.annotation, parameter_info=descriptor.parameter_info)


def install() -> None:
    """Have typer build every parameter's runtime conversion (on its first value) with plain_runtime_param."""
    typer.core.build_runtime_param = plain_runtime_param  # type: ignore[attr-defined]  # the name typer.core calls
