"""Settings that can come from text (launch arguments, environment variables) and how to parse them.

One table of `Setting`s drives environment parsing, launch-argument parsing and `plem config show`, so
a name, its variable and its expected form are written down once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from plem.errors import ConfigError


def parse_int(text: str) -> int:
    """A whole number; '80', '-3' and '0x10' are accepted, '8.5', 'abc' and digits other than 0-9 ('²') are not."""
    text = text.strip()
    if not text.isascii():
        raise ValueError(f"{text!r} holds characters other than ASCII digits")
    return int(text, 0)


def parse_text(text: str) -> str:
    """A non-empty string with surrounding blanks removed."""
    value = text.strip()
    if not value:
        raise ValueError("empty")
    return value


def parse_optional_text(text: str) -> str | None:
    """A string, where an empty value means 'not set'."""
    return text.strip() or None


def parse_int_list(text: str) -> list[int]:
    """Comma-separated whole numbers, optionally in brackets: '1,2,3' or '[1, 2, 3]'."""
    body = text.strip().removeprefix("[").removesuffix("]")
    return [parse_int(item) for item in body.split(",")] if body.strip() else []


@dataclass(frozen=True)
class Setting:
    """A configuration field that can be given as text, with where it may come from."""

    name: str
    parse: Callable[[str], Any]
    expected: str
    description: str
    env: str | None = None
    launch: str | None = None

    def from_text(self, text: str, origin: str) -> Any:
        """Parse `text`; a malformed value is a ConfigError naming `origin` and the expected form."""
        try:
            return self.parse(text)
        except ValueError:
            raise ConfigError(
                f"Malformed value for {origin}",
                what=f"{origin} as {self.expected}",
                why=f"{origin} is {text!r}",
                how=f"set {origin} to {self.expected}",
            ) from None
