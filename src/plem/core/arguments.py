"""Run-time checks of the arguments of plem's public Python functions, matching their type hints.

mypy sees the hints; a script that passes something else (a string for a timeout, None for positions, a number
too large for a float) gets an ArgumentError saying what was expected, before anything deep inside fails on it.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np

from plem.errors import CommandRejected
from plem.ipc.request_bounds import shown


class ArgumentError(CommandRejected, TypeError):
    """An argument of a public function has the wrong type or an unusable value; nothing was done (the arm did not
    move)."""


def refused(name: str, expected: str, value: Any, how: str | None = None) -> ArgumentError:
    """The error for `value` given as `name` where `expected` was expected."""
    return ArgumentError(f"{name} is not {expected}", what=f"{name} as {expected}",
                         why=f"got {shown(repr(value), 80)} ({type(value).__name__})",
                         how=how or f"pass {name} as {expected}")


def is_real(value: Any) -> bool:
    """A real number that is not a bool: int, float or a numpy scalar of either."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def real(value: Any, name: str) -> float:
    """`value` as a float, finite or not; a non-number, or an integer too large for a float, is an ArgumentError."""
    if not is_real(value):
        raise refused(name, "a number", value)
    try:
        return float(value)
    except OverflowError:
        raise refused(name, "a number a float can hold (within ±1.8e308)", value) from None


def seconds(value: Any, name: str) -> float:
    """A finite, non-negative number of seconds (a timeout or a duration)."""
    result = real(value, name)
    if not (math.isfinite(result) and result >= 0.0):
        raise refused(name, "a finite number of seconds >= 0", value,
                       f"pass {name} as seconds >= 0 (None, where allowed, waits without limit)")
    return result


def optional_seconds(value: Any, name: str) -> float | None:
    """None (no limit) or `seconds`."""
    return None if value is None else seconds(value, name)


def whole(value: Any, name: str, low: int = 0) -> int:
    """An int (not a bool) of at least `low`."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < low:
        raise refused(name, f"a whole number >= {low}", value)
    return int(value)


def flag(value: Any, name: str) -> bool:
    """A bool."""
    if not isinstance(value, (bool, np.bool_)):
        raise refused(name, "True or False", value)
    return bool(value)


def text(value: Any, name: str) -> str:
    """A str."""
    if not isinstance(value, str):
        raise refused(name, "a string", value)
    return value


def instance(value: Any, kind: type | tuple[type, ...], name: str, expected: str) -> Any:
    """`value` when it is an instance of `kind` (described to the user as `expected`)."""
    if not isinstance(value, kind):
        raise refused(name, expected, value)
    return value


def items(value: Any, name: str, expected: str) -> tuple[Any, ...]:
    """The items of a sequence (list, tuple, ...; not a string) as a tuple."""
    if isinstance(value, (str, bytes, bytearray)) or not isinstance(value, Sequence):
        raise refused(name, expected, value)
    return tuple(value)


def reals(value: Any, name: str, count: int | None = None) -> tuple[float, ...]:
    """A sequence (list, tuple, range, 1-D array, ...) of numbers as floats, `count` of them when given."""
    if isinstance(value, np.ndarray):
        value = value.tolist() if value.ndim == 1 else value
    if isinstance(value, (str, bytes, bytearray)) or not isinstance(value, Sequence):
        raise refused(name, "a list of numbers", value)
    if count is not None and len(value) != count:
        raise ArgumentError(f"{name} has {len(value)} values", what=f"{name} as {count} numbers",
                            why=f"got {len(value)}", how=f"pass exactly {count} numbers")
    return tuple(real(item, f"{name}[{index}]") for index, item in enumerate(value))


def optional_reals(value: Any, name: str) -> tuple[float, ...] | None:
    """None or `reals`."""
    return None if value is None else reals(value, name)
