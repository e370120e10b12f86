"""A component's start is waited for while it works: real child processes that compute, sleep, exit or announce."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator

import pytest

from plem.launch import startup


def child(code: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)


@pytest.fixture
def short_waits(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Stall and notice periods of a second or less, so that a few seconds of work outlast them."""
    monkeypatch.setattr(startup, "STALL_S", 1.0)
    monkeypatch.setattr(startup, "NOTICE_PERIOD_S", 0.5)
    yield


# A child that needs 1.5 s of its own CPU before it answers: longer than the stall period, however busy the host.
WORKS_THEN_ANSWERS = """
import time
cpu = time.process_time()
while time.process_time() - cpu < 1.5:
    sum(range(1000))
print('{"ready": true}', flush=True)
"""


def test_a_child_that_keeps_working_is_waited_for_and_the_wait_is_told(short_waits: None) -> None:
    said: list[str] = []
    process = child(WORKS_THEN_ANSWERS)
    first = startup.first_line(process, "[arm/rt_driver]", said.append)
    process.wait()
    assert first.line.strip() == '{"ready": true}' and first.why == ""
    assert said, "no progress notice during a start longer than the notice period"
    assert all(line.startswith("[arm/rt_driver] still starting after ") and "load average" in line for line in said)


def test_a_child_that_does_nothing_is_stuck_after_the_stall_period(short_waits: None) -> None:
    process = child("import time; time.sleep(60)")
    try:
        first = startup.first_line(process, "[arm/bridge]", lambda line: None)
    finally:
        process.kill()
        process.wait()
    assert first.line == ""
    assert first.why.startswith("it used no CPU for 1 s without becoming ready (load average ")


def test_a_child_that_exits_says_how() -> None:
    process = child("import sys; sys.exit(3)")
    first = startup.first_line(process, "[arm/recorder]", lambda line: None)
    assert (first.line, first.why) == ("", "it exited with code 3")


def test_a_child_killed_by_a_signal_names_it() -> None:
    process = child("import os, signal; os.kill(os.getpid(), signal.SIGKILL)")
    first = startup.first_line(process, "[arm/planner]", lambda line: None)
    assert (first.line, first.why) == ("", "it was killed by SIGKILL")


def test_a_stop_request_ends_the_wait_without_a_reason() -> None:
    process = child("import time; time.sleep(60)")
    try:
        first = startup.first_line(process, "[arm/rt_driver]", lambda line: None, stopping=lambda: True)
    finally:
        process.kill()
        process.wait()
    assert (first.line, first.why) == ("", "")


def test_cpu_seconds_of_a_process_that_is_gone_is_none() -> None:
    process = child("pass")
    process.wait()
    assert startup.cpu_seconds(process.pid) is None
