"""Robot serial numbers: they name profile files, so they must be safe file names."""

from __future__ import annotations

import re
from typing import Any

MAX_SERIAL_LENGTH = 128
_SAFE_SERIAL = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")


def serial_problem(serial: Any) -> str | None:
    """Why `serial` cannot name a profile file (e.g. '../x', 'a/b', ''), or None when it can."""
    if not isinstance(serial, str):
        return f"it is {type(serial).__name__}, not text"
    if not serial:
        return "it is empty"
    if len(serial) > MAX_SERIAL_LENGTH:
        return f"it is {len(serial)} characters long; at most {MAX_SERIAL_LENGTH} are allowed"
    if ".." in serial or not _SAFE_SERIAL.fullmatch(serial):
        return "only letters, digits, '.', '_' and '-' are allowed, starting with a letter or digit, and no '..'"
    return None
