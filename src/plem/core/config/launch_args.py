"""Launch-style arguments: `name:=value` as `ros2 launch` takes them, plus `--name value` and `--name=value`."""

from __future__ import annotations

import difflib
from collections.abc import Collection, Sequence

from plem.errors import UsageError


def _unknown(name: str, known: Collection[str]) -> UsageError:
    close = difflib.get_close_matches(name, list(known), n=1)
    hint = f"did you mean {close[0]}:=...? " if close else ""
    return UsageError(
        f"Unknown argument '{name}'",
        what=f"one of: {', '.join(sorted(known))}",
        why=f"'{name}' is not an argument of this command",
        how=f"{hint}see --help for the arguments and their defaults",
    )


def parse_launch_arguments(tokens: Sequence[str], known: Collection[str]) -> dict[str, str]:
    """Turn command-line tokens into {name: text}; unknown names, repeats and malformed tokens are usage errors."""
    parsed: dict[str, str] = {}
    index = 0
    while index < len(tokens):
        token = tokens[index]
        if ":=" in token:
            name, _, value = token.partition(":=")
        elif token.startswith("--") and len(token) > 2:
            name, has_value, value = token[2:].partition("=")
            name = name.replace("-", "_")
            if name not in known:
                raise _unknown(name, known)
            if not has_value:
                if index + 1 >= len(tokens):
                    raise UsageError(
                        f"Missing value for --{name}",
                        what=f"--{name} VALUE, --{name}=VALUE or {name}:=VALUE",
                        why=f"--{name} is the last word on the command line",
                        how=f"give a value, e.g. {name}:=<value>",
                    )
                index += 1
                value = tokens[index]
        else:
            raise UsageError(
                f"Cannot read argument '{token}'",
                what="arguments as name:=value (like ros2 launch) or --name value",
                why=f"'{token}' has neither ':=' nor a leading '--'",
                how=f"write it as {token}:=<value> if it is a name, or name:={token} if it is a value",
            )
        name = name.strip()
        if name not in known:
            raise _unknown(name, known)
        if name in parsed:
            raise UsageError(
                f"Argument '{name}' given twice",
                what="each argument at most once",
                why=f"{name} is given as {parsed[name]!r} and as {value!r}",
                how=f"keep one {name}:=... on the command line",
            )
        parsed[name] = value
        index += 1
    return parsed
