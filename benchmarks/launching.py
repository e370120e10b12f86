"""What the launch benchmarks share: `plem launch` of the simulated arm, reader processes, CPU and loop readings.

Used by bridge_ipc.py, dds_bridge.py and recorder.py (run as scripts from benchmarks/, so `import launching`
finds this file).
"""

from __future__ import annotations

import json
import os
import platform
import re
import select
import signal
import subprocess
import sys
import textwrap
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plem.bridge.client import RobotClient
from plem.ipc.records import RAW_SCALARS

LATENCY = RAW_SCALARS.index("latency_ns")
TICKS = os.sysconf("SC_CLK_TCK")
START_TIMEOUT_S = 60.0

# argv: robot_id, seconds, settle seconds. Prints "start" when its window starts, then one JSON line, then exits
# when its stdin closes (so that its CPU time can still be read). A plem.bridge client reading every rt_raw
# sample from shared memory (client.stream()).
SHM_CLIENT = textwrap.dedent("""
    import json, sys, time
    import numpy as np
    from plem.bridge import connect

    robot_id, seconds, settle = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
    client = connect(robot_id)
    stream = client.stream(timeout=5.0)
    next(stream)
    end = time.monotonic() + settle
    for sample in stream:
        if time.monotonic() >= end:
            break
    cycles, latencies = [], []
    dropped = stream.dropped
    print("start", flush=True)
    end = time.monotonic_ns() + int(seconds * 1e9)
    for sample in stream:
        now = time.monotonic_ns()
        cycles.append(sample.cycle)
        latencies.append(now - sample.monotonic_ns)
        if now >= end:
            break
    cycles = np.array(cycles, dtype=np.int64)
    latency_us = np.array(latencies, dtype=np.float64) / 1e3
    p50, p99, p999 = np.percentile(latency_us, (50, 99, 99.9))
    print(json.dumps({
        "received": int(cycles.size), "first": int(cycles.min()), "last": int(cycles.max()),
        "unique": int(np.unique(cycles).size), "in_order": bool(np.all(np.diff(cycles) > 0)),
        "p50": p50, "p99": p99, "p999": p999, "max": float(latency_us.max()),
        "ring_dropped": stream.dropped - dropped,
    }), flush=True)
    sys.stdin.read()
    client.close()
""")


# -- processes -----------------------------------------------------------------------------------------
@dataclass
class Launch:
    process: subprocess.Popen
    log: Path
    driver_pid: int
    bridge_pid: int | None
    recorder_pid: int | None = None
    bag_directory: Path | None = None        # bag_dir/{robot_id}, as the recorder's summary line gives it


def launch(robot_id: str, env: dict[str, str], log: Path, children: list[subprocess.Popen], *, bridge: bool,
           record: bool, bus: str = "mock", **arguments: object) -> Launch:
    """`plem launch bus:=mock robot_id:=… bridge:=… record:=… name:=value…` of the simulated arm, or of another
    `bus` (output to `log`), returned once its summary is printed; checks that the bridge and recorder run
    exactly as asked."""
    extra = [f"{name}:={value}" for name, value in arguments.items()]
    with log.open("w") as output:
        process = subprocess.Popen([sys.executable, "-m", "plem.cli", "launch", f"bus:={bus}", f"robot_id:={robot_id}",
                                    f"record:={str(record).lower()}", f"bridge:={str(bridge).lower()}", *extra],
                                   stdout=output, stderr=subprocess.STDOUT, text=True, env=env,
                                   start_new_session=True)
    children.append(process)
    deadline, seen = time.monotonic() + START_TIMEOUT_S, ""
    while "Ctrl-C stops" not in (text := log.read_text()):
        if text != seen:   # a launch slowed by a busy machine says how far it got: the wait follows it
            deadline, seen = time.monotonic() + START_TIMEOUT_S, text
        if process.poll() is not None or time.monotonic() > deadline:
            raise SystemExit(f"plem launch did not start (exit {process.poll()}):\n{text}")
        time.sleep(0.1)
    driver = re.search(r"rt_driver\s+running, pid (\d+), SCHED_FIFO priority", text)
    bridge_line = re.search(r"bridge\s+running, pid (\d+)", text)
    recorder_line = re.search(r"recorder\s+recording, pid (\d+), into (.+?) \(", text)
    if driver is None or bridge != (bridge_line is not None) or record != (recorder_line is not None):
        raise SystemExit(f"unexpected launch summary (a loop at SCHED_FIFO, bridge:={str(bridge).lower()}, "
                         f"record:={str(record).lower()}):\n{text}")
    return Launch(process, log, int(driver.group(1)), int(bridge_line.group(1)) if bridge_line else None,
                  int(recorder_line.group(1)) if recorder_line else None,
                  Path(recorder_line.group(2)) if recorder_line else None)


def start_component(module: str, arguments: dict[str, str], env: dict[str, str], log: Path,
                    children: list[subprocess.Popen]) -> subprocess.Popen:
    """A component of a running launch started as `plem launch` starts it (`python -m <module> '<arguments>'`,
    its log appended to `log`), returned once it announced that it runs."""
    with log.open("a") as output:
        process = subprocess.Popen([sys.executable, "-m", module, json.dumps(arguments)], stdin=subprocess.PIPE,
                                   stdout=subprocess.PIPE, stderr=output, text=True, env=env, start_new_session=True)
    children.append(process)
    line = read_line(process, 60.0)
    if not json.loads(line or "{}").get("ready"):
        raise SystemExit(f"{module} did not start: {line!r}")
    return process


def stop(process: subprocess.Popen, graceful: signal.Signals = signal.SIGINT, timeout: float = 30.0) -> None:
    if process.poll() is None:
        process.send_signal(graceful)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def start_reader(script: str, robot_id: str, seconds: float, settle: float, env: dict[str, str],
                 children: list[subprocess.Popen]) -> subprocess.Popen:
    """A reader process (e.g. SHM_CLIENT), returned when its window starts."""
    process = subprocess.Popen([sys.executable, "-c", script, robot_id, str(seconds), str(settle)],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
                               start_new_session=True)
    children.append(process)
    line = read_line(process, 30.0 + settle)
    if line != "start":
        raise SystemExit(f"reader did not start: {line!r}")
    return process


def read_line(process: subprocess.Popen, timeout: float) -> str:
    readable, _, _ = select.select([process.stdout], [], [], timeout)
    if not readable:
        raise SystemExit(f"no answer from pid {process.pid} within {timeout:.0f} s")
    return process.stdout.readline().strip()


def result(process: subprocess.Popen, timeout: float) -> dict:
    """The reader's JSON line; it keeps running until `finish`."""
    line = read_line(process, timeout)
    data = json.loads(line) if line.startswith("{") else {"error": line or f"exit {process.poll()}"}
    if "error" in data:
        raise SystemExit(f"reader failed: {data['error']}")
    return data


def finish(process: subprocess.Popen) -> None:
    process.stdin.close()
    process.wait(10)


def stop_all(children: list[subprocess.Popen]) -> None:
    """Every process the benchmark started, newest first: readers (with a stdout pipe) by SIGTERM, launches by
    SIGINT (as Ctrl-C: the arm stops and the components end)."""
    for process in reversed(children):
        stop(process, signal.SIGTERM if process.stdout is not None else signal.SIGINT)


def cpu_ticks(pid: int) -> int:
    """utime + stime of every thread of `pid`, in clock ticks."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])


class CpuMeter:
    """% of one core used by some processes between construction and `done()`."""

    def __init__(self, pids: dict[str, int]) -> None:
        self.pids = pids
        self.start = {name: cpu_ticks(pid) for name, pid in pids.items()}
        self.t0 = time.monotonic()

    def done(self) -> dict[str, float]:
        elapsed = time.monotonic() - self.t0
        return {name: (cpu_ticks(pid) - self.start[name]) / TICKS / elapsed * 100 for name, pid in self.pids.items()}


# -- the run and its report ----------------------------------------------------------------------------
def begin_run() -> str:
    """Check for root (the launched loop runs SCHED_FIFO), stop cleanly on Ctrl-C and SIGTERM (the caller's
    `finally` runs), and describe the machine."""
    if os.geteuid() != 0:
        raise SystemExit("needs root: the launched loop runs SCHED_FIFO 98 (run with sudo)")
    signal.signal(signal.SIGINT, signal.default_int_handler)   # even when started with SIGINT ignored
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(128 + signal.SIGTERM))
    return (f"{platform.node()} {platform.machine()}, {os.cpu_count()} CPUs, kernel {platform.release()}, "
            f"Python {platform.python_version()}")


def verdict(met: bool) -> str:
    return "met" if met else "NOT met"


def ratio(value: float, baseline: float) -> str:
    return f"{value / baseline:.2f}x" if baseline else "-"


def latency_figures(latency_us: np.ndarray) -> tuple[float, float, float, float]:
    """p50, p99, p99.9 and max of a window's wake-up latencies (µs)."""
    p50, p99, p999 = np.percentile(latency_us, (50, 99, 99.9))
    return float(p50), float(p99), float(p999), float(latency_us.max())


# -- loop latency --------------------------------------------------------------------------------------
def drain_loop(client: RobotClient, seconds: float) -> tuple[np.ndarray, int]:
    """Wake-up latency (µs) of every cycle of the next `seconds`, read from the rt_raw ring every 0.5 s."""
    reader = client.channels.rings["rt_raw"].reader()
    latencies: list[np.ndarray] = []
    end = time.monotonic() + seconds
    while (left := end - time.monotonic()) > 0:
        time.sleep(min(0.5, left))
        records = reader.read_all()
        if records:
            latencies.append(np.frombuffer(b"".join(records), dtype=np.float64).reshape(len(records), -1)[:, LATENCY])
    if not latencies:
        raise SystemExit(f"no cycle of robot {client.robot_id} in {seconds:g} s: the loop does not run")
    return np.concatenate(latencies) / 1e3, reader.dropped


def first_sample(client: RobotClient, settle: float) -> None:
    client.set_mode("hold")
    if client.wait_for_state(5.0) is None:
        raise SystemExit("the launched robot publishes no state")
    time.sleep(settle)
