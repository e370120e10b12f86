"""plem's files in /dev/shm left by a killed writer: found by the pid they name, removed by the next launch or stop.

`plem launch` shares its robot's description (`plem_description_{robot_id}.json`) and the recorder its
counters (`plem_recorder_{robot_id}.json`); each names its writer's pid and is removed by its writer when it
ends, but a writer killed with SIGKILL leaves it behind. `remove_stale_files` removes every such file of this
user whose writer no longer runs. Another user's file, a file whose writer runs, and a file that is not of
plem's shape are left alone.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from plem.core.files import UntrustedFile, open_trusted
from plem.ipc.segment import SHM_DIRECTORY
from plem.ipc.state_segment import process_alive

#: The names of the files a writer shares beside a robot's shared memory.
SHARED_FILES = ("plem_description_*.json", "plem_recorder_*.json")
#: The largest such file read (a description's URDF of a few thousand lines fits many times).
MAX_BYTES = 16 << 20


def writer(path: Path) -> tuple[int, int] | None:
    """(pid the file names as its writer, the file's inode) for a file of this user and of plem's shape; None for
    anything else (another user's, a link, a FIFO, not JSON with a pid)."""
    try:
        fd, status = open_trusted(path, os.O_RDONLY, {os.geteuid()})
    except (UntrustedFile, OSError):
        return None
    with os.fdopen(fd, "rb") as handle:
        data = handle.read(MAX_BYTES + 1) if status.st_size <= MAX_BYTES else b""
    try:
        payload = json.loads(data)
    except (ValueError, RecursionError):
        return None
    pid = payload.get("pid") if isinstance(payload, dict) else None
    return (pid, status.st_ino) if type(pid) is int and pid > 0 else None


def remove_stale_files(directory: Path = SHM_DIRECTORY) -> list[Path]:
    """Remove this user's shared files in `directory` whose writer no longer runs; the paths removed.

    A file replaced meanwhile (a new writer renamed its own over it) is left to its new writer."""
    removed = []
    for pattern in SHARED_FILES:
        for path in sorted(directory.glob(pattern)):
            found = writer(path)
            if found is None or process_alive(found[0]):
                continue
            try:
                if os.lstat(path).st_ino == found[1]:
                    os.unlink(path)
                    removed.append(path)
            except FileNotFoundError:
                continue
    return removed
