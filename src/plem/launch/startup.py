"""Waiting for a child process's ready line for as long as it keeps working, not for a fixed time.

On a busy machine a component's start (imports, the model, DDS discovery) takes as long as the CPU it gets
allows. The wait therefore follows the child's own CPU time: a child that keeps using CPU is starting, a child
that used none for `STALL_S` is stuck. While it waits, the launch says every `NOTICE_PERIOD_S` how long it has
waited and how busy the machine is, so a slow start names its reason.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass

#: A child that used less than `STALL_CPU_S` of CPU in this long, without announcing itself, is stuck.
STALL_S = 60.0
STALL_CPU_S = 0.05
#: No start takes longer than this, however busy the machine.
LIMIT_S = 600.0
NOTICE_PERIOD_S = 10.0
_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float | None:
    """CPU time (user and system, all threads) process `pid` has used, None when it is gone."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            fields = stat.read().rsplit(b")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return (int(fields[11]) + int(fields[12])) / _TICKS  # utime and stime: fields 14 and 15 of proc(5)


def machine_load() -> str:
    """The 1-minute load average against the cores, in words."""
    return f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count() or 1} cores"


@dataclass
class FirstLine:
    """What a child printed first, or why it printed nothing."""

    line: str
    why: str = ""


def first_line(process: subprocess.Popen[str], what: str, say: Callable[[str], None],
               stopping: Callable[[], bool] = lambda: False) -> FirstLine:
    """The first line `process` prints on its stdout pipe, waiting while it works; `say` gets the progress notices.

    Without a line, `why` says what happened: it ended, it stopped using CPU, the wait hit `LIMIT_S`, or
    `stopping()` became true (then `why` is empty).
    """
    stream = process.stdout
    assert stream is not None, "the child must be started with stdout=PIPE"
    started = last_progress = last_notice = time.monotonic()
    cpu_at_progress = cpu_seconds(process.pid) or 0.0
    while not stopping():
        readable, _, _ = select.select([stream], [], [], 0.2)
        if readable:
            line = stream.readline()
            return FirstLine(line) if line else FirstLine("", _ended(process))
        if process.poll() is not None:
            return FirstLine("", _ended(process))
        now = time.monotonic()
        cpu = cpu_seconds(process.pid)
        if cpu is not None and cpu - cpu_at_progress >= STALL_CPU_S:
            last_progress, cpu_at_progress = now, cpu
        if now - last_progress > STALL_S:
            return FirstLine("", f"it used no CPU for {STALL_S:.0f} s without becoming ready ({machine_load()})")
        if now - started > LIMIT_S:
            return FirstLine("", f"it was still starting after {LIMIT_S:.0f} s ({machine_load()})")
        if now - last_notice >= NOTICE_PERIOD_S:
            last_notice = now
            say(f"{what} still starting after {now - started:.0f} s, {cpu_at_progress:.1f} s of CPU so far "
                f"({machine_load()})")
    return FirstLine("")


def exit_description(code: int) -> str:
    """How a process ended, from its exit code (negative: the signal that killed it)."""
    return f"killed by {signal.Signals(-code).name}" if code < 0 else f"exited with code {code}"


def _ended(process: subprocess.Popen[str]) -> str:
    code = process.wait()
    return ("it was " if code < 0 else "it ") + exit_description(code)
