"""What the ROS-style commands (`plem topic`, `service`, `action`, `node`) take on the command line.

Names and interface types as ROS 2 spells them, discovery timeouts, and the errors for a name discovery did
not show or a type that does not match it.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from typing import TYPE_CHECKING, Annotated

import typer

from plem.errors import ConfigError, PlemError, UsageError

if TYPE_CHECKING:
    from plem.middleware.node import Node
    from plem.middleware.types import InterfaceLibrary

#: Discovery window of the commands that list what exists (`list`, `info`).
LIST_TIMEOUT_S = 1.5

#: Longest `--timeout` or `--duration` (30 days): DDS waits are counted in int64 nanoseconds.
MAX_SECONDS = 30 * 24 * 3600
#: The interface kinds a TYPE argument names, and the part of the type that holds what the command fills in.
_KINDS = {"msg": ("message", ""), "srv": ("service", "_Request"), "action": ("action", "_Goal")}
#: The services inside an action, whose types ROS 2 names pkg/action/Name_SendGoal and pkg/action/Name_GetResult.
ACTION_SERVICES = ("_SendGoal", "_GetResult")


def seconds(value: float | None, param: typer.CallbackParam) -> float | None:
    """A `--timeout`/`--duration` as given; NaN, infinite, negative or huge seconds are a usage error naming it."""
    if value is not None and not 0 <= value <= MAX_SECONDS:   # false for NaN too
        flag = param.opts[0]
        raise UsageError(f"{flag} must be a number of seconds from 0 to {MAX_SECONDS}",
                         what=f"{flag} SECONDS: a finite number from 0 to {MAX_SECONDS} (30 days)",
                         why=f"{flag} is {value}", how=f"give {flag} a number of seconds, e.g. {flag} 5")
    return value


ListTimeout = Annotated[float, typer.Option("--timeout", callback=seconds, help="Seconds of discovery.")]


# -- names and types given on the command line -----------------------------------------------------------
def ros_name(name: str, kind: str) -> str:
    """The absolute ROS 2 name of a TOPIC, SERVICE, ACTION or NODE argument (a leading '/' may be left out)."""
    from plem.middleware import names

    try:
        return names.check_name(name if name.startswith("/") else f"/{name}")
    except ConfigError as error:
        raise UsageError(f"{kind} '{name}' is not a valid ROS 2 name", what=error.what, why=error.why,
                         how=f"give the {kind}'s absolute name, e.g. /indy/joint_states; list them with "
                             f"`plem {kind} list`") from None


def interface_type(library: InterfaceLibrary, given: str, kind: str) -> str:
    """The full name (`pkg/KIND/Name`) of a TYPE argument of `kind` msg, srv or action; `pkg/Name` may leave the
    kind out, and a service may be one of an action's (`pkg/action/Name_SendGoal`, as `plem service list -t`
    shows them). A malformed name, one of another kind or one the library does not know is a usage error."""
    label, part = _KINDS[kind]
    tokens = given.split("/")
    if len(tokens) == 2:
        tokens.insert(1, kind)
    ros_type = "/".join(tokens)
    of_action = kind == "srv" and tokens[1:2] == ["action"] and tokens[-1].endswith(ACTION_SERVICES)
    if len(tokens) != 3 or (tokens[1] != kind and not of_action) or not all(tokens):
        raise UsageError(f"'{given}' is not a ROS 2 {label} type", what=f"a {label} type as pkg/{kind}/Name",
                         why=f"got '{given}'",
                         how=f"e.g. {_example(kind)}; `plem {_command(kind)} list -t` shows each one's type")
    if not library.known(ros_type + part):
        package = tokens[0]
        same_package = sorted({known.removesuffix(part) for known in library.store.fielddefs
                               if known.startswith(f"{package}/{kind}/") and known.endswith(part)})
        if same_package:
            close = difflib.get_close_matches(ros_type, same_package, n=1)
            why = f"{package} has no {label} {tokens[2]}" + (f" (did you mean {close[0]}?)" if close else "") \
                + f"; its {label}s: {listed(same_package)}"
        else:
            packages = sorted({known.split("/")[0] for known in library.store.fielddefs if f"/{kind}/" in known})
            why = f"no package {package} with {label}s; packages with {label}s: {', '.join(packages)}"
        raise UsageError(f"{label} type {ros_type} is not known to plem",
                         what=f"a {label} type of plem's interface library", why=why,
                         how=f"check the spelling, or add the .{kind} definition under "
                             f"src/plem/middleware/interfaces/{package}/{kind}/")
    return ros_type


def _example(kind: str) -> str:
    return {"msg": "std_msgs/msg/String", "srv": "controller_manager_msgs/srv/ListControllers",
            "action": "plem_msgs/action/SetMode"}[kind]


def _command(kind: str) -> str:
    return {"msg": "topic", "srv": "service", "action": "action"}[kind]


def listed(items: list[str], limit: int = 10) -> str:
    """Up to `limit` items, comma-separated, for an error's WHY."""
    return ", ".join(items[:limit]) + (", ..." if len(items) > limit else "") if items else "none"


def not_found(kind: str, name: str, node: Node, timeout: float, seen: Iterable[str]) -> PlemError:
    """The error for a topic, service, action or node that discovery did not show: what exists, what is close."""
    from plem.middleware.graph import hidden

    known = sorted(seen if hidden(name) else (item for item in seen if not hidden(item)))
    close = difflib.get_close_matches(name, known, n=3)
    why = f"none announced itself within {timeout} s ({node.settings.describe()}); {kind}s seen: {listed(known)}"
    return PlemError(f"unknown {kind} {name} on ROS_DOMAIN_ID={node.domain_id}",
                     what=f"a {kind} {name} on the domain",
                     why=why + (f"; did you mean {' or '.join(close)}?" if close else ""),
                     how=f"list them with `plem {kind} list`, use the robot's ROS_DOMAIN_ID and "
                         "ROS_AUTOMATIC_DISCOVERY_RANGE, or wait longer with --timeout")


def wrong_type(kind: str, name: str, given: str, announced: list[str]) -> PlemError:
    """The error for a service or action whose endpoints announce another type than the one given."""
    return PlemError(f"{kind} {name} is not of type {given}", what=f"TYPE as the {kind}'s type",
                     why=f"{name} announces {', '.join(announced)}",
                     how=f"give {announced[0]}; `plem {kind} list -t` shows each {kind}'s type")
