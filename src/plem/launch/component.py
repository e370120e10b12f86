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
import sys
import threading
from collections.abc import Callable, Sequence
from typing import Any

from plem.errors import PlemError

PR_SET_PDEATHSIG = 1
_announced = threading.Event()


def run_component(name: str, body: Callable[[dict[str, str], threading.Event], None],
                  argv: Sequence[str] | None = None) -> int:
    """A component's main: `body(launch arguments, stop event)`; its exit code.

    An error before the component announced itself becomes its `{"ready": false}` line; one after is logged.
    """
    argv = sys.argv[1:] if argv is None else argv
    stop = begin(name)
    try:
        body(json.loads(argv[0]), stop)
    except PlemError as error:
        if _announced.is_set():
            logging.getLogger(f"plem.{name}").error("%s", error.log_text())
        else:
            announce({"ready": False, "error": error.to_dict()})
        return 1
    return 0


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
    """An event set by SIGTERM or SIGINT.

    The handler sets it from a thread of its own: a handler runs inside whatever the main thread was doing,
    which may hold the event's lock (or be an earlier handler setting it), and setting it there would deadlock.
    """
    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: threading.Thread(target=stop.set, daemon=True).start())
    return stop


def announce(payload: dict[str, Any]) -> None:
    """The component's one line on stdout."""
    print(json.dumps(payload), flush=True)
    _announced.set()
