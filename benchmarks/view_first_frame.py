"""The view's time to first frame: from starting `plem view` to the browser's first frame with the whole arm in it,
against viser alone showing the same URDF, in one run.

Usage: sudo .venv/bin/python benchmarks/view_first_frame.py [--rounds 15] [--busy 0]

One launch of the simulated arm (bus:=mock, record:=false, bridge:=false, its planner running) and one headless
Chromium (Debian's, drawing WebGL in software: a robot computer without a GPU) already open, as a user's browser
is. Each round starts, in an order that rotates between rounds: `plem view ROBOT_ID`; viser's own URDF viewer
(`ViserUrdf`, viser's defaults) on the robot's URDF — the baseline; an empty viser page — the floor that loading
the page costs. The clock starts when the process starts; the page is opened as soon as the server prints its
address; the first frame is the first one the page draws to the screen with as many draw calls as it settles at
(every mesh of the arm, and for plem the commanded pose too; counted by wrapping WebGL's draw calls) and after
which the page does not freeze for a second or more. --busy N
keeps N busy processes running on the machine throughout (a loaded machine).
"""

from __future__ import annotations

import argparse
import os
import re
import select
import signal
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from plem.bridge import connect
from plem.ipc.robot_description import read_description

from launching import begin_run, first_sample, launch, stop, stop_all, verdict

CHROMIUM_FLAGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist")
#: The page has settled when its most draw calls in a frame did not grow for this long.
SETTLED_S = 4.0
#: A page that draws no frame for this long is frozen.
STALL_S = 1.0
START_TIMEOUT_S, FRAME_TIMEOUT_S = 120.0, 180.0

# Counts the draw calls that reach the screen (not an offscreen framebuffer: shadow maps, environment filtering)
# in each animation frame, with the frame's wall-clock time in ms (frames that draw nothing too: their times show
# when the page was frozen).
DRAW_COUNTER = textwrap.dedent("""
    (() => {
      const state = { screen: 0, frames: [] };
      window.__plemDraws = state;
      for (const proto of [WebGLRenderingContext.prototype, WebGL2RenderingContext.prototype]) {
        const bind = proto.bindFramebuffer;
        proto.bindFramebuffer = function (target, framebuffer) {
          this.__plemOffscreen = framebuffer !== null;
          return bind.call(this, target, framebuffer);
        };
        for (const name of ["drawElements", "drawArrays", "drawElementsInstanced", "drawArraysInstanced"]) {
          const draw = proto[name];
          if (draw) proto[name] = function (...args) {
            if (!this.__plemOffscreen) state.screen += 1;
            return draw.apply(this, args);
          };
        }
      }
      const tick = (t) => {
        state.frames.push([performance.timeOrigin + t, state.screen]);
        state.screen = 0;
        requestAnimationFrame(tick);
      };
      requestAnimationFrame(tick);
    })();
""")

# argv: "urdf" PATH or "empty". Viser's defaults, as its own examples start it; prints the address.
VISER_ALONE = textwrap.dedent("""
    import sys, viser
    from pathlib import Path
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    if sys.argv[1] == "urdf":
        from viser.extras import ViserUrdf
        ViserUrdf(server, Path(sys.argv[2]))
    print(f"at http://127.0.0.1:{server.get_port()}", flush=True)
    import threading
    threading.Event().wait()
""")


@dataclass
class Start:
    kind: str            # "plem", "viser" (viser's URDF viewer, the baseline) or "empty" (an empty viser page)
    address_s: float     # the server printed its address
    frame_s: float       # the first frame with everything drawn
    draws: int           # draw calls in that frame


def first_frame(page: Any, started_ms: float) -> tuple[float, int]:
    """Seconds from `started_ms` to the first frame with as many draw calls as the page settles at, after which
    the page never froze for STALL_S (a frame that the page then stops on is not the arm shown), and that count."""
    deadline = time.monotonic() + FRAME_TIMEOUT_S
    most, grew = 0, time.monotonic()
    while time.monotonic() < deadline:
        frames = page.evaluate("window.__plemDraws.frames")
        top = max((count for _, count in frames), default=0)
        if top > most:
            most, grew = top, time.monotonic()
        elif most and time.monotonic() - grew >= SETTLED_S:
            times = [when for when, _ in frames]
            last_stall = max((index for index in range(1, len(times))
                              if times[index] - times[index - 1] > STALL_S * 1e3), default=0)
            shown = next((when for when, count in frames[last_stall:] if count == most), None)
            if shown is not None:
                return (shown - started_ms) / 1e3, most
        page.wait_for_timeout(250)
    raise SystemExit("the page never settled")


def address(process: subprocess.Popen) -> str:
    """The URL a view prints (viser alone prints its banner first)."""
    assert process.stdout is not None
    deadline = time.monotonic() + START_TIMEOUT_S
    while select.select([process.stdout], [], [], max(0.0, deadline - time.monotonic()))[0]:
        line = process.stdout.readline()
        match = re.search(r"at (http://\S+)", line)
        if match is not None:
            return match.group(1)
        if not line:
            break
    raise SystemExit(f"the view did not start (exit {process.poll()})")


def measure(browser: Any, kind: str, command: list[str]) -> Start:
    """Start `command`, open its page in a fresh tab of the running browser, and time its first full frame."""
    page = browser.new_page(viewport={"width": 1000, "height": 700})
    page.add_init_script(DRAW_COUNTER)
    started_ms = time.time() * 1e3
    process = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        url = address(process)
        address_s = time.time() - started_ms / 1e3
        page.goto(url, wait_until="commit", timeout=START_TIMEOUT_S * 1e3)
        frame_s, draws = first_frame(page, started_ms)
    finally:
        page.close()
        stop(process, signal.SIGTERM)
    return Start(kind, address_s, frame_s, draws)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--busy", type=int, default=0, help="busy processes kept running throughout")
    args = parser.parse_args()
    machine = begin_run()
    command = f"sudo .venv/bin/python benchmarks/view_first_frame.py --rounds {args.rounds} --busy {args.busy}"
    children: list[subprocess.Popen] = []
    robot_id = f"framebench_{uuid.uuid4().hex[:6]}"
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="plem_first_frame_") as work, sync_playwright() as playwright:
        try:
            launch(robot_id, dict(os.environ), Path(work) / "launch.log", children, bridge=False, record=False)
            with connect(robot_id) as client:
                first_sample(client, 1.0)
            urdf = Path(work) / "robot.urdf"
            urdf.write_text(read_description(robot_id).urdf)
            children += [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.busy)]
            commands = {"plem": [sys.executable, "-m", "plem.cli", "view", robot_id, "--port", "0"],
                        "viser": [sys.executable, "-c", VISER_ALONE, "urdf", str(urdf)],
                        "empty": [sys.executable, "-c", VISER_ALONE, "empty"]}
            browser = playwright.chromium.launch(executable_path="/usr/bin/chromium", headless=True,
                                                 args=list(CHROMIUM_FLAGS))
            rounds: list[dict[str, Start]] = []
            kinds = list(commands)
            for number in range(args.rounds):
                starts: dict[str, Start] = {}
                for kind in kinds[number % 3:] + kinds[:number % 3]:     # the order rotates between rounds
                    starts[kind] = measure(browser, kind, commands[kind])
                    print(f"round {number + 1:>2} {kind:<6} address {starts[kind].address_s:5.2f} s, first frame "
                          f"{starts[kind].frame_s:5.2f} s ({starts[kind].draws} draws)", flush=True)
                rounds.append(starts)
            browser.close()
        finally:
            stop_all(children)
    report(rounds, args, command, machine)


def report(rounds: list[dict[str, Start]], args: argparse.Namespace, command: str, machine: str) -> None:
    """The table and the summary for BENCHMARKS.md."""
    print("\n---- results (for BENCHMARKS.md) ----")
    print(f"Command: `{command}`. Machine: {machine}.\n")
    print("| round | plem view: address (s) | plem view: first frame (s) | viser's URDF viewer: first frame (s) | "
          "ratio | empty viser page: first frame (s) |")
    print("| --- | --- | --- | --- | --- | --- |")
    ratios = []
    for number, starts in enumerate(rounds, start=1):
        plem, viser, empty = starts["plem"], starts["viser"], starts["empty"]
        ratios.append(plem.frame_s / viser.frame_s)
        print(f"| {number} | {plem.address_s:.2f} | {plem.frame_s:.2f} | {viser.frame_s:.2f} | {ratios[-1]:.2f} | "
              f"{empty.frame_s:.2f} |")

    def median(kind: str, field: str) -> float:
        return statistics.median(getattr(starts[kind], field) for starts in rounds)

    spread = {kind: (min(s[kind].frame_s for s in rounds), max(s[kind].frame_s for s in rounds)) for kind in rounds[0]}
    print(f"\nTime to first frame, median of {args.rounds} rounds ({args.busy} busy processes): plem view "
          f"**{median('plem', 'frame_s'):.2f} s** (spread {spread['plem'][0]:.2f}–{spread['plem'][1]:.2f}; its "
          f"address after {median('plem', 'address_s'):.2f} s); viser's URDF viewer {median('viser', 'frame_s'):.2f} s "
          f"(spread {spread['viser'][0]:.2f}–{spread['viser'][1]:.2f}); an empty viser page "
          f"{median('empty', 'frame_s'):.2f} s. plem ÷ viser: median **{statistics.median(ratios):.2f}×** (spread "
          f"{min(ratios):.2f}–{max(ratios):.2f}; at most 1×: {verdict(statistics.median(ratios) <= 1.0)}).")


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        raise SystemExit("interrupted; the launch, the views and the browser were stopped") from None
