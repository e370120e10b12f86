"""Description packages: discovery, xacro rendering, validation, auto-generation, scaffolding, built-ins."""

from plem.description.discover import DescriptionFiles, discover, locate_package, package_for_launch
from plem.description.generate import ResolvedDescription, resolve_description
from plem.description.problems import DescriptionError, Problem, Severity
from plem.description.render import render_xacro
from plem.description.scaffold import create_package
from plem.description.validate import Stage, ValidationReport, require_valid, validate_package

__all__ = [
    "DescriptionError", "DescriptionFiles", "Problem", "ResolvedDescription", "Severity", "Stage",
    "ValidationReport", "create_package", "discover", "locate_package", "package_for_launch", "render_xacro",
    "require_valid", "resolve_description", "validate_package",
]
