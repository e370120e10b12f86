"""The recorder's CPU per record, next to rosbags' writer alone writing the same messages, with or without CPU hogs.

Usage: python benchmarks/recorder_cpu.py [--seconds 20] [--hogs 2]
Needs root (the launched loop runs SCHED_FIFO).

What runs:
  robot      `plem launch bus:=mock robot_id:=bench_cpu_<hex> bridge:=false record:=false` (Indy7 v2, the
             simulated arm at 1 kHz) in a subprocess.
  hogs       --hogs processes spinning in Python at normal priority (2 busy cores on a 2-core machine), started
             before the recorders.
  recorders  two processes at once, each reading the robot's rings itself (rings have independent readers) for
             --seconds and writing 20 s MCAP segments:
               batched     what `plem launch record:=true` runs: `RecordingFeed.pump_batch` into `Recorder.record`
                           (one ring copy per pump, numpy serialisation, bulk MCAP records);
               per message the same `Recorder` fed one message at a time by `MonitorFeed.pump` (the recorder's
                           path before batching), stopped at the window's end even mid-pump.
             Each reports its process CPU time (utime + stime), the rt_raw records it handed to the bag and the
             records its ring reader lost (the ring holds 4096 cycles).
  baseline   after the window, every message the batched recorder wrote is read back with rosbags (untimed) and
             written again, one `rosbags.rosbag2.Writer.write` call per message, into a fresh MCAP bag (timed:
             process CPU time): the bare cost of the bag writer for the same messages, with no ring reading and no
             serialisation.
Reported: CPU µs per rt_raw record (all topics' messages included in the cost), % of one core, records lost, and
the ratio to the baseline.
"""

from __future__ import annotations

import argparse
import json
import os
import secrets
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rosbags.rosbag2 import Reader, StoragePlugin, Writer

from launching import begin_run, launch, ratio, stop, stop_all

HOG = "while True: pass"

# argv: robot_id, mode (batched | message), seconds, bag directory. Prints one JSON line.
CHILD = """
import json, sys, time
from dataclasses import replace
from pathlib import Path
from plem.bridge import connect
from plem.launch.plan import plan_robot
from plem.launch.recorder import PUMP_PERIOD_S
from plem.middleware.monitor_feed import MONITOR_TOPICS, MonitorFeed
from plem.middleware.types import library
from plem.recording.feed import RecordingFeed
from plem.recording.recorder import Recorder

robot_id, mode, seconds, directory = sys.argv[1], sys.argv[2], float(sys.argv[3]), Path(sys.argv[4])


class WindowOver(Exception):
    pass


class Bounded(Recorder):
    raw = 0

    def rt_raw(self, cdr, wall_ns):
        if time.monotonic() >= end:
            raise WindowOver
        super().rt_raw(cdr, wall_ns)
        self.raw += 1


plan = plan_robot({"bus": "mock", "robot_id": robot_id}, generate=False)
settings = replace(plan.recording(), directory=directory, segment_s=20.0)
interfaces = library()
recorder = Bounded(settings, robot_id, MONITOR_TOPICS, interfaces.store, description=plan.robot_description)
client = connect(robot_id, plan.config.dof)
batched = mode == "batched"
feed = (RecordingFeed if batched else MonitorFeed)(client, interfaces, plan.joint_state_rate(),
                                                   **({} if batched else {"history": True}))
feed.readers["rt_raw"] = client.channels.rings["rt_raw"].reader()     # from the window's start, not the ring's past
cpu0, batched_records = time.process_time(), 0
end = time.monotonic() + seconds
try:
    while time.monotonic() < end:
        batched_records += feed.pump_batch(recorder) if batched else feed.pump(recorder)
        recorder.maintain()
        time.sleep(PUMP_PERIOD_S)
except WindowOver:
    pass
cpu = time.process_time() - cpu0
recorder.close()
raw = feed.readers["rt_raw"]
records = batched_records if batched else recorder.raw
print(json.dumps({"cpu_s": cpu, "records": records, "written": recorder.written, "lost": raw.dropped,
                  "behind": raw.pending}))
client.close()
"""


def child(robot_id: str, mode: str, seconds: float, directory: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", CHILD, robot_id, mode, str(seconds), str(directory)],
                            stdout=subprocess.PIPE, text=True)


def baseline(bag_root: Path, target: Path) -> tuple[float, int, int]:
    """(CPU s, rt_raw messages, all messages) of rosbags' writer writing every message of the bags under `bag_root`."""
    messages = []
    connections = {}
    for segment in sorted(p for p in bag_root.iterdir() if p.is_dir()):
        with Reader(segment) as reader:
            for connection in reader.connections:
                connections[connection.topic] = connection
            messages += [(connection.topic, stamp, data) for connection, stamp, data in reader.messages()]
    writer = Writer(target, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    added = {topic: writer.add_connection(topic, connection.msgtype, msgdef=connection.msgdef.data,
                                          rihs01=connection.digest)
             for topic, connection in connections.items()}
    cpu0 = time.process_time()
    for topic, stamp, data in messages:
        writer.write(added[topic], stamp, data)
    writer.close()
    cpu = time.process_time() - cpu0
    return cpu, sum(topic.endswith("/rt_raw") for topic, _, _ in messages), len(messages)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="the recording window")
    parser.add_argument("--hogs", type=int, default=2, help="busy processes at normal priority")
    args = parser.parse_args()
    machine = begin_run()
    work = Path(tempfile.mkdtemp(prefix="plem-bench-rec-cpu-"))
    children: list[subprocess.Popen] = []
    try:
        robot_id = f"bench_cpu_{secrets.token_hex(4)}"
        robot = launch(robot_id, dict(os.environ), work / "launch.log", children, bridge=False, record=False)
        time.sleep(1.0)
        hogs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(args.hogs)]
        children += hogs
        runs = {mode: child(robot_id, mode, args.seconds, work / mode) for mode in ("batched", "message")}
        results = {mode: json.loads(process.communicate(timeout=args.seconds + 120)[0]) for mode, process in
                   runs.items()}
        for hog in hogs:
            hog.kill()
        stop(robot.process)
        base_cpu, base_raw, base_all = baseline(work / "batched", work / "baseline")
        base_us = base_cpu / base_raw * 1e6
        print(f"machine: {machine}; load average {os.getloadavg()[0]:.2f}")
        print(f"Command: `.venv/bin/python benchmarks/recorder_cpu.py --seconds {args.seconds:g} --hogs {args.hogs} "
              f"` (as root). 1 kHz, {args.hogs} CPU hogs, {args.seconds:g} s.\n")
        print("| path | CPU µs per rt_raw record | % of one core | rt_raw records | ring records lost | "
              "unread at the end | ratio to baseline |")
        print("| --- | --- | --- | --- | --- | --- | --- |")
        for mode, figures in results.items():
            per_record = figures["cpu_s"] / max(figures["records"], 1) * 1e6
            print(f"| plem recorder, {mode} | {per_record:.1f} | {figures['cpu_s'] / args.seconds * 100:.1f} | "
                  f"{figures['records']} | {figures['lost']} | {figures['behind']} | {ratio(per_record, base_us)} |")
        print(f"| baseline: rosbags Writer.write alone, the batched bag's {base_all} messages again | {base_us:.1f} | "
              f"- | {base_raw} | - | - | 1.00x |")
    finally:
        stop_all(children)
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
