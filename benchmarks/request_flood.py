"""The loop's overruns while a client floods the command service with mode requests and stops, against the same
loop with no flood.

Usage: python benchmarks/request_flood.py [--window 10] [--pairs 3] [--quick]
Needs root for SCHED_FIFO (as `plem launch` on a real machine). --quick: 1 pair of 3 s windows.

What runs:
  robot      one `plem launch bus:=mock robot_id:=bench_requests_<hex> bridge:=false record:=false` (Indy7 v2, MockBus,
             1 kHz, SCHED_FIFO 98) in a subprocess, holding.
  floods     a flooder process (ordinary priority, like any client) on one connection of the command socket, sending
             batches of 200 requests as fast as the answers come back, for one window:
               hold      set_mode hold while the arm holds (the mode already as asked)
               stop      stop while no motion runs (nothing to stop)
               changing  set_mode idle and hold in turn (every request a real change)
  windows    for each flood kind, --pairs pairs of --window s: flood / no flood, the order alternating.
             Overruns per window from the driver's statistics (its record after the window minus the one before),
             and the requests the driver itself answered (its finished + failed counters) against those sent.
The figures before a change are those of the same script run with PYTHONPATH pointing at the earlier sources.
"""

from __future__ import annotations

import argparse
import os
import secrets
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path
from typing import Any

from plem.bridge import connect
from plem.bridge.client import RobotClient

import launching

KINDS = ("hold", "stop", "changing")

# argv: robot_id, kind, seconds. Prints "start", floods for `seconds`, prints one JSON line, waits for stdin to close.
FLOODER = textwrap.dedent("""
    import json, socket, struct, sys, time
    from plem.ipc.command_socket import frame, socket_path

    robot_id, kind, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    BATCH = 200

    def request(n):
        if kind == "hold":
            return {"id": f"r{n}", "op": "set_mode", "mode": "hold"}
        if kind == "stop":
            return {"id": f"r{n}", "op": "stop"}
        return {"id": f"r{n}", "op": "set_mode", "mode": "idle" if n % 2 else "hold"}

    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.connect(str(socket_path(robot_id)))
    sent = answered = 0
    buffer = b""
    print("start", flush=True)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        sock.sendall(b"".join(frame(json.dumps(request(sent + i)).encode()) for i in range(BATCH)))
        sent += BATCH
        while answered < sent:
            buffer += sock.recv(1 << 16)
            while len(buffer) >= 4 and len(buffer) >= 4 + (length := struct.unpack_from("<I", buffer)[0]):
                answered += json.loads(buffer[4:4 + length])["stage"] != "accepted"
                buffer = buffer[4 + length:]
    print(json.dumps({"sent": sent}), flush=True)
    sys.stdin.read()
""")


def latest_stats(client: RobotClient) -> dict[str, Any]:
    """The driver's next statistics record (they come 10 times a second), so a window's count is complete."""
    first = client.stats()
    deadline = time.monotonic() + 2.0
    while (record := client.stats()) == first and time.monotonic() < deadline:
        time.sleep(0.01)
    assert record is not None
    return record


def served_by_driver(stats: dict[str, Any]) -> int:
    """Requests the RT driver answered as finished or failed (its refusals are counted with the command service's)."""
    commands = stats["commands"]
    return int(commands["finished"]) + int(commands["failed"])


def window(robot_id: str, kind: str | None, seconds: float, client: RobotClient, env: dict[str, str],
           children: list[subprocess.Popen]) -> dict[str, int]:
    """Overruns, requests sent and requests the driver served in one window (kind None: no flood)."""
    before = latest_stats(client)
    sent = 0
    if kind is None:
        time.sleep(seconds)
    else:
        process = subprocess.Popen([sys.executable, "-c", FLOODER, robot_id, kind, str(seconds)], stdin=subprocess.PIPE,
                                   stdout=subprocess.PIPE, text=True, env=env, start_new_session=True)
        children.append(process)
        if launching.read_line(process, 60.0) != "start":
            raise SystemExit(f"the {kind} flooder did not start")
        sent = launching.result(process, seconds + 60.0)["sent"]
        launching.finish(process)
    after = latest_stats(client)
    client.set_mode("hold")
    return {"overruns": after["overruns"] - before["overruns"], "sent": sent,
            "driver": served_by_driver(after) - served_by_driver(before)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    parser.add_argument("--window", type=float, default=10.0)
    parser.add_argument("--pairs", type=int, default=3)
    parser.add_argument("--quick", action="store_true")
    options = parser.parse_args(argv)
    if options.quick:
        options.pairs, options.window = 1, 3.0
    machine = launching.begin_run()
    robot_id = f"bench_requests_{secrets.token_hex(3)}"
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    children: list[subprocess.Popen] = []
    print(f"# request flood: {machine}")
    print(f"# {options.pairs} pairs of {options.window:g} s windows per flood kind, robot {robot_id}")
    totals = {kind: {"flood": {"overruns": 0, "sent": 0, "driver": 0}, "none": {"overruns": 0, "sent": 0, "driver": 0}}
              for kind in KINDS}
    with tempfile.TemporaryDirectory() as directory:
        try:
            launching.launch(robot_id, env, Path(directory) / "launch.log", children, bridge=False, record=False)
            client = connect(robot_id)
            launching.first_sample(client, 1.0)
            for kind in KINDS:
                for pair in range(options.pairs):
                    for which in (("flood", "none") if pair % 2 == 0 else ("none", "flood")):
                        figures = window(robot_id, kind if which == "flood" else None, options.window, client, env,
                                         children)
                        for key, value in figures.items():
                            totals[kind][which][key] += value
                        print(f"{kind} pair {pair + 1} {which}: {figures}", flush=True)
        finally:
            launching.stop_all(children)
    seconds = options.pairs * options.window
    print()
    print(f"| flood | requests sent ({seconds:g} s) | answered by the driver | overruns flood / no flood |")
    print("|---|---|---|---|")
    for kind, figures in totals.items():
        print(f"| {kind} | {figures['flood']['sent']} | {figures['flood']['driver']} | "
              f"{figures['flood']['overruns']} / {figures['none']['overruns']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
