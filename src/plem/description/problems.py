"""Problems found in a description package: errors and warnings, each a WHAT/WHY/HOW with a place."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

from plem.errors import PlemError, raise_collected


class DescriptionError(PlemError):
    """A description package cannot be used as it is."""


class Severity(StrEnum):
    """How a problem counts: an error stops launch and validation, a warning is only reported."""

    ERROR = "error"
    WARNING = "warning"


@dataclass(frozen=True)
class Problem:
    """One finding. `code` is a stable identifier (e.g. `limits.missing_joint`) for tools and tests."""

    severity: Severity
    code: str
    summary: str
    what: str
    why: str
    how: str
    file: Path | None = None
    line: int | None = None

    @property
    def location(self) -> str:
        """`file:line`, the file alone when the line is unknown, or empty when the problem has no file."""
        if self.file is None:
            return ""
        return f"{self.file}:{self.line}" if self.line else str(self.file)

    def as_error(self) -> DescriptionError:
        """The problem as a raisable error, its WHY prefixed with the location unless it already names the file."""
        known = self.location and (str(self.file) in self.why)
        why = f"{self.location}: {self.why}" if self.location and not known else self.why
        return DescriptionError(self.summary, what=self.what, why=why, how=self.how)

    def render(self) -> str:
        """WHAT/WHY/HOW text headed ERROR or WARNING by severity."""
        text = self.as_error().render()
        return text if self.severity is Severity.ERROR else "WARNING" + text.removeprefix("ERROR")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields for `plem validate --format json`: severity, code, place, summary and WHAT/WHY/HOW."""
        return {"severity": self.severity.value, "code": self.code, "file": str(self.file) if self.file else None,
                "line": self.line, **{k: v for k, v in self.as_error().to_dict().items() if k != "error"}}


@dataclass
class Findings:
    """Problems collected by the checks, in the order they were found."""

    problems: list[Problem] = field(default_factory=list)

    def error(self, code: str, summary: str, *, what: str, why: str, how: str,
              file: Path | None = None, line: int | None = None) -> None:
        """Record a problem that makes the package unusable."""
        self.problems.append(Problem(Severity.ERROR, code, summary, what, why, how, file, line))

    def add(self, code: str, error: PlemError, file: Path | None = None) -> None:
        """Record a PlemError raised by a reader as an error problem, keeping the line it carries."""
        self.error(code, error.summary, what=error.what, why=error.why, how=error.how, file=file,
                   line=getattr(error, "line", None))

    def warning(self, code: str, summary: str, *, what: str, why: str, how: str,
                file: Path | None = None, line: int | None = None) -> None:
        """Record a problem that is reported but lets the package be used."""
        self.problems.append(Problem(Severity.WARNING, code, summary, what, why, how, file, line))

    @property
    def errors(self) -> list[Problem]:
        """The error problems, in the order found."""
        return [p for p in self.problems if p.severity is Severity.ERROR]

    @property
    def warnings(self) -> list[Problem]:
        """The warning problems, in the order found."""
        return [p for p in self.problems if p.severity is Severity.WARNING]

    def codes(self) -> list[str]:
        """The code of every problem, in order (repeated when a code was found more than once)."""
        return [p.code for p in self.problems]

    def raise_errors(self, context: str) -> None:
        """Raise every error together (a single one as itself); warnings never raise."""
        raise_collected([p.as_error() for p in self.errors], context)
