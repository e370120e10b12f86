"""Per-cycle timing statistics: wake-up latency, compute time and overruns.

Recording a cycle is a few index operations on preallocated arrays. A fixed-bin histogram (1 µs bins)
covers the whole run, like cyclictest's; a rolling window of the last samples gives live figures.
Percentiles are computed only when someone asks, outside the loop. `TimingStats` is kept by a loop written
in Python; `CoreTimingStats` reads the same figures from the compiled core's real-time thread (`plem_stats`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

HISTOGRAM_BIN_NS = 1_000
HISTOGRAM_BINS = 10_000  # 0..10 ms; the last bin counts everything above


@dataclass(frozen=True)
class TimingSummary:
    """Figures over a set of cycles, in microseconds."""

    samples: int
    min_us: float
    mean_us: float
    p50_us: float
    p99_us: float
    p999_us: float
    max_us: float

    @classmethod
    def empty(cls) -> TimingSummary:
        """The summary of no cycles at all: every figure 0."""
        return cls(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


class TimingSeries:
    """One timed quantity: whole-run histogram plus a rolling window of raw samples."""

    def __init__(self, window: int) -> None:
        self.histogram = np.zeros(HISTOGRAM_BINS, dtype=np.int64)
        self.window = np.zeros(window, dtype=np.int64)
        self.count = 0
        self.total_ns = 0
        self.min_ns = 0
        self.max_ns = 0

    def add(self, value_ns: int) -> None:
        """Count one sample (negative values count as 0) in the histogram and the window."""
        if value_ns < 0:
            value_ns = 0
        bin_index = value_ns // HISTOGRAM_BIN_NS
        self.histogram[bin_index if bin_index < HISTOGRAM_BINS else HISTOGRAM_BINS - 1] += 1
        size = self.window.shape[0]
        self.window[self.count % size] = value_ns
        if self.count == 0 or value_ns < self.min_ns:
            self.min_ns = value_ns
        if value_ns > self.max_ns:
            self.max_ns = value_ns
        self.count += 1
        self.total_ns += value_ns

    def recent(self) -> TimingSummary:
        """Figures over the rolling window, from the raw samples."""
        return _recent(self.window, self.count)

    def whole_run(self) -> TimingSummary:
        """Figures over every sample so far; percentiles to 1 µs bins."""
        return _whole_run(self.histogram, self.count, self.min_ns, self.total_ns, self.max_ns)


def _recent(window: np.ndarray, count: int) -> TimingSummary:
    filled = min(count, window.shape[0])
    if filled == 0:
        return TimingSummary.empty()
    values = window[:filled] / 1e3
    p50, p99, p999 = np.percentile(values, (50, 99, 99.9))
    return TimingSummary(filled, float(values.min()), float(values.mean()), float(p50), float(p99), float(p999),
                         float(values.max()))


def _whole_run(histogram: np.ndarray, count: int, min_ns: int, total_ns: int, max_ns: int) -> TimingSummary:
    if count == 0:
        return TimingSummary.empty()
    p50, p99, p999 = _percentiles(histogram, count)
    return TimingSummary(count, min_ns / 1e3, total_ns / count / 1e3, p50, p99, p999, max_ns / 1e3)


class CoreSeries:
    """One timed quantity as the core's real-time thread keeps it (`plem_series`), read in place."""

    def __init__(self, series: np.ndarray) -> None:
        self._series = series
        self.histogram: np.ndarray = series["histogram"]
        self.window: np.ndarray = series["window"]

    @property
    def count(self) -> int:
        """Samples so far."""
        return int(self._series["count"])

    @property
    def max_ns(self) -> int:
        """The largest sample so far."""
        return int(self._series["max_ns"])

    def recent(self) -> TimingSummary:
        """Figures over the rolling window, from the raw samples."""
        return _recent(self.window.copy(), self.count)

    def whole_run(self) -> TimingSummary:
        """Figures over every sample so far; percentiles to 1 µs bins."""
        series = self._series
        count = self.count
        return _whole_run(self.histogram.copy(), count, int(series["min_ns"]), int(series["total_ns"]),
                          int(series["max_ns"]))


def _percentiles(histogram: np.ndarray, count: int) -> tuple[float, float, float]:
    """p50, p99, p99.9 in µs as the upper edges of their bins, like cyclictest."""
    cumulative = np.cumsum(histogram)
    indices = np.searchsorted(cumulative, np.array((0.5, 0.99, 0.999)) * count, side="left")
    p50, p99, p999 = (float(i + 1) * HISTOGRAM_BIN_NS / 1e3 for i in indices)
    return p50, p99, p999


def histogram_summary(histogram: np.ndarray) -> TimingSummary:
    """Figures of the cycles a histogram counts (e.g. the difference of two snapshots), to 1 µs bins."""
    count = int(histogram.sum())
    if count == 0:
        return TimingSummary.empty()
    filled = np.flatnonzero(histogram)
    edges_us = HISTOGRAM_BIN_NS / 1e3
    mean = float(np.dot(histogram, np.arange(histogram.size))) / count * edges_us + edges_us / 2
    return TimingSummary(count, float(filled[0]) * edges_us, mean, *_percentiles(histogram, count),
                         float(filled[-1] + 1) * edges_us)


class TimingStats:
    """Timing of every cycle of one loop run."""

    def __init__(self, window: int = 10_000) -> None:
        self.latency = TimingSeries(window)
        self.compute = TimingSeries(window)
        self.cycles = 0
        self.overruns = 0
        self.missed_periods = 0
        self.consecutive_overruns = 0

    def record(self, latency_ns: int, compute_ns: int) -> None:
        """Account one cycle's wake-up latency and compute time."""
        self.latency.add(latency_ns)
        self.compute.add(compute_ns)
        self.cycles += 1

    def record_overrun(self, missed: int) -> None:
        """A cycle ended after the next deadline; `missed` periods are skipped."""
        self.overruns += 1
        self.missed_periods += missed
        self.consecutive_overruns += 1

    def record_on_time(self) -> None:
        """A cycle ended before the next deadline: the run of consecutive overruns is over."""
        self.consecutive_overruns = 0

    def summary(self) -> dict[str, object]:
        """Rolling and whole-run figures, for status lines, the state block and benchmarks."""
        return _summary(self)


class CoreTimingStats:
    """Timing of every cycle of the core's real-time thread (`plem_stats`), read in place."""

    def __init__(self, stats: np.ndarray) -> None:
        self._stats = stats
        self.latency = CoreSeries(stats["latency"])
        self.compute = CoreSeries(stats["compute"])

    @property
    def cycles(self) -> int:
        """Cycles run by the thread."""
        return int(self._stats["cycles"])

    @property
    def overruns(self) -> int:
        """Cycles that ended after the next deadline."""
        return int(self._stats["overruns"])

    @property
    def missed_periods(self) -> int:
        """Deadlines skipped after overruns."""
        return int(self._stats["missed_periods"])

    @property
    def consecutive_overruns(self) -> int:
        """Overruns in a row up to the last cycle."""
        return int(self._stats["consecutive_overruns"])

    def summary(self) -> dict[str, object]:
        """Rolling and whole-run figures, for status lines, the state block and benchmarks."""
        return _summary(self)


def _summary(stats: TimingStats | CoreTimingStats) -> dict[str, object]:
    return {"cycles": stats.cycles, "overruns": stats.overruns, "missed_periods": stats.missed_periods,
            "latency": stats.latency.whole_run(), "compute": stats.compute.whole_run(),
            "latency_recent": stats.latency.recent(), "compute_recent": stats.compute.recent()}
