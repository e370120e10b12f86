"""The launch's stop order: a virtual EtherCAT network outlives the RT driver whose drives it emulates, so the
driver's smooth stop and the disabling of the drives still reach them (otherwise a clean Ctrl-C ends in a fault)."""

from __future__ import annotations

import io
import subprocess
import sys
import time
from pathlib import Path

from plem.launch.supervisor import Child, Supervisor

#: A child process: on SIGTERM the driver takes `delay` s to stop its arm, then leaves a marker file as it exits;
#: the network writes down whether that marker was there when it was told to stop.
_CHILD = """
import pathlib, signal, sys, time
role, marker, seen, ready, delay = sys.argv[1:6]
def stop(*_):
    if role == "network":
        pathlib.Path(seen).write_text("driver ended" if pathlib.Path(marker).exists() else "driver running")
    time.sleep(float(delay))
    if role == "driver":
        pathlib.Path(marker).touch()
    sys.exit(0)
signal.signal(signal.SIGTERM, stop)
pathlib.Path(ready).touch()
while True:
    time.sleep(1)
"""


def _child(component: str, role: str, tmp_path: Path, delay: float) -> Child:
    ready = tmp_path / f"{role}.ready"
    process = subprocess.Popen([sys.executable, "-c", _CHILD, role, str(tmp_path / "driver_ended"),
                                str(tmp_path / "seen"), str(ready), str(delay)])
    deadline = time.monotonic() + 30
    while not ready.exists():
        assert process.poll() is None and time.monotonic() < deadline, f"the {role} did not start"
        time.sleep(0.01)
    return Child("arm", component, process, critical=True, ready={"ready": True})


def test_the_virtual_network_is_stopped_only_after_the_driver_ended(tmp_path: Path):
    out = io.StringIO()
    supervisor = Supervisor([], out=out)
    # started in launch order: the network first, then the driver (which takes a while to stop its arm)
    supervisor.children = [_child("ethercat_sim", "network", tmp_path, 0.0),
                           _child("rt_driver", "driver", tmp_path, 0.5)]
    supervisor._stop_all()
    assert (tmp_path / "seen").read_text() == "driver ended"
    lines = out.getvalue().splitlines()
    assert lines.index("[arm/rt_driver] stopped (exited with code 0)") < \
        lines.index("[arm/ethercat_sim] stopped (exited with code 0)"), lines
