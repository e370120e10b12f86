"""Without real-time rights the loop still runs, with one warning per refused step saying how to allow it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    from plem.control.loop import CycleLoop, LoopSettings
    seen = []
    loop = CycleLoop(lambda: None, LoopSettings(cycle_time_ns=1_000_000, priority=80), on_warning=seen.append)
    loop.run(duration_s=0.05)
    print(loop.report.policy, loop.stats.cycles)
    print("\\n".join(seen))
""")


UNPRIVILEGED = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", sys.executable, "-c"]


def run_unprivileged(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([*UNPRIVILEGED, code], capture_output=True, text=True, timeout=60, cwd="/",
                          env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which("setpriv") is None,
                    reason="needs root and setpriv to run the loop as an unprivileged user")
def test_unprivileged_loop_runs_and_says_how_to_get_realtime():
    probe = run_unprivileged("import plem.control.loop")
    if probe.returncode != 0:
        assert "Permission denied" in probe.stderr or "PermissionError" in probe.stderr, probe.stderr
        pytest.skip("the checkout is not readable by an unprivileged user (permission denied), so the loop "
                    "cannot be run without root here")
    result = run_unprivileged(SCRIPT)
    assert result.returncode == 0, result.stderr
    first, *warnings = result.stdout.splitlines()
    policy, cycles = first.split()
    assert policy == "SCHED_OTHER" and int(cycles) > 10
    text = "\n".join(warnings)
    assert "SCHED_FIFO priority 80 not permitted" in text and "ulimit -r" in text
    assert len([w for w in warnings if "SCHED_FIFO" in w]) == 1
