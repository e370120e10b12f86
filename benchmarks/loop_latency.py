"""Wake-up latency, missed periods and compute time of plem's control loop against cyclictest, at 1 kHz and 4 kHz.

Usage: python benchmarks/loop_latency.py [--seconds 30] [--pairs 3] [--rates 1000,4000] [--quick]
Needs root (SCHED_FIFO 98, mlockall, /dev/cpu_dma_latency). Installs Debian's rt-tests with apt-get when
`cyclictest` is not on PATH.

What runs, alternating plem, cyclictest, plem, cyclictest ... (--pairs pairs of --seconds runs per rate):
  plem        IndyRP2V2 (7 DOF, built-in description with inertials) on MockBus(7), whose simulated drives
              integrate the arm's forward dynamics every cycle; cycle_time = the period, rt_priority 98. A fresh
              robot per run: build, start() (loop thread with SCHED_FIFO 98, mlockall, /dev/cpu_dma_latency held
              at 0), set_mode("hold"), then the main thread keeps a motion running for the whole window:
              move_joints between zero and POSE at full speed, waiting on each handle, planning the next one
              as soon as the previous one finished. The window starts when the first motion is accepted; the
              start-up (building, enabling the drives) is left out by subtracting the loop's histograms and
              counters taken at the window's start from those taken at its end.
  cyclictest  cyclictest -m -p98 --policy=fifo -t1 -i<period µs> -D<seconds> -q -h100000 --histfile=F --json=J
              (one measurement thread, SCHED_FIFO 98, memory locked, absolute clock_nanosleep on
              CLOCK_MONOTONIC, 1 µs histogram up to 100 ms).

Figures (µs):
  latency   wake-up latency: time read right after clock_nanosleep(TIMER_ABSTIME) returned, minus the deadline
            (plem: time.monotonic_ns() in CycleLoop; cyclictest: clock_gettime(CLOCK_MONOTONIC), truncated to
            whole µs). Both sides are binned in 1 µs bins; pXX is the upper edge of the bin in which the
            cumulative count reaches XX % (cyclictest's histogram convention, and plem's TimingSummary); max is
            the largest sample, rounded down to whole µs.
  missed    periods whose deadline was skipped. Both sides use absolute deadlines and the same policy: a late
            loop skips every deadline already past and never bursts to catch up.
              cyclictest (timerthread() in src/cyclictest/cyclictest.c of rt-tests): after each wake-up
              `next += interval; while (tsgreater(&now, &next)) next += interval;` with `now` read right after
              clock_nanosleep returned (it computes nothing in between). It does not count what it skipped: a
              sample of latency L skipped every deadline before L, i.e. ceil(L / period) - 1 of them, counted
              here from the histogram as floor(bin / period) per sample (bins are truncated µs). A sample beyond
              the histogram (over 100 ms) counts as at least 100 ms; the run is then marked with '>='.
              plem (CycleLoop._run): after the cycle `deadline += period`; if the cycle ended after it,
              `missed = (done - deadline) // period + 1` deadlines are skipped and added to missed_periods.
            The only difference is the instant compared with the deadlines: after plem's cycle computation,
            after cyclictest's wake-up.
  compute   plem only: time from the wake-up to the end of ArmRuntime.cycle() (bus read, simulated dynamics,
            supervision, motion sampling, limits, bus write, state publication).
  ratios    plem / cyclictest within each pair, median over the pairs.
  note      plem: motions started, and the periods missed while a motion was handed over (from the caller
            waking up in handle.wait() to move_joints() returning: the loop finishing one motion and the caller
            planning and submitting the next); cyclictest: whether it held /dev/cpu_dma_latency. Both: the
            1-minute load average at the end of the run (other work on the machine shows there).
/dev/cpu_dma_latency: cyclictest opens it, writes 0 and holds it for the whole run unless given --laptop or
--default-system (then it leaves it alone); --latency=N writes N instead of 0. None of them is used here, so both
sides hold it at 0 (plem: plem.control.realtime.RealtimeContext).

Targets: at 1 kHz, latency p99 and p99.9 each <= 1.2x cyclictest's (median ratios); at every rate, missed
periods <= 2x cyclictest's (summed over the runs of each side, since a single run's count is often 0) and compute
p99 <= 100 µs (median over the runs); plem's forward kinematics, Jacobian and ruckig step <= 1.5x the bare
pinocchio / ruckig call (benchmarks/micro_kinematics.py, run first in the same process).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import itertools
import json
import math
import os
import platform
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plem.control.commands import CommandTimeout
from plem.control.timing import HISTOGRAM_BIN_NS, TimingStats
from plem.errors import PlemError
from plem.fieldbus import MockBus
from plem.robot import IndyRP2V2, Robot

import micro_kinematics

PRIORITY = 98
DOF = 7
POSE = (0.6, -0.5, 0.7, -0.8, 0.5, 0.9, -0.6)  # rad, well inside every joint's ±3.05 rad
HOME = (0.0,) * DOF
SPEED_SCALE = 1.0
CYCLICTEST_HISTOGRAM_US = 100_000
LATENCY_TARGET = 1.2
MISSED_TARGET = 2.0
COMPUTE_P99_TARGET_US = 100.0
LATENCY_TARGET_RATE_HZ = 1000
QUICK_SECONDS = 3
QUICK_MICRO = (50, 200)  # rounds, calls
FULL_MICRO = (300, 300)


@dataclass(frozen=True)
class Percentiles:
    """p50 / p99 / p99.9 (upper bin edges) and max (rounded down) of a 1 µs histogram, in µs."""

    p50: int
    p99: int
    p999: int
    max: int

    @classmethod
    def of(cls, counts: np.ndarray, max_us: int) -> Percentiles:
        cumulative = np.cumsum(counts)
        total = int(cumulative[-1])

        def upper_edge(fraction: float) -> int:
            return int(np.searchsorted(cumulative, fraction * total, side="left")) + 1

        return cls(upper_edge(0.5), upper_edge(0.99), upper_edge(0.999), max_us)


@dataclass(frozen=True)
class Run:
    """The figures of one run of one side."""

    side: str
    cycles: int
    latency: Percentiles
    missed: int
    missed_exact: bool = True
    compute: Percentiles | None = None
    note: str = ""


@dataclass(frozen=True)
class Snapshot:
    """The loop's cumulative timing at one instant."""

    latency: np.ndarray
    compute: np.ndarray
    missed: int

    @classmethod
    def of(cls, stats: TimingStats) -> Snapshot:
        return cls(stats.latency.histogram.copy(), stats.compute.histogram.copy(), stats.missed_periods)


def load_note() -> str:
    """The 1-minute load average at the end of a run (other work on the machine shows here)."""
    return f"load {os.getloadavg()[0]:.2f}"


def window_max_us(counts: np.ndarray, whole_run_max_ns: int) -> int:
    """Largest sample of a window, from its histogram; the whole run's exact max when the top bin (overflow) is hit."""
    top = int(np.flatnonzero(counts)[-1])
    return whole_run_max_ns // 1000 if top == len(counts) - 1 else top * HISTOGRAM_BIN_NS // 1000


# -- plem ----------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Window:
    """What happened in one plem run's measured window."""

    start: Snapshot
    end: Snapshot
    motions: int
    handover_missed: int  # periods missed between the caller waking from wait() and move_joints() returning
    fault: str  # why the robot faulted, '' if it did not


def keep_moving(robot: Robot, seconds: int) -> Window:
    """Alternate move_joints(POSE) / move_joints(HOME) for `seconds` from the first acceptance.

    After a fault the window still runs to its end, without motions.
    """
    stats = robot.loop.stats
    targets = itertools.cycle((POSE, HOME))
    handle = robot.move_joints(next(targets), SPEED_SCALE)
    start = Snapshot.of(stats)
    end_time = time.monotonic() + seconds
    motions, handover_missed, fault = 1, 0, ""
    while (remaining := end_time - time.monotonic()) > 0:
        try:
            handle.wait(remaining)
            before = stats.missed_periods
            handle = robot.move_joints(next(targets), SPEED_SCALE)
            handover_missed += stats.missed_periods - before
            motions += 1
        except CommandTimeout:
            break
        except PlemError as error:
            fault = robot.fault_reason or error.summary
            time.sleep(max(0.0, end_time - time.monotonic()))
            break
    return Window(start, Snapshot.of(stats), motions, handover_missed, fault)


def run_plem(period_us: int, seconds: int) -> tuple[Run, list[str]]:
    """One plem run; also returns the set-up: the simulation, and what the loop thread obtained from the machine."""
    config = IndyRP2V2(cycle_time=period_us, rt_priority=PRIORITY)
    config.custom_bus = MockBus(DOF)
    robot = Robot.builder(config).build()
    simulated = "MockBus rigid-body dynamics" if config.custom_bus.simulates_dynamics else "MockBus WITHOUT dynamics"
    robot.start()
    try:
        robot.set_mode("hold")
        window = keep_moving(robot, seconds)
    finally:
        robot.shutdown()
    stats = robot.loop.stats
    report = robot.loop.report
    obtained = [simulated, f"{report.policy} {report.priority}",
                "memory locked" if report.memory_locked else "memory NOT locked",
                "/dev/cpu_dma_latency held at 0" if report.dma_latency_held else "/dev/cpu_dma_latency NOT held",
                *report.warnings]
    start, end = window.start, window.end
    latency = end.latency - start.latency
    compute = end.compute - start.compute
    note = (f"{window.motions} motions, {window.handover_missed} missed at hand-overs, {load_note()}"
            + (f"; FAULT: {window.fault}" if window.fault else ""))
    run = Run("plem", int(latency.sum()), Percentiles.of(latency, window_max_us(latency, stats.latency.max_ns)),
              end.missed - start.missed, compute=Percentiles.of(compute, window_max_us(compute, stats.compute.max_ns)),
              note=note)
    return run, obtained


# -- cyclictest ----------------------------------------------------------------------------------------------------
def ensure_cyclictest() -> str:
    """Path of cyclictest, installing Debian's rt-tests first when it is missing."""
    found = shutil.which("cyclictest")
    if found:
        return found
    print("cyclictest not found: installing Debian's rt-tests (apt-get install -y rt-tests)", flush=True)
    install = ["apt-get", "install", "-y", "rt-tests"]
    if subprocess.run(install, stdout=subprocess.DEVNULL).returncode != 0:  # no package lists yet
        subprocess.run(["apt-get", "update"], check=True, stdout=subprocess.DEVNULL)
        subprocess.run(install, check=True, stdout=subprocess.DEVNULL)
    found = shutil.which("cyclictest")
    if found is None:
        raise SystemExit("cyclictest is still missing after installing rt-tests")
    return found


def cyclictest_command(binary: str, period_us: int, seconds: int, histfile: Path, jsonfile: Path) -> list[str]:
    return [binary, "-m", f"-p{PRIORITY}", "--policy=fifo", "-t1", f"-i{period_us}", f"-D{seconds}", "-q",
            f"-h{CYCLICTEST_HISTOGRAM_US}", f"--histfile={histfile}", f"--json={jsonfile}"]


def run_cyclictest(binary: str, period_us: int, seconds: int) -> tuple[Run, str]:
    """One cyclictest run; also returns its command line."""
    with tempfile.TemporaryDirectory(prefix="plem-cyclictest-") as directory:
        jsonfile = Path(directory) / "result.json"
        command = cyclictest_command(binary, period_us, seconds, Path(directory) / "histogram.txt", jsonfile)
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0 or not jsonfile.exists():
            raise SystemExit(f"{shlex.join(command)} failed ({done.returncode}): {(done.stderr or done.stdout)[-500:]}")
        thread = json.loads(jsonfile.read_text(encoding="utf-8"))["thread"]["0"]
        dma = "held at 0" if "/dev/cpu_dma_latency set to 0us" in done.stdout else "NOT held"
    counts = np.zeros(CYCLICTEST_HISTOGRAM_US, dtype=np.int64)
    for bin_us, count in thread["histogram"].items():
        counts[int(bin_us)] = count
    cycles = int(thread["cycles"])
    overflow = cycles - int(counts.sum())
    max_us = int(thread["max"])
    missed = int(np.dot(np.arange(CYCLICTEST_HISTOGRAM_US) // period_us, counts))
    if overflow:
        missed += max_us // period_us + (overflow - 1) * (CYCLICTEST_HISTOGRAM_US // period_us)
    with_overflow = np.append(counts, overflow)
    run = Run("cyclictest", cycles, Percentiles.of(with_overflow, max_us), missed, overflow == 0,
              note=f"{load_note()}, /dev/cpu_dma_latency {dma}"
              + (f"; {overflow} samples over the histogram" if overflow else ""))
    return run, shlex.join(command)


# -- report --------------------------------------------------------------------------------------------------------
COLUMNS = (("pair", 4), ("side", 10), ("cycles", 7), ("lat p50", 7), ("p99", 5), ("p99.9", 6), ("max", 6),
           ("missed", 7), ("compute p50", 11), ("p99", 5), ("max", 6), ("note", 0))


def format_row(cells: Sequence[str]) -> str:
    return "  ".join(cell.ljust(width) for cell, (_, width) in zip(cells, COLUMNS, strict=False)).rstrip()


def run_row(pair: int, run: Run) -> list[str]:
    latency, compute = run.latency, run.compute
    computed = [str(compute.p50), str(compute.p99), str(compute.max)] if compute else ["-", "-", "-"]
    return [str(pair), run.side, str(run.cycles), str(latency.p50), str(latency.p99), str(latency.p999),
            str(latency.max), ("" if run.missed_exact else ">=") + str(run.missed), *computed, run.note]


def ratio(numerator: float, denominator: float) -> float:
    """numerator / denominator, with 0 / 0 = 1 (no difference) and x / 0 = inf."""
    return numerator / denominator if denominator else (1.0 if numerator == 0 else math.inf)


def times(value: float) -> str:
    return f"{value:.2f}x" if math.isfinite(value) else "inf"


@dataclass(frozen=True)
class RateResult:
    """Every run at one rate, in pair order."""

    rate_hz: int
    plem: tuple[Run, ...]
    cyclictest: tuple[Run, ...]


def measure_rate(binary: str, rate_hz: int, seconds: int, pairs: int) -> RateResult:
    """Alternate plem and cyclictest runs at one rate, printing each run as it ends."""
    period_us = 1_000_000 // rate_hz
    print(f"\n{rate_hz} Hz (period {period_us} µs): {pairs} pair(s) of {seconds} s runs, plem then cyclictest; "
          "latency and compute in µs", flush=True)
    for warning in IndyRP2V2(cycle_time=period_us, rt_priority=PRIORITY).warnings():
        print(f"plem config warning: {warning}")
    print(format_row([name for name, _ in COLUMNS]))
    print(format_row(["-" * max(width, len(name)) for name, width in COLUMNS]), flush=True)
    plem_runs, cyclictest_runs, commands, obtained = [], [], [], {}
    for pair in range(1, pairs + 1):
        plem, setup = run_plem(period_us, seconds)
        obtained[", ".join(setup)] = None
        plem_runs.append(plem)
        print(format_row(run_row(pair, plem)), flush=True)
        cyclictest, command = run_cyclictest(binary, period_us, seconds)
        cyclictest_runs.append(cyclictest)
        commands.append(command)
        print(format_row(run_row(pair, cyclictest)), flush=True)
    print(f"plem loop thread: {'; '.join(obtained)}")
    print(f"cyclictest (pair 1; later pairs differ only in the temporary directory): {commands[0]}")
    return RateResult(rate_hz, tuple(plem_runs), tuple(cyclictest_runs))


def summarize(result: RateResult) -> list[tuple[str, bool]]:
    """Print the median ratios and plem's compute figures of one rate; return its targets as (line, met)."""
    pairs = list(zip(result.plem, result.cyclictest, strict=False))
    ratios = {name: statistics.median(ratio(getattr(p.latency, field), getattr(c.latency, field)) for p, c in pairs)
              for name, field in (("p50", "p50"), ("p99", "p99"), ("p99.9", "p999"), ("max", "max"))}
    missed_ratio = statistics.median(ratio(p.missed, c.missed) for p, c in pairs)
    plem_missed = sum(p.missed for p, _ in pairs)
    cyclictest_missed = sum(c.missed for _, c in pairs)
    compute = {name: statistics.median(getattr(p.compute, field) for p, _ in pairs)
               for name, field in (("p50", "p50"), ("p99", "p99"), ("max", "max"))}
    print(f"\n{result.rate_hz} Hz, median over {len(pairs)} pair(s):")
    print("  latency plem/cyclictest: " + ", ".join(f"{name} {times(value)}" for name, value in ratios.items()))
    print(f"  missed periods: ratio {times(missed_ratio)} (0/0 counts as 1x); over all runs plem {plem_missed}, "
          f"cyclictest {cyclictest_missed}")
    print("  plem compute: " + ", ".join(f"{name} {value:g} µs" for name, value in compute.items()))
    rate = f"{result.rate_hz} Hz"
    targets = []
    if result.rate_hz == LATENCY_TARGET_RATE_HZ:
        targets += [(f"{rate} latency {name} <= {LATENCY_TARGET}x cyclictest's: {times(ratios[name])}",
                     ratios[name] <= LATENCY_TARGET) for name in ("p99", "p99.9")]
    targets.append((f"{rate} missed periods over all runs <= {MISSED_TARGET:g}x cyclictest's: plem {plem_missed}, "
                    f"cyclictest {cyclictest_missed}", plem_missed <= MISSED_TARGET * cyclictest_missed))
    targets.append((f"{rate} compute p99 <= {COMPUTE_P99_TARGET_US:g} µs: {compute['p99']:g} µs",
                    compute["p99"] <= COMPUTE_P99_TARGET_US))
    return targets


def print_machine(cyclictest: str) -> None:
    cpuinfo = Path("/proc/cpuinfo").read_text(encoding="utf-8")
    model = next((line.split(":", 1)[1].strip() for line in cpuinfo.splitlines() if line.startswith("model name")),
                 platform.processor())
    rt_tests = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "rt-tests"], capture_output=True, text=True)
    clocksource = Path("/sys/devices/system/clocksource/clocksource0/current_clocksource")
    print(f"command: {shlex.join([sys.executable, *sys.argv])}")
    print(f"machine: kernel {platform.release()} ({platform.version()}), {os.cpu_count()} CPUs "
          f"(affinity {sorted(os.sched_getaffinity(0))}), {model}"
          f"{', under a hypervisor' if ' hypervisor' in cpuinfo else ''}")
    print(f"/sys/kernel/realtime: {'present' if Path('/sys/kernel/realtime').exists() else 'absent (not PREEMPT_RT)'}"
          f"; clocksource {clocksource.read_text(encoding='utf-8').strip() if clocksource.exists() else 'unknown'}")
    print(f"python {platform.python_version()}; plem {importlib.metadata.version('plem')}, "
          f"pin {importlib.metadata.version('pin')}, ruckig {importlib.metadata.version('ruckig')}, "
          f"numpy {np.__version__}; cyclictest {cyclictest} (rt-tests {rt_tests.stdout or 'unknown version'})")


def parse_rates(text: str) -> list[int]:
    rates = [int(part) for part in text.split(",") if part.strip()]
    for rate in rates:
        if rate <= 0 or 1_000_000 % rate:
            raise argparse.ArgumentTypeError(f"{rate} Hz has no whole-µs period")
    return rates


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=int, default=30, help="length of each run (default 30)")
    parser.add_argument("--pairs", type=int, default=3, help="plem/cyclictest pairs per rate (default 3)")
    parser.add_argument("--rates", type=parse_rates, default=[1000, 4000], help="loop rates in Hz (default 1000,4000)")
    parser.add_argument("--quick", action="store_true",
                        help=f"smoke run: {QUICK_SECONDS} s runs, 1 pair, fewer micro-benchmark rounds")
    args = parser.parse_args(argv)
    seconds, pairs = (QUICK_SECONDS, 1) if args.quick else (args.seconds, args.pairs)
    if os.geteuid() != 0:
        raise SystemExit("run as root: both sides need SCHED_FIFO 98, mlockall and /dev/cpu_dma_latency")
    binary = ensure_cyclictest()
    print_machine(binary)
    rounds, calls = QUICK_MICRO if args.quick else FULL_MICRO
    micro = micro_kinematics.measure(rounds, calls)
    micro_kinematics.print_results(micro, rounds, calls)
    targets = [(f"{r.name}: plem {r.ratio:.2f}x the bare call (<= {micro_kinematics.TARGET_RATIO}x)", r.met)
               for r in micro]
    results = [measure_rate(binary, rate, seconds, pairs) for rate in args.rates]
    for result in results:
        targets += summarize(result)
    print("\nTargets:")
    for line, met in targets:
        print(f"  {'MET' if met else 'NOT MET':7}  {line}")
    print(f"{sum(met for _, met in targets)} of {len(targets)} targets met")


if __name__ == "__main__":
    main()
