"""The loop's wake-up latency with `plem view` open and a browser connected, against none, in one run.

Usage: sudo .venv/bin/python benchmarks/view.py [--rounds 15] [--window 8] [--settle 2]

One launch of the simulated arm (bus:=mock, record:=false, bridge:=false, its planner running), the arm moving
back and forth all the time so the view has something to send. Each of --rounds rounds has three windows of
--window seconds, in an order that rotates between rounds: no view; `plem view` with a websocket client reading
everything it sends (the robot computer's side of a browser on another computer); `plem view` with a headless
Chromium on this machine (Debian's, drawing WebGL in software). In each window every cycle's wake-up latency is
read from the rt_raw ring; per round, p99.9 with ÷ without. Also: the redraws per second reaching the page, the
CPU of the view and of the browser, and what the view sends. Target: median p99.9 ratio ≤ 1.05.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import statistics
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plem.bridge import connect
from plem.bridge.client import RobotClient
from plem.errors import PlemError
from plem.view.live_view import DEFAULT_RATE_HZ

from launching import CpuMeter, begin_run, drain_loop, first_sample, latency_figures, launch, stop, stop_all, verdict

TARGET = 1.05
POSES = (np.radians([30.0, -20.0, 50.0, 0.0, 40.0, 0.0]), np.radians([-30.0, 20.0, -40.0, 20.0, -40.0, 30.0]))
CHROMIUM_FLAGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist")


@dataclass
class Window:
    kind: str                       # "none", "view" (a remote browser's traffic) or "browser" (Chromium here)
    latency_us: np.ndarray
    rate_hz: float | None = None
    view_cpu: float | None = None
    browser_cpu: float | None = None
    received: int | None = None     # bytes the stand-in for a remote browser read


def chromium_pids() -> list[int]:
    """Every running Chromium process (the browser and its renderers and GPU process)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if (entry / "comm").read_text().strip() in ("chromium", "chrome"):
                    pids.append(int(entry.name))
            except OSError:
                continue
    return pids


def keep_moving(client: RobotClient, stop_event: threading.Event) -> None:
    """Move the arm back and forth between two poses until `stop_event`."""
    index = 0
    try:
        while not stop_event.is_set():
            client.move_joints(POSES[index], speed_scale=0.4).wait(60)
            index = 1 - index
    except PlemError:
        if not stop_event.is_set():    # the launch stopping at the end ends the motion: that is no failure
            raise
    finally:
        client.close()


@contextlib.contextmanager
def running_view(robot_id: str) -> Iterator[tuple[subprocess.Popen, str]]:
    """`plem view ROBOT_ID` on a free port, and its address."""
    view = subprocess.Popen([sys.executable, "-m", "plem.cli", "view", robot_id, "--port", "0"],
                            stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        assert view.stdout is not None
        url = re.search(r"at (http://\S+)", view.stdout.readline())
        if url is None:
            raise SystemExit("plem view did not start")
        yield view, url.group(1)
    finally:
        stop(view)


def window_with_reader(client: RobotClient, seconds: float, settle: float) -> Window:
    """One window with `plem view` and a websocket client reading everything it sends: the view's side of a
    browser on another computer."""
    import viser
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect as websocket
    from websockets.typing import Subprotocol

    with running_view(client.robot_id) as (view, url):
        received = [0]
        connection = websocket(url.replace("http", "ws"), max_size=None, close_timeout=1,
                               subprotocols=[Subprotocol(f"viser-v{viser.__version__}")])

        def read() -> None:
            try:
                while True:
                    received[0] += len(connection.recv())
            except ConnectionClosed:   # the window's end closes it
                return

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        time.sleep(settle)
        meter = CpuMeter({"view": view.pid})
        before = received[0]
        latency, _ = drain_loop(client, seconds)
        cpu = meter.done()
        connection.close()
        reader.join(5)
        return Window("view", latency, view_cpu=cpu["view"], received=received[0] - before)


def window_with_browser(client: RobotClient, seconds: float, settle: float) -> Window:
    """One window with `plem view` and a headless Chromium on its page, on this machine."""
    from playwright.sync_api import sync_playwright

    with running_view(client.robot_id) as (view, url), sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path="/usr/bin/chromium", headless=True,
                                             args=list(CHROMIUM_FLAGS))
        page = browser.new_page(viewport={"width": 1000, "height": 700})
        page.goto(url)
        page.wait_for_function("document.body.innerText.includes('browsers connected')", timeout=120_000)
        time.sleep(settle)
        meter = CpuMeter({"view": view.pid, **{f"chromium {pid}": pid for pid in chromium_pids()}})
        latency, _ = drain_loop(client, seconds)
        cpu = meter.done()
        rate = re.search(r"view (\d+(?:\.\d+)?) Hz", page.inner_text("body"))
        browser.close()
    browser_cpu = sum(value for name, value in cpu.items() if name.startswith("chromium"))
    return Window("browser", latency, float(rate.group(1)) if rate else None, cpu["view"], browser_cpu)


def window_without(client: RobotClient, seconds: float, settle: float) -> Window:
    """One window with no view."""
    time.sleep(settle)
    return Window("none", drain_loop(client, seconds)[0])


WINDOWS = {"none": window_without, "view": window_with_reader, "browser": window_with_browser}


def p999(window: Window) -> float:
    return latency_figures(window.latency_us)[2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--window", type=float, default=8.0)
    parser.add_argument("--settle", type=float, default=2.0)
    args = parser.parse_args()
    machine = begin_run()
    command = f"sudo .venv/bin/python benchmarks/view.py --rounds {args.rounds} --window {args.window:g}"
    children: list[subprocess.Popen] = []
    work = Path(f"/tmp/plem_view_bench_{uuid.uuid4().hex[:8]}")
    work.mkdir()
    robot_id = f"viewbench_{uuid.uuid4().hex[:6]}"
    moving = threading.Event()
    try:
        launch(robot_id, dict(os.environ), work / "launch.log", children, bridge=False, record=False)
        client = connect(robot_id)
        first_sample(client, args.settle)
        threading.Thread(target=keep_moving, args=(connect(robot_id), moving), daemon=True).start()
        rounds: list[dict[str, Window]] = []
        kinds = list(WINDOWS)
        for number in range(args.rounds):
            windows: dict[str, Window] = {}
            for kind in kinds[number % 3:] + kinds[:number % 3]:       # the order rotates between rounds
                windows[kind] = WINDOWS[kind](client, args.window, args.settle)
                figures = latency_figures(windows[kind].latency_us)
                print(f"round {number + 1:>2} {kind:<8} p50 {figures[0]:.0f} µs, p99.9 {figures[2]:.0f} µs, "
                      f"max {figures[3]:.0f} µs", flush=True)
            rounds.append(windows)
        moving.set()
        report(rounds, args, command, machine)
    finally:
        moving.set()
        stop_all(children)


def report(rounds: list[dict[str, Window]], args: argparse.Namespace, command: str, machine: str) -> None:
    """The table and the summary for BENCHMARKS.md."""
    print("\n---- results (for BENCHMARKS.md) ----")
    print(f"Command: `{command}`. Machine: {machine}.\n")
    print("| round | p99.9 none (µs) | p99.9 view + remote browser's traffic (µs) | ratio | p99.9 view + Chromium "
          "here (µs) | ratio | redraws/s | view CPU % | Chromium CPU % | view sent kB/s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    view_ratios, browser_ratios = [], []
    for number, windows in enumerate(rounds, start=1):
        none, view, browser = windows["none"], windows["view"], windows["browser"]
        view_ratios.append(p999(view) / p999(none))
        browser_ratios.append(p999(browser) / p999(none))
        print(f"| {number} | {p999(none):.0f} | {p999(view):.0f} | {view_ratios[-1]:.2f} | {p999(browser):.0f} | "
              f"{browser_ratios[-1]:.2f} | {browser.rate_hz if browser.rate_hz is not None else '-'} | "
              f"{view.view_cpu:.1f} | {browser.browser_cpu:.1f} | {(view.received or 0) / args.window / 1e3:.0f} |")
    rates = [windows["browser"].rate_hz for windows in rounds if windows["browser"].rate_hz is not None]
    p50 = {kind: statistics.median(latency_figures(windows[kind].latency_us)[0] for windows in rounds)
           for kind in WINDOWS}

    def summary(ratios: list[float]) -> str:
        median = statistics.median(ratios)
        return (f"**{median:.2f}×** (spread {min(ratios):.2f}–{max(ratios):.2f}; target ≤ {TARGET:g}×: "
                f"{verdict(median <= TARGET)})")

    print(f"\nLoop p99.9 ÷ none, median over {args.rounds} rounds of {args.window:g} s windows: the view serving a "
          f"browser elsewhere {summary(view_ratios)}; the view and a headless Chromium on this machine "
          f"{summary(browser_ratios)}. p50 medians: none {p50['none']:.0f} µs, view {p50['view']:.0f} µs, "
          f"Chromium here {p50['browser']:.0f} µs.")
    print(f"View: {statistics.median(rates) if rates else '-'} redraws/s reached the page (median; lowest "
          f"{min(rates) if rates else '-'}, asked for {DEFAULT_RATE_HZ:g}); CPU "
          f"{statistics.median([w['view'].view_cpu or 0.0 for w in rounds]):.1f} % of one core; headless Chromium "
          f"(software WebGL) {statistics.median([w['browser'].browser_cpu or 0.0 for w in rounds]):.1f} %.")


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        raise SystemExit("interrupted; the launch and the view were stopped") from None
