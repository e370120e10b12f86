"""A frozen reliable subscriber of rt_raw slows neither the loop nor the bridge: nothing is lost before DDS."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path
from typing import Any

from plem.bridge import connect
from plem.middleware.node import Node
from plem.middleware.qos import DEFAULT
from tests.e2e.launched import clean_environment, launched, new_robot_id, python_client, read_line, wait_until

SUBSCRIBER = """
    import sys, time
    from plem.middleware.node import Node
    from plem.middleware.qos import RT_RAW
    raw = Node().subscription(f"/{sys.argv[1]}/rt_raw", "plem_msgs/msg/RtRaw", RT_RAW)
    while not raw.take():
        time.sleep(0.01)
    print("receiving", flush=True)
    while True:
        raw.take()
        time.sleep(0.01)
"""


def newest_stats(node: Node, robot_id: str, timeout: float = 5.0) -> Any:
    """The first rt_monitor_stats a fresh subscription receives (they come at 10 Hz)."""
    stats = node.subscription(f"/{robot_id}/rt_monitor_stats", "plem_msgs/msg/RtMonitorStats", DEFAULT)
    received: list[Any] = []
    assert wait_until(lambda: bool(received.extend(stats.take()) or received), timeout), "no rt_monitor_stats"
    return received[-1]


def queue_counts(stats: Any) -> dict[str, Any]:
    return {queue.name: queue for queue in stats.queues}


def test_a_frozen_reliable_subscriber_slows_neither_loop_nor_bridge(tmp_path: Path):
    robot_id = new_robot_id()
    env = clean_environment(tmp_path / "home")
    with launched(["bus:=mock", f"robot_id:={robot_id}", "record:=false"], [robot_id], tmp_path, env):
        subscriber = python_client(SUBSCRIBER, robot_id, env=env)
        node = Node()
        try:
            assert read_line(subscriber, 20).strip() == "receiving", \
                subscriber.stderr.read() if subscriber.poll() is not None else ""
            published = queue_counts(newest_stats(node, robot_id))["dds:rt_raw"].written
            os.kill(subscriber.pid, signal.SIGSTOP)   # no more acknowledgements: the writer's history fills
            with connect(robot_id) as client:
                before = client.wait_for_state().cycle
                time.sleep(4.0)                       # four times the rt_raw history depth at 1 kHz
                after = client.wait_for_state().cycle
            assert after - before > 3500, "the loop slowed down"
            queues = queue_counts(newest_stats(node, robot_id))
            assert queues["rt_raw"].dropped == 0, "the bridge kept reading shared memory"
            assert queues["dds:rt_raw"].written - published >= 3500, "the bridge kept publishing"
        finally:
            subscriber.kill()
            subscriber.wait()
            node.close()
