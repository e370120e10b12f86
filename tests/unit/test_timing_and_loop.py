"""Timing statistics, the deadline scheduler's overrun policy and the real-time set-up report."""

from __future__ import annotations

import os
import threading
import time

import pytest

from plem.control.loop import CycleLoop, LoopSettings, OverrunWindow
from plem.control.realtime import AbsoluteSleeper, RealtimeContext
from plem.control.timing import TimingStats

PERIOD_NS = 2_000_000


def test_whole_run_percentiles_come_from_the_histogram_like_cyclictest():
    stats = TimingStats(window=100)
    for value_us in range(1, 1001):  # 1..1000 µs, one sample each
        stats.record(value_us * 1000 - 500, 0)
    summary = stats.latency.whole_run()
    assert summary.samples == 1000
    assert summary.p50_us == 500 and summary.p99_us == 990 and summary.p999_us == 999
    assert summary.max_us == pytest.approx(999.5) and summary.min_us == pytest.approx(0.5)


def test_rolling_window_keeps_only_recent_cycles():
    stats = TimingStats(window=10)
    for value in [1_000_000] * 50 + [2_000] * 10:
        stats.record(value, value)
    recent = stats.latency.recent()
    assert recent.samples == 10 and recent.max_us == pytest.approx(2.0)
    assert stats.latency.whole_run().max_us == pytest.approx(1000.0)


def test_values_beyond_the_histogram_land_in_the_last_bin_and_negative_as_zero():
    stats = TimingStats()
    stats.record(-5, 50_000_000)
    assert stats.latency.whole_run().max_us == 0
    assert stats.compute.histogram[-1] == 1


def test_recording_a_cycle_allocates_no_arrays():
    stats = TimingStats()
    before = [id(a) for a in (stats.latency.histogram, stats.latency.window)]
    for i in range(5000):
        stats.record(i * 100, i * 10)
    assert [id(a) for a in (stats.latency.histogram, stats.latency.window)] == before
    assert stats.cycles == 5000


def test_absolute_sleeper_never_returns_before_the_deadline():
    sleeper = AbsoluteSleeper()
    for _ in range(20):
        deadline = time.monotonic_ns() + 300_000
        sleeper.sleep_until(deadline)
        assert time.monotonic_ns() >= deadline


def slow_cycle() -> None:
    """2.5 periods of work: every cycle misses the next two deadlines, however idle the machine is."""
    time.sleep(2.5 * PERIOD_NS / 1e9)


def test_overruns_skip_missed_periods_and_k_in_a_row_are_reported():
    reported: list[int] = []
    loop = CycleLoop(slow_cycle, LoopSettings(cycle_time_ns=PERIOD_NS, max_consecutive_overruns=4, realtime=False),
                     on_overruns=reported.append)
    loop.run(duration_s=0.1)
    stats = loop.stats
    assert reported == [4]
    assert stats.overruns == stats.cycles
    assert stats.missed_periods >= 2 * stats.cycles
    # skipping instead of bursting: about one cycle per three periods, never one per period
    assert stats.cycles <= 0.1 / (PERIOD_NS / 1e9) / 2


def test_overruns_are_summarised_once_per_window_with_the_longest_run():
    windows: list[OverrunWindow] = []
    settings = LoopSettings(cycle_time_ns=PERIOD_NS, realtime=False, overrun_window_s=0.0)  # every cycle ends one
    loop = CycleLoop(slow_cycle, settings, on_overrun_report=windows.append)
    loop.run(duration_s=0.05)
    assert [window.total_overruns for window in windows] == list(range(1, loop.stats.overruns + 1))
    assert all(window.overruns == 1 and window.missed_periods >= 2 for window in windows)
    assert [window.longest_run for window in windows] == list(range(1, len(windows) + 1))  # one run, growing
    assert sum(window.missed_periods for window in windows) == loop.stats.missed_periods


def test_no_summary_before_a_window_ends():
    windows: list[OverrunWindow] = []
    loop = CycleLoop(slow_cycle, LoopSettings(cycle_time_ns=PERIOD_NS, realtime=False, overrun_window_s=3600.0),
                     on_overrun_report=windows.append)
    loop.run(duration_s=0.05)
    assert loop.stats.overruns > 0 and windows == []


def test_a_cycle_that_raises_is_reported_and_the_loop_goes_on():
    calls = {"n": 0}
    errors: list[BaseException] = []

    def flaky() -> None:
        calls["n"] += 1
        if calls["n"] == 3:
            raise RuntimeError("boom")

    loop = CycleLoop(flaky, LoopSettings(cycle_time_ns=PERIOD_NS, realtime=False), on_error=errors.append)
    loop.run(duration_s=0.03)
    assert [str(e) for e in errors] == ["boom"] and calls["n"] > 3


def test_a_cycle_that_keeps_raising_stops_the_loop():
    def broken() -> None:
        raise RuntimeError("always")

    loop = CycleLoop(broken, LoopSettings(cycle_time_ns=PERIOD_NS, realtime=False))
    with pytest.raises(RuntimeError):
        loop.run(duration_s=1.0)


def test_stop_from_another_thread_ends_the_loop():
    loop = CycleLoop(lambda: None, LoopSettings(cycle_time_ns=PERIOD_NS, realtime=False))
    thread = threading.Thread(target=loop.run)
    thread.start()
    time.sleep(0.02)
    loop.stop()
    thread.join(2)
    assert not thread.is_alive() and loop.stats.cycles > 0


def test_realtime_context_reports_what_it_obtained_and_restores_the_thread():
    policy_before = os.sched_getscheduler(0)

    def in_thread(result: dict) -> None:
        with RealtimeContext(priority=10, cpus=(0,), lock_memory=False, hold_dma_latency=True) as report:
            result["inside"] = os.sched_getscheduler(0)
            result["report"] = report
        result["after"] = os.sched_getscheduler(0)

    result: dict = {}
    thread = threading.Thread(target=in_thread, args=(result,))
    thread.start()
    thread.join()
    report = result["report"]
    if report.policy == "SCHED_FIFO":
        assert result["inside"] == os.SCHED_FIFO and report.priority == 10
    else:  # not permitted here: the loop still runs and the warning says how to allow it
        assert any("ulimit -r" in w for w in report.warnings)
    assert result["after"] == policy_before
    assert report.cpus == (0,)
    assert report.dma_latency_held or any("cpu_dma_latency" in w for w in report.warnings)
