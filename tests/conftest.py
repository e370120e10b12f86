"""Shared fixtures: every test runs with its own PLEM_HOME and no plem/ROS variables from the caller."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from plem.core.config.loader import ConfigLoader

ISOLATED_PREFIXES = ("PLEM_", "ROS_", "RMW_", "AMENT_PREFIX_PATH")


@pytest.fixture(autouse=True)
def isolated_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A private PLEM_HOME, a clean environment and an empty YAML cache for each test."""
    for name in list(os.environ):
        if name.startswith(ISOLATED_PREFIXES):
            monkeypatch.delenv(name)
    home = tmp_path / "plem_home"
    monkeypatch.setenv("PLEM_HOME", str(home))
    ConfigLoader.get_instance().invalidate()
    return home
