"""Events of the loop: mode transitions, faults, rejected and finished commands.

Events are rare (never one per cycle in steady state); each has a time, a kind, a cause and a
human-readable reason with drive faults decoded, and goes to a bounded log plus any listeners. Faults
and their clearing are also kept in a history of their own, so that frequent events (overrun reports,
rejected commands) never push the newest fault out.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from enum import StrEnum

from plem.control.modes import Mode


class EventKind(StrEnum):
    """What an event records; the value is the name monitoring messages and records carry."""

    MODE_CHANGED = "mode_changed"
    FAULT = "fault"
    FAULT_CLEARED = "fault_cleared"
    MOTION_STARTED = "motion_started"
    MOTION_FINISHED = "motion_finished"
    COMMAND_REJECTED = "command_rejected"
    OVERRUN = "overrun"
    WARNING = "warning"
    REACTION = "reaction"


#: Kinds kept in the fault history besides the general log.
FAULT_KINDS = frozenset({EventKind.FAULT, EventKind.FAULT_CLEARED})
#: Entries of the fault history: the newest fault is always among the last two.
FAULT_HISTORY = 64


@dataclass(frozen=True)
class Event:
    """One thing that happened, stamped with the monotonic and wall-clock time and the loop cycle."""

    kind: EventKind
    cause: str
    reason: str
    mode: Mode
    cycle: int
    monotonic_ns: int
    wall_time: float
    previous_mode: Mode | None = None

    def describe(self) -> str:
        """One log line, e.g. 'cycle 1200 fault (tracking_error): joint2 ...'."""
        transition = f" {self.previous_mode.name}→{self.mode.name}" if self.previous_mode is not None else ""
        return f"cycle {self.cycle} {self.kind.value}{transition} ({self.cause}): {self.reason}"


def newest_fault(events: Iterable[Event]) -> Event | None:
    """The last FAULT event of `events` (oldest first), or None."""
    return next((event for event in reversed(list(events)) if event.kind is EventKind.FAULT), None)


class EventLog:
    """The most recent events, kept in a bounded deque, fanned out to listeners as they happen."""

    def __init__(self, capacity: int = 1000) -> None:
        self._events: deque[Event] = deque(maxlen=capacity)
        self._faults: deque[Event] = deque(maxlen=FAULT_HISTORY)
        self._listeners: list[Callable[[Event], None]] = []

    def subscribe(self, listener: Callable[[Event], None]) -> None:
        """Call `listener(event)` for every later event (from the loop's thread: keep it short)."""
        self._listeners.append(listener)

    def emit(self, kind: EventKind, cause: str, reason: str, mode: Mode, cycle: int,
             previous_mode: Mode | None = None) -> Event:
        """Record one event, stamped now, and hand it to every listener; returns it."""
        event = Event(kind, cause, reason, mode, cycle, time.monotonic_ns(), time.time(), previous_mode)
        self._events.append(event)
        if kind in FAULT_KINDS:
            self._faults.append(event)
        for listener in self._listeners:
            listener(event)
        return event

    def recent(self, kinds: set[EventKind] | None = None) -> list[Event]:
        """A copy of the kept events, oldest first, optionally of some kinds only."""
        return [e for e in list(self._events) if kinds is None or e.kind in kinds]

    def faults(self) -> list[Event]:
        """Faults and their clearing, oldest first: the last FAULT_HISTORY of them, whatever happened since."""
        return list(self._faults)

    def last_fault(self) -> Event | None:
        """The newest fault, also when it was cleared since (None when the arm never faulted)."""
        return newest_fault(self._faults)
