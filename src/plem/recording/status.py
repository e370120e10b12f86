"""The recorder's counters in shared memory, so the bridge reports them in rt_monitor_stats as well.

The recorder rewrites `/dev/shm/plem_recorder_{robot_id}.json` (JSON, atomically) twice a second and
removes it when it ends (the name stays out of the driver's `{robot_id}_*` set). It is owner-only, or
readable by the group of `shm_group:=` as the robot's shared memory is. /dev/shm is open to every local
user, so a reader takes the file only when it is a regular file of its own user or root, small, and of
the expected shape; anything else, and a file left by a killed recorder (its pid no longer runs), is
ignored: the counters are a report, never a reason for the bridge to stop. The next launch, or the stop of
any launch, removes a file a killed recorder left (`plem.ipc.leftovers`).
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

from plem.core.files import UntrustedFile, read_trusted, remove_own, write_shared
from plem.ipc.segment import SHM_DIRECTORY
from plem.ipc.state_segment import process_alive
from plem.middleware.monitor_feed import QueueCount

#: The largest status file read; the recorder's own are a few hundred bytes.
MAX_STATUS_BYTES = 64 * 1024
MAX_QUEUES = 64
#: Linux's highest possible pid (pid_max cannot exceed it).
MAX_PID = 4_194_304
_FIELDS = tuple(field.name for field in fields(QueueCount))
_COUNTER_LIMITS = {"capacity": 2**32, "fill": 2**32, "written": 2**64, "dropped": 2**64}
_log = logging.getLogger("plem.recorder")
_warned: set[Path] = set()


def status_path(robot_id: str) -> Path:
    """The recorder's status file of `robot_id` in /dev/shm, where the bridge reads its counters."""
    return SHM_DIRECTORY / f"plem_recorder_{robot_id}.json"


def write_status(robot_id: str, queues: list[QueueCount], group: int | None = None) -> None:
    """Replace the recorder's status file with these counters (owner-only, or 0640 with `group`)."""
    payload = {"pid": os.getpid(), "queues": [asdict(queue) for queue in queues]}
    write_shared(status_path(robot_id), json.dumps(payload), group)


def remove_status(robot_id: str) -> None:
    """Remove the status file if it is this user's: a file another user put there is not ours to remove."""
    remove_own(status_path(robot_id))


def read_status(robot_id: str) -> list[QueueCount]:
    """The running recorder's queues, named `recorder:<queue>`; none when no trusted recorder runs."""
    path = status_path(robot_id)
    try:
        data = read_trusted(path, MAX_STATUS_BYTES)
    except FileNotFoundError:
        return []
    except (UntrustedFile, OSError) as error:
        _ignore(path, str(error))
        return []
    if not data:
        _ignore(path, f"empty or larger than {MAX_STATUS_BYTES} bytes")
        return []
    try:
        pid, queues = _parse(json.loads(data))
    except (ValueError, RecursionError) as error:
        _ignore(path, f"not a recorder status: {error}")
        return []
    if not process_alive(pid):
        return []
    return [QueueCount(**{**asdict(queue), "name": f"recorder:{queue.name}"}) for queue in queues]


def _parse(payload: Any) -> tuple[int, list[QueueCount]]:
    """The pid and queues of a status document; ValueError unless every key and type is as the recorder writes."""
    if not isinstance(payload, dict) or set(payload) != {"pid", "queues"}:
        raise ValueError("expected an object with 'pid' and 'queues'")
    pid, queues = payload["pid"], payload["queues"]
    if type(pid) is not int or not 0 < pid <= MAX_PID:
        raise ValueError("'pid' is not a process id")
    if not isinstance(queues, list) or len(queues) > MAX_QUEUES:
        raise ValueError(f"'queues' is not a list of at most {MAX_QUEUES} queues")
    return pid, [_queue(queue) for queue in queues]


def _queue(entry: Any) -> QueueCount:
    if not isinstance(entry, dict) or set(entry) != set(_FIELDS):
        raise ValueError(f"a queue must have exactly {', '.join(_FIELDS)}")
    if not isinstance(entry["name"], str) or not 0 < len(entry["name"]) <= 64:
        raise ValueError("a queue name must be a string of 1 to 64 characters")
    for name, limit in _COUNTER_LIMITS.items():
        value = entry[name]
        if type(value) is not int or not 0 <= value < limit:
            raise ValueError(f"queue {entry['name']!r}: {name} is not a counter")
    return QueueCount(**entry)


def _ignore(path: Path, reason: str) -> None:
    """Log, once per file and process, that a status file was ignored."""
    if path not in _warned:
        _warned.add(path)
        _log.warning("ignoring %s: %s", path, reason)
