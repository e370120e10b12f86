"""The recorder process: one robot's monitoring topics from shared memory into rosbag2 bags.

`plem launch` starts it after the robot's RT driver (and bridge) when `record:=true`, as
`python -m plem.launch.recorder '<launch arguments as JSON>'`. It runs at normal priority and only reads
shared memory, so a slow or full disk never reaches the loop: the rings hold about four seconds, and
what the recorder could not keep is counted. On a stop signal it records on until the driver has
stopped the arm (at most `DRAIN_TIMEOUT_S`), so the stop is in the bag too. Every segment starts with the
robot's URDF text (robot_description, as the bridge publishes it), and its metadata.yaml says who recorded it
(robot, serial, model, host, plem version). Everything it writes is owner-only, or readable by the group of
`shm_group:=` as the robot's shared memory is. With `export_dir:=` a child process at idle priority exports each
closed segment into the fleet dataset (plem.fleet.follow).
"""

from __future__ import annotations

import functools
import logging
import os
import subprocess
import sys
import threading
import time
from dataclasses import replace

from plem.bridge.client import DriverGone, RobotClient, connect
from plem.ipc.state_segment import process_alive
from plem.launch.component import announce, run_component
from plem.launch.plan import bag_directory, plan_robot
from plem.middleware.monitor_feed import MONITOR_TOPICS, QueueCount
from plem.middleware.types import library
from plem.recording.access import restrict_umask
from plem.recording.disk_use import disk_use
from plem.recording.feed import RecordingFeed
from plem.recording.identity import identity
from plem.recording.problems import refuse_unusable
from plem.recording.recorder import Recorder
from plem.recording.settings import RecordingSettings
from plem.recording.status import remove_status, write_status

_log = logging.getLogger("plem.recorder")
#: How often the recorder reads the rings (they hold about 4 s at 1 kHz): each read is one batch, whose fixed
#: cost (a few numpy calls) a longer period spreads over more records.
PUMP_PERIOD_S = 0.1
LIVENESS_PERIOD_S = 0.5
#: After a stop signal, how long the recorder waits for the driver to finish its smooth stop.
DRAIN_TIMEOUT_S = 10.0
#: The recorder process's nice value: ahead of the machine's ordinary processes, so a busy machine still gives it
#: the few percent of a core it needs within the four seconds the rings hold (never ahead of the real-time loops,
#: which run SCHED_FIFO).
RECORDER_NICE = -10
#: After recording ends, how long the continuous export may take to export the last segment.
EXPORT_STOP_S = 30.0


def record(arguments: dict[str, str], stop: threading.Event, nice: int | None = None) -> None:
    """Record until the RT driver is gone, or `DRAIN_TIMEOUT_S` after `stop`; at `nice` when given and allowed.

    A bag_dir the recorder cannot create or write into is one RecordingError (WHAT/WHY/HOW), raised before
    the driver is even looked for.
    """
    if nice is not None:
        try:
            os.setpriority(os.PRIO_PROCESS, 0, nice)
        except PermissionError as error:
            _log.warning("recording at normal priority: nice %d refused (%s); on a busy machine the recorder may "
                         "lose cycles: run plem launch as root, or give it CAP_SYS_NICE", nice, error.strerror)
    refuse_unusable(bag_directory(arguments))            # before the plan, whose checks would stumble on it
    plan = plan_robot(arguments, generate=False)
    settings = replace(plan.recording(), group=plan.shm_group)
    interfaces = library()
    recorder = Recorder(settings, plan.robot_id, MONITOR_TOPICS, interfaces.store,   # the bag_dir is checked first
                        description=plan.robot_description,
                        identity=identity(plan.robot_id, plan.config.robot_serial, plan.config.MODEL.name
                                          if plan.config.MODEL else plan.robot_name, plan.joint_names))
    client = connect(plan.robot_id, plan.config.dof)
    exporter = start_export(arguments, settings)
    feed = RecordingFeed(client, interfaces, plan.joint_state_rate())
    try:
        use = disk_use(settings, client.joint_names, client.cycle_time_s, plan.joint_state_rate(), interfaces)
        announce({"ready": True, "directory": str(settings.directory),
                  "settings": f"{settings.describe()}; {use.describe()}"})
        run(client, feed, recorder, stop, plan.shm_group)
    finally:
        try:
            feed.pump_batch(recorder)
        finally:
            recorder.close()
            remove_status(plan.robot_id)
            client.close()
            stop_export(exporter)


def start_export(arguments: dict[str, str], settings: RecordingSettings) -> subprocess.Popen[bytes] | None:
    """The continuous export of closed segments into `export_dir:=` (plem.fleet.follow), a child process at idle
    priority; None without export_dir."""
    if not arguments.get("export_dir"):
        return None
    environment = {**os.environ, "PLEM_LAUNCH_PID": str(os.getpid())}     # it dies with the recorder
    return subprocess.Popen([sys.executable, "-m", "plem.fleet.follow", str(settings.directory),
                             arguments["export_dir"], f"{settings.disk_threshold:g}"], env=environment,
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL)


def stop_export(exporter: subprocess.Popen[bytes] | None) -> None:
    """Let the export take the last segment (at most `EXPORT_STOP_S`), then end it."""
    if exporter is None:
        return
    exporter.terminate()
    try:
        exporter.wait(EXPORT_STOP_S)
    except subprocess.TimeoutExpired:
        exporter.kill()                       # a file it was writing is written again by the next export
        exporter.wait()


def run(client: RobotClient, feed: RecordingFeed, recorder: Recorder, stop: threading.Event,
        group: int | None = None) -> None:
    """Pump the feed into the recorder, keep the disk in check, publish the recorder's counters."""
    next_check = time.monotonic()
    drain_deadline: float | None = None
    published = True
    while True:
        feed.pump_batch(recorder)
        recorder.maintain()
        now = time.monotonic()
        if now >= next_check:
            published = publish_status(client.robot_id, [*recorder.queues(), *feed.reader_queues()], group,
                                       published)
            if not driver_running(client):
                return
            next_check = now + LIVENESS_PERIOD_S
        if stop.is_set():
            drain_deadline = drain_deadline or now + DRAIN_TIMEOUT_S
            if now >= drain_deadline:
                return
        time.sleep(PUMP_PERIOD_S)


def publish_status(robot_id: str, queues: list[QueueCount], group: int | None, published: bool) -> bool:
    """Write the counters for the bridge; False when refused (logged when it starts failing), recording goes on."""
    try:
        write_status(robot_id, queues, group)
    except OSError as error:
        if published:
            _log.warning("recorder counters not published (%s); the bridge will not report them", error)
        return False
    return True


def driver_running(client: RobotClient) -> bool:
    """The driver still writes cycles: its process runs and its heartbeat is fresh."""
    if not process_alive(client.channels.rings["rt_raw"].writer_pid):
        return False
    try:
        client.live_state()
    except DriverGone:
        return False
    return True


def main(argv: list[str] | None = None) -> int:
    """The recorder process; its umask is owner-only because rosbags creates the bag files itself."""
    restrict_umask()
    return run_component("recorder", functools.partial(record, nice=RECORDER_NICE), argv)


if __name__ == "__main__":
    sys.exit(main())
