"""Shared fixtures: every test runs with its own PLEM_HOME and no plem/ROS variables from the caller."""

from __future__ import annotations

import os
import random
import signal
from pathlib import Path

import pytest

from plem.core.config.loader import ConfigLoader

ISOLATED_PREFIXES = ("PLEM_", "ROS_", "RMW_", "AMENT_PREFIX_PATH", "CYCLONEDDS_")
#: This process's share of DDS domains. Each pytest-xdist worker (gw0, gw1, ...) of a run takes its own, so
#: tests running side by side never meet; a run without workers takes them all.
_WORKER = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw"))
_WORKERS = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
_RUN = int(os.environ.get("PYTEST_XDIST_TESTRUNUID", "0"), 16) or os.getpid()
TEST_DOMAIN_ID = 1 + (_RUN + _WORKER) % 100
#: Domains above the default test domain's range, each handed out once per process by `fresh_domain`.
_FREE_DOMAINS = random.sample(range(101 + _WORKER, 233, _WORKERS), len(range(101 + _WORKER, 233, _WORKERS)))

# Tests press Ctrl-C on the commands they start. A runner started in the background of a shell without job
# control ignores SIGINT, and its children would inherit that: give them the terminal's default instead.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def fresh_domain() -> int:
    """A DDS domain id no other test of this run uses: Cyclone allows one configuration per domain and process,
    and tests that share a domain would see each other's endpoints."""
    return _FREE_DOMAINS.pop()


@pytest.fixture(autouse=True)
def isolated_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A private PLEM_HOME, a clean environment and an empty YAML cache for each test."""
    for name in list(os.environ):
        if name.startswith(ISOLATED_PREFIXES):
            monkeypatch.delenv(name)
    # DDS stays on this host and on a domain of this test run, never meeting other runs or a real robot.
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(TEST_DOMAIN_ID))
    home = tmp_path / "plem_home"
    monkeypatch.setenv("PLEM_HOME", str(home))
    ConfigLoader.get_instance().invalidate()
    return home
