"""Description packages: discovery, xacro rendering, validation, auto-generation, scaffolding, built-ins.

The names of the heavier modules are imported on first use, so importing one module of this package (say
`plem.description.validate`) does not import the others.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from plem.description.discover import DescriptionFiles, discover, locate_package, package_for_launch
from plem.description.problems import DescriptionError, Problem, Severity

if TYPE_CHECKING:
    from plem.description.generate import ResolvedDescription, resolve_description
    from plem.description.render import render_xacro
    from plem.description.scaffold import create_package
    from plem.description.validate import Stage, ValidationReport, require_valid, validate_package

_LAZY = {"ResolvedDescription": "generate", "resolve_description": "generate", "render_xacro": "render",
         "create_package": "scaffold", "Stage": "validate", "ValidationReport": "validate",
         "require_valid": "validate", "validate_package": "validate"}

__all__ = [
    "DescriptionError", "DescriptionFiles", "Problem", "ResolvedDescription", "Severity", "Stage",
    "ValidationReport", "create_package", "discover", "locate_package", "package_for_launch", "render_xacro",
    "require_valid", "resolve_description", "validate_package",
]


def __getattr__(name: str) -> Any:
    """A name of __all__ not imported yet, from its module."""
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
