"""The compiled core's real-time thread, for an arm whose bus the core steps itself (the simulated arm, EtherCAT).

The thread is created by the core, not by Python's threading: it sets its own SCHED_FIFO priority and CPU
affinity, sleeps to absolute deadlines, runs the cycle, writes the rt_raw record and its timing, and faults the
arm on consecutive overruns, all without the interpreter. Python locks the process's memory, holds
/dev/cpu_dma_latency, and serves the core from a thread of its own: answering command handles, wording events and
serving the bus beside the cycle (EtherCAT recovery).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable

from plem.control import compiled
from plem.control.loop import LoopSettings
from plem.control.realtime import RealtimeContext, RealtimeReport
from plem.control.runtime import ArmRuntime
from plem.control.timing import CoreTimingStats

#: How often the service thread answers handles and words events.
SERVICE_PERIOD_S = 0.001
#: Longest wait for the thread's first cycle.
START_TIMEOUT_S = 2.0


def _cpu_mask(cpus: tuple[int, ...] | None) -> int:
    return sum(1 << cpu for cpu in cpus or ())


class CoreThread:
    """Runs `runtime`'s cycles on the core's own thread; the interface of `CycleLoop` that a Robot uses."""

    def __init__(self, runtime: ArmRuntime, settings: LoopSettings,
                 on_warning: Callable[[str], None] | None = None) -> None:
        self.runtime = runtime
        self.settings = settings
        self.on_warning = on_warning
        self.stats = CoreTimingStats(runtime.stats[0])
        self.report = RealtimeReport()
        self.error: BaseException | None = None
        self._context: RealtimeContext | None = None
        self._stop = threading.Event()
        self._service: threading.Thread | None = None

    @property
    def running(self) -> bool:
        """The real-time thread runs the cycles."""
        return self.runtime.thread_running

    def start(self) -> RealtimeReport:
        """Lock memory and hold the DMA latency (when real-time), start the thread and its service; what was got."""
        settings = self.settings
        if settings.realtime:   # an AddressSanitizer build maps terabytes of shadow memory that cannot be locked
            self._context = RealtimeContext(settings.priority, lock_memory=not compiled.core.build()["sanitized"],
                                            hold_dma_latency=True, schedule_caller=False)
            self.report = self._context.__enter__()
        self.runtime.start_thread(settings.cycle_time_ns, settings.priority if settings.realtime else 0,
                                  _cpu_mask(settings.cpus), settings.max_consecutive_overruns,
                                  round(settings.overrun_window_s * 1e9))
        self._stop.clear()
        self._service = threading.Thread(target=self._serve, name="plem-core-service", daemon=True)
        self._service.start()
        started = threading.Event()
        waited = 0.0
        while self.stats.cycles == 0 and waited < START_TIMEOUT_S:
            started.wait(0.001)
            waited += 0.001
        self._report_thread()
        for warning in self.report.warnings:
            if self.on_warning is not None:
                self.on_warning(warning)
        return self.report

    def _report_thread(self) -> None:
        """What the thread obtained (policy, priority, CPUs), with a warning for each step the machine refused."""
        stats, report, settings = self.runtime.stats[0], self.report, self.settings
        if int(stats["policy"]):
            report.policy, report.priority = "SCHED_FIFO", int(stats["priority"])
        elif settings.realtime:
            report.warnings.append(
                f"SCHED_FIFO priority {settings.priority} not permitted ({os.strerror(int(stats['sched_error']))}); "
                "the loop runs without real-time priority. Allow it with `ulimit -r 99` (or a line "
                "`@realtime - rtprio 99` in /etc/security/limits.conf) or run with CAP_SYS_NICE")
        if int(stats["affinity_error"]):
            report.warnings.append(f"CPU affinity {list(settings.cpus or ())} not applied "
                                   f"({os.strerror(int(stats['affinity_error']))})")
        report.cpus = tuple(cpu for cpu in range(64) if int(stats["cpus"]) >> cpu & 1)

    def _serve(self) -> None:
        """Answer handles, word events and serve the bus until stopped; an error here never reaches the real-time
        thread."""
        while not self._stop.wait(SERVICE_PERIOD_S):
            try:
                self.runtime.drain()
                self.runtime.service_bus()
            except Exception as error:  # noqa: BLE001 - the arm runs on; the error is kept for the caller
                self.error = error

    def stop(self) -> None:
        """Stop the thread after its current cycle, then the service (after a last drain); safe to repeat."""
        self.runtime.stop_thread()
        self._stop.set()
        if self._service is not None and self._service is not threading.current_thread():
            self._service.join()
        self._service = None
        self.runtime.drain()
        if self._context is not None:
            self._context.__exit__(None, None, None)
            self._context = None

