"""The RT driver's set-up: the loop settings it takes from the launch, and no shared memory left when it fails."""

from __future__ import annotations

import uuid
from collections.abc import Iterator

import pytest

from plem.errors import PlemError
from plem.ipc.channels import channel_names
from plem.ipc.segment import SegmentError, SharedSegment, segment_path
from plem.launch import rt_driver
from plem.launch.command_process import CommandServiceFailed
from plem.launch.plan import RobotPlan, plan_robot
from plem.launch.rt_driver import build, driving

#: Group ids chown cannot take: beyond 32 bits (an OverflowError in Python) and negative.
IMPOSSIBLE_GROUPS = (2**40, 99_999_999_999, -5)


def left_behind(robot_id: str) -> list[str]:
    return [name for name in channel_names(robot_id).values() if segment_path(name).exists()]


@pytest.fixture
def plan() -> Iterator[RobotPlan]:
    robot_id = f"setup_{uuid.uuid4().hex[:8]}"
    yield plan_robot({"bus": "mock", "robot_id": robot_id, "record": "false"})
    for name in channel_names(robot_id).values():
        segment_path(name).unlink(missing_ok=True)


@pytest.mark.parametrize("group", IMPOSSIBLE_GROUPS)
def test_a_segment_that_cannot_be_given_its_group_is_removed(group: int):
    name = f"/setup_{uuid.uuid4().hex[:8]}_state"
    with pytest.raises(SegmentError) as caught:
        SharedSegment.create(name, 4096, 0o640, group)
    assert "shm_group:=" in caught.value.how
    assert not segment_path(name).exists()


@pytest.mark.parametrize("group", IMPOSSIBLE_GROUPS)
def test_a_driver_that_cannot_create_its_memory_leaves_none(plan: RobotPlan, group: int):
    plan.shm_group = group  # as if the launch's check had been passed by
    with pytest.raises(SegmentError):
        build(plan)
    assert left_behind(plan.robot_id) == []


def test_a_driver_whose_command_service_does_not_start_stops_and_removes_everything(
        plan: RobotPlan, monkeypatch: pytest.MonkeyPatch):
    def refuse(self: object) -> None:
        raise CommandServiceFailed("the command service did not start", what="a command service",
                                   why="refused by the test", how="none")

    monkeypatch.setattr(rt_driver.CommandServiceProcess, "start", refuse)
    with pytest.raises(PlemError, match="the command service did not start"), driving(plan):
        pytest.fail("the driver ran without its command service")
    assert left_behind(plan.robot_id) == []


@pytest.mark.parametrize("arguments, expected", [({}, 1000), ({"max_consecutive_overruns": "25"}, 25)])
def test_the_loop_faults_after_the_overruns_the_launch_allows(arguments: dict[str, str], expected: int):
    plan = plan_robot({"bus": "mock", "robot_id": f"setup_{uuid.uuid4().hex[:8]}", "record": "false", **arguments})
    robot, channels = build(plan)
    try:
        assert robot.loop.settings.max_consecutive_overruns == expected
    finally:
        robot.shutdown()
        channels.remove()
