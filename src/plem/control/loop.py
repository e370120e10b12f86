"""The scheduler: runs a cycle function on absolute deadlines and accounts its timing.

Deadlines advance by exactly one period; after an overrun the missed periods are skipped (never
burst to catch up), and K consecutive overruns are reported to the runtime as a fault. Overruns are
summarised once per window (`OverrunWindow`), not reported one by one.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from plem.control.realtime import AbsoluteSleeper, RealtimeContext, RealtimeReport
from plem.control.timing import TimingStats

MAX_CONSECUTIVE_ERRORS = 3
#: Seconds of one overrun summary.
OVERRUN_WINDOW_S = 10.0
_log = logging.getLogger("plem.control")


@dataclass(frozen=True)
class LoopSettings:
    """Timing and real-time settings of one loop."""

    cycle_time_ns: int = 1_000_000
    priority: int = 98
    cpus: tuple[int, ...] | None = None
    max_consecutive_overruns: int = 10
    realtime: bool = True
    overrun_window_s: float = OVERRUN_WINDOW_S


@dataclass(frozen=True)
class OverrunWindow:
    """The overruns of one summary window: how many, the periods they skipped, the longest run in a row."""

    overruns: int
    missed_periods: int
    longest_run: int
    total_overruns: int
    seconds: float


class CycleLoop:
    """Calls `cycle()` once per period until `stop()`; timing goes to `stats`.

    `on_overruns(count)` is called once when `max_consecutive_overruns` overruns happen in a row;
    `on_overrun_report(window)` at the end of each `overrun_window_s` window that had overruns;
    `on_warning(text)` once per real-time set-up step the machine refused (default: a log warning);
    `on_error(exc)` when the cycle raises (the loop keeps running, so the robot can still be stopped,
    unless it raises MAX_CONSECUTIVE_ERRORS times in a row); `after_cycle(latency_ns, previous_compute_ns)`
    right after each cycle, inside the timed part (the RT driver's per-cycle sample).
    """

    def __init__(self, cycle: Callable[[], None], settings: LoopSettings,
                 on_overruns: Callable[[int], None] | None = None,
                 on_error: Callable[[BaseException], None] | None = None,
                 on_overrun_report: Callable[[OverrunWindow], None] | None = None,
                 on_warning: Callable[[str], None] = _log.warning,
                 after_cycle: Callable[[int, int], None] | None = None) -> None:
        self.cycle = cycle
        self.after_cycle = after_cycle
        self.on_warning = on_warning
        self.on_overrun_report = on_overrun_report
        self.settings = settings
        self.on_overruns = on_overruns
        self.on_error = on_error
        self.stats = TimingStats()
        self.report = RealtimeReport()
        self._stop = threading.Event()
        self.error: BaseException | None = None

    def stop(self) -> None:
        """Ask the loop to end after the cycle in progress (safe from any thread)."""
        self._stop.set()

    @property
    def stopping(self) -> bool:
        """stop() was called."""
        return self._stop.is_set()

    def run(self, duration_s: float | None = None) -> RealtimeReport:
        """Run in the calling thread until stop() (or for `duration_s`); returns what RT set-up obtained."""
        settings = self.settings
        context = RealtimeContext(settings.priority, settings.cpus, lock_memory=settings.realtime,
                                  hold_dma_latency=settings.realtime) if settings.realtime else None
        if context is not None:
            self.report = context.__enter__()
            for warning in self.report.warnings:
                self.on_warning(warning)
        try:
            self._run(duration_s)
        finally:
            if context is not None:
                context.__exit__(None, None, None)
        return self.report

    def _run(self, duration_s: float | None) -> None:
        period = self.settings.cycle_time_ns
        limit = self.settings.max_consecutive_overruns
        stats = self.stats
        sleeper = AbsoluteSleeper()
        clock = time.monotonic_ns
        cycle = self.cycle
        after_cycle = self.after_cycle
        compute = 0
        stop = self._stop
        deadline = clock() + period
        end = deadline + int(duration_s * 1e9) if duration_s is not None else None
        errors = 0
        window_ns = int(self.settings.overrun_window_s * 1e9)
        window_start = clock()
        window_end = window_start + window_ns
        reported_overruns = reported_missed = longest_run = 0
        while not stop.is_set():
            sleeper.sleep_until(deadline)
            woke = clock()
            try:
                cycle()
                if after_cycle is not None:
                    after_cycle(woke - deadline, compute)
                errors = 0
            except Exception as error:  # a bug must not leave the arm uncontrolled: report and keep cycling
                errors += 1
                self.error = error
                if self.on_error is not None:
                    self.on_error(error)
                if errors >= MAX_CONSECUTIVE_ERRORS:
                    raise
            done = clock()
            compute = done - woke
            stats.record(woke - deadline, compute)
            deadline += period
            if done > deadline:
                missed = (done - deadline) // period + 1
                deadline += missed * period
                stats.record_overrun(int(missed))
                longest_run = max(longest_run, stats.consecutive_overruns)
                if stats.consecutive_overruns == limit and self.on_overruns is not None:
                    self.on_overruns(stats.consecutive_overruns)
            else:
                stats.record_on_time()
            if done >= window_end:
                if stats.overruns > reported_overruns and self.on_overrun_report is not None:
                    self.on_overrun_report(OverrunWindow(stats.overruns - reported_overruns,
                                                         stats.missed_periods - reported_missed, longest_run,
                                                         stats.overruns, (done - window_start) / 1e9))
                reported_overruns, reported_missed, longest_run = stats.overruns, stats.missed_periods, 0
                window_start, window_end = done, done + window_ns
            if end is not None and deadline > end:
                break
