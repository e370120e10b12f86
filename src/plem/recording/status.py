"""The recorder's counters in shared memory, so the bridge reports them in rt_monitor_stats as well.

The recorder rewrites `/dev/shm/plem_recorder_{robot_id}.json` (JSON, atomically, owner only) twice a
second and removes it when it ends (the name stays out of the driver's `{robot_id}_*` set); a file left
by a killed recorder is ignored because its pid no longer runs.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict
from pathlib import Path

from plem.core.files import write_atomic
from plem.ipc.segment import SHM_DIRECTORY
from plem.ipc.state_segment import process_alive
from plem.middleware.monitor_feed import QueueCount


def status_path(robot_id: str) -> Path:
    return SHM_DIRECTORY / f"plem_recorder_{robot_id}.json"


def write_status(robot_id: str, queues: list[QueueCount]) -> None:
    payload = {"pid": os.getpid(), "queues": [asdict(queue) for queue in queues]}
    write_atomic(status_path(robot_id), json.dumps(payload), mode=0o600)


def remove_status(robot_id: str) -> None:
    status_path(robot_id).unlink(missing_ok=True)


def read_status(robot_id: str) -> list[QueueCount]:
    """The running recorder's queues, named `recorder:<queue>`; none when no recorder runs."""
    try:
        payload = json.loads(status_path(robot_id).read_text())
    except (OSError, ValueError):
        return []
    if not process_alive(payload["pid"]):
        return []
    return [QueueCount(**{**queue, "name": f"recorder:{queue['name']}"}) for queue in payload["queues"]]
