"""The launch the planner's ROS tests share: `plem launch bus:=mock` with the planner and the bridge, no recorder,
and each test in its domain. A module imports both fixtures to use them."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.e2e.launched import Launch, join_domain, launched_robot


@pytest.fixture(scope="module")
def launch(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "record:=false", "planner:=true", ros=True) as running:
        yield running


@pytest.fixture(autouse=True)
def same_domain(isolated_environment: Path, monkeypatch: pytest.MonkeyPatch, launch: Launch) -> None:
    join_domain(monkeypatch, launch)
