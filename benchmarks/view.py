"""The loop's wake-up latency with `plem view` open and a browser showing it, against none, in one run.

Usage: sudo .venv/bin/python benchmarks/view.py [--pairs 15] [--window 8] [--settle 2]

One launch of the simulated arm (bus:=mock, record:=false, bridge:=false, its planner running), the arm moving
back and forth all the time so the view has something to send. --pairs pairs of --window second windows
alternate (the order alternates between pairs): `plem view` running with a headless Chromium (Debian's, WebGL
in software) showing its page / neither. In each window every cycle's wake-up latency is read from the rt_raw
ring; per pair, p99.9 with ÷ without. Also: the view's redraw rate as its page shows it, and the CPU of the
view and of the browser. Target: median p99.9 ratio ≤ 1.05.
"""

from __future__ import annotations

import argparse
import os
import re
import socket
import statistics
import subprocess
import sys
import threading
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plem.bridge import connect
from plem.bridge.client import RobotClient
from plem.errors import PlemError

from launching import CpuMeter, begin_run, drain_loop, first_sample, latency_figures, launch, stop, stop_all, verdict

TARGET = 1.05
POSES = (np.radians([30.0, -20.0, 50.0, 0.0, 40.0, 0.0]), np.radians([-30.0, 20.0, -40.0, 20.0, -40.0, 30.0]))
CHROMIUM_FLAGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist")


@dataclass
class Window:
    view: bool
    latency_us: np.ndarray
    rate_hz: float | None = None
    view_cpu: float | None = None
    browser_cpu: float | None = None


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


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


def window_with_view(client: RobotClient, seconds: float, settle: float) -> Window:
    """One window with `plem view` and a headless Chromium on its page."""
    from playwright.sync_api import sync_playwright

    view = subprocess.Popen([sys.executable, "-m", "plem.cli", "view", client.robot_id, "--port", str(free_port())],
                            stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        assert view.stdout is not None
        url = re.search(r"at (http://\S+)", view.stdout.readline())
        if url is None:
            raise SystemExit("plem view did not start")
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path="/usr/bin/chromium", headless=True,
                                                 args=list(CHROMIUM_FLAGS))
            page = browser.new_page(viewport={"width": 1000, "height": 700})
            page.goto(url.group(1))
            page.wait_for_function("document.body.innerText.includes('browsers connected')", timeout=120_000)
            time.sleep(settle)
            meter = CpuMeter({"view": view.pid, **{f"chromium {pid}": pid for pid in chromium_pids()}})
            latency, _ = drain_loop(client, seconds)
            cpu = meter.done()
            rate = re.search(r"view (\d+) Hz", page.inner_text("body"))
            browser.close()
        browser_cpu = sum(value for name, value in cpu.items() if name.startswith("chromium"))
        return Window(True, latency, float(rate.group(1)) if rate else None, cpu["view"], browser_cpu)
    finally:
        stop(view)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=15)
    parser.add_argument("--window", type=float, default=8.0)
    parser.add_argument("--settle", type=float, default=2.0)
    args = parser.parse_args()
    machine = begin_run()
    command = f"sudo .venv/bin/python benchmarks/view.py --pairs {args.pairs} --window {args.window:g}"
    children: list[subprocess.Popen] = []
    work = Path(f"/tmp/plem_view_bench_{uuid.uuid4().hex[:8]}")
    work.mkdir()
    robot_id = f"viewbench_{uuid.uuid4().hex[:6]}"
    moving = threading.Event()
    try:
        launch(robot_id, dict(os.environ), work / "launch.log", children, bridge=False, record=False)
        client = connect(robot_id)
        first_sample(client, args.settle)
        mover = threading.Thread(target=keep_moving, args=(connect(robot_id), moving), daemon=True)
        mover.start()
        windows: list[tuple[int, Window]] = []
        for pair in range(1, args.pairs + 1):
            for with_view in ((True, False) if pair % 2 else (False, True)):
                if with_view:
                    windows.append((pair, window_with_view(client, args.window, args.settle)))
                else:
                    time.sleep(args.settle)
                    windows.append((pair, Window(False, drain_loop(client, args.window)[0])))
                figures = latency_figures(windows[-1][1].latency_us)
                print(f"pair {pair:>2} {'view' if with_view else 'none'}: p50 {figures[0]:.0f} µs, p99.9 "
                      f"{figures[2]:.0f} µs, max {figures[3]:.0f} µs", flush=True)
        moving.set()
        ratios = []
        print("\n---- results (for BENCHMARKS.md) ----")
        print(f"Command: `{command}`. Machine: {machine}.\n")
        print("| pair | p99.9 with view (µs) | p99.9 without (µs) | ratio | view redraws/s | view CPU % "
              "| browser CPU % |")
        print("| --- | --- | --- | --- | --- | --- | --- |")
        for pair in range(1, args.pairs + 1):
            by_kind = {window.view: window for p, window in windows if p == pair}
            on, off = by_kind[True], by_kind[False]
            ratio = latency_figures(on.latency_us)[2] / latency_figures(off.latency_us)[2]
            ratios.append(ratio)
            print(f"| {pair} | {latency_figures(on.latency_us)[2]:.0f} | {latency_figures(off.latency_us)[2]:.0f} | "
                  f"{ratio:.2f} | {on.rate_hz if on.rate_hz is not None else '-'} | {on.view_cpu:.1f} | "
                  f"{on.browser_cpu:.1f} |")
        views = [window for _, window in windows if window.view]
        median = statistics.median(ratios)
        rates = [window.rate_hz for window in views if window.rate_hz is not None]
        print(f"\nLoop p99.9 with a view and a browser ÷ without, median over {args.pairs} pairs of {args.window:g} s: "
              f"**{median:.2f}×** (spread {min(ratios):.2f}–{max(ratios):.2f}; target ≤ {TARGET:g}×: "
              f"{verdict(median <= TARGET)}). View: {statistics.median(rates) if rates else '-'} redraws/s (median), "
              f"CPU {statistics.median([w.view_cpu or 0.0 for w in views]):.1f} % of one core; headless Chromium "
              f"(software WebGL) {statistics.median([w.browser_cpu or 0.0 for w in views]):.1f} %.")
    finally:
        moving.set()
        stop_all(children)


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        raise SystemExit("interrupted; the launch and the view were stopped") from None
