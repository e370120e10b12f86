"""Errors a user can cause, each rendered as ERROR/WHAT/WHY/HOW.

One renderer serves the CLI and the logs, so a message reads the same wherever it shows up.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from enum import IntEnum
from typing import Any


def _indent_continuation(text: str) -> str:
    """Indent every line after the first so multi-line fields stay readable under their label."""
    return text.replace("\n", "\n      ")


class PlemError(Exception):
    """A problem the user can fix: a one-line summary plus what was expected, what was found and the fix."""

    exit_code = 1

    def __init__(self, summary: str, *, what: str, why: str, how: str) -> None:
        super().__init__(summary)
        self.summary = summary
        self.what = what
        self.why = why
        self.how = how

    def render(self) -> str:
        """The four-line WHAT/WHY/HOW form printed by the CLI and written to logs."""
        return (
            f"ERROR: {self.summary}\n"
            f"WHAT: {_indent_continuation(self.what)}\n"
            f"WHY: {_indent_continuation(self.why)}\n"
            f"HOW: {_indent_continuation(self.how)}"
        )

    def log_text(self) -> str:
        """The rendered error without its `ERROR: ` label, for a log line whose format names the level already."""
        return self.render().removeprefix("ERROR: ")

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready form for `--format json` output."""
        return {
            "error": type(self).__name__,
            "summary": self.summary,
            "what": self.what,
            "why": self.why,
            "how": self.how,
        }

    def __str__(self) -> str:
        return self.render()


class UsageError(PlemError):
    """The command line itself is wrong (unknown argument, malformed `name:=value`)."""

    exit_code = 2


class ConfigError(PlemError):
    """A configuration value, file or environment variable is invalid."""


class ProfileError(PlemError):
    """A robot profile is missing, unreadable or invalid."""


class PackageNotFoundError(PlemError):
    """A package named by the user is not on the package search path."""


class MultipleErrors(PlemError):
    """Several problems found by one validation pass, reported together rather than one at a time."""

    def __init__(self, errors: Sequence[PlemError], context: str = "") -> None:
        self.errors = list(errors)
        summary = f"{len(self.errors)} problems" + (f" in {context}" if context else "")
        super().__init__(
            summary,
            what="; ".join(e.what for e in self.errors),
            why="; ".join(e.why for e in self.errors),
            how="; ".join(e.how for e in self.errors),
        )
        self.exit_code = max(e.exit_code for e in self.errors)

    def render(self) -> str:
        """The count, then each problem in its own four-line block."""
        header = f"ERROR: {self.summary}"
        return header + "\n\n" + "\n\n".join(e.render() for e in self.errors)

    def to_dict(self) -> dict[str, Any]:
        """The summary and every problem's own JSON form, for `--format json` output."""
        return {"error": "MultipleErrors", "summary": self.summary, "errors": [e.to_dict() for e in self.errors]}


def raise_collected(errors: Iterable[PlemError], context: str = "") -> None:
    """Raise nothing, the one error, or all of them together, so validators can collect before reporting."""
    errors = list(errors)
    if len(errors) == 1:
        raise errors[0]
    if errors:
        raise MultipleErrors(errors, context)


class CommandRejected(PlemError):
    """A motion or mode command was refused before it reached the drives; the arm did not move."""


class RobotFault(PlemError):
    """The robot is in FAULT (or faulted while a command ran); the message carries the decoded reason."""


class MoveItCode(IntEnum):
    """moveit_msgs/MoveItErrorCodes values, which planning results carry on every surface."""

    SUCCESS = 1
    FAILURE = 99999
    PLANNING_FAILED = -1
    INVALID_MOTION_PLAN = -2
    CONTROL_FAILED = -4
    TIMED_OUT = -6
    PREEMPTED = -7
    START_STATE_IN_COLLISION = -10
    GOAL_IN_COLLISION = -12
    GOAL_CONSTRAINTS_VIOLATED = -14
    INVALID_GROUP_NAME = -15
    INVALID_GOAL_CONSTRAINTS = -16
    INVALID_ROBOT_STATE = -17
    INVALID_LINK_NAME = -18
    INVALID_OBJECT_NAME = -19
    FRAME_TRANSFORM_FAILURE = -21
    START_STATE_INVALID = -26
    GOAL_STATE_INVALID = -27
    UNRECOGNIZED_GOAL_TYPE = -28
    NO_IK_SOLUTION = -31


class PlanningError(PlemError):
    """A planning request that cannot be served as asked; `code` is MoveIt's MoveItErrorCodes value for it."""

    def __init__(self, summary: str, *, what: str, why: str, how: str,
                 code: MoveItCode = MoveItCode.PLANNING_FAILED) -> None:
        super().__init__(summary, what=what, why=why, how=how)
        self.code = code

    def to_dict(self) -> dict[str, Any]:
        """The JSON form, with the MoveIt error code."""
        return {**super().to_dict(), "code": int(self.code)}
