"""Named joint states: the SRDF's group_states, found by the name a user types, and `zero`.

A name means the SRDF's state of exactly that name, else the one state whose name differs from it only in
case (Kinova's `Home` answers `home`). `zero` is every joint at 0 rad; an SRDF that names a state `zero`
itself keeps its own. Nothing else is made up: an arm whose SRDF has no `home` has no `home`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

from plem.errors import MoveItCode, PlanningError

#: The state every SRDF has in plem: every joint at 0 rad (unless the SRDF defines a state of this name).
ZERO = "zero"


def with_zero(states: Mapping[str, Sequence[float]], dof: int) -> dict[str, list[float]]:
    """The SRDF's states and, unless one of them answers to `zero`, `zero` with every joint at 0 rad."""
    named = {name: list(values) for name, values in states.items()}
    if _matching(ZERO, named) == []:
        named[ZERO] = [0.0] * dof
    return named


def find_state(name: str, names: Iterable[str]) -> str | None:
    """The state `name` means: the one of that exact name, else the only one equal to it ignoring case."""
    found = _matching(name, names)
    return found[0] if len(found) == 1 else None


def resolve_state(name: str, names: Iterable[str]) -> str:
    """The state `name` means (see `find_state`); a PlanningError naming the states there are when none or
    several match."""
    known = list(names)
    found = _matching(name, known)
    if len(found) == 1:
        return found[0]
    why = (f"{', '.join(found)} differ from {name!r} only in case, so it is not clear which is meant" if found
           else f"no state is named {name!r}, in any case")
    how = ("spell the state exactly as the SRDF does" if found else
           "use one of the names listed, or add a <group_state> giving every arm joint a value to the SRDF "
           f"('{ZERO}' is every joint at 0 rad unless the SRDF defines its own)")
    raise PlanningError(f"unknown named state {name!r}",
                        what=f"one of the arm's named states: {', '.join(known) or 'none'}",
                        why=why, how=how, code=MoveItCode.INVALID_GOAL_CONSTRAINTS)


def _matching(name: str, names: Iterable[str]) -> list[str]:
    """`[name]` when a state has exactly that name, else every state equal to it ignoring case."""
    known = list(names)
    if name in known:
        return [name]
    folded = name.casefold()
    return [other for other in known if other.casefold() == folded]
