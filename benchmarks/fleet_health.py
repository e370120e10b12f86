"""`plem fleet health` over 24 robot-hours of 1 kHz data, with DuckDB and on a local 2-worker Dask cluster.

Usage: python benchmarks/fleet_health.py [--dir /tmp/plem_fleet_bench] [--robots 4] [--days 6] [--hours 1]
                                         [--repeat 3] [--quick]
--quick: 2 robots x 2 days x 2 minutes (a smoke run, in its own directory DIR/quick).

What runs:
  dataset     plem.fleet.synthetic: --robots 6-axis robots, each recording --hours hours a day on --days consecutive
              days (default 4 x 6 x 1 h = 24 robot-hours = 86.4 M rt_raw rows, every column of schema.rt_raw(6)),
              in 60 s segments (the recorder's default), zstd, in the exported layout. Written once into --dir and
              reused while its parameters match (DIR/complete.json); its size is printed.
  duckdb      `plem fleet health DIR --format csv` as a user runs it (a subprocess: start-up, opening the
              dataset, the schema-version check of every file, both aggregates, the report), --repeat times;
              median and each run's wall time. Target: <= 10 s.
  baseline    the latency half done bare in this process: one DuckDB query with read_parquet over
              DIR/rt_raw/**/*.parquet (hive partitions) computing per robot and date partition the count, exact
              quantiles (quantile_disc) of latency_ns at 0.5/0.99/0.999 and the max: what DuckDB alone takes for
              the heaviest part, without the counters, the version check or the CLI; ratio plem / bare.
  load        the 1-minute load average at the end (the machine may be shared).
  dask        `plem fleet health DIR --engine dask --format csv` (a local cluster of 2 worker processes, 1
              thread each, started by the command), --repeat times; median, and its overhead against the duckdb
              median. Its CSV must equal DuckDB's (checked).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import duckdb

from plem.fleet.synthetic import Run, write_runs

PLEM = [sys.executable, "-m", "plem.cli"]


def dataset(directory: Path, robots: int, days: int, seconds: int) -> Path:
    """The synthetic dataset for these parameters, written unless DIR/complete.json says it is there."""
    parameters = {"robots": robots, "days": days, "seconds": seconds, "layout": 2}   # layout: the generator's version
    marker = directory / "complete.json"
    if marker.exists() and json.loads(marker.read_text()) == parameters:
        return directory
    shutil.rmtree(directory, ignore_errors=True)
    directory.mkdir(parents=True)
    started = time.monotonic()
    first_day = datetime(2026, 11, 2, 8, tzinfo=UTC)
    for robot in range(robots):
        for day in range(days):
            run = Run(f"arm_{robot:02d}", 6, first_day + timedelta(days=day, minutes=robot), seconds,
                      latency_base_us=8 + robot * day, overruns=robot * day * 3, missed_periods=day,
                      lost_frames=robot, segment_seconds=60)
            write_runs(directory, [run])
        print(f"  wrote arm_{robot:02d} ({time.monotonic() - started:.0f} s)", flush=True)
    marker.write_text(json.dumps(parameters))
    return directory


def size(directory: Path) -> int:
    return sum(path.stat().st_size for path in directory.rglob("*.parquet"))


def timed(command: list[str]) -> tuple[float, str]:
    started = time.monotonic()
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    elapsed = time.monotonic() - started
    if result.returncode != 0:
        sys.exit(f"{' '.join(command)} failed:\n{result.stderr}")
    return elapsed, result.stdout


def bare(directory: Path) -> float:
    started = time.monotonic()
    connection = duckdb.connect()
    connection.execute("SET TimeZone = 'UTC'")
    connection.sql(
        "SELECT robot_id, date, count(*), "
        "quantile_disc(latency_ns, [0.5, 0.99, 0.999]), max(latency_ns) "
        f"FROM read_parquet('{directory}/rt_raw/**/*.parquet', hive_partitioning = true) GROUP BY ALL").fetchall()
    return time.monotonic() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dir", type=Path, default=Path("/tmp/plem_fleet_bench"))
    parser.add_argument("--robots", type=int, default=4)
    parser.add_argument("--days", type=int, default=6)
    parser.add_argument("--hours", type=float, default=1.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true")
    options = parser.parse_args()
    if options.quick:
        options.dir, options.robots, options.days, options.hours = options.dir / "quick", 2, 2, 2 / 60
    seconds = round(options.hours * 3600)
    print(f"dataset: {options.robots} robots x {options.days} days x {seconds} s at 1 kHz = "
          f"{options.robots * options.days * seconds / 3600:g} robot-hours, "
          f"{options.robots * options.days * seconds * 1000 / 1e6:g} M rt_raw rows, in {options.dir}")
    directory = dataset(options.dir, options.robots, options.days, seconds)
    files = sum(1 for _ in directory.rglob("*.parquet"))
    print(f"  {files} files, {size(directory) / 1e9:.2f} GB ({size(directory / 'rt_raw') / 1e9:.2f} GB rt_raw)")

    duck_times, dask_times, bare_times = [], [], []
    duck_out = dask_out = ""
    for _ in range(options.repeat):
        elapsed, duck_out = timed([*PLEM, "fleet", "health", str(directory), "--format", "csv"])
        duck_times.append(elapsed)
        bare_times.append(bare(directory))
        elapsed, dask_out = timed([*PLEM, "fleet", "health", str(directory), "--engine", "dask", "--format", "csv"])
        dask_times.append(elapsed)
    duck, base, dask = (statistics.median(times) for times in (duck_times, bare_times, dask_times))
    print(f"plem fleet health (DuckDB): median {duck:.2f} s  runs {', '.join(f'{t:.2f}' for t in duck_times)}  "
          f"target <= 10 s: {'met' if duck <= 10 else 'NOT met'}")
    print(f"baseline, bare DuckDB query: median {base:.2f} s  runs {', '.join(f'{t:.2f}' for t in bare_times)}  "
          f"ratio plem / bare {duck / base:.2f}x")
    print(f"plem fleet health --engine dask (local, 2 workers): median {dask:.2f} s  "
          f"runs {', '.join(f'{t:.2f}' for t in dask_times)}  overhead against DuckDB {dask / duck:.2f}x "
          f"(+{dask - duck:.2f} s)")
    print(f"load average (1 min) at the end: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"Dask's report equals DuckDB's: {'yes' if dask_out == duck_out else 'NO'} "
          f"({duck_out.count(chr(10)) - 1} rows)")


if __name__ == "__main__":
    main()
