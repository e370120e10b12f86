"""Real-time set-up of the loop's thread: SCHED_FIFO, CPU affinity, mlockall, /dev/cpu_dma_latency, GC.

Each step is attempted and its outcome recorded; a step the machine does not permit yields one warning
that says how to allow it, and the loop runs anyway (a laptop without RT rights can still simulate).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import gc
import os
import struct
from dataclasses import dataclass, field

CLOCK_MONOTONIC = 1
TIMER_ABSTIME = 1
MCL_CURRENT = 1
MCL_FUTURE = 2
CPU_DMA_LATENCY = "/dev/cpu_dma_latency"

_libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


_clock_nanosleep = _libc.clock_nanosleep
_clock_nanosleep.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.POINTER(_Timespec), ctypes.c_void_p]
_clock_nanosleep.restype = ctypes.c_int


class AbsoluteSleeper:
    """Sleeps until an absolute CLOCK_MONOTONIC deadline (clock_nanosleep with TIMER_ABSTIME).

    The timespec is allocated once; each call only sets two fields, so sleeping allocates nothing.
    """

    def __init__(self) -> None:
        self._deadline = _Timespec()
        self._pointer = ctypes.pointer(self._deadline)

    def sleep_until(self, deadline_ns: int) -> None:
        """Return at or after `deadline_ns` on the monotonic clock (retries when a signal interrupts)."""
        self._deadline.tv_sec = deadline_ns // 1_000_000_000
        self._deadline.tv_nsec = deadline_ns % 1_000_000_000
        while _clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, self._pointer, None) == 4:  # EINTR
            pass


@dataclass
class RealtimeReport:
    """What the loop obtained from the machine, for the start-up summary and the state block."""

    policy: str = "SCHED_OTHER"
    priority: int = 0
    cpus: tuple[int, ...] = ()
    memory_locked: bool = False
    dma_latency_held: bool = False
    warnings: list[str] = field(default_factory=list)


def keep_threads_scheduled(priority: int = 1) -> str | None:
    """Put the calling thread, and threads it starts later, on SCHED_FIFO `priority`; a warning if refused.

    The loop thread shares the interpreter lock with its process's other threads. If one of them is
    preempted by ordinary processes while it holds the lock, the loop waits for it; at FIFO priority 1 they
    run ahead of every ordinary process and behind interrupt threads and the loop itself.
    """
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError as error:
        return (f"helper threads stay at normal priority ({error.strerror}): a busy host can delay the loop "
                "while one of them holds the interpreter lock")
    return None


class RealtimeContext:
    """Applies the real-time settings on `__enter__` and restores the machine on `__exit__`."""

    def __init__(self, priority: int, cpus: tuple[int, ...] | None = None, *, lock_memory: bool = True,
                 hold_dma_latency: bool = True, schedule_caller: bool = True) -> None:
        self.priority = priority
        self.cpus = cpus
        self.lock_memory = lock_memory
        self.hold_dma_latency = hold_dma_latency
        self.schedule_caller = schedule_caller  # False: a thread of the compiled core schedules itself
        self.report = RealtimeReport()
        self._dma_fd: int | None = None
        self._previous_policy: tuple[int, os.sched_param] | None = None
        self._gc_was_enabled = False

    def __enter__(self) -> RealtimeReport:
        if self.schedule_caller:
            self._set_scheduler()
            self._set_affinity()
        self._lock_memory()
        self._hold_dma_latency()
        self._gc_was_enabled = gc.isenabled()
        gc.collect()
        gc.freeze()
        gc.disable()
        return self.report

    def __exit__(self, *exc: object) -> None:
        if self._gc_was_enabled:
            gc.enable()
        gc.unfreeze()
        if self._dma_fd is not None:
            os.close(self._dma_fd)
            self._dma_fd = None
        if self.report.memory_locked:
            _libc.munlockall()
        if self._previous_policy is not None:
            policy, param = self._previous_policy
            with contextlib.suppress(OSError):
                os.sched_setscheduler(0, policy, param)

    def _set_scheduler(self) -> None:
        try:
            previous = (os.sched_getscheduler(0), os.sched_getparam(0))
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.priority))
        except (PermissionError, OSError) as error:
            self.report.warnings.append(
                f"SCHED_FIFO priority {self.priority} not permitted ({error.strerror}); the loop runs without "
                "real-time priority. Allow it with `ulimit -r 99` (or a line `@realtime - rtprio 99` in "
                "/etc/security/limits.conf) or run with CAP_SYS_NICE")
            return
        self._previous_policy = previous
        self.report.policy = "SCHED_FIFO"
        self.report.priority = self.priority

    def _set_affinity(self) -> None:
        if self.cpus:
            try:
                os.sched_setaffinity(0, self.cpus)
            except OSError as error:
                self.report.warnings.append(f"CPU affinity {list(self.cpus)} not applied ({error.strerror})")
        self.report.cpus = tuple(sorted(os.sched_getaffinity(0)))

    def _lock_memory(self) -> None:
        if not self.lock_memory:
            return
        if _libc.mlockall(MCL_CURRENT | MCL_FUTURE) == 0:
            self.report.memory_locked = True
        else:
            self.report.warnings.append(
                f"mlockall failed ({os.strerror(ctypes.get_errno())}); page faults may delay cycles. "
                "Raise the limit with `ulimit -l unlimited` or run with CAP_IPC_LOCK")

    def _hold_dma_latency(self) -> None:
        if not self.hold_dma_latency:
            return
        try:
            fd = os.open(CPU_DMA_LATENCY, os.O_WRONLY)
            os.write(fd, struct.pack("i", 0))
        except OSError as error:
            self.report.warnings.append(
                f"{CPU_DMA_LATENCY} not held at 0 ({error.strerror}); deep CPU idle states may add wake-up "
                "latency. Run as root or give the user write access to the device")
            return
        self._dma_fd = fd
        self.report.dma_latency_held = True
