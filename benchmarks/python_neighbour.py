"""Wake-up latency of plem's loop with a busy pure-Python thread in the same process, against the loop without one.

Usage: python benchmarks/python_neighbour.py [--pairs 15] [--seconds 4] [--period-us 1000]
Needs root (SCHED_FIFO 98, mlockall, /dev/cpu_dma_latency), as benchmarks/loop_latency.py.

Each pair is two runs in one order, alternating which goes first: `quiet` and `busy`. A run is
loop_latency.run_plem: a fresh IndyRP2V2 (7 DOF) on MockBus(7) at the period given, rt_priority 98, the main
thread keeping a motion running for the whole window. In a `busy` run one more thread of the same process
computes in pure Python (sum(range(10_000)) over and over) from before the robot is built until after it is
shut down: the neighbour a user's script is. The figures are the loop's own (its histograms over the window):
wake-up latency p99, p99.9 and max, missed periods, and whether the arm faulted. Ratios are busy / quiet within
each pair; the table gives their median and spread (min-max) over the pairs.

Target (issue): wake-up p99 with the busy thread / without <= 1.1, and 0 faults.
"""

from __future__ import annotations

import argparse
import statistics
import threading

import loop_latency


def spin(stop: threading.Event) -> None:
    """Pure-Python work until told to stop: holds the interpreter lock as any busy script does."""
    while not stop.is_set():
        sum(range(10_000))


def run(period_us: int, seconds: int, busy: bool) -> loop_latency.Run:
    stop = threading.Event()
    neighbour = threading.Thread(target=spin, args=(stop,), daemon=True)
    if busy:
        neighbour.start()
    try:
        result, _ = loop_latency.run_plem(period_us, seconds)
    finally:
        stop.set()
        if busy:
            neighbour.join()
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=15)
    parser.add_argument("--seconds", type=int, default=4)
    parser.add_argument("--period-us", type=int, default=1000)
    args = parser.parse_args()
    rows = []
    for pair in range(args.pairs):
        order = (False, True) if pair % 2 == 0 else (True, False)
        runs = {busy: run(args.period_us, args.seconds, busy) for busy in order}
        quiet, busy = runs[False], runs[True]
        rows.append((quiet, busy))
        print(f"pair {pair + 1:2d}: quiet p99 {quiet.latency.p99:4d} p99.9 {quiet.latency.p999:5d} max "
              f"{quiet.latency.max:6d} missed {quiet.missed:3d} | busy p99 {busy.latency.p99:4d} p99.9 "
              f"{busy.latency.p999:5d} max {busy.latency.max:6d} missed {busy.missed:3d} | p99 ratio "
              f"{busy.latency.p99 / quiet.latency.p99:.2f}"
              + ("".join(f" | {side} FAULT" for side, r in (("quiet", quiet), ("busy", busy)) if "FAULT" in r.note)),
              flush=True)

    def spread(values: list[float]) -> str:
        return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"

    p99 = [b.latency.p99 / q.latency.p99 for q, b in rows]
    p999 = [b.latency.p999 / q.latency.p999 for q, b in rows]
    faults = sum("FAULT" in b.note for _, b in rows) + sum("FAULT" in q.note for q, _ in rows)
    print()
    print(f"period {args.period_us} µs, {args.pairs} pairs of {args.seconds} s runs")
    verdict = "met" if statistics.median(p99) <= 1.1 else "NOT met"
    print(f"wake-up p99   busy / quiet: median {spread(p99)}   target <= 1.1: {verdict}")
    print(f"wake-up p99.9 busy / quiet: median {spread(p999)}")
    print(f"p99 quiet µs: median {statistics.median(q.latency.p99 for q, _ in rows)}, busy: "
          f"{statistics.median(b.latency.p99 for _, b in rows)}")
    print(f"missed periods: quiet {sum(q.missed for q, _ in rows)}, busy {sum(b.missed for _, b in rows)}")
    print(f"faults: {faults}   target 0: {'met' if faults == 0 else 'NOT met'}")


if __name__ == "__main__":
    main()
