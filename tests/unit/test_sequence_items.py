"""Sequence items and tool limits as users build them and as the planner reads them from JSON: round trips, and a
WHAT/WHY/HOW naming the item for anything else."""

from __future__ import annotations

import json

import pytest

from plem.errors import MoveItCode, PlanningError
from plem.planning.poses import Pose
from plem.planning.sequence import Circular, Joint, Linear, ToolLimits, item_json, items_from_json

DOWN = Pose((0.4, -0.2, 0.45), (0.0, 1.0, 0.0, 0.0))


@pytest.mark.parametrize("item", [
    Joint("home"), Joint([0.1, 0.2, 0.3, 0.4, 0.5, 0.6], blend=0.02), Joint({"joint0": 0.5}), Joint(DOWN, frame="tcp"),
    Linear(DOWN, blend=0.05), Circular(DOWN, via=(0.4, -0.1, 0.5)), Circular(DOWN, center=DOWN, blend=0.01)])
def test_items_survive_json(item: Joint | Linear | Circular) -> None:
    back = items_from_json(json.loads(json.dumps([item_json(item)])))[0]
    assert item_json(back) == item_json(item)


@pytest.mark.parametrize(("value", "said"), [
    ([], "1 to 1000 items"), ("LIN", "1 to 1000 items"), ([{"type": "SPLINE"}], "item 0 of the sequence"),
    ([{"type": "LIN", "pose": {"position": [0, 0, 0]}}, {"type": "PTP", "target": [0.1, "a"]}], "item 1"),
    ([{"type": "LIN", "pose": {"position": [0, 0, 0]}, "blend": -1}], "blend radius"),
    ([{"type": "LIN", "pose": {"position": [0, 0, 0]}, "blend": True}], "blend radius"),
    ([{"type": "CIRC", "pose": {"position": [0, 0, 0]}}], "via or center"),
    ([{"type": "CIRC", "pose": {"position": [0, 0, 0]}, "via": [0, 0, 1], "center": [0, 1, 0]}], "via or center"),
    ([{"type": "PTP", "target": {"joints": {"joint0": float("nan")}}}], "item 0"),
    ([{"type": "CIRC", "pose": {"position": [0, 0, 0]}, "via": "up"}], "position"),
    ([{"type": "LIN", "pose": {"position": [0, 0, 0]}, "frame": 3}], "frame of item 0")])
def test_malformed_items_are_refused_naming_them(value: object, said: str) -> None:
    with pytest.raises(PlanningError) as caught:
        items_from_json(value)
    error = caught.value
    assert error.code == MoveItCode.INVALID_GOAL_CONSTRAINTS and error.what and error.why and error.how
    assert said in error.render()


def test_tool_limits_scale_and_refuse_nonsense() -> None:
    assert ToolLimits().scaled(0.5, 0.25) == ToolLimits(0.125, 0.3, 0.785, 0.785)
    assert ToolLimits.from_json({"max_trans_vel": 0.1}) == ToolLimits(max_trans_vel=0.1)
    for bad in ({"max_trans_vel": 0}, {"max_rot_vel": "fast"}, {"max_speed": 1.0}, [0.1]):
        with pytest.raises(PlanningError) as caught:
            ToolLimits.from_json(bad)
        assert caught.value.how
