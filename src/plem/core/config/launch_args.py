"""Launch-style arguments: `name:=value` as `ros2 launch` takes them, plus `--name value` and `--name=value`.

Their numbers are plain ASCII decimals (`whole_number`, `decimal_number`, `number_list`), their paths may start
with ~ or ~user (`check_home`); `shown` quotes a value in a message.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Collection, Sequence
from pathlib import Path

from plem.errors import ConfigError, UsageError


def _unknown(name: str, known: Collection[str]) -> UsageError:
    close = difflib.get_close_matches(name, list(known), n=1)
    hint = f"did you mean {close[0]}:=...? " if close else ""
    return UsageError(
        f"Unknown argument '{shown(name)}'",
        what=f"one of: {', '.join(sorted(known))}",
        why=f"'{shown(name)}' is not an argument of this command",
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
            word = shown(token)
            raise UsageError(
                f"Cannot read argument '{word}'",
                what="arguments as name:=value (like ros2 launch) or --name value",
                why=f"'{word}' has neither ':=' nor a leading '--'",
                how=f"write it as {word}:=<value> if it is a name, or name:={word} if it is a value",
            )
        name = name.strip()
        if name not in known:
            raise _unknown(name, known)
        if name in parsed:
            raise UsageError(
                f"Argument '{name}' given twice",
                what="each argument at most once",
                why=f"{name} is given as '{shown(parsed[name])}' and as '{shown(value)}'",
                how=f"keep one {name}:=... on the command line",
            )
        parsed[name] = value
        index += 1
    return parsed


#: Plain numbers as launch arguments take them: ASCII digits only (Python's int() and float() would also take
#: other scripts' digits, '1_000', '1e3', 'nan' or 'inf'), at most 18 digits on each side of the point.
_WHOLE = re.compile(r"[0-9]{1,18}")
_DECIMAL = re.compile(r"[0-9]{1,18}(?:\.[0-9]{0,18})?|\.[0-9]{1,18}")
_SIGNED = re.compile(r"[+-]?(?:[0-9]{1,18}(?:\.[0-9]{0,18})?|\.[0-9]{1,18})")
#: The longest part of a value quoted in a message.
SHOWN_CHARACTERS = 60


def whole_number(text: str) -> int | None:
    """`text` as a whole number written with the ASCII digits 0-9 only ('80'), else None."""
    return int(text) if _WHOLE.fullmatch(text) else None


def decimal_number(text: str) -> float | None:
    """`text` as a finite number written with ASCII digits and at most one point ('2.5', '50'), else None."""
    return float(text) if _DECIMAL.fullmatch(text) else None


def number_list(text: str) -> list[float] | None:
    """`text` as comma-separated numbers, each with an optional sign, ASCII digits and at most one point
    ('0, -1.57,0.5'), else None."""
    items = [item.strip() for item in text.split(",")]
    return [float(item) for item in items] if all(_SIGNED.fullmatch(item) for item in items) else None


def shown(text: str) -> str:
    """A value as a message quotes it: control characters escaped, cut after SHOWN_CHARACTERS with the length."""
    quoted = text if text.isprintable() else repr(text)[1:-1]
    if len(quoted) <= SHOWN_CHARACTERS:
        return quoted
    return f"{quoted[:SHOWN_CHARACTERS]}... ({len(text)} characters)"


def check_home(text: str, spelled: str) -> None:
    """A ConfigError when the path `text` starts with ~user of a user the system does not know.

    `spelled` is how the command line gave it (`robots:=~ann/robots.yaml`, or the word itself), for the message.
    """
    try:
        Path(text).expanduser()
    except RuntimeError:
        user = text[1:].partition("/")[0]
        raise ConfigError(f"unknown home directory in {shown(spelled)}",
                          what="a path whose ~ or ~USER names the home directory of a user of this system",
                          why=f"there is no user '{shown(user)}'" if user else "$HOME is not set",
                          how="write the path with ~/ or ~USER/ of an existing user, or as an absolute path") from None
