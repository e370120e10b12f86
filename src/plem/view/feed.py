"""What a view shows of a running arm, whichever way it arrives (shared memory on this host, or DDS): the joint
positions measured and commanded, and the readouts beside the arm."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from plem.control.modes import Mode
from plem.fieldbus.cia402 import describe_error_code
from plem.middleware.monitor_feed import QueueCount

#: Readouts, in the order the page lists them.
READOUTS = ("mode", "drives", "fault", "latency", "recorder")


@dataclass(frozen=True)
class Snapshot:
    """One look at the arm: positions (rad, the arm's joint order), the commanded ones when known, readouts."""

    position: np.ndarray
    command_position: np.ndarray | None
    readouts: dict[str, str] = field(default_factory=dict)


class Feed(Protocol):
    """A source of snapshots of one arm."""

    robot_id: str
    joint_names: tuple[str, ...]
    urdf: str
    packages: dict[str, str]

    def snapshot(self, readouts: bool) -> Snapshot | None:
        """The newest state (None before the first); `readouts`: also refresh the readouts (they cost more)."""
        ...

    def close(self) -> None:
        """Release what the feed holds; the arm runs on."""
        ...


def mode_text(mode: Mode | str, faulted: bool) -> str:
    """The mode as the page shows it."""
    name = mode.name.lower() if isinstance(mode, Mode) else mode
    return f"{name} (faulted)" if faulted and name != "fault" else name


def drives_text(enabled: bool, drives: list[dict[str, object]], joint_names: tuple[str, ...]) -> str:
    """Whether the drives are enabled, and each drive's CiA402 state (with its error code when it has one)."""
    head = "enabled" if enabled else "disabled"
    if not drives:
        return head
    parts = []
    for name, drive in zip(joint_names, drives, strict=False):
        code = int(drive.get("error_code", 0) or 0)  # type: ignore[call-overload]
        state = str(drive.get("state", "?")).replace("_", " ")
        parts.append((name, state + (f" ({describe_error_code(code)})" if code else "")))
    states = {state for _, state in parts}
    if len(states) == 1:
        return f"{head} — all {len(parts)}: {states.pop()}"
    return f"{head} — " + "; ".join(f"{name}: {state}" for name, state in parts)


def latency_text(p99_us: float | None, overruns: int | None) -> str:
    """Loop wake-up latency p99 over the last interval and the overruns so far."""
    if p99_us is None:
        return "no statistics yet"
    return f"p99 {p99_us:.0f} µs, overruns {overruns or 0}"


def fault_text(faulted: bool, reason: str, last: tuple[str, float] | None) -> str:
    """The present fault's `reason` (else the last fault's), or the last fault (reason, wall time in s) and that it
    was cleared, or "none"."""
    if faulted:
        return reason or (last[0] if last else "faulted")
    if last is None:
        return "none"
    return f"none (last, {time.time() - last[1]:.0f} s ago, cleared: {last[0]})"


def recorder_text(bag: QueueCount | None, absent: str) -> str:
    """The recorder's bag queue as the page shows it; `absent` when there is none."""
    return absent if bag is None else f"recording — {bag.written} messages written, {bag.dropped} not recorded"


def joints_text(names: Sequence[str], position: Sequence[float] | np.ndarray) -> str:
    """Each joint's position in degrees, on one line."""
    return "  ".join(f"{name} {np.degrees(value):.1f}°" for name, value in zip(names, position, strict=True))
