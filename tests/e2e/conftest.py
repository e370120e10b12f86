"""Fixtures shared by the end-to-end tests; each module defines the `robot` launch they attach to."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from plem.bridge import connect
from plem.bridge.client import RobotClient
from tests.e2e.launched import Launch


@pytest.fixture
def client(robot: Launch) -> Iterator[RobotClient]:
    """A command connection to the module's launched robot, checked to be running first."""
    assert robot.process.poll() is None, robot.describe()
    with connect(robot.robot_id) as connected:
        yield connected
