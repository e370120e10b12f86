"""What every child process of `plem launch` does alike: die with the launch, stop on signals, announce itself.

A component prints exactly one JSON line on stdout: `{"ready": true, ...}` once it runs, or
`{"ready": false, "error": {...}}` with the WHAT/WHY/HOW of why it could not start.
"""

from __future__ import annotations

import ctypes
import json
import logging
import os
import signal
import threading
from typing import Any

PR_SET_PDEATHSIG = 1


def begin(name: str) -> threading.Event:
    """Start a component process: its log format, death with the launch, and the event its signals set."""
    logging.basicConfig(level=logging.INFO, format=f"[{name}] %(levelname)s: %(message)s")
    die_with_parent()
    return stop_on_signals()


def die_with_parent() -> None:
    """Ask the kernel for SIGTERM when the launching process exits (and catch a parent already gone)."""
    parent = int(os.environ.get("PLEM_LAUNCH_PID", os.getppid()))
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    if os.getppid() != parent:
        os.kill(os.getpid(), signal.SIGTERM)


def stop_on_signals() -> threading.Event:
    """An event set by SIGTERM or SIGINT."""
    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: stop.set())
    return stop


def announce(payload: dict[str, Any]) -> None:
    """The component's one line on stdout."""
    print(json.dumps(payload), flush=True)
